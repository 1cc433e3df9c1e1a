//! `myriad view --vr`: a dataset in a headset through OpenXR (Discher et al. 2018). The `openxr`
//! crate over the system's loader; Vulkan through XR_KHR_vulkan_enable2, the runtime making the
//! instance and the device wgpu then drives (`vr_vulkan.rs`); each frame the runtime's
//! predicted display time, both eyes' poses and fields of view located, one selection for both
//! eyes, both images drawn in one pass (on the runtime's GPU into a texture; on the CPU where
//! that GPU is a software one, unless `--gpu`), cut into the eyes' swapchain images on the GPU
//! and submitted as a projection layer. The data stand in front of the user at the stage's
//! origin, `scale` metres a data unit, Z up.
//!
//! The session is [`run`]'s steps: the runtime opened (`Runtime`), the session set up
//! (`Vr::begin`), then per frame: events polled, the frame waited for, the eyes located, the
//! controllers read, the eyes' fields fitted, both eyes selected and drawn, a measuring point
//! taken, the image checked, the frame submitted, the budget paced and the frame reported;
//! the session let go (`Vr::finish`).
//!
//! The hidden area: the runtime's triangles (XR_KHR_visibility_mask, fetched again when it says
//! they changed) mask each eye's pixels for the point pass, and are drawn black over the
//! swapchain images.
//!
//! The controllers (`vr_hands.rs`; Discher et al. 2018's interaction; bound for the Khronos
//! simple controller, which every runtime maps its controllers to): the right trigger flies
//! along the right hand's pointing direction, both triggers grab the data (move with the hands,
//! scale with their distance: `vr_nav.rs`), the right menu button marks a measuring point where
//! its ray meets the drawn points; the report gives the distances.
//!
//! Off-axis eyes: each eye's field is cut from a symmetric image holding both eyes' fields
//! (`vr_nav::cover`), pixel for pixel what an off-axis projection draws.

use crate::vr_hands::{Hands, Input, rotate};
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

/// Runs a VR session on `dataset` until the runtime ends it (or `o.frames` were submitted):
/// the runtime opened, the session set up, then frame after frame (events polled, the frame
/// waited for, the eyes located, the controllers read, both eyes selected and drawn, the
/// frame submitted, the budget paced) until the session ends.
pub fn run(dataset: Arc<Dataset>, o: &VrOptions) -> Result<VrReport, String> {
    let runtime = Runtime::open()?;
    let mut vr = Vr::begin(&runtime, dataset, o)?;
    while vr.frame(&runtime, o)? {}
    Ok(vr.finish())
}

/// The OpenXR runtime: the loader, the instance (with the extensions wanted), the headset and
/// its two views. (Fields drop in this order: the reverse of their making.)
struct Runtime {
    views: Vec<xr::ViewConfigurationView>,
    system: xr::SystemId,
    instance: xr::Instance,
    wanted: xr::ExtensionSet,
    _entry: xr::Entry,
}

