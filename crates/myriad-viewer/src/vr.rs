//! `myriad view --vr`: a dataset in a headset through OpenXR (seed 002). The `openxr` crate over
//! the system's loader; Vulkan through XR_KHR_vulkan_enable2, the runtime making the instance
//! and the device wgpu then drives (`vr_vulkan.rs`); each frame the runtime's predicted display
//! time, both eyes' poses and fields of view located, one selection for both eyes, both images
//! drawn in one pass (on the runtime's GPU into a texture; on the CPU where that GPU is a
//! software one, unless `--gpu`), cut into the eyes' swapchain images on the GPU and submitted
//! as a projection layer. The data stand in front of the user at the stage's origin, `scale`
//! metres a data unit, Z up.
//!
//! The hidden area: the runtime's triangles (XR_KHR_visibility_mask, fetched again when it says
//! they changed) mask each eye's pixels for the point pass, and are drawn black over the
//! swapchain images.
//!
//! The controllers (002's interaction; bound for the Khronos simple controller, which every
//! runtime maps its controllers to): the right trigger flies along the right hand's pointing
//! direction, both triggers grab the data (move with the hands, scale with their distance:
//! `vr_nav.rs`), the right menu button marks a measuring point where its ray meets the drawn
//! points; the report gives the distances.
//!
//! Off-axis eyes: each eye's field is cut from a symmetric image holding both eyes' fields
//! (`vr_nav::cover`), pixel for pixel what an off-axis projection draws.

use myriad_format::Dataset;
use myriad_lod::{Camera, SelectOptions};
use myriad_render::stereo::Stereo;
use myriad_render::{Gpu, Rasterizer, Scene, Style};
use openxr as xr;
use std::sync::Arc;
use std::time::Instant;

/// What a VR session did.
#[derive(Debug, Default, Clone)]
pub struct VrReport {
    /// The session reached FOCUSED.
    pub focused: bool,
    /// Frames submitted with both eyes' images, and the views each had.
    pub frames: u64,
    pub views: usize,
    /// Intervals between frame submissions (ms), and the eyes' positions (metres, stage space)
    /// at each submitted frame.
    pub intervals: Vec<f64>,
    pub heads: Vec<[f32; 3]>,
    /// The session ended by the runtime's EXITING (after our request or the user's).
    pub ended: bool,
    /// The runtime's display period (ms), as it predicted it for each frame.
    pub periods: Vec<f64>,
    /// Each eye's image size (the runtime's recommendation).
    pub size: (u32, u32),
    /// Frames whose image was looked at (every frame drawn on the CPU; every
    /// `CHECK_EVERY`th on a GPU, read back), and of those the ones that differed from the one
    /// looked at before (the views follow the head).
    pub checked: u64,
    pub changed: u64,
    /// Pixels lit where the runtime's hidden area is (none: masked), and pixels of the
    /// swapchain images (read back) that differ from the frame they were cut from (the hidden
    /// area's rim at most), in every `CHECK_EVERY`th frame.
    pub hidden_lit: u64,
    pub swapchain_differ: u64,
    /// The runtime's Vulkan device, and what draws.
    pub device: String,
    /// The point budget the frame rate settled on (held at the runtime's display rate).
    pub budget: u64,
    /// Each frame's work (ms): from the runtime's go to the submission.
    pub work: Vec<f64>,
    /// Frames in which both controllers' aim poses were located.
    pub hands: u64,
    /// Points marked with the measuring ray (data coordinates), in order.
    pub measured: Vec<[f64; 3]>,
    /// Per eye, the pixels of its image the runtime's hidden-area mesh hides (masked: black,
    /// skipped by the point pass); None where the runtime has no XR_KHR_visibility_mask.
    pub hidden: Option<[u64; 2]>,
}

/// VR's own options.
#[derive(Debug, Clone)]
pub struct VrOptions {
    /// End the session after this many frames (tests, scripts); None: until the runtime ends it.
    pub frames: Option<u64>,
    pub budget: u64,
    pub style: Style,
    /// Metres a data unit is shown at.
    pub scale: f64,
    /// Draw on the runtime's device even where it is a software one (lavapipe).
    pub gpu: bool,
}

fn err(what: &str) -> impl Fn(xr::sys::Result) -> String + '_ {
    move |e| format!("{what}: {e}")
}

