//! The tools over the view, each a value of its own in its own file: measuring (`measure.rs`),
//! annotating and the saved work (`annotate.rs`), the profile of a section line
//! (`profile.rs`), the volume over a polygon (`volume.rs`), editing classes (`edit.rs`), the
//! terrain's contours (`contours.rs`), camera paths (`path.rs`), the clipping box (`clip.rs`)
//! and picking a point (`pick.rs`). [`Tools`] holds them: the keys that start and stop them (one
//! takes clicks at a time), the clicks they take, their parts of the panel, and what they draw
//! over the view.

pub(crate) mod annotate;
pub(crate) mod clip;
pub(crate) mod contours;
pub(crate) mod edit;
pub(crate) mod measure;
pub(crate) mod path;
pub(crate) mod pick;
pub(crate) mod profile;
pub(crate) mod volume;

use crate::measure::Kind;
use crate::options::{SectionAsked, VolumeAsked};
use crate::shown::Layers;
use eframe::egui;
use myriad_core::Aabb;
use myriad_lod::Camera;
use std::path::PathBuf;
use std::time::Instant;

/// Where a point shows over the view (`rect`, `ppp` pixels a point) seen by `cam`; `None`
/// behind the eye.
pub(crate) fn on_view(
    cam: &Camera,
    rect: egui::Rect,
    ppp: f32,
) -> impl Fn([f64; 3]) -> Option<egui::Pos2> + '_ {
    let focal = cam.focal();
    move |p| {
        let e = cam.to_eye(p);
        (e[2] > 1e-9).then(|| {
            let x = cam.width as f64 / 2.0 + e[0] * focal / e[2];
            let y = cam.height as f64 / 2.0 - e[1] * focal / e[2];
            rect.min + egui::vec2(x as f32 / ppp, y as f32 / ppp)
        })
    }
}

pub(crate) struct Tools {
    pub measure: measure::Measuring,
    /// Annotations and the measurements as saved beside the first dataset.
    pub annotate: annotate::Saved,
    /// The cross-section tool and its profile's window.
    pub profile: profile::Section,
    pub volume: volume::Volumes,
    pub edit: edit::Editing,
    pub contours: contours::Contours,
    pub path: path::Paths,
    pub clip: clip::Clip,
    pub pick: pick::Picking,
}

/// What a tool's part of the panel asks of the window.
pub(crate) struct Asked {
    /// An annotation's view to go to: eye and target.
    pub go: Option<([f64; 3], [f64; 3])>,
    /// The clip the points are drawn with.
    pub clip: Option<myriad_render::Clip>,
}

impl Tools {
    /// The tools over `layers` (the first dataset's CRS, name and spacing), the clipping box
    /// within `bounds`; the work saved in `work` (none: not kept); a section and a volume
    /// asked for on the command line, and the dataset to edit with the edits asked for there.
    pub fn new(
        layers: &Layers,
        bounds: Aabb,
        work: Option<PathBuf>,
        (section, volume): (Option<SectionAsked>, Option<VolumeAsked>),
        (edits, contours): (Option<edit::EditsAsked>, Option<f64>),
        paths: Option<path::PathsAsked>,
    ) -> Tools {
        let crs = layers.crs();
        let crs = crs.as_deref();
        let annotate = annotate::Saved::open(work, crs);
        let units = myriad_measure::measurement::crs_units(crs);
        Tools {
            measure: measure::Measuring::new(annotate.work.measurements.clone(), crs),
            profile: profile::Section::first(layers, crs, section),
            volume: volume::Volumes::new(units, volume),
            edit: edit::Editing::new(edits),
            contours: contours::Contours::new(contours),
            path: path::Paths::new(paths),
            clip: clip::Clip::new(bounds),
            pick: pick::Picking::new(crs),
            annotate,
        }
    }

    /// The first frame: the edits, the section and the volume asked for on the command line,
    /// over `bounds` (the data's extent).
    pub fn start(&mut self, bounds: &Aabb, layers: &mut Layers) {
        self.edit.start(layers);
        self.contours.start(layers);
        self.path.start(&mut self.annotate.work);
        self.profile.start(bounds, layers);
        self.volume.start(bounds, layers);
    }

    /// No tool takes clicks: measuring, annotating, a section line, a volume's polygon.
    pub fn stop(&mut self) {
        self.measure.tool = None;
        self.annotate.placing = false;
        self.profile.drawing = false;
        self.volume.drawing = false;
        self.edit.drawing = false;
    }

    fn start_measuring(&mut self, kind: Kind) {
        self.stop();
        self.measure.start(kind);
    }

    /// The tools' keys (`pressed`): Esc stops them; V a volume's polygon, K an edit's, X a
    /// section line, T an annotation, M N A O C Z I the measurements, J adds the view to the
    /// camera path (not in fly mode, whose keys move).
    pub fn keys(&mut self, pressed: &dyn Fn(egui::Key) -> bool, fly: bool) {
        if pressed(egui::Key::Escape) {
            self.stop();
        }
        if pressed(egui::Key::K) && !fly {
            let on = !self.edit.drawing;
            self.stop();
            self.edit.draw_polygon(on);
        }
        if pressed(egui::Key::V) && !fly {
            let on = !self.volume.drawing;
            self.stop();
            self.volume.draw_polygon(on);
        }
        if pressed(egui::Key::X) && !fly {
            let on = !self.profile.drawing;
            self.stop();
            self.profile.draw_line(on);
        }
        if pressed(egui::Key::J) && !fly {
            self.path.add_asked = true;
        }
        if pressed(egui::Key::T) && !fly {
            let on = !self.annotate.placing;
            self.stop();
            self.annotate.placing = on;
        }
        for (key, kind) in [
            (egui::Key::M, Kind::Distance),
            (egui::Key::N, Kind::Height),
            (egui::Key::A, Kind::Area),
            (egui::Key::O, Kind::Angle),
            (egui::Key::C, Kind::Circle),
            (egui::Key::Z, Kind::Azimuth),
            (egui::Key::I, Kind::Point),
        ] {
            if pressed(key) && !fly {
                self.start_measuring(kind);
            }
        }
    }

