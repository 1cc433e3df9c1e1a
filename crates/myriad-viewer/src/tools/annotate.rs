//! The annotation tool (T, then a click on a point; titles and texts in the panel) and the
//! saved work in the window: the annotations and measurements of the first dataset, loaded
//! from its sidecar (`myriad_measure::work`) when the window opens and written back (atomically)
//! half a second after each change and when it closes, so that they are there when it opens
//! again, in `serve`'s web viewer and for `myriad annotate`. A sidecar that does not parse is
//! said once and left alone: nothing of this session is written over it.

use eframe::egui;
use myriad_measure::measurement::Measurement;
use myriad_measure::work::{Annotation, MAX_TEXT, MAX_TITLE, View, Work};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// The colour annotations are marked in.
pub const MARK: egui::Color32 = egui::Color32::from_rgb(255, 64, 200);
/// Changes are written this long after the last one (typing a title writes once).
const SETTLE: Duration = Duration::from_millis(500);

pub(crate) struct Saved {
    /// Where the work is written; `None`: nowhere (a URL, or a sidecar that did not parse).
    path: Option<PathBuf>,
    /// The annotations, and the measurements as last taken from the view.
    pub work: Work,
    written: Work,
    changed: Option<Instant>,
    /// The annotation whose text is open in the panel; whether a click places a new one.
    pub editing: Option<usize>,
    pub placing: bool,
    /// What went wrong reading or writing the sidecar, shown in the panel.
    pub problem: Option<String>,
}

impl Saved {
    /// The work in `path` (none there: empty, of `crs`).
    pub fn open(path: Option<PathBuf>, crs: Option<&str>) -> Saved {
        let mut problem = None;
        let (path, work) = match path {
            None => (None, Work::new(crs)),
            Some(p) => match myriad_measure::files::load_work(&p, crs) {
                Ok(w) => (Some(p), w),
                Err(e) => {
                    let m = format!("{e}: annotations and measurements are not saved");
                    eprintln!("warning: {m}");
                    problem = Some(m);
                    (None, Work::new(crs))
                }
            },
        };
        Saved {
            path,
            written: work.clone(),
            work,
            changed: None,
            editing: None,
            placing: false,
            problem,
        }
    }

    /// A new annotation at `p`, seen from `eye` looking at `target`; its index.
    pub fn annotate(&mut self, p: [f64; 3], eye: [f64; 3], target: [f64; 3]) -> usize {
        let n = self.work.annotations.len() + 1;
        self.work.annotations.push(Annotation {
            position: p,
            title: format!("annotation {n}"),
            text: String::new(),
            camera: Some(View {
                position: eye,
                target,
            }),
        });
        self.editing = Some(n - 1);
        n - 1
    }

    /// Takes the view's complete measurements, and writes the work once it has not changed
    /// for [`SETTLE`] (`now`).
    pub fn sync(&mut self, measurements: &[Measurement], now: Instant) {
        let complete: Vec<Measurement> = measurements
            .iter()
            .filter(|m| m.complete())
            .cloned()
            .collect();
        if complete != self.work.measurements {
            self.work.measurements = complete;
        }
        if self.work != self.written {
            let since = *self.changed.get_or_insert(now);
            if now.duration_since(since) >= SETTLE {
                self.flush();
            }
        }
    }

    /// Writes the work if it changed since it was last written.
    pub fn flush(&mut self) {
        self.changed = None;
        if self.work == self.written {
            return;
        }
        let Some(path) = &self.path else { return };
        match myriad_measure::files::save_work(path, &self.work) {
            Ok(()) => {
                self.written = self.work.clone();
                self.problem = None;
            }
            Err(e) => self.problem = Some(e.to_string()),
        }
    }

    /// Where the work is kept, for the panel.
    pub fn place(&self) -> String {
        self.path.as_ref().map_or_else(
            || "not saved".into(),
            |p| {
                p.file_name()
                    .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
            },
        )
    }

