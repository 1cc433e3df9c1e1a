//! `myriad view`: a window (eframe: winit, wgpu, egui) showing datasets through the myriad-render
//! pipeline, with navigation, panels and tools. It owns no rendering or level-of-detail logic:
//! each frame a [`Scene`] selects, streams and draws (on the window's GPU straight into the
//! texture it shows, `present.rs`; or on the CPU where the only adapter is a software one, into an
//! image uploaded as a texture), shown under the panels; or, asked for, the surface the drawn
//! points make (`surface.rs`).
//!
//! Navigation lives in [`nav`] (no window needed, tested alone).

mod blit;
pub mod builds;
mod input;
pub mod measure;
pub mod motion;
pub mod nav;
mod options;
mod panel;
mod present;
mod report;
mod saved;
mod section;
mod shown;
mod surface;
mod volumes;
pub mod vr;
pub mod vr_nav;
mod vr_vulkan;

pub use builds::{Builds, Built};
use eframe::egui;
use eframe::egui_wgpu;
use eframe::wgpu;
use measure::{Kind, Measurement, Units};
use myriad_core::Aabb;
use myriad_format::Dataset;
use myriad_lod::{Camera, SelectOptions};
use myriad_render::{ColorBy, FrameStats, Gpu, Rasterizer, Scene, Style};
use nav::{Nav, View};
pub use options::{ViewOptions, VolumeAsked};
use present::Presented;
use report::{HELP, report_orbit, write_png};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

struct Layer {
    name: String,
    scene: Scene,
    dataset: Arc<Dataset>,
    visible: bool,
}

/// Frame time, smoothed.
#[derive(Default)]
struct Timing {
    frame_ms: f64,
    fps: f64,
    last: Option<Instant>,
}

struct App {
    gpu: Gpu,
    raster: Rasterizer,
    layers: Vec<Layer>,
    nav: Nav,
    options: SelectOptions,
    /// The budget following the frame rate while the camera moves, if held (its maximum is
    /// the budget slider's, the budget at rest).
    pace: Option<myriad_lod::Pace>,
    /// The resolution and budget by whether the camera moves.
    motion: motion::Motion,
    /// The size of the last image drawn (shown again while a converged view rests).
    last_size: Option<(u32, u32)>,
    /// A layer's scene changed without an input (a build's snapshot or result swapped in):
    /// the next frame is drawn.
    redraw: bool,
    /// The last frame was drawn as moving.
    moving: bool,
    /// The view's rectangle in the window, pixels: left, top, width, height.
    view_px: [u32; 4],
    /// The last frame drawn's time (ms), and whether the view at rest after an orbit was
    /// reported.
    drawn_ms: f64,
    rest_reported: bool,
    /// The CPU path's image goes to the window through `blit` (installed).
    blit: bool,
    style: Style,
    colour: ColorBy,
    /// The data's extent, for framing.
    bounds: Aabb,
    texture: Option<egui::TextureHandle>,
    /// GPU frames drawn into the window's texture: the render state and the texture.
    present: Option<(egui_wgpu::RenderState, Option<Presented>)>,
    stats: Vec<FrameStats>,
    timing: Timing,
    help: bool,
    picked: Option<String>,
    /// Picked points to longitude, latitude and ellipsoidal height (the dataset's CRS through
    /// PROJ; none without either).
    geographic: Option<myriad_io::proj::Geographic>,
    /// The ellipsoid measurements are made on, where the CRS is geographic.
    earth: Option<(f64, f64)>,
    screenshot: Option<PathBuf>,
    exit_after: bool,
    /// Frames drawn since everything selected was in (the screenshot waits for two).
    settled: u32,
    shot_requested: bool,
    /// The view is framed on the first frame, when the view's size is known.
    framed: bool,
    orbit_left: u32,
    /// Frame intervals and drawing times (ms) while orbiting.
    orbit_times: Vec<(f64, f64)>,
    /// The measuring tool in use, if any.
    tool: Option<Kind>,
    /// Measurements, the one being made last; the units their lengths show in, and metres per
    /// unit of the first dataset's coordinates (from its CRS).
    measurements: Vec<Measurement>,
    units: Units,
    data_metres: Option<f64>,
    /// Saved views: name, camera, pivot.
    bookmarks: Vec<(String, Camera, [f64; 3])>,
    /// Screenshots saved from the panel.
    shots: u32,
    /// The clipping box as fractions of the data's extent per axis (min, max), whether it is
    /// on, and whether it keeps the inside.
    clip: [[f64; 2]; 3],
    clip_on: bool,
    clip_inside: bool,
    surfaces: surface::Surfaces,
    stereo: surface::StereoView,
    /// Datasets still being built, their layers showing a preview; and the caches' shares a
    /// layer's new scene gets.
    builds: Option<Builds>,
    shares: (usize, usize),
    /// The command line's filter, and the overview's classes: points there, shown.
    filter: myriad_measure::Filter,
    classes: std::collections::BTreeMap<u8, (u64, bool)>,
    /// The panel's colour ramp and "where" box: what is typed, the conditions it gave (on top
    /// of the command line's), and why the last one was not taken.
    typed: shown::Typed,
    /// Annotations and the measurements as saved beside the first dataset.
    saved: saved::Saved,
    /// The axis view and the parallel view asked for on the command line, taken on the
    /// first frame.
    start_view: (Option<View>, bool),
    /// The cross-section tool and its profile's window; one asked for on the command line.
    section: section::Section,
    start_section: Option<(Vec<[f64; 2]>, f64)>,
    /// The volume tool; one asked for on the command line.
    volumes: volumes::Volumes,
    start_volume: Option<options::VolumeAsked>,
}

