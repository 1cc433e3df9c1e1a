//! What the points show in the viewer: which (`view --classes`/`--where` from the command line,
//! and the class list in the panel, each class of the overview shown or hidden: a change reopens
//! each layer's scene with the new filter, its settings and the view kept, so the level of detail
//! is drawn from the points kept and nothing filtered out is drawn), and in what colour (the
//! schemes, or any attribute through a gradient over a range). The panel's "where" box adds
//! conditions (`--where`'s syntax) to the command line's, checked against every dataset's
//! attributes first: one the data lack is said there and nothing changes.

use crate::{App, Layer};
use eframe::egui;
use myriad_core::colour::{Gradient, choose};
use myriad_core::{Column, Schema};
use myriad_format::Dataset;
use myriad_measure::Filter;
use myriad_measure::filter::Condition;
use myriad_measure::filter::class_name;
use myriad_render::{ColorBy, Scene};
use std::collections::BTreeMap;
use std::sync::Arc;

/// The classes of the dataset's root node (the overview: a sample of the whole) and their
/// points there.
pub fn overview_classes(ds: &Dataset) -> BTreeMap<u8, u64> {
    let mut out = BTreeMap::new();
    if let Some(c) = ds.overview().and_then(|b| b.classification) {
        for k in c {
            *out.entry(k).or_insert(0) += 1;
        }
    }
    out
}

/// A scene of `ds` drawing what `filter` keeps (all of it where the dataset lacks what the
/// filter reads, with a warning), with `old`'s settings.
pub fn reopen(
    old: &Scene,
    ds: Arc<Dataset>,
    filter: &Filter,
    (ram, gpu): (usize, usize),
    colour: ColorBy,
) -> Scene {
    let bound = filter.bind(&ds.meta.schema).unwrap_or_else(|e| {
        eprintln!("warning: {}: {e}: drawn unfiltered", ds.path().display());
        myriad_measure::Bound::all()
    });
    let mut scene = Scene::open_filtered(ds, bound, ram, gpu);
    scene.set_colour(colour);
    scene.occlusion = old.occlusion;
    scene.upload_limit = old.upload_limit;
    scene.query_wait = old.query_wait;
    scene
}

/// The panel's colour ramp and "where" box.
#[derive(Default)]
pub struct Typed {
    pub text: String,
    pub conditions: Vec<Condition>,
    pub problem: Option<String>,
}

/// The conditions in `text` (`--where`'s syntax; none when empty), checked against each of
/// `schemas`.
pub fn typed_conditions(text: &str, schemas: &[&Schema]) -> Result<Vec<Condition>, String> {
    if text.trim().is_empty() {
        return Ok(Vec::new());
    }
    let conditions = Filter::parse_where(text)?;
    let f = Filter {
        classes: None,
        conditions,
    };
    for s in schemas {
        f.bind(s).map_err(|e| e.replace("--where: ", ""))?;
    }
    Ok(f.conditions)
}

/// `name`'s values of `ds` through `gradient`, over the 2nd to 98th percentiles of its overview
/// (`--color NAME --gradient G`).
pub fn ramp_over(ds: &Dataset, name: &str, gradient: Gradient) -> Result<ColorBy, String> {
    choose(name, Some(gradient), None, &ds.meta.schema, || {
        ds.overview().unwrap_or_default()
    })
}

impl Layer {
    pub(crate) fn refilter(&mut self, filter: &Filter, shares: (usize, usize), colour: ColorBy) {
        self.scene = reopen(&self.scene, self.dataset.clone(), filter, shares, colour);
    }
}

impl App {
    /// The filter the view draws: the command line's conditions and the panel's, and the
    /// classes ticked.
    pub(crate) fn filter(&self) -> Filter {
        let mut f = self.filter.clone();
        f.conditions.extend(self.typed.conditions.iter().cloned());
        if self.classes.values().any(|&(_, shown)| !shown) {
            f.classes = Some(
                (self.classes.iter())
                    .filter(|(_, (_, shown))| *shown)
                    .map(|(c, _)| *c)
                    .collect(),
            );
        }
        f
    }

