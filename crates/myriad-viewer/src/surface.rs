//! Surfaces and stereo in the viewer. Surfaces (Schiffner et al. 2015): made on their own
//! thread from the points the frames draw, again whenever the view, the drawn points or the
//! parameters change; the last surface is shown (from the current view, drawn on the frame's
//! device and read back) until the new one is in, so a frame never waits for one.

use eframe::egui;
use myriad_lod::{Camera, SelectOptions};
use myriad_render::surface::{self, Kind, Made, Normals, Surface, Worker};
use myriad_render::{FrameStats, Gpu, Rasterizer, Scene, Style};

pub(crate) struct Surfaces {
    pub on: bool,
    pub params: Surface,
    worker: Worker,
    made: Option<Made>,
    /// The view and the number of points drawn the last surface was asked for.
    asked: Option<(Camera, u64)>,
    /// Drawing on a GPU: its surface pipelines (made when first needed).
    drawer: Option<surface::Drawer>,
    /// The first surface with cells was reported (where it was made, how long it took).
    reported: bool,
}

impl Surfaces {
    pub fn new(s: Option<Surface>) -> Surfaces {
        Surfaces {
            on: s.is_some(),
            params: s.unwrap_or_default(),
            worker: Worker::new(),
            made: None,
            asked: None,
            drawer: None,
            reported: false,
        }
    }
    /// Its steps on `gpu` from now on (the frames' device, where it is a GPU).
    pub fn on_gpu(&mut self, gpu: myriad_render::Gpu) {
        self.worker = Worker::on(Some(gpu));
    }

    /// Off, or the surface of the last view asked for is shown (for screenshots of a converged
    /// view).
    pub fn settled(&self) -> bool {
        !self.on
            || (!self.worker.busy() && self.made.as_ref().is_some_and(|m| m.surface == self.params))
    }
    /// With surfaces on: the newest surface taken in, a new one asked for where the view, the
    /// drawn points (`stats`: the frame's) or the parameters changed (when the worker is free),
    /// and the image of the last surface seen from `cam` (the points' image until there is
    /// one), drawn on `gpu`. `visible`: the scenes drawn.
    pub(crate) fn image<'a>(
        &mut self,
        cam: &Camera,
        points_image: Vec<u8>,
        stats: &[FrameStats],
        visible: impl Iterator<Item = &'a Scene>,
        style: &Style,
        gpu: &Gpu,
    ) -> Vec<u8> {
        let s = self;
        if let Some(m) = s.worker.take() {
            if !s.reported && !m.built.clustering.cells.is_empty() {
                s.reported = true;
                println!(
                    "surface: {} cells made on {} in {:.0} ms",
                    m.built.clustering.cells.len(),
                    m.device,
                    m.ms
                );
            }
            s.made = Some(m);
        }
        let drawn: u64 = stats.iter().map(|x| x.points).sum();
        let key = (*cam, drawn);
        let stale = s.asked != Some(key) || s.made.as_ref().is_some_and(|m| m.surface != s.params);
        if stale && !s.worker.busy() {
            let mut points = Vec::new();
            let mut colours = Vec::new();
            for scene in visible {
                let (p, c) = surface::drawn_points(scene, style.clip);
                points.extend(p);
                colours.extend(c);
            }
            if s.worker.ask(cam, points, colours, &s.params) {
                s.asked = Some(key);
            }
        }
        let Some(m) = &s.made else {
            return points_image;
        };
        if gpu.is_cpu() {
            return surface::draw(cam, &m.built.mesh, style);
        }
        s.drawer
            .get_or_insert_with(|| surface::Drawer::new(gpu))
            .draw(gpu, cam, &m.built.mesh, style)
    }
}

/// The surface's choices: kind (or off), normals, neighbours, grid; what the last one took.
pub(crate) fn surface_panel(ui: &mut egui::Ui, s: &mut Surfaces) {
    ui.label("surface");
    let current = if s.on {
        format!("{:?}", s.params.kind).to_lowercase()
    } else {
        "off (points)".into()
    };
    egui::ComboBox::from_label("surface")
        .selected_text(current)
        .show_ui(ui, |ui| {
            if ui.selectable_label(!s.on, "off (points)").clicked() {
                s.on = false;
            }
            for (k, name) in [
                (Kind::Quads, "quads"),
                (Kind::Boxes, "boxes"),
                (Kind::Splats, "splats"),
            ] {
                if ui
                    .selectable_label(s.on && s.params.kind == k, name)
                    .clicked()
                {
                    s.on = true;
                    s.params.kind = k;
                }
            }
        });
    if !s.on {
        return;
    }
    ui.horizontal(|ui| {
        ui.label("normals");
        ui.radio_value(&mut s.params.normals, Normals::Tensor, "tensor");
        ui.radio_value(&mut s.params.normals, Normals::Cells, "cells");
    });
    ui.horizontal(|ui| {
        ui.label("move to");
        for n in [0, 1, 3] {
            ui.radio_value(&mut s.params.neighbours, n, n.to_string());
        }
        ui.label("neighbours");
    });
    ui.horizontal(|ui| {
        ui.label("grid");
        for (v, top) in s.params.grid.iter_mut().zip([600, 600, 200]) {
            ui.add(egui::DragValue::new(v).range(4..=top));
        }
    });
    if let Some(m) = &s.made {
        ui.label(format!(
            "{} cells from {} points, made on {} in {:.0} ms",
            m.built.clustering.cells.len(),
            m.built.clustering.inside,
            m.device,
            m.ms
        ));
    }
}

/// Both eyes side by side in the window (Discher et al. 2018), for a check without a headset.
pub(crate) struct StereoView {
    pub on: bool,
    /// Distance between the eyes, in the data's units.
    pub ipd: f64,
}

impl StereoView {
    /// Both eyes of `scene` (the first visible dataset's; none: black) side by side, each half
    /// the view's width (one selection for both: `Scene::frame_stereo`, single-pass on the CPU
    /// path); the frame's statistics where it was drawn.
    pub(crate) fn draw(
        &self,
        cam: &Camera,
        scene: Option<&mut Scene>,
        (gpu, raster): (&Gpu, &Rasterizer),
        options: &SelectOptions,
        style: &Style,
    ) -> (Vec<u8>, Option<FrameStats>) {
        let (w, h) = (cam.width as usize, cam.height as usize);
        let mut eye = *cam;
        eye.width = (cam.width / 2).max(1);
        let eyes = eye.eyes(self.ipd);
        let stereo = myriad_render::stereo::Stereo {
            ipd: self.ipd,
            ..Default::default()
        };
        let Some(scene) = scene else {
            return (vec![0; w * h * 4], None);
        };
        let (image, stats) = scene.frame_stereo(gpu, raster, &eyes, options, style, &stereo, None);
        // An odd width leaves a column: black.
        let half = 2 * eye.width as usize;
        let mut out = vec![0u8; w * h * 4];
        for y in 0..h {
            out[y * w * 4..][..half * 4].copy_from_slice(&image[y * half * 4..][..half * 4]);
        }
        (out, Some(stats))
    }
}

/// The stereo switch and the eyes' distance.
pub(crate) fn stereo_panel(ui: &mut egui::Ui, s: &mut StereoView) {
    ui.checkbox(&mut s.on, "stereo (both eyes side by side)");
    if s.on {
        ui.add(
            egui::Slider::new(&mut s.ipd, 0.001..=100.0)
                .logarithmic(true)
                .text("eye distance"),
        );
    }
}