/// Runs a VR session on `dataset` until the runtime ends it (or `o.frames` were submitted).
pub fn run(dataset: Arc<Dataset>, o: &VrOptions) -> Result<VrReport, String> {
    // SAFETY: the system's OpenXR loader conforms to the specification. Debian's
    // libopenxr-loader1 has the versioned name only (libopenxr-dev adds the plain one).
    let entry = unsafe {
        xr::Entry::load(&())
            .or_else(|_| xr::Entry::load_from(std::path::Path::new("libopenxr_loader.so.1"), &()))
    }
    .map_err(|e| {
        format!("no OpenXR loader ({e}): install the OpenXR loader (Debian: libopenxr-loader1)")
    })?;
    let available = entry
        .enumerate_extensions()
        .map_err(|e| format!("no OpenXR runtime ({e}): install one, or set XR_RUNTIME_JSON"))?;
    if !available.khr_vulkan_enable2 {
        return Err("the OpenXR runtime has no XR_KHR_vulkan_enable2 (Vulkan)".into());
    }
    let mut wanted = xr::ExtensionSet::default();
    wanted.khr_vulkan_enable2 = true;
    wanted.khr_visibility_mask = available.khr_visibility_mask;
    let instance = entry
        .create_instance(
            &xr::ApplicationInfo {
                application_name: "myriad",
                application_version: 1,
                engine_name: "myriad",
                engine_version: 1,
                api_version: xr::Version::new(1, 0, 0),
            },
            &wanted,
            &[],
            &(),
        )
        .map_err(|e| format!("no OpenXR runtime ({e}): install one, or set XR_RUNTIME_JSON"))?;
    let system = instance
        .system(xr::FormFactor::HEAD_MOUNTED_DISPLAY)
        .map_err(|e| format!("no headset ({e})"))?;
    let views_config = instance
        .enumerate_view_configuration_views(system, xr::ViewConfigurationType::PRIMARY_STEREO)
        .map_err(err("the headset's views"))?;
    if views_config.len() != 2 {
        return Err(format!(
            "the headset has {} views, not two",
            views_config.len()
        ));
    }
    // Vulkan through the runtime, under wgpu.
    let xr_device = crate::vr_vulkan::create(&instance, system)?;
    // SAFETY: the handles come from the runtime's Vulkan instance and device above.
    let (session, mut waiter, mut stream) =
        unsafe { instance.create_session::<xr::Vulkan>(system, &xr_device.session_info) }
            .map_err(err("the OpenXR session"))?;
    let space = session
        .create_reference_space(xr::ReferenceSpaceType::STAGE, xr::Posef::IDENTITY)
        .or_else(|_| {
            session.create_reference_space(xr::ReferenceSpaceType::LOCAL, xr::Posef::IDENTITY)
        })
        .map_err(err("a reference space"))?;
    let (w, h) = (
        views_config[0].recommended_image_rect_width,
        views_config[0].recommended_image_rect_height,
    );
    let xr_gpu = xr_device.gpu;
    let mut swapchains = crate::vr_vulkan::Eyes::new(&session, &xr_gpu, (w, h))?;
    // The lenses' hidden areas (the runtime's triangles), and each eye's mask in its symmetric
    // image made from them for the fields the runtime gives.
    // A runtime that offers the extension but fails to give a mesh: drawn without it.
    let fetch = |session: &xr::Session<xr::Vulkan>| {
        hidden_meshes(session)
            .inspect_err(|e| eprintln!("warning: {e}: no hidden-area mask"))
            .ok()
    };
    let mut hidden = if wanted.khr_visibility_mask {
        fetch(&session)
    } else {
        None
    };
    let mut masks: Option<(crate::vr_nav::Cover, [Vec<bool>; 2])> = None;

    // The data and the renderer.
    let mut scene = Scene::open(dataset.clone(), 2 << 30, 1 << 30);
    // The runtime's device draws where it is a hardware GPU (or where asked to); a software
    // one (lavapipe) leaves the drawing to the CPU path, as the window does.
    let on_gpu = o.gpu || !xr_gpu.software;
    let cpu = Gpu::cpu();
    let gpu = if on_gpu { &xr_gpu } else { &cpu };
    let raster = Rasterizer::new(gpu);
    let mut options = SelectOptions {
        budget: o.budget,
        min_pixels: 1.0,
    };
    // The budget follows the time a frame's work takes against the runtime's display period
    // (002: the budget adjusted to hold the headset's rate; 90 fps where it says none).
    let mut pace: Option<myriad_lod::Pace> = None;
    let mut last_image = 0u64;
    let centre = scene.view_bounds.center();
    // The data's centre, at its ground, at the stage's origin.
    let mut nav =
        crate::vr_nav::StageNav::new([centre[0], centre[1], scene.view_bounds.min[2]], o.scale);
    let hands = Hands::new(&instance, &session)?;
    let mut measure_was = false;
    let mut last_work: Option<Instant> = None;
    let mut report = VrReport {
        views: 2,
        size: (w, h),
        device: format!(
            "{}, drawing on {}",
            xr_gpu.name,
            if on_gpu { "it" } else { "the CPU" }
        ),
        ..Default::default()
    };
    let mut running = false;
    let mut last = None;
    let mut events = xr::EventDataBuffer::new();
    'frames: loop {
        while let Some(event) = instance
            .poll_event(&mut events)
            .map_err(err("OpenXR events"))?
        {
            match event {
                xr::Event::SessionStateChanged(e) => match e.state() {
                    xr::SessionState::READY => {
                        session
                            .begin(xr::ViewConfigurationType::PRIMARY_STEREO)
                            .map_err(err("beginning the session"))?;
                        running = true;
                    }
                    xr::SessionState::FOCUSED => report.focused = true,
                    xr::SessionState::STOPPING => {
                        session.end().map_err(err("ending the session"))?;
                        running = false;
                    }
                    xr::SessionState::EXITING | xr::SessionState::LOSS_PENDING => {
                        report.ended = true;
                        break 'frames;
                    }
                    _ => {}
                },
                xr::Event::VisibilityMaskChangedKHR(_) => {
                    hidden = fetch(&session);
                    masks = None;
                }
                xr::Event::InstanceLossPending(_) => break 'frames,
                _ => {}
            }
        }
        if !running {
            std::thread::sleep(std::time::Duration::from_millis(5));
            continue;
        }
        let state = waiter.wait().map_err(err("waiting for a frame"))?;
        let work = Instant::now();
        report
            .periods
            .push(state.predicted_display_period.as_nanos() as f64 / 1e6);
        stream.begin().map_err(err("beginning a frame"))?;
        if !state.should_render {
            stream
                .end(
                    state.predicted_display_time,
                    xr::EnvironmentBlendMode::OPAQUE,
                    &[],
                )
                .map_err(err("ending a frame"))?;
            continue;
        }
        let (_, views) = session
            .locate_views(
                xr::ViewConfigurationType::PRIMARY_STEREO,
                state.predicted_display_time,
                &space,
            )
            .map_err(err("locating the eyes"))?;
        // Stage space (metres, Y up) to data (units, Z up): the data's centre at the stage's
        // origin, a data unit `scale` metres.
        // The controllers: fly with the right trigger, grab with both (move and scale), mark a
        // measuring point with the right menu button where its ray meets the data.
        let input = hands.read(&session, &space, state.predicted_display_time)?;
        let now = Instant::now();
        let dt = last_work.map_or(0.0, |t| now.duration_since(t).as_secs_f64());
        last_work = Some(now);
        report.hands += input.located as u64;
        match (input.select, input.aim) {
            ([true, true], [Some(l), Some(r)]) => nav.grab(Some([l.0, r.0])),
            ([false, true], [_, Some(r)]) => {
                nav.grab(None);
                nav.fly(r.1, dt, FLY_SPEED);
            }
            _ => nav.grab(None),
        }
        let to_data = |v: xr::Vector3f| nav.to_data([v.x as f64, v.y as f64, v.z as f64]);
        // Off-axis eyes cut from symmetric images holding both fields (`vr_nav::cover`).
        let tangents = [0, 1].map(|k| {
            let f = views[k].fov;
            crate::vr_nav::Tangents {
                left: (f.angle_left as f64).tan(),
                right: (f.angle_right as f64).tan(),
                up: (f.angle_up as f64).tan(),
                down: (f.angle_down as f64).tan(),
            }
        });
        let cover = crate::vr_nav::cover(tangents, w, h);
        if masks.as_ref().is_none_or(|m| m.0 != cover) {
            let none = [Vec::new(), Vec::new()];
            let tris = hidden.as_ref().unwrap_or(&none);
            let m = [0, 1].map(|k| cover.mask(k, w, h, &tris[k]));
            // The runtime's hidden pixels in each eye's own field (its cut).
            let outside = (cover.width * cover.height - w * h) as u64;
            report.hidden = hidden.is_some().then(|| {
                m.each_ref()
                    .map(|m| m.iter().filter(|&&b| b).count() as u64 - outside)
            });
            masks = Some((cover, m));
            // The hidden area over each eye's cut, drawn black into its swapchain image.
            for k in 0..2 {
                let tris = hidden.as_ref().map_or(&[][..], |t| &t[k][..]);
                swapchains.set_hidden(&xr_gpu, k, tris, cover.drawn[k]);
            }
        }
        let eyes: [Camera; 2] = std::array::from_fn(|k| {
            let pose = views[k].pose;
            let forward = rotate(pose.orientation, [0.0, 0.0, -1.0]);
            let up = rotate(pose.orientation, [0.0, 1.0, 0.0]);
            let p = pose.position;
            let at = xr::Vector3f {
                x: p.x + forward.x,
                y: p.y + forward.y,
                z: p.z + forward.z,
            };
            let up_data = crate::vr_nav::to_data_axes([up.x as f64, up.y as f64, up.z as f64]);
            Camera {
                position: to_data(p),
                target: to_data(at),
                up: up_data,
                fov_y: cover.fov_y,
                width: cover.width,
                height: cover.height,
                near: 0.05 / nav.scale,
                far: 1e4 / nav.scale,
            }
        });
        let stereo = Stereo {
            ipd: 0.0,
            single_pass: true,
            hidden_area: true,
        };
        let eye_masks = masks.as_ref().map(|m| &m.1);
        // On the GPU the frame is drawn into the texture the eyes are cut from, and read back
        // (to see that it follows the head) every `CHECK_EVERY` frames only.
        let wide = (2 * cover.width, cover.height);
        let verify = report.frames.is_multiple_of(CHECK_EVERY);
        let checked = !on_gpu || verify;
        raster.present_to((!checked).then(|| {
            swapchains
                .frame(&xr_gpu, wide.0, wide.1)
                .create_view(&Default::default())
        }));
        let (image, stats) =
            scene.frame_stereo(gpu, &raster, &eyes, &options, &o.style, &stereo, eye_masks);
        if input.measure
            && !measure_was
            && let Some((at, dir)) = input.aim[1]
        {
            // A narrow camera along the ray; the nearest drawn point under its centre.
            let from = nav.to_data(at);
            let d = crate::vr_nav::to_data_axes(dir);
            let ray = Camera {
                position: from,
                target: std::array::from_fn(|a| from[a] + d[a]),
                up: [0.0, 0.0, 1.0],
                fov_y: 5.0,
                width: 65,
                height: 65,
                near: 0.01 / nav.scale,
                far: 1e4 / nav.scale,
            };
            if let Some(p) = scene.pick(&ray, 32.5, 32.5, 3.0) {
                report.measured.push(p.position);
            }
        }
        measure_was = input.measure;
        if checked {
            // FNV-1a of the image: did the view change since the last frame checked?
            let hash = image.iter().fold(0xcbf29ce484222325u64, |h, &b| {
                (h ^ b as u64).wrapping_mul(0x100000001b3)
            });
            report.changed += (report.checked > 0 && hash != last_image) as u64;
            report.checked += 1;
            last_image = hash;
        }
        // Every `CHECK_EVERY`th frame (read back on a GPU too): no pixel the runtime hides lit.
        if verify && let Some((_, m)) = &masks {
            let full = cover.width as usize;
            for (k, m) in m.iter().enumerate() {
                report.hidden_lit += m
                    .iter()
                    .enumerate()
                    .filter(|&(i, &hidden)| {
                        let at = ((i / full) * 2 * full + k * full + i % full) * 4;
                        hidden && image[at..at + 3] != [0, 0, 0]
                    })
                    .count() as u64;
            }
        }
        // Each eye's field cut from its half of the side-by-side frame into its swapchain.
        let corners = [0, 1].map(|k| {
            (
                k as u32 * cover.width + cover.corners[k].0,
                cover.corners[k].1,
            )
        });
        let upload = checked.then_some(&image[..]);
        if let Some(d) = swapchains.submit(&xr_gpu, upload, verify, wide, corners)? {
            report.swapchain_differ += d;
        }
        // The field each cut covers (the eye's own, to a pixel).
        let layer_views: Vec<(xr::Posef, xr::Fovf)> = (0..2)
            .map(|k| {
                let t = cover.drawn[k];
                let drawn = xr::Fovf {
                    angle_left: t.left.atan() as f32,
                    angle_right: t.right.atan() as f32,
                    angle_up: t.up.atan() as f32,
                    angle_down: t.down.atan() as f32,
                };
                (views[k].pose, drawn)
            })
            .collect();
        let projection: Vec<xr::CompositionLayerProjectionView<xr::Vulkan>> = layer_views
            .iter()
            .zip(&swapchains.swapchains)
            .map(|(&(pose, fov), sc)| {
                xr::CompositionLayerProjectionView::new()
                    .pose(pose)
                    .fov(fov)
                    .sub_image(
                        xr::SwapchainSubImage::new()
                            .swapchain(sc)
                            .image_array_index(0)
                            .image_rect(xr::Rect2Di {
                                offset: xr::Offset2Di { x: 0, y: 0 },
                                extent: xr::Extent2Di {
                                    width: w as i32,
                                    height: h as i32,
                                },
                            }),
                    )
            })
            .collect();
        stream
            .end(
                state.predicted_display_time,
                xr::EnvironmentBlendMode::OPAQUE,
                &[&xr::CompositionLayerProjection::new()
                    .space(&space)
                    .views(&projection)],
            )
            .map_err(err("submitting a frame"))?;
        report.frames += 1;
        let period = state.predicted_display_period.as_nanos() as f64 / 1e9;
        let p = pace.get_or_insert_with(|| myriad_lod::Pace::new(90.0, o.budget, 20_000, o.budget));
        // The runtime's period as it predicts it now (it may settle after the first frames).
        if period > 0.0 {
            p.target = period;
        }
        report.work.push(work.elapsed().as_secs_f64() * 1e3);
        let limited = stats.selected_points as f64 >= 0.98 * options.budget as f64;
        options.budget = p.frame(work.elapsed().as_secs_f64(), stats.points, limited);
        report.budget = options.budget;
        let p = views[0].pose.position;
        report.heads.push([p.x, p.y, p.z]);
        let now = Instant::now();
        if let Some(t) = last {
            report
                .intervals
                .push(now.duration_since(t).as_secs_f64() * 1e3);
        }
        last = Some(now);
        if o.frames.is_some_and(|n| report.frames == n) {
            session.request_exit().map_err(err("asking to end"))?;
        }
    }
    drop(swapchains);
    drop(session);
    Ok(report)
}