impl Runtime {
    /// The system's loader, a runtime with Vulkan, a headset with two views.
    fn open() -> Result<Runtime, String> {
        // SAFETY: the system's OpenXR loader conforms to the specification. Debian's
        // libopenxr-loader1 has the versioned name only (libopenxr-dev adds the plain one).
        let entry = unsafe {
            xr::Entry::load(&()).or_else(|_| {
                xr::Entry::load_from(std::path::Path::new("libopenxr_loader.so.1"), &())
            })
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
        let views = instance
            .enumerate_view_configuration_views(system, xr::ViewConfigurationType::PRIMARY_STEREO)
            .map_err(err("the headset's views"))?;
        if views.len() != 2 {
            return Err(format!("the headset has {} views, not two", views.len()));
        }
        Ok(Runtime {
            views,
            system,
            instance,
            wanted,
            _entry: entry,
        })
    }
}

/// A hidden-area mask (the runtime's triangles, XR_KHR_visibility_mask): each eye's triangles
/// in tangents of its view.
type Hidden = [Vec<[[f64; 2]; 3]>; 2];

/// A running session and what draws into it. (Fields drop in this order, the reverse of their
/// making, as the locals of one function did; [`Vr::finish`] drops the swapchains and the
/// session first.)
struct Vr {
    events: xr::EventDataBuffer,
    /// When the last frame was submitted.
    last: Option<Instant>,
    /// The session is running (between READY and STOPPING).
    running: bool,
    report: VrReport,
    /// When the last frame's work began (the controllers' time step).
    last_work: Option<Instant>,
    /// The measure button was down in the frame before.
    measure_was: bool,
    hands: Hands,
    nav: crate::vr_nav::StageNav,
    /// FNV-1a of the last image checked.
    last_image: u64,
    /// The budget following the time a frame's work takes against the runtime's display
    /// period (Discher et al. 2018: the budget adjusted to hold the headset's rate; 90 fps
    /// where it says none).
    pace: Option<myriad_lod::Pace>,
    options: SelectOptions,
    raster: Rasterizer,
    /// The CPU path, drawing where the runtime's device is a software one.
    cpu: Gpu,
    /// The runtime's device draws.
    on_gpu: bool,
    scene: Scene,
    /// The cut of the eyes' fields and each eye's mask in it, for the hidden area below.
    masks: Option<(crate::vr_nav::Cover, [Vec<bool>; 2])>,
    hidden: Option<Hidden>,
    swapchains: crate::vr_vulkan::Eyes,
    xr_gpu: Gpu,
    /// Each eye's image size (the runtime's recommendation).
    size: (u32, u32),
    space: xr::Space,
    stream: xr::FrameStream<xr::Vulkan>,
    waiter: xr::FrameWaiter,
    session: xr::Session<xr::Vulkan>,
}

/// A frame drawn: the side-by-side image (both eyes' symmetric images), its statistics, its
/// size, whether it was looked at (read back) and whether its swapchain images are compared.
struct Drawn {
    image: Vec<u8>,
    stats: myriad_render::FrameStats,
    wide: (u32, u32),
    checked: bool,
    verify: bool,
}

/// The hidden area's triangles, where the runtime gives them; a runtime that offers the
/// extension but fails to give a mesh: drawn without it.
fn fetch_hidden(session: &xr::Session<xr::Vulkan>) -> Option<Hidden> {
    hidden_meshes(session)
        .inspect_err(|e| eprintln!("warning: {e}: no hidden-area mask"))
        .ok()
}

impl Vr {
    /// Session set-up: Vulkan through the runtime (under wgpu), the session, the stage, the
    /// eyes' swapchains, the lenses' hidden areas; the data, the renderer, the controllers.
    fn begin(rt: &Runtime, dataset: Arc<Dataset>, o: &VrOptions) -> Result<Vr, String> {
        let (instance, system) = (&rt.instance, rt.system);
        // Vulkan through the runtime, under wgpu.
        let xr_device = crate::vr_vulkan::create(instance, system)?;
        // SAFETY: the handles come from the runtime's Vulkan instance and device above.
        let (session, waiter, stream) =
            unsafe { instance.create_session::<xr::Vulkan>(system, &xr_device.session_info) }
                .map_err(err("the OpenXR session"))?;
        let space = session
            .create_reference_space(xr::ReferenceSpaceType::STAGE, xr::Posef::IDENTITY)
            .or_else(|_| {
                session.create_reference_space(xr::ReferenceSpaceType::LOCAL, xr::Posef::IDENTITY)
            })
            .map_err(err("a reference space"))?;
        let (w, h) = (
            rt.views[0].recommended_image_rect_width,
            rt.views[0].recommended_image_rect_height,
        );
        let xr_gpu = xr_device.gpu;
        let swapchains = crate::vr_vulkan::Eyes::new(&session, &xr_gpu, (w, h))?;
        // The lenses' hidden areas (the runtime's triangles), and each eye's mask in its
        // symmetric image made from them for the fields the runtime gives.
        let hidden = if rt.wanted.khr_visibility_mask {
            fetch_hidden(&session)
        } else {
            None
        };

        // The data and the renderer.
        let scene = Scene::open(dataset.clone(), 2 << 30, 1 << 30);
        // The runtime's device draws where it is a hardware GPU (or where asked to); a software
        // one (lavapipe) leaves the drawing to the CPU path, as the window does.
        let on_gpu = o.gpu || !xr_gpu.software;
        let cpu = Gpu::cpu();
        let raster = Rasterizer::new(if on_gpu { &xr_gpu } else { &cpu });
        let options = SelectOptions {
            budget: o.budget,
            min_pixels: 1.0,
        };
        let centre = scene.view_bounds.center();
        // The data's centre, at its ground, at the stage's origin.
        let nav =
            crate::vr_nav::StageNav::new([centre[0], centre[1], scene.view_bounds.min[2]], o.scale);
        let hands = Hands::new(instance, &session)?;
        let report = VrReport {
            views: 2,
            size: (w, h),
            device: format!(
                "{}, drawing on {}",
                xr_gpu.name,
                if on_gpu { "it" } else { "the CPU" }
            ),
            ..Default::default()
        };
        Ok(Vr {
            events: xr::EventDataBuffer::new(),
            last: None,
            running: false,
            report,
            last_work: None,
            measure_was: false,
            hands,
            nav,
            last_image: 0,
            pace: None,
            options,
            raster,
            cpu,
            on_gpu,
            scene,
            masks: None,
            hidden,
            swapchains,
            xr_gpu,
            size: (w, h),
            space,
            stream,
            waiter,
            session,
        })
    }

