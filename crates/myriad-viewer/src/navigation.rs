//! The window's camera and navigation: the camera moved by [`Nav`] (`nav.rs`, no window
//! needed) from the mouse and the keys over the view, the data's extent it frames, the axis and
//! parallel views (the command line's taken on the first frame), and the views saved in the
//! panel.

use crate::nav::{Nav, View};
use eframe::egui;
use myriad_core::Aabb;
use myriad_lod::Camera;

pub(crate) struct Navigation {
    pub nav: Nav,
    /// The data's extent, for framing.
    pub bounds: Aabb,
    /// The view is framed on the first frame, when the view's size is known.
    framed: bool,
    /// The axis view and the parallel view asked for on the command line, taken on the
    /// first frame.
    start_view: (Option<View>, bool),
    /// Saved views: name, camera, pivot.
    bookmarks: Vec<(String, Camera, [f64; 3])>,
}

impl Navigation {
    /// Framing `bounds` (`all`: everything there is, for near and far planes) with a `fov`
    /// degrees field of view, or looking from `camera`'s eye at its target; `view` and
    /// `parallel`: as asked on the command line.
    pub fn new(
        (bounds, all): (Aabb, Aabb),
        fov: f64,
        camera: Option<([f64; 3], [f64; 3])>,
        (view, parallel): (Option<View>, bool),
    ) -> Navigation {
        let mut nav = Nav::framing(&bounds, &all, fov);
        if let Some((eye, target)) = camera {
            nav.look(eye, target);
        }
        Navigation {
            nav,
            bounds,
            framed: camera.is_some(),
            start_view: (view, parallel),
            bookmarks: Vec::new(),
        }
    }

    /// The camera put at `eye` looking at `target` with `up` and a `fov` degrees field of view
    /// (a photo's pose): the first frame frames nothing then.
    pub fn put(&mut self, eye: [f64; 3], target: [f64; 3], up: [f64; 3], fov: f64) {
        self.nav.look(eye, target);
        (self.nav.camera.up, self.nav.camera.fov_y) = (up, fov);
        self.framed = true;
    }

    /// The view's size in pixels; on the first frame, the view asked for (or the data
    /// framed).
    pub fn size(&mut self, width: u32, height: u32) {
        self.nav.camera.width = width.max(1);
        self.nav.camera.height = height.max(1);
        if !self.framed {
            self.framed = true;
            match self.start_view.0 {
                Some(v) => self.nav.standard(v, &self.bounds),
                None => self.nav.frame(&self.bounds),
            }
        }
        if std::mem::take(&mut self.start_view.1) {
            self.nav.set_parallel(true);
        }
    }

    /// The navigation's keys (`pressed`): G fly mode, F frame all, 1 to 6 the axis views, 0
    /// the parallel view.
    pub fn keys(&mut self, pressed: &dyn Fn(egui::Key) -> bool) {
        if pressed(egui::Key::G) {
            self.nav.fly = !self.nav.fly;
        }
        if pressed(egui::Key::F) {
            self.nav.frame(&self.bounds);
        }
        for (key, view) in [
            egui::Key::Num1,
            egui::Key::Num2,
            egui::Key::Num3,
            egui::Key::Num4,
            egui::Key::Num5,
            egui::Key::Num6,
        ]
        .into_iter()
        .zip(View::ALL)
        {
            if pressed(key) {
                self.nav.standard(view, &self.bounds);
            }
        }
        if pressed(egui::Key::Num0) {
            let on = !self.nav.parallel();
            self.nav.set_parallel(on);
        }
    }

    /// The mouse over the view (`response`; `cursor`: its position in the view, pixels;
    /// `scale`: pixels a point) and the fly keys: a drag orbits around the point under the
    /// cursor (`pick`: the drawn point at a pixel, seen by the camera as it is now) or looks
    /// around, pans; the wheel zooms towards the cursor, or sets the fly speed.
    pub fn mouse(
        &mut self,
        ui: &egui::Ui,
        response: &egui::Response,
        (cursor, scale): (Option<(f64, f64)>, f64),
        pick: &dyn Fn(f64, f64) -> Option<[f64; 3]>,
    ) {
        let (dt, keys) = ui.input(|i| {
            let k = |key| i.key_down(key);
            (
                i.stable_dt.min(0.1) as f64,
                [
                    k(egui::Key::W),
                    k(egui::Key::S),
                    k(egui::Key::A),
                    k(egui::Key::D),
                    k(egui::Key::Q),
                    k(egui::Key::E),
                ],
            )
        });
        if response.drag_started_by(egui::PointerButton::Primary)
            && !self.nav.fly
            && let Some((x, y)) = cursor
            && let Some(p) = pick(x, y)
        {
            self.nav.pivot = p;
        }
        let d = response.drag_delta();
        let (dx, dy) = (d.x as f64 * scale, d.y as f64 * scale);
        if response.dragged_by(egui::PointerButton::Primary) {
            if self.nav.fly {
                self.nav.look_around(dx, dy);
            } else {
                self.nav.orbit(dx, dy);
            }
        }
        if response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
        {
            self.nav.pan(dx, dy);
        }
        let scroll = if response.hovered() {
            ui.input(|i| i.smooth_scroll_delta.y) as f64
        } else {
            0.0
        };
        if scroll != 0.0 {
            if self.nav.fly {
                self.nav.speed *= (1.0 + scroll / 200.0).clamp(0.5, 2.0);
            } else if let Some((x, y)) = cursor {
                self.nav.zoom_towards(x, y, scroll);
            }
        }
        if self.nav.fly {
            self.nav.fly_step(keys, dt);
        }
    }

    /// The panel's views: the axis views, the parallel view, views saved and gone back to.
    pub fn panel(&mut self, ui: &mut egui::Ui) {
        ui.label("views");
        ui.horizontal_wrapped(|ui| {
            for v in View::ALL {
                if ui.small_button(v.name()).clicked() {
                    self.nav.standard(v, &self.bounds);
                }
            }
        });
        let mut parallel = self.nav.parallel();
        if ui
            .checkbox(&mut parallel, "parallel (orthographic, 0)")
            .changed()
        {
            self.nav.set_parallel(parallel);
        }
        if ui.button("save this view").clicked() {
            let n = self.bookmarks.len() + 1;
            self.bookmarks
                .push((format!("view {n}"), self.nav.camera, self.nav.pivot));
        }
        let mut go = None;
        for (i, (name, _, _)) in self.bookmarks.iter().enumerate() {
            if ui.button(name).clicked() {
                go = Some(i);
            }
        }
        if let Some(i) = go {
            let (_, cam, pivot) = self.bookmarks[i];
            self.nav.camera = Camera {
                width: self.nav.camera.width,
                height: self.nav.camera.height,
                ..cam
            };
            self.nav.pivot = pivot;
        }
    }
}
