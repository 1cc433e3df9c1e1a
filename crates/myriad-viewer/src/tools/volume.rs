//! Volumes in the window: a polygon clicked on the data (V, then its corners; a right click or
//! "measure" measures) over the first visible dataset, above the rim's plane or an elevation,
//! on cells of a size given or chosen from the spacing (`myriad_measure::volume`, as `myriad
//! volume` measures, on a thread of its own). The result is in the panel; the view draws the
//! polygon, the base (its outline at the base's heights) and the grid (each cell at the
//! surface's height, green where there is fill, red where there is cut; coarser blocks of cells
//! where there are more than a few thousand). One asked for on the command line (`view
//! --volume`) is measured on the first frame, its result printed.

use crate::options::VolumeAsked;
use crate::shown::Layers;
use eframe::egui;
use myriad_core::Aabb;
use myriad_format::Dataset;
use myriad_measure::volume::{Base, Cells, Volume, volume_and_cells};
use myriad_measure::{Filter, Polygon};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, channel};

/// The polygon's colour, and the base's.
pub const OUTLINE: egui::Color32 = egui::Color32::from_rgb(255, 210, 0);
pub const BASE: egui::Color32 = egui::Color32::from_rgb(255, 140, 0);
/// Blocks of cells drawn at most.
const DRAWN: usize = 3000;

/// What the volume is measured down to (a dataset base is the command line's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Down {
    Rim,
    Elevation(f64),
}

type Measured = Result<(Volume, Option<Cells>, Polygon), String>;

pub(crate) struct Volumes {
    pub drawing: bool,
    pub polygon: Vec<[f64; 3]>,
    pub base: Down,
    /// 0: from the points' spacing.
    pub cell: f64,
    job: Option<Receiver<Measured>>,
    result: Option<(Volume, Option<Cells>, Polygon)>,
    pub problem: Option<String>,
    units: &'static str,
    /// Print each result on stdout (`view --volume`, for scripts).
    pub print: bool,
    /// The volume asked for on the command line, measured on the first frame.
    asked: Option<VolumeAsked>,
}

impl Volumes {
    pub fn new(units: &'static str, asked: Option<VolumeAsked>) -> Volumes {
        Volumes {
            asked,
            drawing: false,
            polygon: Vec::new(),
            base: Down::Rim,
            cell: 0.0,
            job: None,
            result: None,
            problem: None,
            units,
            print: false,
        }
    }

    /// The volume asked for on the command line, its polygon at the bottom of `bounds` (the
    /// data's extent), measured in `layers` (once).
    pub fn start(&mut self, bounds: &Aabb, layers: &Layers) {
        if let Some(VolumeAsked {
            polygon,
            base,
            cell,
        }) = self.asked.take()
        {
            let z = bounds.min[2];
            self.polygon = polygon.iter().map(|p| [p[0], p[1], z]).collect();
            self.base = base.map_or(Down::Rim, Down::Elevation);
            self.cell = cell.unwrap_or(0.0);
            self.print = true;
            self.measure_first(layers);
        }
    }

    /// Measures the volume over the polygon drawn, in the first visible dataset of `layers`.
    pub fn measure_first(&mut self, layers: &Layers) {
        let filter = layers.filter();
        if let Some(l) = layers.first_visible() {
            self.measure(l.dataset.clone(), &filter);
        }
    }

    /// Measures over the polygon so far, on a thread of its own.
    pub fn measure(&mut self, ds: Arc<Dataset>, filter: &Filter) {
        self.drawing = false;
        let plan: Vec<[f64; 2]> = self.polygon.iter().map(|p| [p[0], p[1]]).collect();
        let polygon = match Polygon::new(&plan) {
            Ok(p) => p,
            Err(e) => {
                self.problem = Some(e);
                return;
            }
        };
        let bound = match filter.bind(&ds.meta.schema) {
            Ok(b) => b,
            Err(e) => {
                self.problem = Some(e);
                return;
            }
        };
        let (base, cell) = (self.base, (self.cell > 0.0).then_some(self.cell));
        let (tx, rx) = channel();
        std::thread::spawn(move || {
            let b = match base {
                Down::Rim => Base::Rim,
                Down::Elevation(z) => Base::Elevation(z),
            };
            let r = volume_and_cells(&ds, &polygon, b, cell, &bound);
            let _ = tx.send(r.map(|(v, c)| (v, c, polygon)));
        });
        self.problem = None;
        self.result = None;
        self.job = Some(rx);
    }

    pub fn settled(&self) -> bool {
        self.job.is_none()
    }

    /// Takes a finished measurement.
    pub fn take(&mut self) {
        let Some(rx) = &self.job else { return };
        let Ok(done) = rx.try_recv() else { return };
        self.job = None;
        match done {
            Ok(r) => {
                if self.print {
                    println!("volume: {}", self.describe(&r.0));
                }
                self.result = Some(r);
            }
            Err(e) => self.problem = Some(e),
        }
    }

