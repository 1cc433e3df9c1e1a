//! The clipping box: a box given as fractions of the data's extent per axis, on or off,
//! keeping the inside or the outside; its sliders in the panel, its edges over the view, and
//! the clip the points are drawn with.

use eframe::egui;
use myriad_core::Aabb;

pub(crate) struct Clip {
    /// The data's extent the fractions are of.
    bounds: Aabb,
    /// Per axis, the box's (min, max) as fractions of the extent.
    fractions: [[f64; 2]; 3],
    on: bool,
    /// The box keeps the inside.
    inside: bool,
}

impl Clip {
    /// Off, the middle half of `bounds` on each axis, keeping the inside.
    pub fn new(bounds: Aabb) -> Clip {
        Clip {
            bounds,
            fractions: [[0.25, 0.75]; 3],
            on: false,
            inside: true,
        }
    }

    /// The clipping box in world coordinates.
    fn world(&self) -> Aabb {
        let b = &self.bounds;
        let at = |axis: usize, f: f64| b.min[axis] + f * (b.max[axis] - b.min[axis]);
        Aabb::new(
            std::array::from_fn(|a| at(a, self.fractions[a][0])),
            std::array::from_fn(|a| at(a, self.fractions[a][1])),
        )
    }

    /// The panel's part: on or off, inside or outside, the box's sliders. The clip the points
    /// are drawn with.
    pub fn panel(&mut self, ui: &mut egui::Ui) -> Option<myriad_render::Clip> {
        ui.checkbox(&mut self.on, "clipping box");
        if self.on {
            ui.horizontal(|ui| {
                ui.radio_value(&mut self.inside, true, "show inside");
                ui.radio_value(&mut self.inside, false, "outside");
            });
            for (axis, name) in ["x", "y", "z"].iter().enumerate() {
                let [lo, hi] = &mut self.fractions[axis];
                ui.add(egui::Slider::new(lo, 0.0..=1.0).text(format!("{name} from")));
                ui.add(egui::Slider::new(hi, 0.0..=1.0).text(format!("{name} to")));
                if *lo > *hi {
                    std::mem::swap(lo, hi);
                }
            }
        }
        self.on.then(|| myriad_render::Clip {
            bounds: self.world(),
            inside: self.inside,
        })
    }

    /// The box's edges over the view, where it is on.
    pub fn draw(&self, painter: &egui::Painter, screen: &dyn Fn([f64; 3]) -> Option<egui::Pos2>) {
        if !self.on {
            return;
        }
        let c = self.world().corners();
        // Corners differ in one axis bit along each of the 12 edges.
        for i in 0..8usize {
            for bit in [1usize, 2, 4] {
                let j = i ^ bit;
                if j > i
                    && let (Some(a), Some(b)) = (screen(c[i]), screen(c[j]))
                {
                    painter.line_segment([a, b], egui::Stroke::new(1.0, egui::Color32::LIGHT_BLUE));
                }
            }
        }
    }
}
