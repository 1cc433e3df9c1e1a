//! Camera paths in the window: J (or "add view") adds the view to the path being recorded, a
//! view every few seconds; the panel names it, removes its last view, clears it, saves it with
//! the first dataset's saved work (replacing one of the same name), and plays it or any saved
//! path in the window. `render --path NAME` flies a saved one to frames. From the command line,
//! `view --path-view EYE,TARGET` (repeatable) records views and `--record-path NAME` saves them;
//! `view --play-path NAME` plays one once the first view is in.

use eframe::egui;
use myriad_lod::Camera;
use myriad_measure::camera_path::{CameraPath, GAP, View};
use myriad_measure::work::Work;
use std::time::Instant;

/// The paths asked for on the command line.
#[derive(Debug, Clone, Default)]
pub struct PathsAsked {
    /// Views to record, eye and target each, and the name to save them under.
    pub views: Vec<View>,
    pub save_as: Option<String>,
    /// A path to play once the first view is in; or the one recorded.
    pub play: Option<CameraPath>,
    pub play_recorded: bool,
}

pub(crate) struct Paths {
    /// The path being recorded.
    pub recording: CameraPath,
    /// Seconds from a view added to the next.
    gap: f64,
    /// The path playing and when it began.
    playing: Option<(CameraPath, Instant)>,
    /// J was pressed: the view is added on the next click step (which has the camera).
    pub add_asked: bool,
    asked: Option<PathsAsked>,
    pub said: Option<String>,
}

impl Paths {
    pub fn new(asked: Option<PathsAsked>) -> Paths {
        Paths {
            recording: CameraPath {
                name: "path 1".into(),
                keys: Vec::new(),
            },
            gap: GAP,
            playing: None,
            add_asked: false,
            asked,
            said: None,
        }
    }

    /// The first frame: the command line's views recorded (and saved into `work`), its path
    /// played.
    pub fn start(&mut self, work: &mut Work) {
        let Some(a) = self.asked.take() else {
            return;
        };
        for v in a.views {
            self.add(v);
        }
        if let Some(name) = a.save_as {
            self.recording.name = name;
            self.save(work);
        }
        if let Some(p) = a.play {
            self.play(p);
        } else if a.play_recorded {
            self.play(self.recording.clone());
        }
    }

    /// Adds `v`, [`Paths::gap`] seconds after the last view.
    pub fn add(&mut self, v: View) {
        let time = (self.recording.keys.last()).map_or(0.0, |k| k.time + self.gap);
        (self.recording.keys).push(myriad_measure::camera_path::Key { view: v, time });
    }

    /// Adds the view of `cam`.
    pub fn add_camera(&mut self, cam: &Camera) {
        self.add(View {
            position: cam.position,
            target: cam.target,
        });
    }

    /// The recording kept in `work`, in place of a path of its name.
    fn save(&mut self, work: &mut Work) {
        if self.recording.keys.is_empty() {
            return;
        }
        // As the saved work's reader will take it: else said, and not saved.
        let p = match CameraPath::from_json(&self.recording.to_json(), "") {
            Ok(p) => p,
            Err(e) => {
                self.said = Some(format!("not saved: {e}"));
                return;
            }
        };
        match work.paths.iter_mut().find(|q| q.name == p.name) {
            Some(q) => *q = p,
            None => work.paths.push(p),
        }
        self.said = Some(format!(
            "saved \"{}\": {} views, {:.1} s",
            self.recording.name,
            self.recording.keys.len(),
            self.recording.duration()
        ));
        println!("camera path {}", self.said.as_deref().unwrap_or_default());
    }

    fn play(&mut self, p: CameraPath) {
        if !p.keys.is_empty() {
            self.playing = Some((p, Instant::now()));
        }
    }

    /// The view now while a path plays (it stops at its end).
    pub fn tick(&mut self) -> Option<View> {
        let (p, t0) = self.playing.as_ref()?;
        let t = t0.elapsed().as_secs_f64();
        let v = p.at(t);
        if t >= p.duration() {
            println!("played camera path \"{}\" ({:.1} s)", p.name, p.duration());
            self.playing = None;
        }
        Some(v)
    }

    /// No path playing.
    pub fn settled(&self) -> bool {
        self.playing.is_none()
    }

    /// The panel: the recording (name, views, gap, add, remove last, clear, save, play) and the
    /// saved paths (play, remove), `cam` the view now.
    pub fn panel(&mut self, ui: &mut egui::Ui, work: &mut Work, cam: &Camera) {
        egui::CollapsingHeader::new("camera path (J adds the view)")
            .default_open(false)
            .show(ui, |ui| {
                ui.horizontal(|ui| {
                    ui.label("name");
                    ui.text_edit_singleline(&mut self.recording.name);
                });
                ui.label(format!(
                    "{} views, {:.1} s",
                    self.recording.keys.len(),
                    self.recording.duration()
                ));
                ui.add(
                    egui::DragValue::new(&mut self.gap)
                        .range(0.1..=600.0)
                        .speed(0.1)
                        .prefix("seconds between views: "),
                );
                ui.horizontal(|ui| {
                    if ui.button("add view").clicked() {
                        self.add_camera(cam);
                    }
                    if ui.button("remove last").clicked() {
                        self.recording.keys.pop();
                    }
                    if ui.button("clear").clicked() {
                        self.recording.keys.clear();
                    }
                });
                ui.horizontal(|ui| {
                    let some = !self.recording.keys.is_empty();
                    if ui.add_enabled(some, egui::Button::new("save")).clicked() {
                        self.save(work);
                    }
                    if ui.add_enabled(some, egui::Button::new("play")).clicked() {
                        self.play(self.recording.clone());
                    }
                    if self.playing.is_some() && ui.button("stop").clicked() {
                        self.playing = None;
                    }
                });
                if let Some(s) = &self.said {
                    ui.label(s);
                }
                let mut gone = None;
                for (i, p) in work.paths.iter().enumerate() {
                    ui.horizontal(|ui| {
                        ui.label(format!("{} ({:.1} s)", p.name, p.duration()));
                        if ui.small_button("play").clicked() {
                            self.playing = Some((p.clone(), Instant::now()));
                        }
                        if ui.small_button("edit").clicked() {
                            self.recording = p.clone();
                        }
                        if ui.small_button("remove").clicked() {
                            gone = Some(i);
                        }
                    });
                }
                if let Some(i) = gone {
                    work.paths.remove(i);
                }
            });
    }

    /// The recording's views over the view: a dot at each eye, a line along them.
    pub fn draw(&self, painter: &egui::Painter, screen: &dyn Fn([f64; 3]) -> Option<egui::Pos2>) {
        let colour = egui::Color32::from_rgb(90, 200, 255);
        let eyes: Vec<Option<egui::Pos2>> = (self.recording.keys.iter())
            .map(|k| screen(k.view.position))
            .collect();
        for pair in eyes.windows(2) {
            if let [Some(a), Some(b)] = pair {
                painter.line_segment([*a, *b], egui::Stroke::new(1.5, colour));
            }
        }
        for p in eyes.into_iter().flatten() {
            painter.circle_filled(p, 4.0, colour);
        }
    }
}
