//! The settings panel on the left of the view, and the help window. The panel's parts are the
//! values' own (budget and frame rate: `pacing.rs`; colour, filter, classes and datasets:
//! `shown.rs`; the post passes: `present.rs`; surfaces and stereo: `surface.rs`; the tools:
//! `tools/`; views: `navigation.rs`), laid out in order by the app; here are the point style,
//! what the frame reports, and the help.

use crate::pacing::Timing;
use crate::render::Render;
use crate::report::HELP;
use crate::shown::Layers;
use eframe::egui;
use myriad_render::{PointSize, Shape, Style};

/// The side panel's own state: whether the help window is open.
#[derive(Default)]
pub(crate) struct Panel {
    pub help: bool,
}

impl Panel {
    /// The help window's button.
    pub fn help_button(&mut self, ui: &mut egui::Ui) {
        if ui.button("help (H)").clicked() {
            self.help = !self.help;
        }
    }

    /// The shortcuts, where the help is open.
    pub fn help_window(&self, ctx: &egui::Context) {
        if self.help {
            egui::Window::new("Shortcuts")
                .collapsible(false)
                .show(ctx, |ui| {
                    egui::Grid::new("keys").show(ui, |ui| {
                        for (k, v) in HELP {
                            ui.strong(*k);
                            ui.label(*v);
                            ui.end_row();
                        }
                    });
                });
        }
    }
}

/// The points' size (adaptive or fixed, and its scale or pixels) and shape.
pub(crate) fn style_panel(ui: &mut egui::Ui, style: &mut Style) {
    let adaptive = matches!(style.size, PointSize::Adaptive { .. });
    ui.horizontal(|ui| {
        if ui.radio(adaptive, "adaptive").clicked() && !adaptive {
            style.size = PointSize::adaptive();
        }
        if ui.radio(!adaptive, "fixed").clicked() && adaptive {
            style.size = PointSize::Fixed(2.0);
        }
    });
    match &mut style.size {
        PointSize::Adaptive { scale, .. } => {
            ui.add(egui::Slider::new(scale, 0.25..=4.0).text("size scale"));
        }
        PointSize::Fixed(px) => {
            ui.add(egui::Slider::new(px, 1.0..=16.0).text("size (px)"));
        }
    }
    egui::ComboBox::from_label("shape")
        .selected_text(format!("{:?}", style.shape))
        .show_ui(ui, |ui| {
            for s in [Shape::Square, Shape::Round, Shape::Paraboloid] {
                ui.selectable_value(&mut style.shape, s, format!("{s:?}"));
            }
        });
}

/// What the last frame reports: the rate and time, the points and nodes drawn, the selection's
/// time, the caches, what is loading, and what draws.
pub(crate) fn frame_report(ui: &mut egui::Ui, render: &Render, layers: &Layers, timing: &Timing) {
    let stats = &render.stats;
    let points: u64 = stats.iter().map(|s| s.points).sum();
    let nodes: usize = stats.iter().map(|s| s.nodes).sum();
    let loading: usize = stats.iter().map(|s| s.in_flight).sum();
    let ram: usize = (layers.list.iter())
        .map(|l| l.scene.loader.resident_bytes())
        .sum();
    let vram: usize = layers.list.iter().map(|l| l.scene.buffers.bytes()).sum();
    let tree: usize = stats.iter().map(|s| s.hierarchy_bytes).sum();
    ui.label(format!(
        "{:.1} fps, frame {:.0} ms",
        timing.fps, timing.frame_ms
    ));
    ui.label(format!("{points} points in {nodes} nodes"));
    let select = stats
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
    let on_gpu: u64 = stats.iter().map(|s| s.gpu_points).sum();
    let read: u64 = stats.iter().map(|s| s.read_bytes).sum();
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
        render.gpu.name, render.raster.path
    ));
}
