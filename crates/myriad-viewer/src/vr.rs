//! `myriad view --vr`: a dataset in a headset through OpenXR (seed 002). The `openxr` crate over
//! the system's loader; Vulkan through XR_KHR_vulkan_enable2 (the runtime makes the instance and
//! the device, `ash` drives them); each frame the runtime's predicted display time, both eyes'
//! poses and fields of view located, one selection for both eyes, both images drawn (single
//! pass on the CPU path), copied into the eyes' swapchain images and submitted as a projection
//! layer. The data stand in front of the user at the stage's origin, `scale` metres a data unit,
//! Z up.
//!
//! The controllers (002's interaction; bound for the Khronos simple controller, which every
//! runtime maps its controllers to): the right trigger flies along the right hand's pointing
//! direction, both triggers grab the data (move with the hands, scale with their distance:
//! `vr_nav.rs`), the right menu button marks a measuring point where its ray meets the drawn
//! points; the report gives the distances.
//!
//! Off-axis eyes: each eye's field is cut from a symmetric image holding both eyes' fields
//! (`vr_nav::cover`), pixel for pixel what an off-axis projection draws.
//!
//! Not yet: a GPU image handed to the runtime without a copy through the CPU.

use ash::vk;
use ash::vk::Handle;
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
    /// Frames whose image differed from the frame's before (the views follow the head).
    pub changed: u64,
    /// The point budget the frame rate settled on (held at the runtime's display rate).
    pub budget: u64,
    /// Each frame's work (ms): from the runtime's go to the submission.
    pub work: Vec<f64>,
    /// Frames in which both controllers' aim poses were located.
    pub hands: u64,
    /// Points marked with the measuring ray (data coordinates), in order.
    pub measured: Vec<[f64; 3]>,
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
    let requirements = instance
        .graphics_requirements::<xr::Vulkan>(system)
        .map_err(err("Vulkan requirements"))?;

    // Vulkan through the runtime.
    // SAFETY: loads the system's Vulkan loader.
    let vk_entry = unsafe { ash::Entry::load() }.map_err(|e| format!("no Vulkan loader: {e}"))?;
    let api = vk::make_api_version(0, 1, 1, 0);
    if api
        < vk::make_api_version(
            0,
            requirements.min_api_version_supported.major() as u32,
            requirements.min_api_version_supported.minor() as u32,
            0,
        )
    {
        return Err("the OpenXR runtime needs a newer Vulkan".into());
    }
    let app_info = vk::ApplicationInfo::default()
        .application_name(c"myriad")
        .api_version(api);
    let get_proc = vk_entry.static_fn().get_instance_proc_addr;
    // SAFETY: the create infos outlive the calls; the runtime returns valid handles or errors.
    let (vk_instance, physical, device, queue_family) = unsafe {
        let raw = instance
            .create_vulkan_instance(
                system,
                std::mem::transmute::<vk::PFN_vkGetInstanceProcAddr, _>(get_proc),
                &vk::InstanceCreateInfo::default().application_info(&app_info) as *const _
                    as *const _,
            )
            .map_err(err("the runtime's Vulkan instance"))?
            .map_err(|r| {
                format!(
                    "the runtime's Vulkan instance: {:?}",
                    vk::Result::from_raw(r)
                )
            })?;
        let vk_instance =
            ash::Instance::load(vk_entry.static_fn(), vk::Instance::from_raw(raw as _));
        let physical = vk::PhysicalDevice::from_raw(
            instance
                .vulkan_graphics_device(system, raw as _)
                .map_err(err("the runtime's Vulkan device"))? as _,
        );
        let queue_family = vk_instance
            .get_physical_device_queue_family_properties(physical)
            .iter()
            .position(|q| q.queue_flags.contains(vk::QueueFlags::GRAPHICS))
            .ok_or("the Vulkan device has no graphics queue")? as u32;
        let priorities = [1.0];
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family)
            .queue_priorities(&priorities)];
        let raw_device = instance
            .create_vulkan_device(
                system,
                std::mem::transmute::<vk::PFN_vkGetInstanceProcAddr, _>(get_proc),
                physical.as_raw() as _,
                &vk::DeviceCreateInfo::default().queue_create_infos(&queues) as *const _
                    as *const _,
            )
            .map_err(err("the runtime's Vulkan device"))?
            .map_err(|r| format!("the runtime's Vulkan device: {:?}", vk::Result::from_raw(r)))?;
        let device =
            ash::Device::load(vk_instance.fp_v1_0(), vk::Device::from_raw(raw_device as _));
        (vk_instance, physical, device, queue_family)
    };
    // SAFETY: the handles come from the runtime's Vulkan instance and device above.
    let (session, mut waiter, mut stream) = unsafe {
        instance.create_session::<xr::Vulkan>(
            system,
            &xr::vulkan::SessionCreateInfo {
                instance: vk_instance.handle().as_raw() as _,
                physical_device: physical.as_raw() as _,
                device: device.handle().as_raw() as _,
                queue_family_index: queue_family,
                queue_index: 0,
            },
        )
    }
    .map_err(err("the OpenXR session"))?;
    let space = session
        .create_reference_space(xr::ReferenceSpaceType::STAGE, xr::Posef::IDENTITY)
        .or_else(|_| {
            session.create_reference_space(xr::ReferenceSpaceType::LOCAL, xr::Posef::IDENTITY)
        })
        .map_err(err("a reference space"))?;
    let formats = session
        .enumerate_swapchain_formats()
        .map_err(err("swapchain formats"))?;
    let format = [vk::Format::R8G8B8A8_SRGB, vk::Format::R8G8B8A8_UNORM]
        .into_iter()
        .find(|f| formats.contains(&(f.as_raw() as u32)))
        .ok_or("the runtime offers no RGBA8 swapchain")?;
    let (w, h) = (
        views_config[0].recommended_image_rect_width,
        views_config[0].recommended_image_rect_height,
    );
    let mut swapchains = Vec::new();
    for _ in 0..2 {
        let sc = session
            .create_swapchain(&xr::SwapchainCreateInfo {
                create_flags: xr::SwapchainCreateFlags::EMPTY,
                usage_flags: xr::SwapchainUsageFlags::COLOR_ATTACHMENT
                    | xr::SwapchainUsageFlags::TRANSFER_DST,
                format: format.as_raw() as u32,
                sample_count: 1,
                width: w,
                height: h,
                face_count: 1,
                array_size: 1,
                mip_count: 1,
            })
            .map_err(err("a swapchain"))?;
        let images: Vec<vk::Image> = sc
            .enumerate_images()
            .map_err(err("swapchain images"))?
            .into_iter()
            .map(vk::Image::from_raw)
            .collect();
        swapchains.push((sc, images));
    }
    let copier = Copier::new(&vk_instance, physical, &device, queue_family, (w, h))?;

    // The data and the renderer.
    let mut scene = Scene::open(dataset.clone(), 2 << 30, 1 << 30);
    let gpu = Gpu::cpu();
    let raster = Rasterizer::new(&gpu);
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
        scene.take(&scene.select_eyes(&eyes, &options, None));
        let stereo = Stereo {
            ipd: 0.0,
            single_pass: true,
            hidden_area: false,
        };
        let (image, stats) = scene.frame_stereo(&gpu, &raster, &eyes, &options, &o.style, &stereo);
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
        // FNV-1a of the image: did the view change?
        let hash = image.iter().fold(0xcbf29ce484222325u64, |h, &b| {
            (h ^ b as u64).wrapping_mul(0x100000001b3)
        });
        report.changed += (report.frames > 0 && hash != last_image) as u64;
        last_image = hash;
        let mut layer_views = Vec::new();
        for (k, (sc, images)) in swapchains.iter_mut().enumerate() {
            let i = sc.acquire_image().map_err(err("a swapchain image"))? as usize;
            sc.wait_image(xr::Duration::INFINITE)
                .map_err(err("a swapchain image"))?;
            // This eye's field, cut from its half of the side-by-side image.
            let (x0, y0) = cover.corners[k];
            let full = cover.width as usize;
            let cut: Vec<u8> = (0..h as usize)
                .flat_map(|y| {
                    let row = ((y0 as usize + y) * 2 * full + k * full + x0 as usize) * 4;
                    image[row..row + w as usize * 4].to_vec()
                })
                .collect();
            copier.copy(&device, images[i], &cut)?;
            sc.release_image().map_err(err("a swapchain image"))?;
            // The field the cut covers (the eye's own, to a pixel).
            let t = cover.drawn[k];
            let drawn = xr::Fovf {
                angle_left: t.left.atan() as f32,
                angle_right: t.right.atan() as f32,
                angle_up: t.up.atan() as f32,
                angle_down: t.down.atan() as f32,
            };
            layer_views.push((views[k].pose, drawn));
        }
        let projection: Vec<xr::CompositionLayerProjectionView<xr::Vulkan>> = layer_views
            .iter()
            .zip(&swapchains)
            .map(|(&(pose, fov), (sc, _))| {
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
    copier.destroy(&device);
    drop(swapchains);
    drop(session);
    Ok(report)
}

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

/// Copies RGBA8 images into swapchain images: a host-visible staging buffer, one command
/// buffer, a fence.
struct Copier {
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    pool: vk::CommandPool,
    commands: vk::CommandBuffer,
    fence: vk::Fence,
    queue: vk::Queue,
    size: (u32, u32),
}

impl Copier {
    fn new(
        instance: &ash::Instance,
        physical: vk::PhysicalDevice,
        device: &ash::Device,
        family: u32,
        size: (u32, u32),
    ) -> Result<Copier, String> {
        let bytes = size.0 as u64 * size.1 as u64 * 4;
        let vkerr = |what: &'static str| move |e: vk::Result| format!("Vulkan {what}: {e}");
        // SAFETY: plain Vulkan object creation on a valid device.
        unsafe {
            let buffer = device
                .create_buffer(
                    &vk::BufferCreateInfo::default()
                        .size(bytes)
                        .usage(vk::BufferUsageFlags::TRANSFER_SRC),
                    None,
                )
                .map_err(vkerr("staging buffer"))?;
            let needs = device.get_buffer_memory_requirements(buffer);
            let props = instance.get_physical_device_memory_properties(physical);
            let kind = (0..props.memory_type_count)
                .find(|&i| {
                    needs.memory_type_bits & (1 << i) != 0
                        && props.memory_types[i as usize].property_flags.contains(
                            vk::MemoryPropertyFlags::HOST_VISIBLE
                                | vk::MemoryPropertyFlags::HOST_COHERENT,
                        )
                })
                .ok_or("no host-visible Vulkan memory")?;
            let memory = device
                .allocate_memory(
                    &vk::MemoryAllocateInfo::default()
                        .allocation_size(needs.size)
                        .memory_type_index(kind),
                    None,
                )
                .map_err(vkerr("staging memory"))?;
            device
                .bind_buffer_memory(buffer, memory, 0)
                .map_err(vkerr("staging memory"))?;
            let pool = device
                .create_command_pool(
                    &vk::CommandPoolCreateInfo::default()
                        .queue_family_index(family)
                        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                    None,
                )
                .map_err(vkerr("command pool"))?;
            let commands = device
                .allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(pool)
                        .command_buffer_count(1),
                )
                .map_err(vkerr("command buffer"))?[0];
            let fence = device
                .create_fence(&vk::FenceCreateInfo::default(), None)
                .map_err(vkerr("fence"))?;
            let queue = device.get_device_queue(family, 0);
            Ok(Copier {
                buffer,
                memory,
                pool,
                commands,
                fence,
                queue,
                size,
            })
        }
    }

    /// `rgba` (the swapchain's size) into `image`, left in COLOR_ATTACHMENT_OPTIMAL as the
    /// runtime expects a released image.
    fn copy(&self, device: &ash::Device, image: vk::Image, rgba: &[u8]) -> Result<(), String> {
        let vkerr = |e: vk::Result| format!("Vulkan copy: {e}");
        let (w, h) = self.size;
        let range = vk::ImageSubresourceRange::default()
            .aspect_mask(vk::ImageAspectFlags::COLOR)
            .level_count(1)
            .layer_count(1);
        let barrier = |from, to, src, dst| {
            vk::ImageMemoryBarrier::default()
                .old_layout(from)
                .new_layout(to)
                .src_access_mask(src)
                .dst_access_mask(dst)
                .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .image(image)
                .subresource_range(range)
        };
        // SAFETY: the staging memory is host-visible and as large as an image; the command
        // buffer is recorded, submitted and waited for before it is used again.
        unsafe {
            let ptr = device
                .map_memory(
                    self.memory,
                    0,
                    rgba.len() as u64,
                    vk::MemoryMapFlags::empty(),
                )
                .map_err(vkerr)?;
            std::ptr::copy_nonoverlapping(rgba.as_ptr(), ptr as *mut u8, rgba.len());
            device.unmap_memory(self.memory);
            let c = self.commands;
            device
                .reset_command_buffer(c, vk::CommandBufferResetFlags::empty())
                .map_err(vkerr)?;
            device
                .begin_command_buffer(c, &vk::CommandBufferBeginInfo::default())
                .map_err(vkerr)?;
            device.cmd_pipeline_barrier(
                c,
                vk::PipelineStageFlags::TOP_OF_PIPE,
                vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &[barrier(
                    vk::ImageLayout::UNDEFINED,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    vk::AccessFlags::empty(),
                    vk::AccessFlags::TRANSFER_WRITE,
                )],
            );
            device.cmd_copy_buffer_to_image(
                c,
                self.buffer,
                image,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &[vk::BufferImageCopy::default()
                    .image_subresource(
                        vk::ImageSubresourceLayers::default()
                            .aspect_mask(vk::ImageAspectFlags::COLOR)
                            .layer_count(1),
                    )
                    .image_extent(vk::Extent3D {
                        width: w,
                        height: h,
                        depth: 1,
                    })],
            );
            device.cmd_pipeline_barrier(
                c,
                vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &[barrier(
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                    vk::AccessFlags::TRANSFER_WRITE,
                    vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
                )],
            );
            device.end_command_buffer(c).map_err(vkerr)?;
            let buffers = [c];
            device
                .queue_submit(
                    self.queue,
                    &[vk::SubmitInfo::default().command_buffers(&buffers)],
                    self.fence,
                )
                .map_err(vkerr)?;
            device
                .wait_for_fences(&[self.fence], true, u64::MAX)
                .map_err(vkerr)?;
            device.reset_fences(&[self.fence]).map_err(vkerr)?;
        }
        Ok(())
    }

    fn destroy(&self, device: &ash::Device) {
        // SAFETY: nothing uses these objects after the last copy was waited for.
        unsafe {
            device.destroy_fence(self.fence, None);
            device.destroy_command_pool(self.pool, None);
            device.destroy_buffer(self.buffer, None);
            device.free_memory(self.memory, None);
        }
    }
}