    /// The annotations' panel: each title (editable), its view, its removal, and the text of
    /// the one open. Returns the camera of an annotation to go to.
    pub fn panel(&mut self, ui: &mut egui::Ui) -> Option<View> {
        ui.horizontal(|ui| {
            ui.label("annotations");
            if ui
                .selectable_label(self.placing, "add (T)")
                .on_hover_text("click a point of the view to annotate it")
                .clicked()
            {
                self.placing = !self.placing;
            }
        });
        ui.small(format!("kept in {}", self.place()));
        if let Some(p) = &self.problem {
            ui.colored_label(egui::Color32::LIGHT_RED, p);
        }
        let (mut go, mut remove) = (None, None);
        for (i, a) in self.work.annotations.iter_mut().enumerate() {
            ui.horizontal(|ui| {
                let open = self.editing == Some(i);
                if ui.selectable_label(open, "✎").clicked() {
                    self.editing = if open { None } else { Some(i) };
                }
                ui.add(
                    egui::TextEdit::singleline(&mut a.title)
                        .char_limit(MAX_TITLE)
                        .desired_width(110.0),
                );
                if ui.button("go").clicked() {
                    go = a.camera;
                }
                if ui.button("×").clicked() {
                    remove = Some(i);
                }
            });
            if self.editing == Some(i) {
                ui.add(
                    egui::TextEdit::multiline(&mut a.text)
                        .char_limit(MAX_TEXT)
                        .desired_rows(3)
                        .hint_text("text"),
                );
                let p = a.position;
                ui.small(format!("at {:.3}, {:.3}, {:.3}", p[0], p[1], p[2]));
            }
        }
        if let Some(i) = remove {
            self.work.annotations.remove(i);
            self.editing = None;
        }
        go
    }

    /// The annotations over the view: a mark at each point and its title beside it.
    pub fn draw(&self, painter: &egui::Painter, screen: &dyn Fn([f64; 3]) -> Option<egui::Pos2>) {
        for a in &self.work.annotations {
            let Some(at) = screen(a.position) else {
                continue;
            };
            painter.circle_filled(at, 6.0, MARK);
            painter.circle_stroke(at, 6.0, egui::Stroke::new(1.0, egui::Color32::WHITE));
            let font = egui::FontId::proportional(14.0);
            let text = at + egui::vec2(10.0, -10.0);
            let galley = painter.layout_no_wrap(a.title.clone(), font, egui::Color32::WHITE);
            let rect = egui::Align2::LEFT_BOTTOM
                .anchor_size(text, galley.size())
                .expand(3.0);
            painter.rect_filled(rect, 3.0, egui::Color32::from_black_alpha(170));
            painter.galley(
                rect.min + egui::vec2(3.0, 3.0),
                galley,
                egui::Color32::WHITE,
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_measure::measurement::Kind;

    #[test]
    fn work_made_in_the_window_is_there_when_it_opens_again() {
        let dir = std::env::temp_dir().join(format!("myriad-saved-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("city.work.json");
        let mut s = Saved::open(Some(path.clone()), Some("EPSG:32633"));
        assert!(s.work.is_empty() && s.problem.is_none());
        let i = s.annotate([1.0, 2.0, 3.0], [0.0, 0.0, 50.0], [1.0, 2.0, 3.0]);
        s.work.annotations[i].title = "gate".into();
        let mut d = Measurement::new(Kind::Distance);
        d.add([0.0; 3]);
        let t = Instant::now();
        // An incomplete measurement is not saved; nothing is written before the change settles.
        s.sync(std::slice::from_ref(&d), t);
        assert!(!path.exists());
        d.add([3.0, 4.0, 0.0]);
        s.sync(std::slice::from_ref(&d), t + Duration::from_millis(100));
        assert!(!path.exists());
        s.sync(std::slice::from_ref(&d), t + Duration::from_millis(700));
        assert!(path.exists());
        let again = Saved::open(Some(path.clone()), None);
        assert_eq!(again.work.annotations[0].title, "gate");
        assert_eq!(again.work.measurements, vec![d.clone()]);
        assert_eq!(again.work.crs.as_deref(), Some("EPSG:32633"));
        // Closing writes what has not settled yet.
        s.work.annotations[0].text = "north side".into();
        s.sync(std::slice::from_ref(&d), t + Duration::from_millis(800));
        s.flush();
        let again = Saved::open(Some(path.clone()), None);
        assert_eq!(again.work.annotations[0].text, "north side");
        // A sidecar that does not parse is never written over.
        std::fs::write(&path, "{ broken").unwrap();
        let mut b = Saved::open(Some(path.clone()), None);
        assert!(
            b.problem.as_ref().unwrap().contains("line 1"),
            "{:?}",
            b.problem
        );
        b.annotate([0.0; 3], [1.0; 3], [0.0; 3]);
        b.flush();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "{ broken");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
