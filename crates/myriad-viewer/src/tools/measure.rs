//! The measuring tool: the kind being measured (M, N, A, O, C, Z, I or the panel), the
//! measurements made (the one being made last; clicks add points, a right click ends one),
//! the units their lengths show in, and their lines and figures over the view. The geometry is
//! `myriad_measure::measurement`'s (`crate::measure`).

use crate::measure::{Kind, Measurement, Units};
use eframe::egui;

pub(crate) struct Measuring {
    /// The kind being measured, if any.
    pub tool: Option<Kind>,
    /// Measurements, the one being made last.
    pub measurements: Vec<Measurement>,
    /// The units lengths show in; metres per unit of the first dataset's coordinates (from
    /// its CRS); the ellipsoid measurements are made on, where the CRS is geographic.
    units: Units,
    data_metres: Option<f64>,
    earth: Option<(f64, f64)>,
}

impl Measuring {
    /// With the measurements saved before, in the first dataset's `crs`.
    pub fn new(measurements: Vec<Measurement>, crs: Option<&str>) -> Measuring {
        Measuring {
            tool: None,
            measurements,
            units: Units::Data,
            data_metres: crs.and_then(crate::measure::metres_per_unit),
            earth: myriad_measure::measurement::earth(crs),
        }
    }

    /// Measures `kind` from now on (a new measurement where the last is of another kind or
    /// has points).
    pub fn start(&mut self, kind: Kind) {
        self.tool = Some(kind);
        if self
            .measurements
            .last()
            .is_none_or(|m| m.kind != kind || !m.points.is_empty())
        {
            self.measurements.push(Measurement::new(kind));
        }
    }

    /// A click on the view while measuring: `clicked` adds the point under the cursor
    /// (`at`, looked for only then), `ended` (a right click) ends the measurement.
    pub fn click(&mut self, clicked: bool, ended: bool, at: &dyn Fn() -> Option<[f64; 3]>) {
        let Some(kind) = self.tool else { return };
        if clicked && let Some(p) = at() {
            if self.measurements.last().is_none_or(|m| m.kind != kind) {
                self.measurements.push(Measurement::new(kind));
            }
            self.measurements.last_mut().expect("pushed above").add(p);
        }
        if ended {
            self.measurements.push(Measurement::new(kind));
        }
    }

    /// The panel's part: the kinds, the units, stop and clear, and each measurement's figure.
    /// The kind started, if one was.
    pub fn panel(&mut self, ui: &mut egui::Ui) -> Option<Kind> {
        ui.label("measure");
        let mut started = None;
        ui.horizontal_wrapped(|ui| {
            for kind in Kind::ALL {
                if ui
                    .selectable_label(self.tool == Some(kind), kind.name())
                    .clicked()
                {
                    self.start(kind);
                    started = Some(kind);
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
        started
    }

    /// The measurements over the view: lines between their points, the figure by the last.
    pub fn draw(&self, painter: &egui::Painter, screen: &dyn Fn([f64; 3]) -> Option<egui::Pos2>) {
        let colour = egui::Color32::from_rgb(255, 210, 0);
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
    }
}