    /// One turn of the frame loop; false: the session ended.
    fn frame(&mut self, rt: &Runtime, o: &VrOptions) -> Result<bool, String> {
        if !self.poll_events(&rt.instance)? {
            return Ok(false);
        }
        if !self.running {
            std::thread::sleep(std::time::Duration::from_millis(5));
            return Ok(true);
        }
        let Some((state, work)) = self.wait_frame()? else {
            return Ok(true);
        };
        let views = self.locate_views(state.predicted_display_time)?;
        let input = self.steer(state.predicted_display_time)?;
        let cover = self.fit(&views);
        let eyes = self.eyes(&views, &cover);
        let drawn = self.draw(&eyes, &cover, o);
        self.measure(&input);
        self.check(&drawn, &cover);
        self.submit(&state, &views, &cover, &drawn)?;
        self.pace(&state, work, &drawn.stats, &views, o)?;
        Ok(true)
    }

    /// Step: the runtime's events: the session begun when READY, ended when STOPPING; the
    /// hidden area fetched again when it changed. False: the session is over (EXITING, LOSS
    /// PENDING, the instance lost).
    fn poll_events(&mut self, instance: &xr::Instance) -> Result<bool, String> {
        while let Some(event) = instance
            .poll_event(&mut self.events)
            .map_err(err("OpenXR events"))?
        {
            match event {
                xr::Event::SessionStateChanged(e) => match e.state() {
                    xr::SessionState::READY => {
                        self.session
                            .begin(xr::ViewConfigurationType::PRIMARY_STEREO)
                            .map_err(err("beginning the session"))?;
                        self.running = true;
                    }
                    xr::SessionState::FOCUSED => self.report.focused = true,
                    xr::SessionState::STOPPING => {
                        self.session.end().map_err(err("ending the session"))?;
                        self.running = false;
                    }
                    xr::SessionState::EXITING | xr::SessionState::LOSS_PENDING => {
                        self.report.ended = true;
                        return Ok(false);
                    }
                    _ => {}
                },
                xr::Event::VisibilityMaskChangedKHR(_) => {
                    self.hidden = fetch_hidden(&self.session);
                    self.masks = None;
                }
                xr::Event::InstanceLossPending(_) => return Ok(false),
                _ => {}
            }
        }
        Ok(true)
    }

    /// Step: waits for the runtime's go and begins the frame; the frame state and when its
    /// work began, or None where it is not to be drawn (then ended empty).
    fn wait_frame(&mut self) -> Result<Option<(xr::FrameState, Instant)>, String> {
        let state = self.waiter.wait().map_err(err("waiting for a frame"))?;
        let work = Instant::now();
        self.report
            .periods
            .push(state.predicted_display_period.as_nanos() as f64 / 1e6);
        self.stream.begin().map_err(err("beginning a frame"))?;
        if !state.should_render {
            self.stream
                .end(
                    state.predicted_display_time,
                    xr::EnvironmentBlendMode::OPAQUE,
                    &[],
                )
                .map_err(err("ending a frame"))?;
            return Ok(None);
        }
        Ok(Some((state, work)))
    }

    /// Step: both eyes' poses and fields at the predicted display `time`, in the stage.
    fn locate_views(&self, time: xr::Time) -> Result<Vec<xr::View>, String> {
        let (_, views) = self
            .session
            .locate_views(xr::ViewConfigurationType::PRIMARY_STEREO, time, &self.space)
            .map_err(err("locating the eyes"))?;
        Ok(views)
    }

