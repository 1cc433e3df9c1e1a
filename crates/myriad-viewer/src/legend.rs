//! What the view needs to be read, over it: in the parallel view a scale bar (a round length
//! at the target's depth), and for a gradient colouring its colours from the low end of the
//! range to the high, both labelled, as `render --legend` draws them into PNGs
//! (`myriad_render::legend`).

use eframe::egui;
use myriad_lod::Camera;
use myriad_measure::profile::nice_step;
use myriad_render::ColorBy;
use myriad_render::legend::number;

const INK: egui::Color32 = egui::Color32::from_rgb(20, 20, 20);
const PAPER: egui::Color32 = egui::Color32::from_rgba_premultiplied(204, 204, 204, 204);

/// A scale bar from `at` (its left end) of a round length near `want` points, `per_point`
/// units a point, labelled above by `label` of its length, on a pale box.
pub(crate) fn scale_bar(
    painter: &egui::Painter,
    at: egui::Pos2,
    per_point: f64,
    want: f64,
    label: &dyn Fn(f64) -> String,
) {
    let len = myriad_render::legend::bar_length(per_point * want);
    let bar = (len / per_point) as f32;
    let paper = egui::Rect::from_min_max(
        at + egui::vec2(-6.0, -22.0),
        at + egui::vec2(bar + 6.0, 12.0),
    );
    painter.rect_filled(paper, 2.0, PAPER);
    painter.rect_filled(
        egui::Rect::from_min_size(at, egui::vec2(bar, 4.0)),
        0.0,
        INK,
    );
    for x in [0.0, bar - 2.0] {
        let tick = egui::Rect::from_min_size(at + egui::vec2(x, -6.0), egui::vec2(2.0, 10.0));
        painter.rect_filled(tick, 0.0, INK);
    }
    let font = egui::FontId::monospace(12.0);
    painter.text(
        at + egui::vec2(bar / 2.0, -11.0),
        egui::Align2::CENTER_CENTER,
        label(len),
        font,
        INK,
    );
}

/// Draws over `rect`: a scale bar where `parallel` gives the parallel view's camera, a legend
/// where `colour` is a gradient; lengths in `units`.
pub fn draw(
    painter: &egui::Painter,
    rect: egui::Rect,
    parallel: Option<&Camera>,
    colour: ColorBy,
    units: &str,
) {
    let font = egui::FontId::monospace(12.0);
    if let Some(cam) = parallel {
        let d: f64 = (0..3)
            .map(|i| (cam.position[i] - cam.target[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        let per_point = 2.0 * d * (cam.fov_y.to_radians() / 2.0).tan() / rect.height() as f64;
        let at = rect.left_bottom() + egui::vec2(16.0, -20.0);
        let label = |len: f64| format!("{} {units}", number(len, len));
        scale_bar(painter, at, per_point, rect.width() as f64 / 5.0, &label);
    }
    if let ColorBy::Ramp(r) = colour {
        let w = (rect.width() / 4.0).clamp(80.0, 320.0);
        let right = rect.right_bottom() + egui::vec2(-16.0, -30.0);
        let left = right - egui::vec2(w, 0.0);
        painter.rect_filled(
            egui::Rect::from_min_max(
                left + egui::vec2(-8.0, -24.0),
                right + egui::vec2(8.0, 26.0),
            ),
            2.0,
            PAPER,
        );
        let steps = 64;
        for i in 0..steps {
            let [cr, cg, cb] = r.gradient.at(i as f64 / (steps - 1) as f64);
            let x0 = left.x + w * i as f32 / steps as f32;
            let cell = egui::Rect::from_min_max(
                egui::pos2(x0, left.y),
                egui::pos2(x0 + w / steps as f32 + 0.5, left.y + 10.0),
            );
            painter.rect_filled(cell, 0.0, egui::Color32::from_rgb(cr, cg, cb));
        }
        let step = nice_step((r.range[1] - r.range[0]).abs().max(1e-9) / 10.0);
        let below = egui::vec2(0.0, 20.0);
        painter.text(
            left + below,
            egui::Align2::LEFT_CENTER,
            number(r.range[0], step),
            font.clone(),
            INK,
        );
        painter.text(
            right + below,
            egui::Align2::RIGHT_CENTER,
            number(r.range[1], step),
            font,
            INK,
        );
    }
}
