//! Contours over the view (issue 70): the lines of the terrain `myriad ground` found under the
//! first visible dataset, every interval (the panel's, or `view --contours I` on opening, the
//! count printed), drawn at their elevations over the points, every fifth brighter. Made on a
//! thread of their own (`myriad_measure::contours::of_terrain`, from the surface sampled on a
//! grid of at most [`CELLS`] cells).

use crate::shown::Layers;
use eframe::egui;
use myriad_measure::contours::{Contour, of_terrain};
use std::sync::mpsc::{Receiver, channel};

/// The sampled grid's cells at most.
pub const CELLS: usize = 512 * 512;
/// Segments drawn at most a frame.
const SEGMENTS: usize = 200_000;
/// The lines' colours: ordinary and every fifth.
pub const LINE: egui::Color32 = egui::Color32::from_rgb(230, 170, 90);
pub const INDEX: egui::Color32 = egui::Color32::from_rgb(255, 225, 150);

type Made = Result<Vec<Contour>, String>;

pub(crate) struct Contours {
    pub on: bool,
    pub interval: f64,
    lines: Vec<Contour>,
    job: Option<Receiver<Made>>,
    pub problem: Option<String>,
    /// Print what was made (`view --contours`, for scripts).
    print: bool,
    asked: Option<f64>,
}

impl Contours {
    pub fn new(asked: Option<f64>) -> Contours {
        Contours {
            on: false,
            interval: asked.unwrap_or(1.0),
            lines: Vec::new(),
            job: None,
            problem: None,
            print: false,
            asked,
        }
    }

    /// The contours asked for on the command line, made (once).
    pub fn start(&mut self, layers: &Layers) {
        if let Some(i) = self.asked.take() {
            (self.on, self.interval, self.print) = (true, i, true);
            self.make(layers);
        }
    }

    /// Makes the contours of the first visible dataset's terrain, on a thread.
    pub fn make(&mut self, layers: &Layers) {
        self.lines.clear();
        let Some(ds) = layers.first_visible().map(|l| l.dataset.clone()) else {
            return;
        };
        let interval = self.interval;
        let (tx, rx) = channel();
        std::thread::spawn(move || {
            let _ = tx.send(of_terrain(&ds, interval, CELLS));
        });
        self.problem = None;
        self.job = Some(rx);
    }

    /// Takes finished contours.
    pub fn take(&mut self) {
        let Some(rx) = &self.job else { return };
        let Ok(done) = rx.try_recv() else { return };
        self.job = None;
        match done {
            Ok(lines) => {
                if self.print {
                    let vertices: usize = lines.iter().map(|c| c.points.len()).sum();
                    println!(
                        "contours: {} lines every {} ({vertices} vertices)",
                        lines.len(),
                        self.interval
                    );
                }
                self.lines = lines;
            }
            Err(e) => {
                if self.print {
                    eprintln!("contours: {e}");
                }
                self.problem = Some(e);
            }
        }
    }

    pub fn settled(&self) -> bool {
        self.job.is_none()
    }

    /// The panel's part: shown or not, the interval.
    pub fn panel(&mut self, ui: &mut egui::Ui, layers: &Layers) {
        let (was_on, was) = (self.on, self.interval);
        ui.horizontal(|ui| {
            ui.checkbox(&mut self.on, "contours every");
            ui.add(
                egui::DragValue::new(&mut self.interval)
                    .range(0.01..=10_000.0)
                    .speed(0.1),
            );
        });
        if self.on && (!was_on || was != self.interval) {
            self.make(layers);
        }
        if let Some(p) = self.problem.as_ref().filter(|_| self.on) {
            ui.colored_label(egui::Color32::from_rgb(255, 100, 100), p);
        }
    }

    /// The lines over the view, at their elevations.
    pub fn draw(&self, painter: &egui::Painter, screen: &dyn Fn([f64; 3]) -> Option<egui::Pos2>) {
        if !self.on {
            return;
        }
        let mut drawn = 0;
        for c in &self.lines {
            let index = (c.elevation / (5.0 * self.interval)).round() * 5.0 * self.interval;
            let stroke = match (c.elevation - index).abs() < self.interval * 1e-6 {
                true => egui::Stroke::new(1.6, INDEX),
                false => egui::Stroke::new(1.0, LINE),
            };
            let at = |p: &[f64; 2]| screen([p[0], p[1], c.elevation]);
            let closing = c.closed.then(|| (c.points.last(), c.points.first()));
            let pairs = (c.points.windows(2).map(|w| (&w[0], &w[1])))
                .chain(closing.and_then(|(a, b)| Some((a?, b?))));
            for (a, b) in pairs {
                if let (Some(a), Some(b)) = (at(a), at(b)) {
                    painter.line_segment([a, b], stroke);
                    drawn += 1;
                    if drawn >= SEGMENTS {
                        return;
                    }
                }
            }
        }
    }
}