    /// The colour scheme, and a ramp's (`--color ATTRIBUTE`) gradient and range.
    pub(crate) fn colour_panel(&mut self, ui: &mut egui::Ui) {
        let before = self.colour;
        egui::ComboBox::from_label("colour")
            .selected_text(match self.colour {
                ColorBy::Ramp(r) => format!("{:?} ramp", r.column),
                c => format!("{c:?}"),
            })
            .show_ui(ui, |ui| {
                for c in [
                    ColorBy::Rgb,
                    ColorBy::Intensity,
                    ColorBy::Elevation,
                    ColorBy::Classification,
                    ColorBy::ReturnNumber,
                    ColorBy::PointSource,
                    ColorBy::Level,
                    ColorBy::Uniform,
                ] {
                    ui.selectable_value(&mut self.colour, c, format!("{c:?}"));
                }
                // Any attribute of the first dataset through a gradient.
                let Some(ds) = self.layers.first().map(|l| l.dataset.clone()) else {
                    return;
                };
                ui.separator();
                ui.label("attribute through a gradient");
                let mut names = vec![("z".to_string(), Column::Axis(2))];
                names.extend(Column::columns(&ds.meta.schema));
                for (name, column) in names {
                    let on = matches!(self.colour, ColorBy::Ramp(r) if r.column == column);
                    if ui.selectable_label(on, &name).clicked() && !on {
                        let gradient = match self.colour {
                            ColorBy::Ramp(r) => r.gradient,
                            _ if name == "z" => Gradient::Spectral,
                            _ => Gradient::Viridis,
                        };
                        match ramp_over(&ds, &name, gradient) {
                            Ok(c) => self.colour = c,
                            Err(e) => self.typed.problem = Some(e),
                        }
                    }
                }
            });
        if let ColorBy::Ramp(r) = &mut self.colour {
            egui::ComboBox::from_label("gradient")
                .selected_text(format!("{:?}", r.gradient))
                .show_ui(ui, |ui| {
                    for g in Gradient::ALL {
                        ui.selectable_value(&mut r.gradient, g, format!("{g:?}"));
                    }
                });
            let span = (r.range[1] - r.range[0]).abs().max(1e-6);
            ui.horizontal(|ui| {
                ui.label("range");
                ui.add(egui::DragValue::new(&mut r.range[0]).speed(span / 100.0));
                ui.add(egui::DragValue::new(&mut r.range[1]).speed(span / 100.0));
            });
        }
        if self.colour != before {
            for l in &mut self.layers {
                l.scene.set_colour(self.colour);
            }
        }
        // Conditions on top of the command line's.
        let mut apply = false;
        ui.horizontal(|ui| {
            ui.label("where");
            let r = ui.add(
                egui::TextEdit::singleline(&mut self.typed.text)
                    .hint_text("intensity>100 and return_number=1")
                    .desired_width(170.0),
            );
            apply = r.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
            apply |= ui.button("apply").clicked();
        });
        if apply {
            let schemas: Vec<&Schema> =
                self.layers.iter().map(|l| &l.dataset.meta.schema).collect();
            match typed_conditions(&self.typed.text, &schemas) {
                Ok(c) => {
                    self.typed.problem = None;
                    if c != self.typed.conditions {
                        self.typed.conditions = c;
                        let f = self.filter();
                        for l in &mut self.layers {
                            l.refilter(&f, self.shares, self.colour);
                        }
                    }
                }
                Err(e) => self.typed.problem = Some(e),
            }
        }
        if let Some(p) = &self.typed.problem {
            ui.colored_label(egui::Color32::LIGHT_RED, p);
        }
    }

    /// The class list: a box per class of the overview with its colour, name and points there.
    pub(crate) fn classes_panel(&mut self, ui: &mut egui::Ui) {
        if self.classes.is_empty() {
            return;
        }
        let mut changed = false;
        egui::CollapsingHeader::new("classes (points in the overview)")
            .default_open(false)
            .show(ui, |ui| {
                for (c, (count, shown)) in self.classes.iter_mut() {
                    ui.horizontal(|ui| {
                        let [r, g, b] = myriad_core::colour::class_colour(*c);
                        let (rect, _) =
                            ui.allocate_exact_size(egui::vec2(10.0, 10.0), egui::Sense::hover());
                        ui.painter()
                            .rect_filled(rect, 0.0, egui::Color32::from_rgb(r, g, b));
                        changed |= ui
                            .checkbox(shown, format!("{c} {}: {count}", class_name(*c)))
                            .changed();
                    });
                }
            });
        if changed {
            let f = self.filter();
            for l in &mut self.layers {
                l.refilter(&f, self.shares, self.colour);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_core::Attribute;

    #[test]
    fn typed_conditions_are_checked_against_every_dataset() {
        let both = Schema::for_las_format(1);
        let rgb_only = Schema::new(vec![Attribute::Rgb]);
        let c = typed_conditions("intensity>100 and return_number=1", &[&both]).unwrap();
        assert_eq!(c.len(), 2);
        assert!(
            typed_conditions("  ", &[&both, &rgb_only])
                .unwrap()
                .is_empty()
        );
        // One dataset lacks intensity: said, naming it.
        let e = typed_conditions("intensity>100", &[&both, &rgb_only]).unwrap_err();
        assert!(e.contains("no attribute \"intensity\""), "{e}");
        let e = typed_conditions("intensity", &[&both]).unwrap_err();
        assert!(e.contains("expected NAME OP VALUE"), "{e}");
    }
}