/// Opens the window and runs until it is closed.
pub fn run(datasets: Vec<(String, Arc<Dataset>)>, o: ViewOptions) -> Result<(), String> {
    let (gpu, _) = Gpu::best();
    let raster = Rasterizer::new(&gpu);
    // One memory budget for all datasets, in equal shares.
    let shares = datasets.len().max(1);
    let ram = (2usize << 30) / shares;
    let gpu_bytes = (1usize << 30) / shares;
    let mut layers = Vec::new();
    let mut bounds = Aabb::EMPTY;
    let mut all = Aabb::EMPTY;
    let mut classes = std::collections::BTreeMap::new();
    for (name, ds) in datasets {
        for (c, n) in shown::overview_classes(&ds) {
            let shown = o.filter.classes.as_ref().is_none_or(|l| l.contains(&c));
            classes.entry(c).or_insert((0, shown)).0 += n;
        }
        let bound = (o.filter.bind(&ds.meta.schema))
            .map_err(|e| format!("{}: {e}", ds.path().display()))?;
        let mut scene = Scene::open_filtered(ds.clone(), bound, ram, gpu_bytes);
        scene.set_colour(o.colour);
        scene.occlusion = o.occlusion;
        // At most 64 MB to the GPU per frame (4 M points), shared by the datasets.
        scene.upload_limit = (64 << 20) / shares;
        // Occlusion queries read when the GPU has them: a frame never waits for the last one
        // (on the CPU path they are answered at once and waited for: `draw`).
        scene.query_wait = false;
        bounds.extend(scene.view_bounds.min);
        bounds.extend(scene.view_bounds.max);
        all.extend(ds.meta.bounds.min);
        all.extend(ds.meta.bounds.max);
        layers.push(Layer {
            name,
            scene,
            dataset: ds,
            visible: true,
        });
    }
    if layers.is_empty() {
        return Err("no dataset to view".into());
    }
    let crs = layers.first().and_then(|l| l.dataset.meta.crs.clone());
    let data_metres = crs.as_deref().and_then(measure::metres_per_unit);
    let saved = saved::Saved::open(o.work.clone(), crs.as_deref());
    let section = {
        let first = &layers[0];
        let m = &first.dataset.meta;
        let s = m.bounds.size();
        let spacing = (s[0] * s[1] / m.points.max(1) as f64).sqrt();
        let stem = std::path::Path::new(&first.name)
            .file_stem()
            .map_or_else(|| "view".into(), |n| n.to_string_lossy().into_owned());
        section::Section::new(
            &stem,
            myriad_measure::measurement::crs_units(crs.as_deref()),
            spacing,
        )
    };
    let mut nav = Nav::framing(&bounds, &all, o.fov);
    if let Some((eye, target)) = o.camera {
        nav.look(eye, target);
    }
    let app = App {
        gpu,
        raster,
        layers,
        nav,
        options: SelectOptions {
            budget: o.budget,
            min_pixels: o.lod_threshold,
        },
        motion: motion::Motion::new(o.moving_scale.unwrap_or(0.5)),
        last_size: None,
        redraw: false,
        moving: false,
        view_px: [0; 4],
        drawn_ms: 0.0,
        rest_reported: false,
        blit: false,
        pace: o
            .target_fps
            .map(|fps| myriad_lod::Pace::new(fps, o.budget, 100_000, o.budget)),
        style: o.style,
        colour: o.colour,
        bounds,
        texture: None,
        present: None,
        stats: Vec::new(),
        timing: Timing::default(),
        help: false,
        picked: None,
        geographic: crs
            .as_deref()
            .and_then(|c| myriad_io::proj::Geographic::new(c).ok()),
        earth: myriad_measure::measurement::earth(crs.as_deref()),
        screenshot: o.screenshot,
        exit_after: o.exit_after_converged,
        settled: 0,
        shot_requested: false,
        framed: o.camera.is_some(),
        orbit_left: o.orbit_frames,
        orbit_times: Vec::new(),
        tool: None,
        measurements: saved.work.measurements.clone(),
        saved,
        start_view: (o.view, o.parallel),
        section,
        start_section: o.section.clone(),
        volumes: volumes::Volumes::new(myriad_measure::measurement::crs_units(crs.as_deref())),
        start_volume: o.volume.clone(),
        units: Units::Data,
        data_metres,
        bookmarks: Vec::new(),
        shots: 0,
        clip: [[0.25, 0.75]; 3],
        clip_on: false,
        clip_inside: true,
        surfaces: surface::Surfaces::new(o.surface),
        builds: o.builds,
        shares: (ram, gpu_bytes),
        filter: o.filter,
        classes,
        typed: shown::Typed::default(),
        stereo: surface::StereoView {
            on: o.stereo.is_some(),
            ipd: o.stereo.unwrap_or(0.064),
        },
    };
    // The window's device is asked for what the compute path needs, so that frames drawn on it
    // go to the screen without a readback.
    let setup = egui_wgpu::WgpuSetupCreateNew {
        device_descriptor: std::sync::Arc::new(|adapter: &wgpu::Adapter| {
            let atomics = Gpu::atomics_features();
            wgpu::DeviceDescriptor {
                label: Some("myriad view"),
                required_features: if adapter.features().contains(atomics) {
                    atomics
                } else {
                    wgpu::Features::empty()
                },
                required_limits: adapter.limits(),
                ..Default::default()
            }
        }),
        ..egui_wgpu::WgpuSetupCreateNew::without_display_handle()
    };
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size([o.width as f32, o.height as f32])
            .with_title("Myriad"),
        wgpu_options: egui_wgpu::WgpuConfiguration {
            wgpu_setup: egui_wgpu::WgpuSetup::CreateNew(setup),
            ..Default::default()
        },
        ..Default::default()
    };
    let (want_gpu, readback, moving_scale) = (o.gpu, o.readback, o.moving_scale);
    eframe::run_native(
        "Myriad",
        native,
        Box::new(move |cc| {
            let mut app = app;
            // The window's adapter draws where it is a hardware GPU (or asked for); else the CPU.
            if let Some(rs) = &cc.wgpu_render_state {
                let info = rs.adapter.get_info();
                if want_gpu || info.device_type != wgpu::DeviceType::Cpu {
                    app.gpu = Gpu::from_device(rs.device.clone(), rs.queue.clone(), &info);
                    app.raster = Rasterizer::new(&app.gpu);
                    // The surface's steps on the same device (seed 001 runs them on the GPU).
                    let worker = Gpu::from_device(rs.device.clone(), rs.queue.clone(), &info);
                    app.surfaces.on_gpu(worker);
                    if !readback {
                        app.present = Some((rs.clone(), None));
                    }
                }
                blit::install(rs);
                app.blit = !readback;
            }
            // While moving: half the resolution on the CPU path, whose cost is per pixel.
            if moving_scale.is_none() && app.raster.path != myriad_render::Path::Cpu {
                app.motion.scale = 1.0;
            }
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| format!("window: {e}"))
}

impl App {
    /// The clipping box in world coordinates.
    fn clip_box(&self) -> Aabb {
        let b = &self.bounds;
        let at = |axis: usize, f: f64| b.min[axis] + f * (b.max[axis] - b.min[axis]);
        Aabb::new(
            std::array::from_fn(|a| at(a, self.clip[a][0])),
            std::array::from_fn(|a| at(a, self.clip[a][1])),
        )
    }

    /// Saves the window as myriad-screenshot-N.png in the current folder.
    fn screenshot_now(&mut self, ctx: &egui::Context) {
        self.shots += 1;
        let path = PathBuf::from(format!("myriad-screenshot-{}.png", self.shots));
        ctx.request_screenshot(move |image| match write_png(&path, &image) {
            Ok(()) => println!("{}: screenshot written", path.display()),
            Err(e) => eprintln!("error: {}: {e}", path.display()),
        });
    }

    /// Cuts the section line drawn across the first visible dataset.
    fn cut_section(&mut self) {
        let filter = self.filter();
        if let Some(l) = self.layers.iter().find(|l| l.visible) {
            self.section.cut(l.dataset.clone(), &filter, self.colour);
        }
    }

    /// Measures the volume over the polygon drawn, in the first visible dataset.
    fn measure_volume(&mut self) {
        let filter = self.filter();
        if let Some(l) = self.layers.iter().find(|l| l.visible) {
            self.volumes.measure(l.dataset.clone(), &filter);
        }
    }

    /// No tool takes clicks: measuring, annotating, a section line, a volume's polygon.
    fn stop_tools(&mut self) {
        self.tool = None;
        self.saved.placing = false;
        self.section.drawing = false;
        self.volumes.drawing = false;
    }

    fn start_measuring(&mut self, kind: Kind) {
        self.stop_tools();
        self.tool = Some(kind);
        if self
            .measurements
            .last()
            .is_none_or(|m| m.kind != kind || !m.points.is_empty())
        {
            self.measurements.push(Measurement::new(kind));
        }
    }

    /// The measurements drawn over the view: lines between their points, the figure by the last.
    fn draw_measurements(&self, painter: &egui::Painter, rect: egui::Rect, ppp: f32) {
        let cam = &self.nav.camera;
        let focal = cam.focal();
        let screen = |p: [f64; 3]| -> Option<egui::Pos2> {
            let e = cam.to_eye(p);
            if e[2] <= 1e-9 {
                return None;
            }
            let x = cam.width as f64 / 2.0 + e[0] * focal / e[2];
            let y = cam.height as f64 / 2.0 - e[1] * focal / e[2];
            Some(rect.min + egui::vec2(x as f32 / ppp, y as f32 / ppp))
        };
        let colour = egui::Color32::from_rgb(255, 210, 0);
        if self.clip_on {
            let c = self.clip_box().corners();
            // Corners differ in one axis bit along each of the 12 edges.
            for i in 0..8usize {
                for bit in [1usize, 2, 4] {
                    let j = i ^ bit;
                    if j > i
                        && let (Some(a), Some(b)) = (screen(c[i]), screen(c[j]))
                    {
                        painter.line_segment(
                            [a, b],
                            egui::Stroke::new(1.0, egui::Color32::LIGHT_BLUE),
                        );
                    }
                }
            }
        }
        for m in &self.measurements {
            let pts: Vec<Option<egui::Pos2>> = m.points.iter().map(|&p| screen(p)).collect();
            let mut pairs: Vec<(usize, usize)> = (1..pts.len()).map(|i| (i - 1, i)).collect();
            if m.kind == Kind::Area && pts.len() >= 3 {
                pairs.push((pts.len() - 1, 0));
            }
            for (a, b) in pairs {
                if let (Some(a), Some(b)) = (pts[a], pts[b]) {
                    painter.line_segment([a, b], egui::Stroke::new(2.0, colour));
                }
            }
            for p in pts.iter().flatten() {
                painter.circle_filled(*p, 4.0, colour);
            }
            if let (Some(label), Some(Some(at))) = (
                m.label_for(self.units, self.data_metres, self.earth),
                pts.last(),
            ) {
                painter.text(
                    *at + egui::vec2(8.0, -8.0),
                    egui::Align2::LEFT_BOTTOM,
                    label,
                    egui::FontId::monospace(14.0),
                    colour,
                );
            }
        }
        self.saved.draw(painter, &screen);
        self.section.draw(painter, &screen);
        self.volumes.draw(painter, &screen);
    }

    fn pick(&self, cam: &Camera, x: f64, y: f64) -> Option<myriad_render::Picked> {
        self.layers
            .iter()
            .filter(|l| l.visible)
            .filter_map(|l| l.scene.pick(cam, x, y, 6.0))
            .min_by(|a, b| a.depth.total_cmp(&b.depth))
    }

    /// Draws the visible datasets in one frame: one budget, one depth buffer. Drawing on a GPU,
    /// selection runs on its own thread per dataset and the frame draws the newest selection in
    /// (never waits for it); drawing on the CPU, the cores that would select are the cores that
    /// draw, and the frame selects itself (the frame-rate budget then sees its own selection).
    fn draw(&mut self, width: u32, height: u32, scale: f32) -> Vec<u8> {
        self.nav.camera.width = width.max(1);
        self.nav.camera.height = height.max(1);
        if !self.framed {
            self.framed = true;
            match self.start_view.0 {
                Some(v) => self.nav.standard(v, &self.bounds),
                None => self.nav.frame(&self.bounds),
            }
        }
        if std::mem::take(&mut self.start_view.1) {
            self.nav.set_parallel(true);
        }
        if let Some((line, width)) = self.start_section.take() {
            let z = self.bounds.max[2];
            self.section.line = line.iter().map(|p| [p[0], p[1], z]).collect();
            self.section.width = width;
            self.cut_section();
        }
        if let Some(options::VolumeAsked {
            polygon,
            base,
            cell,
        }) = self.start_volume.take()
        {
            let z = self.bounds.min[2];
            self.volumes.polygon = polygon.iter().map(|p| [p[0], p[1], z]).collect();
            self.volumes.base = base.map_or(volumes::Down::Rim, volumes::Down::Elevation);
            self.volumes.cell = cell.unwrap_or(0.0);
            self.volumes.print = true;
            self.measure_volume();
        }
        let full = self.nav.camera;
        if self.stereo.on {
            return self.draw_stereo(&full);
        }
        let cam = motion::scaled(&full, scale);
        let mut scenes: Vec<&mut Scene> = self
            .layers
            .iter_mut()
            .filter(|l| l.visible)
            .map(|l| &mut l.scene)
            .collect();
        // On the CPU the occlusion queries are answered at once: each frame waits for them, and
        // the nodes culled that show are drawn in the frame they come into sight (003's queries
        // as Gobbetti and Marton schedule them); on a GPU they are read when it has them.
        let cpu = self.raster.path == myriad_render::Path::Cpu;
        for s in scenes.iter_mut() {
            s.query_wait = cpu;
        }
        let frame = if cpu {
            myriad_render::frame_many
        } else {
            myriad_render::frame_many_threaded
        };
        let (image, stats) = frame(
            &mut scenes,
            &self.gpu,
            &self.raster,
            &cam,
            &self.options,
            &self.style,
        );
        self.stats = stats;
        if self.surfaces.on {
            return self.surface_image(&full, image);
        }
        image
    }
}

/// A texture (the frame drawn on a GPU, or read back) over the view.
fn show_texture(painter: &egui::Painter, rect: egui::Rect, id: egui::TextureId) {
    let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
    painter.image(id, rect, uv, egui::Color32::WHITE);
}

impl eframe::App for App {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.take_builds(&ctx);
        egui::Panel::left("settings")
            .default_size(230.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.settings(ui));
            });
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| {
                let rect = ui.max_rect();
                let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
                self.navigate(ui, &response, rect);
                let ppp = ctx.pixels_per_point();
                let (w, h) = (
                    (rect.width() * ppp).round().max(1.0) as u32,
                    (rect.height() * ppp).round().max(1.0) as u32,
                );
                if self.orbit_left > 0 {
                    self.nav.orbit(8.0, 0.0);
                }
                self.view_px = [
                    (rect.left() * ppp).round() as u32,
                    (rect.top() * ppp).round() as u32,
                    w,
                    h,
                ];
                let t = Instant::now();
                // Moving: the budget the frame rate allows, at the lower resolution; at rest:
                // the whole budget at the full one (a surface or stereo pair: always full).
                let mut full = self.nav.camera;
                (full.width, full.height) = (w, h);
                let drawn = self.motion.frame(&full, t, self.orbit_left > 0);
                self.moving = drawn.moving;
                let scale = if self.surfaces.on || self.stereo.on {
                    1.0
                } else {
                    drawn.scale
                };
                if let Some(p) = &self.pace {
                    self.options.budget = if drawn.moving { p.budget() } else { p.max };
                }
                let small = motion::scaled(&full, scale);
                let (dw, dh) = (small.width, small.height);
                // A converged view at rest that nothing touched: the last image again.
                let touched = ui.input(|i| !i.events.is_empty());
                // (`settled`: the frames since the view converged.)
                let again = self.settled > 0
                    && !drawn.moving
                    && !touched
                    && !std::mem::take(&mut self.redraw)
                    && self.last_size == Some((dw, dh));
                // A surface's image is read back and uploaded: the window's texture is let go.
                let shown = if self.surfaces.on || self.stereo.on {
                    self.stop_presenting();
                    None
                } else {
                    self.present_texture(dw, dh)
                };
                let image = (!again).then(|| self.draw(w, h, scale));
                if image.is_some() {
                    self.last_size = Some((dw, dh));
                }
                let ms = t.elapsed().as_secs_f64() * 1e3;
                let now = Instant::now();
                if let Some(last) = self.timing.last.filter(|_| image.is_some()) {
                    let interval = now.duration_since(last).as_secs_f64().max(1e-6);
                    self.timing.fps = 0.8 * self.timing.fps + 0.2 / interval;
                    // The budget follows the frames drawn with it: a threaded frame may still
                    // draw a selection made with an earlier budget (a feedback loop with a
                    // delay in it oscillates).
                    let current = self
                        .stats
                        .iter()
                        .all(|s| s.select_budget == self.options.budget);
                    if let Some(p) = self.pace.as_mut().filter(|_| current && drawn.moving) {
                        let drawn: u64 = self.stats.iter().map(|s| s.points).sum();
                        let selected: u64 = self.stats.iter().map(|s| s.selected_points).sum();
                        let limited = selected as f64 >= 0.98 * self.options.budget as f64;
                        self.options.budget = p.frame(interval, drawn, limited);
                    }
                    if self.orbit_left > 0 {
                        self.orbit_times.push((interval * 1e3, ms));
                        self.orbit_left -= 1;
                        if self.orbit_left == 0 {
                            let target = self.pace.as_ref().map(|p| p.target);
                            report_orbit(&mut self.orbit_times, &self.stats, target);
                            if self.pace.is_some() {
                                println!("budget settled on {} points", self.options.budget);
                            }
                        }
                    }
                }
                self.timing.last = Some(now);
                if image.is_some() {
                    self.timing.frame_ms = 0.8 * self.timing.frame_ms + 0.2 * ms;
                    self.drawn_ms = ms;
                }
                match shown {
                    Some(id) => show_texture(ui.painter(), rect, id),
                    None if self.blit => blit::paint(ui.painter(), rect, image, dw, dh),
                    None => {
                        if let Some(image) = image {
                            let colour = egui::ColorImage::from_rgba_unmultiplied(
                                [dw as usize, dh as usize],
                                &image,
                            );
                            let options = egui::TextureOptions::NEAREST;
                            match &mut self.texture {
                                Some(t) => t.set(colour, options),
                                None => {
                                    self.texture = Some(ctx.load_texture("view", colour, options))
                                }
                            }
                        }
                        if let Some(t) = &self.texture {
                            show_texture(ui.painter(), rect, t.id());
                        }
                    }
                }
                self.draw_measurements(ui.painter(), rect, ppp);
                if self.stats.iter().any(|s| s.in_flight > 0) {
                    ui.painter().text(
                        rect.right_top() + egui::vec2(-10.0, 10.0),
                        egui::Align2::RIGHT_TOP,
                        "loading…",
                        egui::FontId::proportional(14.0),
                        egui::Color32::LIGHT_GRAY,
                    );
                }
            });
        let ds = self
            .layers
            .iter()
            .find(|l| l.visible)
            .map(|l| l.dataset.clone());
        let filter = self.filter();
        self.section.window(&ctx, ds.as_deref(), &filter);
        self.volumes.take();
        if self.help {
            egui::Window::new("Shortcuts")
                .collapsible(false)
                .show(&ctx, |ui| {
                    egui::Grid::new("keys").show(ui, |ui| {
                        for (k, v) in HELP {
                            ui.strong(*k);
                            ui.label(*v);
                            ui.end_row();
                        }
                    });
                });
        }
        // Converged: the selection of this view in, every node of it drawn, nothing loading,
        // no dataset still being built.
        let converged = self.orbit_left == 0
            && !self.moving
            && self.builds.as_ref().is_none_or(Builds::done)
            && !self.stats.is_empty()
            && self
                .stats
                .iter()
                .all(|s| s.select_current && s.complete && s.in_flight == 0)
            && self.surfaces.settled()
            && self.section.settled()
            && self.volumes.settled();
        self.settled = if converged { self.settled + 1 } else { 0 };
        if converged && !self.orbit_times.is_empty() && !self.rest_reported {
            self.rest_reported = true;
            let points: u64 = self.stats.iter().map(|s| s.points).sum();
            let c = &self.nav.camera;
            println!(
                "at rest: {points} points drawn at {}x{} (budget {}), the last frame {:.1} ms",
                c.width, c.height, self.options.budget, self.drawn_ms
            );
        }
        if self.settled >= 2
            && !self.shot_requested
            && let Some(path) = self.screenshot.clone()
        {
            self.shot_requested = true;
            let exit = self.exit_after;
            let c = ctx.clone();
            let [x, y, w, h] = self.view_px;
            ctx.request_screenshot(move |image| {
                if let Err(e) = write_png(&path, &image) {
                    eprintln!("error: {}: {e}", path.display());
                } else {
                    // Where the view is in it (tests compare it with `render`'s image).
                    let path = path.display();
                    println!("{path}: screenshot written (the view {w}x{h} at {x},{y})");
                }
                if exit {
                    c.send_viewport_cmd(egui::ViewportCommand::Close);
                }
                c.request_repaint();
            });
        }
        self.saved.sync(&self.measurements, Instant::now());
        if converged {
            // Nothing to draw until something is touched (input repaints at once).
            ctx.request_repaint_after(std::time::Duration::from_millis(250));
        } else {
            ctx.request_repaint();
        }
    }

    fn on_exit(&mut self) {
        self.saved.flush();
    }
}