    /// Step: the controllers at `time`: fly with the right trigger, grab with both (move and
    /// scale); what they did (the measure button is taken after drawing).
    fn steer(&mut self, time: xr::Time) -> Result<Input, String> {
        // Stage space (metres, Y up) to data (units, Z up): the data's centre at the stage's
        // origin, a data unit `scale` metres.
        // The controllers: fly with the right trigger, grab with both (move and scale), mark a
        // measuring point with the right menu button where its ray meets the data.
        let input = self.hands.read(&self.session, &self.space, time)?;
        let now = Instant::now();
        let dt = self
            .last_work
            .map_or(0.0, |t| now.duration_since(t).as_secs_f64());
        self.last_work = Some(now);
        self.report.hands += input.located as u64;
        let nav = &mut self.nav;
        match (input.select, input.aim) {
            ([true, true], [Some(l), Some(r)]) => nav.grab(Some([l.0, r.0])),
            ([false, true], [_, Some(r)]) => {
                nav.grab(None);
                nav.fly(r.1, dt, FLY_SPEED);
            }
            _ => nav.grab(None),
        }
        Ok(input)
    }

    /// Step: off-axis eyes cut from symmetric images holding both fields
    /// (`vr_nav::cover`); where the cut changed, each eye's mask of the hidden area in it, and
    /// the hidden area drawn black into its swapchain image.
    fn fit(&mut self, views: &[xr::View]) -> crate::vr_nav::Cover {
        let (w, h) = self.size;
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
        if self.masks.as_ref().is_none_or(|m| m.0 != cover) {
            let hidden = &self.hidden;
            let none = [Vec::new(), Vec::new()];
            let tris = hidden.as_ref().unwrap_or(&none);
            let m = [0, 1].map(|k| cover.mask(k, w, h, &tris[k]));
            // The runtime's hidden pixels in each eye's own field (its cut).
            let outside = (cover.width * cover.height - w * h) as u64;
            self.report.hidden = hidden.is_some().then(|| {
                m.each_ref()
                    .map(|m| m.iter().filter(|&&b| b).count() as u64 - outside)
            });
            self.masks = Some((cover, m));
            // The hidden area over each eye's cut, drawn black into its swapchain image.
            for k in 0..2 {
                let tris = hidden.as_ref().map_or(&[][..], |t| &t[k][..]);
                (self.swapchains).set_hidden(&self.xr_gpu, k, tris, cover.drawn[k]);
            }
        }
        cover
    }

    /// Step: the eyes' cameras in the data (the runtime's poses through the stage's place in
    /// the data), each seeing `cover`'s symmetric field.
    fn eyes(&self, views: &[xr::View], cover: &crate::vr_nav::Cover) -> [Camera; 2] {
        let nav = &self.nav;
        let to_data = |v: xr::Vector3f| nav.to_data([v.x as f64, v.y as f64, v.z as f64]);
        std::array::from_fn(|k| {
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
        })
    }

    /// Step: one selection for both eyes and both images drawn in one pass, the hidden area
    /// masked. On the GPU the frame is drawn into the texture the eyes are cut from, and read
    /// back (to see that it follows the head) every `CHECK_EVERY` frames only.
    fn draw(&mut self, eyes: &[Camera; 2], cover: &crate::vr_nav::Cover, o: &VrOptions) -> Drawn {
        let stereo = Stereo {
            ipd: 0.0,
            single_pass: true,
            hidden_area: true,
        };
        let eye_masks = self.masks.as_ref().map(|m| &m.1);
        let wide = (2 * cover.width, cover.height);
        let verify = self.report.frames.is_multiple_of(CHECK_EVERY);
        let checked = !self.on_gpu || verify;
        self.raster.present_to((!checked).then(|| {
            (self.swapchains)
                .frame(&self.xr_gpu, wide.0, wide.1)
                .create_view(&Default::default())
        }));
        let gpu = if self.on_gpu { &self.xr_gpu } else { &self.cpu };
        let (image, stats) = (self.scene).frame_stereo(
            gpu,
            &self.raster,
            eyes,
            &self.options,
            &o.style,
            &stereo,
            eye_masks,
        );
        Drawn {
            image,
            stats,
            wide,
            checked,
            verify,
        }
    }

    /// Step: the right menu button pressed: a measuring point where its ray meets the drawn
    /// points.
    fn measure(&mut self, input: &Input) {
        if input.measure
            && !self.measure_was
            && let Some((at, dir)) = input.aim[1]
        {
            // A narrow camera along the ray; the nearest drawn point under its centre.
            let from = self.nav.to_data(at);
            let d = crate::vr_nav::to_data_axes(dir);
            let ray = Camera {
                position: from,
                target: std::array::from_fn(|a| from[a] + d[a]),
                up: [0.0, 0.0, 1.0],
                fov_y: 5.0,
                width: 65,
                height: 65,
                near: 0.01 / self.nav.scale,
                far: 1e4 / self.nav.scale,
            };
            if let Some(p) = self.scene.pick(&ray, 32.5, 32.5, 3.0) {
                self.report.measured.push(p.position);
            }
        }
        self.measure_was = input.measure;
    }

