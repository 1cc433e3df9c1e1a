//! The settings panel on the left of the view: budget and frame rate, point style and colour,
//! the filter, the post passes, surfaces and stereo, datasets, views, the clipping box, the
//! tools, and what the frame reports.

use crate::measure::{Kind, Units};
use crate::nav::View;
use crate::present::passes_panel;
use crate::{App, surface};
use eframe::egui;
use myriad_lod::Camera;
use myriad_render::{PointSize, Shape};

impl App {
    pub(crate) fn settings(&mut self, ui: &mut egui::Ui) {
        ui.heading("Myriad");
        let most = self.pace.as_ref().map_or(self.options.budget, |p| p.max);
        let mut budget = most as f64 / 1e6;
        ui.add(
            egui::Slider::new(&mut budget, 0.1..=20.0)
                .logarithmic(true)
                .text(if self.pace.is_some() {
                    "most points (M)"
                } else {
                    "budget (M points)"
                }),
        );
        let budget = (budget * 1e6) as u64;
        let mut hold = self.pace.is_some();
        ui.checkbox(&mut hold, "hold the frame rate");
        match (&mut self.pace, hold) {
            (Some(p), true) => {
                p.max = budget;
                let mut fps = 1.0 / p.target;
                ui.add(egui::Slider::new(&mut fps, 1.0..=120.0).text("target fps"));
                p.target = 1.0 / fps;
                ui.label(format!(
                    "budget now {:.2} M points",
                    self.options.budget as f64 / 1e6
                ));
            }
            (None, true) => {
                self.pace = Some(myriad_lod::Pace::new(30.0, budget, 100_000, budget));
            }
            (_, false) => {
                self.pace = None;
                self.options.budget = budget;
            }
        }
        ui.add(
            egui::Slider::new(&mut self.options.min_pixels, 0.25..=8.0)
                .logarithmic(true)
                .text("LOD threshold (px)"),
        );
        ui.separator();
        let adaptive = matches!(self.style.size, PointSize::Adaptive { .. });
        ui.horizontal(|ui| {
            if ui.radio(adaptive, "adaptive").clicked() && !adaptive {
                self.style.size = PointSize::adaptive();
            }
            if ui.radio(!adaptive, "fixed").clicked() && adaptive {
                self.style.size = PointSize::Fixed(2.0);
            }
        });
        match &mut self.style.size {
            PointSize::Adaptive { scale, .. } => {
                ui.add(egui::Slider::new(scale, 0.25..=4.0).text("size scale"));
            }
            PointSize::Fixed(px) => {
                ui.add(egui::Slider::new(px, 1.0..=16.0).text("size (px)"));
            }
        }
        egui::ComboBox::from_label("shape")
            .selected_text(format!("{:?}", self.style.shape))
            .show_ui(ui, |ui| {
                for s in [Shape::Square, Shape::Round, Shape::Paraboloid] {
                    ui.selectable_value(&mut self.style.shape, s, format!("{s:?}"));
                }
            });
        self.colour_panel(ui);
        self.classes_panel(ui);
        passes_panel(ui, &mut self.style.passes);
        ui.separator();
        surface::surface_panel(ui, &mut self.surfaces);
        surface::stereo_panel(ui, &mut self.stereo);
        ui.separator();
        ui.label("datasets");
        for l in &mut self.layers {
            ui.checkbox(&mut l.visible, &l.name);
        }
        ui.separator();
        let points: u64 = self.stats.iter().map(|s| s.points).sum();
        let nodes: usize = self.stats.iter().map(|s| s.nodes).sum();
        let loading: usize = self.stats.iter().map(|s| s.in_flight).sum();
        let ram: usize = self
            .layers
            .iter()
            .map(|l| l.scene.loader.resident_bytes())
            .sum();
        let vram: usize = self.layers.iter().map(|l| l.scene.buffers.bytes()).sum();
        let tree: usize = self.stats.iter().map(|s| s.hierarchy_bytes).sum();
        ui.label(format!(
            "{:.1} fps, frame {:.0} ms",
            self.timing.fps, self.timing.frame_ms
        ));
        ui.label(format!("{points} points in {nodes} nodes"));
        let select = self
            .stats
            .iter()
            .map(|s| s.select_thread)
            .max()
            .unwrap_or_default();
        ui.label(format!(
            "selection {:.1} ms (own thread)",
            select.as_secs_f64() * 1e3
        ));
        ui.label(format!(
            "cache: {:.0} MB decoded, {:.0} MB of point buffers, {:.1} MB of hierarchy",
            ram as f64 / 1e6,
            vram as f64 / 1e6,
            tree as f64 / 1e6
        ));
        let on_gpu: u64 = self.stats.iter().map(|s| s.gpu_points).sum();
        let read: u64 = self.stats.iter().map(|s| s.read_bytes).sum();
        ui.label(format!(
            "point buffers: {:.1} bytes a point, {:.1} read per drawn point",
            vram as f64 / on_gpu.max(1) as f64,
            read as f64 / points.max(1) as f64
        ));
        ui.horizontal(|ui| {
            if loading > 0 {
                ui.spinner();
                ui.label(format!("loading {loading} nodes and pages"));
            } else {
                ui.label("all loaded");
            }
        });
        ui.label(format!(
            "drawn by: {} ({:?})",
            self.gpu.name, self.raster.path
        ));
        if let Some(p) = &self.picked {
            ui.separator();
            ui.label("picked point");
            ui.monospace(p);
        }
        ui.separator();
        ui.label("measure");
        ui.horizontal_wrapped(|ui| {
            for kind in Kind::ALL {
                if ui
                    .selectable_label(self.tool == Some(kind), kind.name())
                    .clicked()
                {
                    self.start_measuring(kind);
                }
            }
        });
        egui::ComboBox::from_label("units")
            .selected_text(format!("{:?}", self.units))
            .show_ui(ui, |ui| {
                for u in [Units::Data, Units::Metres, Units::Feet, Units::UsFeet] {
                    ui.selectable_value(&mut self.units, u, format!("{u:?}"));
                }
            });
        ui.horizontal(|ui| {
            if ui.button("stop").clicked() {
                self.tool = None;
            }
            if ui.button("clear").clicked() {
                self.measurements.clear();
            }
        });
        for m in &self.measurements {
            if let Some(l) = m.label_for(self.units, self.data_metres, self.earth) {
                ui.monospace(l);
            }
        }
        ui.separator();
        if self.saved.placing {
            self.tool = None;
        }
        if let Some(v) = self.saved.panel(ui) {
            self.nav.look(v.position, v.target);
        }
        ui.separator();
        if self.section.panel(ui) {
            self.cut_section();
        }
        ui.separator();
        if self.volumes.panel(ui) {
            self.measure_volume();
        }
        ui.separator();
        ui.checkbox(&mut self.clip_on, "clipping box");
        if self.clip_on {
            ui.horizontal(|ui| {
                ui.radio_value(&mut self.clip_inside, true, "show inside");
                ui.radio_value(&mut self.clip_inside, false, "outside");
            });
            for (axis, name) in ["x", "y", "z"].iter().enumerate() {
                let [lo, hi] = &mut self.clip[axis];
                ui.add(egui::Slider::new(lo, 0.0..=1.0).text(format!("{name} from")));
                ui.add(egui::Slider::new(hi, 0.0..=1.0).text(format!("{name} to")));
                if *lo > *hi {
                    std::mem::swap(lo, hi);
                }
            }
        }
        self.style.clip = self.clip_on.then(|| myriad_render::Clip {
            bounds: self.clip_box(),
            inside: self.clip_inside,
        });
        ui.separator();
        ui.label("views");
        ui.horizontal_wrapped(|ui| {
            for v in View::ALL {
                if ui.small_button(v.name()).clicked() {
                    self.nav.standard(v, &self.bounds);
                }
            }
        });
        let mut parallel = self.nav.parallel();
        if ui
            .checkbox(&mut parallel, "parallel (orthographic, 0)")
            .changed()
        {
            self.nav.set_parallel(parallel);
        }
        if ui.button("save this view").clicked() {
            let n = self.bookmarks.len() + 1;
            self.bookmarks
                .push((format!("view {n}"), self.nav.camera, self.nav.pivot));
        }
        let mut go = None;
        for (i, (name, _, _)) in self.bookmarks.iter().enumerate() {
            if ui.button(name).clicked() {
                go = Some(i);
            }
        }
        if let Some(i) = go {
            let (_, cam, pivot) = self.bookmarks[i];
            self.nav.camera = Camera {
                width: self.nav.camera.width,
                height: self.nav.camera.height,
                ..cam
            };
            self.nav.pivot = pivot;
        }
        if ui.button("screenshot (P)").clicked() {
            self.screenshot_now(ui.ctx());
        }
        ui.separator();
        if ui.button("help (H)").clicked() {
            self.help = !self.help;
        }
    }
}