/// Each eye's hidden-area triangles from the runtime (XR_KHR_visibility_mask), in tangents of
/// its view (x right, y up: the mesh lies on the plane one unit ahead).
fn hidden_meshes(session: &xr::Session<xr::Vulkan>) -> Result<[Vec<[[f64; 2]; 3]>; 2], String> {
    let mut out = [Vec::new(), Vec::new()];
    for (k, tris) in out.iter_mut().enumerate() {
        let m = session
            .get_visibility_mask_khr(
                xr::ViewConfigurationType::PRIMARY_STEREO,
                k as u32,
                xr::VisibilityMaskTypeKHR::HIDDEN_TRIANGLE_MESH,
            )
            .map_err(err("the hidden-area mesh"))?;
        for t in m.indices.chunks_exact(3) {
            let v = |i: u32| {
                m.vertices
                    .get(i as usize)
                    .map(|v| [v.x as f64, v.y as f64])
                    .ok_or_else(|| {
                        format!("the hidden-area mesh: vertex {i} of {}", m.vertices.len())
                    })
            };
            tris.push([v(t[0])?, v(t[1])?, v(t[2])?]);
        }
    }
    Ok(out)
}

/// A frame in this many is read back (on a GPU) and its swapchain images compared with it.
pub const CHECK_EVERY: u64 = 10;

/// Metres a second the right trigger flies.
const FLY_SPEED: f64 = 2.0;

/// The controllers' actions: aim poses and triggers (select) of both hands, the right menu
/// button (measure), bound for the Khronos simple controller (every runtime maps its controllers
/// to it).
struct Hands {
    set: xr::ActionSet,
    select: xr::Action<bool>,
    menu: xr::Action<bool>,
    paths: [xr::Path; 2],
    spaces: [xr::Space; 2],
}

/// What the controllers did this frame.
struct Input {
    /// Each hand's aim: position and pointing direction (stage).
    aim: [Option<([f64; 3], [f64; 3])>; 2],
    select: [bool; 2],
    measure: bool,
    /// Both aims located.
    located: bool,
}

impl Hands {
    fn new(instance: &xr::Instance, session: &xr::Session<xr::Vulkan>) -> Result<Hands, String> {
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

    fn read(
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
fn rotate(q: xr::Quaternionf, v: [f32; 3]) -> xr::Vector3f {
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
