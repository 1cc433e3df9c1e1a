//! What the points show in the viewer: which (`view --classes`/`--where` from the command line,
//! and the class list in the panel, each class of the overview shown or hidden: a change reopens
//! each layer's scene with the new filter, its settings and the view kept, so the level of detail
//! is drawn from the points kept and nothing filtered out is drawn), and in what colour (the
//! schemes, or any attribute through a gradient over a range). The panel's "where" box adds
//! conditions (`--where`'s syntax) to the command line's, checked against every dataset's
//! attributes first: one the data lack is said there and nothing changes.
//!
//! It holds the window's layers ([`Layers`]: each dataset's scene, whether it is shown), the
//! filter they draw and their colour.

use eframe::egui;
use myriad_core::Aabb;
use myriad_core::colour::Gradient;
use myriad_core::{Attribute, Column, Schema};
use myriad_format::Dataset;
use myriad_lod::Camera;
use myriad_measure::Filter;
use myriad_measure::filter::Condition;
use myriad_measure::filter::class_name;
use myriad_render::{ColorBy, Scene};
use std::collections::BTreeMap;
use std::sync::Arc;

/// A dataset in the window: its name, scene, and whether it is shown.
pub(crate) struct Layer {
    pub name: String,
    pub scene: Scene,
    pub dataset: Arc<Dataset>,
    pub visible: bool,
}

