//! Editing classes in the window (issue 70): a polygon clicked on the data (K, then its
//! corners; a right click or "apply" applies it) gives the points inside it, of the classes
//! shown, a class or removes them, as `myriad classify --polygon ... --to C` does: one change
//! to the edits kept beside the first dataset (`myriad_measure::edits`, under the lock every
//! editor takes, so that another program editing at once loses nothing). Undo and redo
//! (Ctrl+Z, Ctrl+Y, or the panel) are changes too. After each, the layers of that dataset
//! reopen it with its edits and draw it again. Changes asked on the command line (`view
//! --classify`, `--undo-edits`) are made on the first frame through the same code, each printed.

use crate::shown::Layers;
use eframe::egui;
use myriad_measure::edits::{Area, Change, Edit};
use std::path::PathBuf;

/// The polygon's colour.
pub const OUTLINE: egui::Color32 = egui::Color32::from_rgb(255, 48, 48);

/// What the command line gives the edit tool: the dataset edited (the first given, where it is
/// a dataset on this machine's disk; else why none is) and the changes to make on opening.
#[derive(Debug, Clone)]
pub struct EditsAsked {
    pub dataset: Result<PathBuf, String>,
    pub changes: Vec<Change>,
}

pub(crate) struct Editing {
    pub drawing: bool,
    pub polygon: Vec<[f64; 3]>,
    /// The class given; `remove`: the points removed instead.
    pub to: u8,
    pub remove: bool,
    dataset: Result<PathBuf, String>,
    /// Edits in the layer, and undone ones (for the panel's buttons).
    counts: (usize, usize),
    pub done: Option<String>,
    pub problem: Option<String>,
    /// A change was made since this was last taken (what depends on the edits is made again).
    pub changed: bool,
    asked: Vec<Change>,
}

impl Editing {
    pub fn new(asked: Option<EditsAsked>) -> Editing {
        let (dataset, asked) = match asked {
            Some(a) => (a.dataset, a.changes),
            None => (Err("no dataset to edit".into()), Vec::new()),
        };
        let counts = match &dataset {
            Ok(p) => match myriad_measure::edits::read(&myriad_measure::edits::sidecar_for(p)) {
                Ok(l) => l.map_or((0, 0), |l| (l.edits.len(), l.undone.len())),
                Err(_) => (0, 0),
            },
            Err(_) => (0, 0),
        };
        Editing {
            drawing: false,
            polygon: Vec::new(),
            to: 7,
            remove: false,
            dataset,
            counts,
            done: None,
            problem: None,
            changed: false,
            asked,
        }
    }

    /// The changes asked on the command line, made in `layers` (once), each printed.
    pub fn start(&mut self, layers: &mut Layers) {
        for c in std::mem::take(&mut self.asked) {
            self.change(c, layers);
            match (&self.done, &self.problem) {
                (_, Some(p)) => eprintln!("edit: {p}"),
                (Some(d), None) => println!("{d}"),
                _ => {}
            }
        }
    }

    pub fn draw_polygon(&mut self, on: bool) {
        self.drawing = on && self.dataset.is_ok();
        self.polygon.clear();
    }

    /// The polygon drawn, made an edit of the classes `layers` shows.
    pub fn apply(&mut self, layers: &mut Layers) {
        self.drawing = false;
        let ring: Vec<[f64; 2]> = self.polygon.iter().map(|p| [p[0], p[1]]).collect();
        self.polygon.clear();
        let classes = layers.classes_drawn();
        if classes.as_deref() == Some("") {
            self.problem = Some("every class is hidden: nothing to edit".into());
            return;
        }
        let edit = Edit {
            area: Area::Polygon { ring, z: None },
            classes,
            wheres: Vec::new(),
            action: match self.remove {
                true => myriad_measure::edits::Action::Remove,
                false => myriad_measure::edits::Action::Class(self.to),
            },
        };
        self.change(Change::Add(edit), layers);
    }

    /// Makes `c` to the edits of the dataset edited, and shows the layers of it edited.
    pub fn change(&mut self, c: Change, layers: &mut Layers) {
        let path = match &self.dataset {
            Ok(p) => p.clone(),
            Err(m) => {
                self.problem = Some(m.clone());
                return;
            }
        };
        let Some(meta) = (layers.list.iter())
            .find(|l| l.dataset.path() == path)
            .map(|l| l.dataset.meta.clone())
        else {
            self.problem = Some(format!("{}: not shown", path.display()));
            return;
        };
        match c.apply(&path, &meta) {
            Ok((layer, done)) => {
                self.counts = (layer.edits.len(), layer.undone.len());
                self.done = Some(done);
                self.problem = layers.reopen(&path).err();
                self.changed = true;
            }
            Err(r) => {
                self.done = None;
                self.problem = Some(r.to_string());
            }
        }
    }

    /// The tool's part of the panel: the class (or removal), the polygon, undo and redo.
    pub fn panel(&mut self, ui: &mut egui::Ui, layers: &mut Layers) {
        ui.label("edit classes");
        if let Err(m) = &self.dataset {
            ui.label(format!("not editable: {m}"));
            return;
        }
        ui.horizontal(|ui| {
            ui.checkbox(&mut self.remove, "remove");
            if !self.remove {
                ui.label("to class");
                ui.add(egui::DragValue::new(&mut self.to).range(0..=255));
                ui.label(myriad_measure::filter::class_name(self.to));
            }
        });
        ui.horizontal(|ui| {
            let label = if self.drawing {
                "drawing (K)"
            } else {
                "polygon (K)"
            };
            if ui.selectable_label(self.drawing, label).clicked() {
                let on = !self.drawing;
                self.draw_polygon(on);
            }
            if ui
                .add_enabled(self.polygon.len() >= 3, egui::Button::new("apply"))
                .clicked()
            {
                self.apply(layers);
            }
        });
        ui.horizontal(|ui| {
            if ui
                .add_enabled(self.counts.0 > 0, egui::Button::new("undo (Ctrl+Z)"))
                .clicked()
            {
                self.change(Change::Undo, layers);
            }
            if ui
                .add_enabled(self.counts.1 > 0, egui::Button::new("redo (Ctrl+Y)"))
                .clicked()
            {
                self.change(Change::Redo, layers);
            }
        });
        ui.label(format!("{} edits", self.counts.0));
        if let Some(d) = &self.done {
            ui.label(d);
        }
        if let Some(p) = &self.problem {
            ui.colored_label(egui::Color32::from_rgb(255, 100, 100), p);
        }
    }

    /// The polygon being drawn over the view.
    pub fn draw(&self, painter: &egui::Painter, screen: &dyn Fn([f64; 3]) -> Option<egui::Pos2>) {
        let pts: Vec<egui::Pos2> = self.polygon.iter().filter_map(|p| screen(*p)).collect();
        if pts.len() < 2 || pts.len() != self.polygon.len() {
            return;
        }
        let stroke = egui::Stroke::new(2.0, OUTLINE);
        for w in pts.windows(2) {
            painter.line_segment([w[0], w[1]], stroke);
        }
        if !self.drawing {
            painter.line_segment([pts[pts.len() - 1], pts[0]], stroke);
        }
    }
}
