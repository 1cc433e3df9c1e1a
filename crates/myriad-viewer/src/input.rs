//! Mouse and keyboard over the view: navigation, the shortcuts, the measuring tools' clicks,
//! picking.

use crate::App;
use crate::measure::{Kind, Measurement};
use crate::nav::View;
use crate::report::{self, describe};
use eframe::egui;

impl App {
    /// Mouse and keyboard over the view.
    pub(crate) fn navigate(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) {
        let scale = ui.ctx().pixels_per_point() as f64;
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
        // Keys typed into the panel (an annotation's title) are not shortcuts.
        let typing = ui.ctx().egui_wants_keyboard_input();
        let pressed = |key| !typing && ui.input(|i| i.key_pressed(key));
        if pressed(egui::Key::H) {
            self.help = !self.help;
        }
        if pressed(egui::Key::G) {
            self.nav.fly = !self.nav.fly;
        }
        if pressed(egui::Key::P) {
            self.screenshot_now(ui.ctx());
        }
        if pressed(egui::Key::Escape) {
            self.stop_tools();
        }
        if pressed(egui::Key::V) && !self.nav.fly {
            let on = !self.volumes.drawing;
            self.stop_tools();
            self.volumes.drawing = on;
            if on {
                self.volumes.polygon.clear();
            }
        }
        if pressed(egui::Key::X) && !self.nav.fly {
            let on = !self.section.drawing;
            self.stop_tools();
            self.section.drawing = on;
            if on {
                self.section.line.clear();
            }
        }
        if pressed(egui::Key::T) && !self.nav.fly {
            let on = !self.saved.placing;
            self.stop_tools();
            self.saved.placing = on;
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
            if pressed(key) && !self.nav.fly {
                self.start_measuring(kind);
            }
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
        let cursor = response.hover_pos().map(|p| {
            (
                ((p.x - rect.min.x) as f64) * scale,
                ((p.y - rect.min.y) as f64) * scale,
            )
        });
        let cam = self.nav.camera;
        if response.drag_started_by(egui::PointerButton::Primary)
            && !self.nav.fly
            && let Some((x, y)) = cursor
            && let Some(p) = self.pick(&cam, x, y)
        {
            self.nav.pivot = p.position;
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
        if response.double_clicked()
            && let Some((x, y)) = cursor
        {
            self.picked = self.pick(&cam, x, y).map(|p| {
                let geo = self.geographic.as_mut().and_then(|g| g.of(p.position));
                describe(&p) + &report::geographic(geo)
            });
        }
        if self.volumes.drawing {
            if response.clicked()
                && let Some((x, y)) = cursor
                && let Some(p) = self.pick(&cam, x, y)
            {
                self.volumes.polygon.push(p.position);
            }
            if response.secondary_clicked() && self.volumes.polygon.len() >= 3 {
                self.measure_volume();
            }
        }
        if self.section.drawing {
            if response.clicked()
                && let Some((x, y)) = cursor
                && let Some(p) = self.pick(&cam, x, y)
            {
                self.section.line.push(p.position);
            }
            if response.secondary_clicked() && self.section.line.len() >= 2 {
                self.cut_section();
            }
        }
        if self.saved.placing
            && response.clicked()
            && let Some((x, y)) = cursor
            && let Some(p) = self.pick(&cam, x, y)
        {
            self.saved.annotate(p.position, cam.position, p.position);
            self.saved.placing = false;
        }
        if let Some(kind) = self.tool {
            if response.clicked()
                && let Some((x, y)) = cursor
                && let Some(p) = self.pick(&cam, x, y)
            {
                if self.measurements.last().is_none_or(|m| m.kind != kind) {
                    self.measurements.push(Measurement::new(kind));
                }
                self.measurements
                    .last_mut()
                    .expect("pushed above")
                    .add(p.position);
            }
            if response.secondary_clicked() {
                self.measurements.push(Measurement::new(kind));
            }
        }
    }
}