    /// Clicks on the view (`response`; `cursor`: its position in the view, pixels) seen by
    /// `cam`: a double click picks a point; a click adds the point under the cursor (of
    /// `layers`) to the tool taking clicks, a right click ends its figure (a volume measured, a
    /// section cut, an edit applied).
    pub fn clicks(
        &mut self,
        response: &egui::Response,
        cursor: Option<(f64, f64)>,
        cam: &Camera,
        layers: &mut Layers,
    ) {
        if std::mem::take(&mut self.path.add_asked) {
            self.path.add_camera(cam);
        }
        if self.edit.drawing {
            let at = cursor
                .and_then(|(x, y)| layers.pick(cam, x, y))
                .map(|p| p.position);
            if response.clicked()
                && let Some(p) = at
            {
                self.edit.polygon.push(p);
            }
            if response.secondary_clicked() && self.edit.polygon.len() >= 3 {
                self.edit.apply(layers);
            }
        }
        let layers = &*layers;
        let at = || {
            let (x, y) = cursor?;
            layers.pick(cam, x, y).map(|p| p.position)
        };
        if response.double_clicked()
            && let Some((x, y)) = cursor
        {
            self.pick.picked(layers.pick(cam, x, y));
        }
        if self.volume.drawing {
            if response.clicked()
                && let Some(p) = at()
            {
                self.volume.polygon.push(p);
            }
            if response.secondary_clicked() && self.volume.polygon.len() >= 3 {
                self.volume.measure_first(layers);
            }
        }
        if self.profile.drawing {
            if response.clicked()
                && let Some(p) = at()
            {
                self.profile.line.push(p);
            }
            if response.secondary_clicked() && self.profile.line.len() >= 2 {
                self.profile.cut_first(layers);
            }
        }
        if self.annotate.placing
            && response.clicked()
            && let Some(p) = at()
        {
            self.annotate.annotate(p, cam.position, p);
            self.annotate.placing = false;
        }
        (self.measure).click(response.clicked(), response.secondary_clicked(), &at);
    }

    /// The tools' parts of the panel: measuring, annotations, the profile, the volume, the
    /// edits, the clipping box.
    pub fn panel(&mut self, ui: &mut egui::Ui, layers: &mut Layers, cam: &Camera) -> Asked {
        ui.separator();
        if self.measure.panel(ui).is_some() {
            // One tool takes clicks at a time.
            self.annotate.placing = false;
            self.profile.drawing = false;
            self.volume.drawing = false;
            self.edit.drawing = false;
        }
        ui.separator();
        if self.annotate.placing {
            self.measure.tool = None;
        }
        let go = (self.annotate.panel(ui)).map(|v| (v.position, v.target));
        ui.separator();
        if self.profile.panel(ui) {
            self.profile.cut_first(layers);
        }
        ui.separator();
        if self.volume.panel(ui) {
            self.volume.measure_first(layers);
        }
        ui.separator();
        let was = self.edit.drawing;
        self.edit.panel(ui, layers);
        if self.edit.drawing && !was {
            self.stop();
            self.edit.drawing = true;
        }
        self.contours.panel(ui, layers);
        ui.separator();
        self.path.panel(ui, &mut self.annotate.work, cam);
        ui.separator();
        let clip = self.clip.panel(ui);
        Asked { go, clip }
    }

    /// What the tools draw over the view (`rect`, `ppp` pixels a point) seen by `cam`: the
    /// clipping box, the measurements, the annotations, the section line, the volume's polygon
    /// and grid.
    pub fn draw(&self, painter: &egui::Painter, rect: egui::Rect, ppp: f32, cam: &Camera) {
        let screen = on_view(cam, rect, ppp);
        self.contours.draw(painter, &screen);
        self.clip.draw(painter, &screen);
        self.measure.draw(painter, &screen);
        self.annotate.draw(painter, &screen);
        self.profile.draw(painter, &screen);
        self.volume.draw(painter, &screen);
        self.edit.draw(painter, &screen);
        self.path.draw(painter, &screen);
    }

    /// After the frame: the profile's window (its picture's points saved from the first
    /// visible dataset of `layers`), a finished volume taken in.
    pub fn after_frame(&mut self, ctx: &egui::Context, layers: &Layers) {
        let ds = layers.first_visible().map(|l| l.dataset.clone());
        let filter = layers.filter();
        self.profile.window(ctx, ds.as_deref(), &filter);
        self.volume.take();
        if std::mem::take(&mut self.edit.changed) && self.contours.on {
            self.contours.make(layers);
        }
        self.contours.take();
    }

    /// No profile being cut, no volume being measured.
    pub fn settled(&self) -> bool {
        self.profile.settled()
            && self.volume.settled()
            && self.contours.settled()
            && self.path.settled()
    }

    /// The complete measurements taken into the saved work, written once it has settled.
    pub fn sync(&mut self, now: Instant) {
        self.annotate.sync(&self.measure.measurements, now);
    }

    /// The work written, where it changed (the window closes).
    pub fn flush(&mut self) {
        self.annotate.flush();
    }
}
