//! The headset's controllers in a VR session (`vr.rs`): the actions (aim poses and triggers of
//! both hands, the right menu button) bound for the Khronos simple controller, which every
//! runtime maps its controllers to, and what they did each frame, in the stage's space.

use openxr as xr;

/// The controllers' actions: aim poses and triggers (select) of both hands, the right menu
/// button (measure), bound for the Khronos simple controller (every runtime maps its controllers
/// to it).
pub(crate) struct Hands {
    set: xr::ActionSet,
    select: xr::Action<bool>,
    menu: xr::Action<bool>,
    paths: [xr::Path; 2],
    spaces: [xr::Space; 2],
}

/// What the controllers did this frame.
pub(crate) struct Input {
    /// Each hand's aim: position and pointing direction (stage).
    pub aim: [Option<([f64; 3], [f64; 3])>; 2],
    pub select: [bool; 2],
    pub measure: bool,
    /// Both aims located.
    pub located: bool,
}

impl Hands {
    pub fn new(
        instance: &xr::Instance,
        session: &xr::Session<xr::Vulkan>,
    ) -> Result<Hands, String> {
        let e = |what: &'static str| move |r: xr::sys::Result| format!("controllers ({what}): {r}");
        let set = instance
            .create_action_set("myriad", "myriad", 0)
            .map_err(e("action set"))?;
        let paths = [
            instance
                .string_to_path("/user/hand/left")
                .map_err(e("path"))?,
            instance
                .string_to_path("/user/hand/right")
                .map_err(e("path"))?,
        ];
        let aim = set
            .create_action::<xr::Posef>("aim", "pointing", &paths)
            .map_err(e("aim"))?;
        let select = set
            .create_action::<bool>("select", "fly, and with both hands grab", &paths)
            .map_err(e("select"))?;
        let menu = set
            .create_action::<bool>("measure", "measure", &paths[1..])
            .map_err(e("measure"))?;
        let p = |s: &str| instance.string_to_path(s).map_err(e("binding path"));
        instance
            .suggest_interaction_profile_bindings(
                p("/interaction_profiles/khr/simple_controller")?,
                &[
                    xr::Binding::new(&aim, p("/user/hand/left/input/aim/pose")?),
                    xr::Binding::new(&aim, p("/user/hand/right/input/aim/pose")?),
                    xr::Binding::new(&select, p("/user/hand/left/input/select/click")?),
                    xr::Binding::new(&select, p("/user/hand/right/input/select/click")?),
                    xr::Binding::new(&menu, p("/user/hand/right/input/menu/click")?),
                ],
            )
            .map_err(e("bindings"))?;
        session.attach_action_sets(&[&set]).map_err(e("attach"))?;
        let spaces = [
            aim.create_space(session, paths[0], xr::Posef::IDENTITY)
                .map_err(e("space"))?,
            aim.create_space(session, paths[1], xr::Posef::IDENTITY)
                .map_err(e("space"))?,
        ];
        Ok(Hands {
            set,
            select,
            menu,
            paths,
            spaces,
        })
    }

    pub fn read(
        &self,
        session: &xr::Session<xr::Vulkan>,
        base: &xr::Space,
        time: xr::Time,
    ) -> Result<Input, String> {
        let e = |r: xr::sys::Result| format!("controllers: {r}");
        session.sync_actions(&[(&self.set).into()]).map_err(e)?;
        let mut aim = [None, None];
        for (k, space) in self.spaces.iter().enumerate() {
            let l = space.locate(base, time).map_err(e)?;
            let valid =
                xr::SpaceLocationFlags::POSITION_VALID | xr::SpaceLocationFlags::ORIENTATION_VALID;
            if l.location_flags.contains(valid) {
                let q = l.pose.orientation;
                let d = rotate(q, [0.0, 0.0, -1.0]);
                let p = l.pose.position;
                aim[k] = Some((
                    [p.x as f64, p.y as f64, p.z as f64],
                    [d.x as f64, d.y as f64, d.z as f64],
                ));
            }
        }
        let on = |a: &xr::Action<bool>, path| -> Result<bool, String> {
            let s = a.state(session, path).map_err(e)?;
            Ok(s.is_active && s.current_state)
        };
        Ok(Input {
            located: aim.iter().all(Option::is_some),
            aim,
            select: [
                on(&self.select, self.paths[0])?,
                on(&self.select, self.paths[1])?,
            ],
            measure: on(&self.menu, self.paths[1])?,
        })
    }
}

/// `v` turned by the unit quaternion `q`.
pub(crate) fn rotate(q: xr::Quaternionf, v: [f32; 3]) -> xr::Vector3f {
    let (x, y, z, w) = (q.x, q.y, q.z, q.w);
    let t = [
        2.0 * (y * v[2] - z * v[1]),
        2.0 * (z * v[0] - x * v[2]),
        2.0 * (x * v[1] - y * v[0]),
    ];
    xr::Vector3f {
        x: v[0] + w * t[0] + (y * t[2] - z * t[1]),
        y: v[1] + w * t[1] + (z * t[0] - x * t[2]),
        z: v[2] + w * t[2] + (x * t[1] - y * t[0]),
    }
}
