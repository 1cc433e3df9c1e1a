//! The window's app: [`App`] holds the values each concern owns (what is drawn and how:
//! `render.rs`; the layers and their filter: `shown.rs`; camera and navigation:
//! `navigation.rs`; budget pacing: `pacing.rs`; the scripted orbit: `orbit.rs`; screenshots:
//! `shots.rs`; the tools: `tools/`; the panel: `panel.rs`; datasets being built: `builds.rs`)
//! and runs a frame as named steps over them: take the builds, lay out the panel, handle the
//! input, pace the budget and draw, show the frame and what the tools draw, then see whether
//! the view converged and report.

use crate::builds::Builds;
use crate::motion;
use crate::navigation::Navigation;
use crate::options::ViewOptions;
use crate::orbit::Orbit;
use crate::pacing::Pacing;
use crate::panel::{self, Panel};
use crate::present::passes_panel;
use crate::render::Render;
use crate::shots::Shots;
use crate::shown::Layers;
use crate::surface::{self, StereoView, Surfaces};
use crate::tools::Tools;
use eframe::egui;
use eframe::egui_wgpu;
use myriad_format::Dataset;
use myriad_render::{Gpu, Rasterizer};
use std::sync::Arc;
use std::time::Instant;

pub(crate) struct App {
    /// What draws the view, how, and where the frame goes.
    render: Render,
    /// The datasets' layers, what they draw and in what colour.
    layers: Layers,
    /// The camera and navigation.
    view: Navigation,
    /// The budget and the frame rate.
    pacing: Pacing,
    /// The scripted orbit (`--orbit-frames`) and its report.
    orbit: Orbit,
    /// Screenshots: the command line's, and those saved from the panel.
    shots: Shots,
    tools: Tools,
    /// The map beside the view.
    map: crate::map::MiniMap,
    /// Photos and panoramas kept with the first dataset.
    photos: crate::photos::Photos,
    panel: Panel,
    /// Datasets still being built, their layers showing a preview.
    builds: Option<Builds>,
    /// A layer's scene changed without an input (a build's snapshot or result swapped in):
    /// the next frame is drawn.
    redraw: bool,
    /// Frames drawn since everything selected was in (the screenshot waits for two).
    settled: u32,
}

impl App {
    /// The window's state for `datasets` as the command line asks (`o`); the frames drawn on
    /// the best device there is until the window's own is known ([`App::adopt`]).
    pub fn new(datasets: Vec<(String, Arc<Dataset>)>, o: ViewOptions) -> Result<App, String> {
        let (gpu, _) = Gpu::best();
        let raster = Rasterizer::new(&gpu);
        let (layers, extent) = Layers::open(datasets, o.filter, o.colour, o.occlusion)?;
        let tools = Tools::new(
            &layers,
            extent.view,
            o.work,
            (o.section, o.volume),
            (o.edits, o.contours),
            o.paths,
        );
        let first = layers.list.first().map(|l| l.dataset.meta.bounds);
        let map = crate::map::MiniMap::new(
            o.map_tiles,
            layers.crs().as_deref(),
            &first.unwrap_or(extent.all),
        );
        let photos =
            crate::photos::Photos::new(layers.list.first().map(|l| l.dataset.path()), o.photo);
        let view = Navigation::new(
            (extent.view, extent.all),
            o.fov,
            o.camera,
            (o.view, o.parallel),
        );
        let stereo = StereoView {
            on: o.stereo.is_some(),
            ipd: o.stereo.unwrap_or(0.064),
        };
        Ok(App {
            render: Render::new((gpu, raster), o.style, Surfaces::new(o.surface), stereo),
            layers,
            view,
            pacing: Pacing::new(
                o.budget,
                o.lod_threshold,
                o.target_fps,
                o.moving_scale.unwrap_or(0.5),
            ),
            orbit: Orbit::new(o.orbit_frames),
            shots: Shots::new(o.screenshot, o.exit_after_converged),
            tools,
            map,
            photos,
            panel: Panel::default(),
            builds: o.builds,
            redraw: false,
            settled: 0,
        })
    }

    /// The window's adapter known (`rs`): it draws where it is a hardware GPU (or `want_gpu`);
    /// else the CPU. `readback`: GPU frames read back. `moving_scale`: as asked.
    pub fn adopt(
        &mut self,
        rs: Option<&egui_wgpu::RenderState>,
        (want_gpu, readback): (bool, bool),
        moving_scale: Option<f32>,
    ) {
        self.render.adopt(rs, want_gpu, readback);
        // While moving: half the resolution on the CPU path, whose cost is per pixel.
        if moving_scale.is_none() && self.render.raster.path != myriad_render::Path::Cpu {
            self.pacing.motion.scale = 1.0;
        }
    }