    fn describe(&self, v: &Volume) -> String {
        v.summary(self.units)
    }

    /// Starts drawing a polygon anew (`on`), or stops drawing it.
    pub fn draw_polygon(&mut self, on: bool) {
        self.drawing = on;
        if on {
            self.polygon.clear();
        }
    }

    /// The panel's part; whether to measure now.
    pub fn panel(&mut self, ui: &mut egui::Ui) -> bool {
        ui.label("volume");
        let mut go = false;
        ui.horizontal(|ui| {
            if ui
                .selectable_label(self.drawing, "polygon (V)")
                .on_hover_text("click the polygon's corners; a right click measures")
                .clicked()
            {
                self.draw_polygon(!self.drawing);
                if self.drawing {
                    self.result = None;
                }
            }
            if ui
                .add_enabled(
                    self.polygon.len() >= 3 && self.job.is_none(),
                    egui::Button::new("measure"),
                )
                .clicked()
            {
                go = true;
            }
        });
        ui.horizontal(|ui| {
            let mut rim = self.base == Down::Rim;
            ui.radio_value(&mut rim, true, "rim's plane");
            ui.radio_value(&mut rim, false, "elevation");
            match (rim, self.base) {
                (true, _) => self.base = Down::Rim,
                (false, Down::Rim) => {
                    let z = self
                        .polygon
                        .iter()
                        .map(|p| p[2])
                        .fold(f64::INFINITY, f64::min);
                    self.base = Down::Elevation(if z.is_finite() { z } else { 0.0 });
                }
                (false, Down::Elevation(mut z)) => {
                    ui.add(egui::DragValue::new(&mut z).speed(0.05));
                    self.base = Down::Elevation(z);
                }
            }
        });
        ui.add(
            egui::DragValue::new(&mut self.cell)
                .range(0.0..=1e5)
                .speed(0.01)
                .prefix("cell ")
                .custom_formatter(|v, _| {
                    if v == 0.0 {
                        "from the spacing".into()
                    } else {
                        format!("{v}")
                    }
                }),
        );
        if self.job.is_some() {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label("measuring…");
            });
        }
        if let Some((v, _, _)) = &self.result {
            ui.monospace(self.describe(v).replace(", ", "\n"));
        }
        if let Some(p) = &self.problem {
            ui.colored_label(egui::Color32::LIGHT_RED, p);
        }
        go
    }

    /// The polygon, the base and the grid over the view.
    pub fn draw(&self, painter: &egui::Painter, screen: &dyn Fn([f64; 3]) -> Option<egui::Pos2>) {
        let ring = |pts: &[Option<egui::Pos2>], colour: egui::Color32, closed: bool| {
            let n = pts.len();
            let edges = if closed && n >= 3 {
                n
            } else {
                n.saturating_sub(1)
            };
            for i in 0..edges {
                if let (Some(a), Some(b)) = (pts[i], pts[(i + 1) % n]) {
                    painter.line_segment([a, b], egui::Stroke::new(2.0, colour));
                }
            }
        };
        let outline: Vec<Option<egui::Pos2>> = self.polygon.iter().map(|&p| screen(p)).collect();
        ring(&outline, OUTLINE, !self.drawing);
        for p in outline.iter().flatten() {
            painter.circle_filled(*p, 3.5, OUTLINE);
        }
        let Some((v, cells, polygon)) = &self.result else {
            return;
        };
        // The base under each corner.
        let elevation = match self.base {
            Down::Elevation(z) => Some(z),
            Down::Rim => None,
        };
        let base: Vec<Option<egui::Pos2>> = (polygon.vertices().iter())
            .map(|q| screen([q[0], q[1], v.base_at(polygon, elevation, q[0], q[1])?]))
            .collect();
        let Some(c) = cells else {
            ring(&base, BASE, true);
            return;
        };
        // Squares of cells, each drawn at the surface's height of its first cell.
        for b in c.blocks(DRAWN) {
            let [x, y] = b.centre;
            let corners: Option<Vec<egui::Pos2>> =
                [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                    .iter()
                    .map(|(dx, dy)| screen([x + dx * b.half, y + dy * b.half, b.top]))
                    .collect();
            let Some(corners) = corners else { continue };
            let fill = if b.fill {
                egui::Color32::from_rgba_unmultiplied(60, 210, 60, 70)
            } else {
                egui::Color32::from_rgba_unmultiplied(230, 50, 50, 70)
            };
            painter.add(egui::Shape::convex_polygon(
                corners,
                fill,
                egui::Stroke::new(0.5, egui::Color32::from_white_alpha(60)),
            ));
        }
        ring(&base, BASE, true);
    }
}