    /// Step: a frame looked at: did the view change since the last one checked; every
    /// `CHECK_EVERY`th frame (read back on a GPU too): no pixel the runtime hides lit.
    fn check(&mut self, drawn: &Drawn, cover: &crate::vr_nav::Cover) {
        let (image, report) = (&drawn.image, &mut self.report);
        if drawn.checked {
            // FNV-1a of the image: did the view change since the last frame checked?
            let hash = image.iter().fold(0xcbf29ce484222325u64, |h, &b| {
                (h ^ b as u64).wrapping_mul(0x100000001b3)
            });
            report.changed += (report.checked > 0 && hash != self.last_image) as u64;
            report.checked += 1;
            self.last_image = hash;
        }
        // Every `CHECK_EVERY`th frame (read back on a GPU too): no pixel the runtime hides lit.
        if drawn.verify
            && let Some((_, m)) = &self.masks
        {
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
    }

    /// Step: each eye's field cut from its half of the side-by-side frame into its swapchain,
    /// and the frame submitted as a projection layer (each view the field its cut covers).
    fn submit(
        &mut self,
        state: &xr::FrameState,
        views: &[xr::View],
        cover: &crate::vr_nav::Cover,
        drawn: &Drawn,
    ) -> Result<(), String> {
        let (w, h) = self.size;
        // Each eye's field cut from its half of the side-by-side frame into its swapchain.
        let corners = [0, 1].map(|k| {
            (
                k as u32 * cover.width + cover.corners[k].0,
                cover.corners[k].1,
            )
        });
        let upload = drawn.checked.then_some(&drawn.image[..]);
        let (wide, verify) = (drawn.wide, drawn.verify);
        if let Some(d) = (self.swapchains).submit(&self.xr_gpu, upload, verify, wide, corners)? {
            self.report.swapchain_differ += d;
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
            .zip(&self.swapchains.swapchains)
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
        self.stream
            .end(
                state.predicted_display_time,
                xr::EnvironmentBlendMode::OPAQUE,
                &[&xr::CompositionLayerProjection::new()
                    .space(&self.space)
                    .views(&projection)],
            )
            .map_err(err("submitting a frame"))?;
        Ok(())
    }

    /// Step: the frame reported (its work since `work`, the head, the interval) and the budget
    /// paced to the runtime's display period; the exit asked for after the frames wanted.
    fn pace(
        &mut self,
        state: &xr::FrameState,
        work: Instant,
        stats: &myriad_render::FrameStats,
        views: &[xr::View],
        o: &VrOptions,
    ) -> Result<(), String> {
        let report = &mut self.report;
        report.frames += 1;
        let period = state.predicted_display_period.as_nanos() as f64 / 1e9;
        let p = (self.pace)
            .get_or_insert_with(|| myriad_lod::Pace::new(90.0, o.budget, 20_000, o.budget));
        // The runtime's period as it predicts it now (it may settle after the first frames).
        if period > 0.0 {
            p.target = period;
        }
        report.work.push(work.elapsed().as_secs_f64() * 1e3);
        let limited = stats.selected_points as f64 >= 0.98 * self.options.budget as f64;
        self.options.budget = p.frame(work.elapsed().as_secs_f64(), stats.points, limited);
        report.budget = self.options.budget;
        let p = views[0].pose.position;
        report.heads.push([p.x, p.y, p.z]);
        let now = Instant::now();
        if let Some(t) = self.last {
            report
                .intervals
                .push(now.duration_since(t).as_secs_f64() * 1e3);
        }
        self.last = Some(now);
        if o.frames.is_some_and(|n| report.frames == n) {
            (self.session)
                .request_exit()
                .map_err(err("asking to end"))?;
        }
        Ok(())
    }

    /// The session's end: the swapchains and the session let go first, then the rest in
    /// turn; what the session did.
    fn finish(self) -> VrReport {
        let Vr {
            events,
            report,
            hands,
            raster,
            cpu,
            scene,
            masks,
            hidden,
            swapchains,
            xr_gpu,
            space,
            stream,
            waiter,
            session,
            ..
        } = self;
        drop(swapchains);
        drop(session);
        drop((
            events, hands, raster, cpu, scene, masks, hidden, xr_gpu, space, stream, waiter,
        ));
        report
    }
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