/// The layers, what they draw (the filter: the command line's, the panel's conditions, the
/// classes ticked) and in what colour.
pub(crate) struct Layers {
    pub list: Vec<Layer>,
    /// The caches' shares a layer's new scene gets: decoded points and GPU buffers (bytes).
    pub shares: (usize, usize),
    /// The command line's filter, and the overview's classes: points there, shown.
    pub filter: Filter,
    classes: BTreeMap<u8, (u64, bool)>,
    /// The panel's colour ramp and "where" box: what is typed, the conditions it gave (on top
    /// of the command line's), and why the last one was not taken.
    typed: Typed,
    pub colour: ColorBy,
}

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
    let bound = (filter.for_schema(&ds.meta.schema).bind(&ds.meta.schema)).unwrap_or_else(|e| {
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
    ds.choose_colour(name, Some(gradient), None)
}

/// `filter` drawing the classes of `classes` ticked there, where one is not, and the others as
/// `filter` says (classes not seen yet, an edit's new class, drawn unless it names classes).
fn with_classes(filter: &Filter, classes: &BTreeMap<u8, (u64, bool)>) -> Filter {
    let mut f = filter.clone();
    if classes.values().any(|&(_, shown)| !shown) {
        f.classes = Some(
            (0..=255u8)
                .filter(|c| match classes.get(c) {
                    Some(&(_, shown)) => shown,
                    None => filter.classes.as_ref().is_none_or(|l| l.contains(c)),
                })
                .collect(),
        );
    }
    f
}

impl Layer {
    pub(crate) fn refilter(&mut self, filter: &Filter, shares: (usize, usize), colour: ColorBy) {
        self.scene = reopen(&self.scene, self.dataset.clone(), filter, shares, colour);
    }
}

/// What the data open with: the datasets' extent for framing (their scenes' bounds) and the
/// extent of everything there is (for near and far planes).
pub(crate) struct Extent {
    pub view: Aabb,
    pub all: Aabb,
}

impl Layers {
    /// A layer for each dataset, drawing what `filter` keeps in `colour`: one memory budget
    /// for all datasets, in equal shares.
    pub fn open(
        datasets: Vec<(String, Arc<Dataset>)>,
        filter: Filter,
        colour: ColorBy,
        occlusion: myriad_lod::Occlusion,
    ) -> Result<(Layers, Extent), String> {
        let shares = datasets.len().max(1);
        let ram = (2usize << 30) / shares;
        let gpu_bytes = (1usize << 30) / shares;
        let mut list = Vec::new();
        let mut bounds = Aabb::EMPTY;
        let mut all = Aabb::EMPTY;
        // The classes of the overviews, and those the class scheme hides (unticked, none
        // drawn) where the command line names none.
        let scheme = myriad_core::classes::current();
        let mut classes = BTreeMap::new();
        for (_, ds) in &datasets {
            for (c, n) in overview_classes(ds) {
                let shown =
                    (filter.classes.as_ref()).map_or(!scheme.is_hidden(c), |l| l.contains(&c));
                classes.entry(c).or_insert((0, shown)).0 += n;
            }
            if filter.classes.is_none() && ds.meta.schema.has(&Attribute::Classification) {
                for c in scheme.hidden_classes() {
                    classes.entry(c).or_insert((0, false));
                }
            }
        }
        let drawn = with_classes(&filter, &classes);
        for (name, ds) in datasets {
            let bound = (drawn.for_schema(&ds.meta.schema).bind(&ds.meta.schema))
                .map_err(|e| format!("{}: {e}", ds.path().display()))?;
            let mut scene = Scene::open_filtered(ds.clone(), bound, ram, gpu_bytes);
            scene.set_colour(colour);
            scene.occlusion = occlusion;
            // At most 64 MB to the GPU per frame (4 M points), shared by the datasets.
            scene.upload_limit = (64 << 20) / shares;
            // Occlusion queries read when the GPU has them: a frame never waits for the last
            // one (on the CPU path they are answered at once and waited for: `Render::draw`).
            scene.query_wait = false;
            bounds.extend(scene.view_bounds.min);
            bounds.extend(scene.view_bounds.max);
            all.extend(ds.meta.bounds.min);
            all.extend(ds.meta.bounds.max);
            list.push(Layer {
                name,
                scene,
                dataset: ds,
                visible: true,
            });
        }
        if list.is_empty() {
            return Err("no dataset to view".into());
        }
        let layers = Layers {
            list,
            shares: (ram, gpu_bytes),
            filter,
            classes,
            typed: Typed::default(),
            colour,
        };
        Ok((layers, Extent { view: bounds, all }))
    }

    /// The layers of the dataset at `path` shown with its edits as they are now (the dataset
    /// opened again: its edits read), their settings kept and their points read again.
    pub fn reopen(&mut self, path: &std::path::Path) -> Result<(), String> {
        let ds = Arc::new(Dataset::open(path).map_err(|e| e.to_string())?);
        // Its terrain as it is now, for colours above it.
        let _ = ds.above_ground();
        let filter = self.filter();
        let (shares, colour) = (self.shares, self.colour);
        for l in self.list.iter_mut().filter(|l| l.dataset.path() == path) {
            l.dataset = ds.clone();
            l.refilter(&filter, shares, colour);
        }
        Ok(())
    }

    /// The classes drawn, as `--classes` takes them: every class the command line's filter
    /// keeps and the panel does not hide, those not seen yet included (`None`: all of them).
    pub(crate) fn classes_drawn(&self) -> Option<String> {
        let drawn = |c: u8| {
            self.filter.classes.as_ref().is_none_or(|l| l.contains(&c))
                && self.classes.get(&c).is_none_or(|&(_, shown)| shown)
        };
        if (0..=255).all(drawn) {
            return None;
        }
        let mut runs: Vec<(u8, u8)> = Vec::new();
        for c in (0..=255u8).filter(|&c| drawn(c)) {
            match runs.last_mut() {
                Some((_, b)) if *b as u16 + 1 == c as u16 => *b = c,
                _ => runs.push((c, c)),
            }
        }
        Some(
            (runs.iter())
                .map(|&(a, b)| match a == b {
                    true => a.to_string(),
                    false => format!("{a}-{b}"),
                })
                .collect::<Vec<_>>()
                .join(","),
        )
    }

    /// The first dataset's coordinate reference system.
    pub fn crs(&self) -> Option<String> {
        self.list.first().and_then(|l| l.dataset.meta.crs.clone())
    }

    /// The first visible layer (the tools work on its dataset).
    pub fn first_visible(&self) -> Option<&Layer> {
        self.list.iter().find(|l| l.visible)
    }

    /// The visible layers' scenes.
    pub fn visible_scenes(&mut self) -> Vec<&mut Scene> {
        (self.list.iter_mut())
            .filter(|l| l.visible)
            .map(|l| &mut l.scene)
            .collect()
    }

    /// The nearest point drawn within 6 pixels of (`x`, `y`) seen by `cam`, of any visible
    /// layer.
    pub fn pick(&self, cam: &Camera, x: f64, y: f64) -> Option<myriad_render::Picked> {
        self.list
            .iter()
            .filter(|l| l.visible)
            .filter_map(|l| l.scene.pick(cam, x, y, 6.0))
            .min_by(|a, b| a.depth.total_cmp(&b.depth))
    }

    /// A box per dataset: shown or not.
    pub fn list_panel(&mut self, ui: &mut egui::Ui) {
        ui.label("datasets");
        for l in &mut self.list {
            ui.checkbox(&mut l.visible, &l.name);
        }
    }

    /// The filter the view draws: the command line's conditions and the panel's, and the
    /// classes ticked.
    pub(crate) fn filter(&self) -> Filter {
        let mut f = with_classes(&self.filter, &self.classes);
        f.conditions.extend(self.typed.conditions.iter().cloned());
        f
    }

    /// The colour scheme, and a ramp's (`--color ATTRIBUTE`) gradient and range.
    pub(crate) fn colour_panel(&mut self, ui: &mut egui::Ui) {
        let before = self.colour;
        egui::ComboBox::from_label("colour")
            .selected_text(match self.colour {
                ColorBy::Ramp(r) => match r.column {
                    Column::AboveGround(_) => "above ground ramp".to_string(),
                    c => format!("{c:?} ramp"),
                },
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
                let Some(ds) = self.list.first().map(|l| l.dataset.clone()) else {
                    return;
                };
                ui.separator();
                ui.label("attribute through a gradient");
                let mut names = vec![("z".to_string(), Column::Axis(2))];
                // Above the terrain where `myriad ground` found one.
                if let Some(c) = ds.above_ground() {
                    names.push(("above_ground".to_string(), c));
                }
                names.extend(Column::columns(&ds.meta.schema));
                for (name, column) in names {
                    let on = matches!(self.colour, ColorBy::Ramp(r) if r.column == column);
                    if ui.selectable_label(on, &name).clicked() && !on {
                        let gradient = match self.colour {
                            ColorBy::Ramp(r) => r.gradient,
                            _ if name == "z" => Gradient::Spectral,
                            _ if name == "above_ground" => Gradient::Turbo,
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
            for l in &mut self.list {
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
            let schemas: Vec<&Schema> = self.list.iter().map(|l| &l.dataset.meta.schema).collect();
            match typed_conditions(&self.typed.text, &schemas) {
                Ok(c) => {
                    self.typed.problem = None;
                    if c != self.typed.conditions {
                        self.typed.conditions = c;
                        let f = self.filter();
                        for l in &mut self.list {
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
        let scheme = myriad_core::classes::current();
        egui::CollapsingHeader::new("classes (points in the overview)")
            .default_open(false)
            .show(ui, |ui| {
                for (c, (count, shown)) in self.classes.iter_mut() {
                    ui.horizontal(|ui| {
                        let [r, g, b] = scheme.colour(*c);
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
            for l in &mut self.list {
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