    /// Step: the datasets that arrived put in their layers.
    fn take_builds(&mut self, ctx: &egui::Context) {
        if let Some(b) = &mut self.builds
            && b.take(ctx, &mut self.layers, self.view.nav.camera.target)
        {
            self.redraw = true;
        }
    }

    /// Step: the settings panel, each concern's part in turn.
    fn settings(&mut self, ui: &mut egui::Ui) {
        ui.heading("Myriad");
        self.pacing.panel(ui);
        ui.separator();
        panel::style_panel(ui, &mut self.render.style);
        self.layers.colour_panel(ui);
        self.layers.classes_panel(ui);
        passes_panel(ui, &mut self.render.style.passes);
        ui.separator();
        surface::surface_panel(ui, &mut self.render.surfaces);
        surface::stereo_panel(ui, &mut self.render.stereo);
        ui.separator();
        self.layers.list_panel(ui);
        ui.separator();
        panel::frame_report(ui, &self.render, &self.layers, &self.pacing.timing);
        self.tools.pick.panel(ui);
        self.map.panel(ui);
        self.photos.panel(ui);
        let cam = self.view.nav.camera;
        let asked = self.tools.panel(ui, &mut self.layers, &cam);
        if let Some((eye, target)) = asked.go {
            self.view.nav.look(eye, target);
        }
        self.render.style.clip = asked.clip;
        ui.separator();
        self.view.panel(ui);
        if ui.button("screenshot (P)").clicked() {
            self.shots.now(ui.ctx());
        }
        ui.separator();
        self.panel.help_button(ui);
    }

    /// Step: mouse and keyboard over the view (`response`, over `rect`): the help, navigation,
    /// a screenshot, the tools' keys and clicks.
    fn navigate(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) {
        let scale = ui.ctx().pixels_per_point() as f64;
        // Keys typed into the panel (an annotation's title) are not shortcuts.
        let typing = ui.ctx().egui_wants_keyboard_input();
        // Ctrl (Cmd) with a key is a command, not the key's tool.
        let command = ui.input(|i| i.modifiers.command);
        let pressed = |key| !typing && !command && ui.input(|i| i.key_pressed(key));
        let with_command = |key| !typing && command && ui.input(|i| i.key_pressed(key));
        let shift = ui.input(|i| i.modifiers.shift);
        if with_command(egui::Key::Z) && !shift {
            (self.tools.edit).change(myriad_measure::edits::Change::Undo, &mut self.layers);
        } else if with_command(egui::Key::Y) || with_command(egui::Key::Z) {
            (self.tools.edit).change(myriad_measure::edits::Change::Redo, &mut self.layers);
        }
        if pressed(egui::Key::H) {
            self.panel.help = !self.panel.help;
        }
        self.view.keys(&pressed);
        if pressed(egui::Key::P) {
            self.shots.now(ui.ctx());
        }
        self.tools.keys(&pressed, self.view.nav.fly);
        let cursor = response.hover_pos().map(|p| {
            (
                ((p.x - rect.min.x) as f64) * scale,
                ((p.y - rect.min.y) as f64) * scale,
            )
        });
        // The camera the clicks were made in (before this frame's drag moves it).
        let cam = self.view.nav.camera;
        // Clicks and drags on the map are the map's.
        if (response.hover_pos()).is_some_and(|p| self.map.covers(rect, p)) {
            return;
        }
        let layers = &self.layers;
        let pick = |x, y| layers.pick(&cam, x, y).map(|p| p.position);
        self.view.mouse(ui, response, (cursor, scale), &pick);
        self.tools.clicks(response, cursor, &cam, &mut self.layers);
    }

    /// Step: the budget paced for this frame (begun at `t`, the view `w` x `h` pixels) and the
    /// frame drawn, unless a converged view at rest that nothing touched shows the last image
    /// again. Where the frame goes, the image drawn, and its size.
    fn pace_and_draw(
        &mut self,
        ui: &egui::Ui,
        t: Instant,
        (w, h): (u32, u32),
    ) -> (Option<egui::TextureId>, Option<Vec<u8>>, (u32, u32)) {
        // Moving: the budget the frame rate allows, at the lower resolution; at rest: the
        // whole budget at the full one (a surface or stereo pair: always full).
        let mut full = self.view.nav.camera;
        (full.width, full.height) = (w, h);
        let drawn = self.pacing.start(&full, t, self.orbit.on());
        let scale = if self.render.whole() {
            1.0
        } else {
            drawn.scale
        };
        let small = motion::scaled(&full, scale);
        let (dw, dh) = (small.width, small.height);
        // A converged view at rest that nothing touched: the last image again.
        let touched = ui.input(|i| !i.events.is_empty());
        // (`settled`: the frames since the view converged.)
        let again = self.settled > 0
            && !drawn.moving
            && !touched
            && !std::mem::take(&mut self.redraw)
            && self.render.last_size == Some((dw, dh));
        let shown = self.render.target(dw, dh);
        let image = (!again).then(|| self.draw(w, h, scale));
        if image.is_some() {
            self.render.last_size = Some((dw, dh));
        }
        (shown, image, (dw, dh))
    }

    /// Draws the visible datasets in one frame of `width` x `height` pixels (at `scale` of
    /// it): on the first, the view and the tools asked for on the command line.
    fn draw(&mut self, width: u32, height: u32, scale: f32) -> Vec<u8> {
        self.view.size(width, height);
        self.tools.start(&self.view.bounds, &mut self.layers);
        let full = self.view.nav.camera;
        (self.render).draw(&mut self.layers, &full, scale, &self.pacing.select)
    }

    /// Step: the view (the central panel): input, the frame paced and drawn, its times followed
    /// (and the orbit's), the frame shown, the tools' figures over it.
    fn view(&mut self, ui: &mut egui::Ui) {
        let rect = ui.max_rect();
        let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        self.navigate(ui, &response, rect);
        let ppp = ui.ctx().pixels_per_point();
        let (w, h) = (
            (rect.width() * ppp).round().max(1.0) as u32,
            (rect.height() * ppp).round().max(1.0) as u32,
        );
        self.orbit.step(&mut self.view.nav);
        // `view --photo N`: the camera at its pose.
        if let Some(v) = self.photos.start(ui.ctx()) {
            self.view.put(v.eye, v.target, v.up, v.fov_y);
        }
        // A camera path playing moves the camera.
        if let Some(v) = self.tools.path.tick() {
            self.view.nav.look(v.position, v.target);
        }
        self.shots.view_at(rect, ppp, (w, h));
        let t = Instant::now();
        let (shown, image, size) = self.pace_and_draw(ui, t, (w, h));
        let stats = &self.render.stats;
        if let Some(times) = self.pacing.end(t, image.is_some(), stats) {
            let budget = self.pacing.select.budget;
            (self.orbit).frame(times, stats, self.pacing.pace.as_ref(), budget);
        }
        self.render.show(ui, rect, shown, image, size);
        (self.tools).draw(ui.painter(), rect, ppp, &self.view.nav.camera);
        let units = myriad_measure::measurement::crs_units(self.layers.crs().as_deref());
        let parallel = self.view.nav.parallel().then_some(&self.view.nav.camera);
        crate::legend::draw(ui.painter(), rect, parallel, self.layers.colour, units);
        // The photos' markers, the one open over the view from its pose.
        let cam = self.view.nav.camera;
        let screen = crate::tools::on_view(&cam, rect, ppp);
        if let Some(v) = self.photos.draw(ui, rect, &response, &cam, &screen) {
            self.view.put(v.eye, v.target, v.up, v.fov_y);
        }
        // The map; a click there moves the camera, its offset from the target kept.
        if let Some([x, y]) = self.map.draw(ui, rect, &response, &cam) {
            let d = [x - cam.target[0], y - cam.target[1]];
            let eye = [
                cam.position[0] + d[0],
                cam.position[1] + d[1],
                cam.position[2],
            ];
            self.view.nav.look(eye, [x, y, cam.target[2]]);
        }
        if self.render.loading() {
            ui.painter().text(
                rect.right_top() + egui::vec2(-10.0, 10.0),
                egui::Align2::RIGHT_TOP,
                "loading…",
                egui::FontId::proportional(14.0),
                egui::Color32::LIGHT_GRAY,
            );
        }
    }

    /// Converged: the orbit over, the view at rest, no dataset still being built, the selection
    /// of this view in, every node of it drawn, nothing loading, no tool still working.
    fn converged(&self) -> bool {
        !self.orbit.on()
            && !self.pacing.moving
            && self.builds.as_ref().is_none_or(Builds::done)
            && self.render.converged()
            && self.tools.settled()
            && self.map.settled()
    }

    /// Step: after the frame, the view converged or not: the report at rest after an orbit,
    /// the command line's screenshot, the saved work, and when to draw again.
    fn report(&mut self, ctx: &egui::Context) {
        let converged = self.converged();
        self.settled = if converged { self.settled + 1 } else { 0 };
        let (points, camera) = (self.render.points(), &self.view.nav.camera);
        let (budget, drawn_ms) = (self.pacing.select.budget, self.pacing.drawn_ms);
        (self.orbit).at_rest(converged, points, camera, budget, drawn_ms);
        self.shots.when_settled(ctx, self.settled);
        self.tools.sync(Instant::now());
        if converged {
            // Nothing to draw until something is touched (input repaints at once).
            ctx.request_repaint_after(std::time::Duration::from_millis(250));
        } else {
            ctx.request_repaint();
        }
    }
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
            .show(ui, |ui| self.view(ui));
        self.tools.after_frame(&ctx, &self.layers);
        self.panel.help_window(&ctx);
        self.report(&ctx);
    }

    fn on_exit(&mut self) {
        self.tools.flush();
    }
}
