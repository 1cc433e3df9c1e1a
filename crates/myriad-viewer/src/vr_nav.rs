//! Where the headset's stage stands in the data, the controllers' navigation (Discher et al.
//! 2018: fly, rotate and scale the clouds), and the eyes' off-axis fields of view cut from
//! symmetric images: pure arithmetic, tested without a runtime.
//!
//! Stage space is the runtime's (metres, Y up, -Z ahead); data space is the dataset's (its
//! units, Z up). A stage vector (x, y, z) is the data direction (x, -z, y); `scale` metres show one
//! data unit.

/// A stage direction in data axes.
pub fn to_data_axes(v: [f64; 3]) -> [f64; 3] {
    [v[0], -v[2], v[1]]
}

fn len(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Two hands' positions (stage) and the stage's placement when a grab began.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Grab {
    hands: [[f64; 3]; 2],
    origin: [f64; 3],
    scale: f64,
}

/// The stage in the data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StageNav {
    /// The data point at the stage's origin.
    pub origin: [f64; 3],
    /// Metres a data unit is shown at.
    pub scale: f64,
    grab: Option<Grab>,
}

impl StageNav {
    pub fn new(origin: [f64; 3], scale: f64) -> StageNav {
        StageNav {
            origin,
            scale,
            grab: None,
        }
    }

    /// The data point at stage position `v`.
    pub fn to_data(&self, v: [f64; 3]) -> [f64; 3] {
        let d = to_data_axes(v);
        std::array::from_fn(|a| self.origin[a] + d[a] / self.scale)
    }

    /// Flies `seconds` at `speed` metres a second along the stage direction `aim` (a
    /// controller's pointing direction): the data come towards the user.
    pub fn fly(&mut self, aim: [f64; 3], seconds: f64, speed: f64) {
        let l = len(aim);
        if l == 0.0 {
            return;
        }
        let d = to_data_axes(aim);
        for (a, o) in self.origin.iter_mut().enumerate() {
            *o += d[a] / l * speed * seconds / self.scale;
        }
    }

    /// Both hands holding (their stage positions) or not: while held, the data point that was
    /// between the hands when they closed stays between them, and the data grow and shrink with
    /// the hands' distance.
    pub fn grab(&mut self, hands: Option<[[f64; 3]; 2]>) {
        let Some(h) = hands else {
            self.grab = None;
            return;
        };
        let g = *self.grab.get_or_insert(Grab {
            hands: h,
            origin: self.origin,
            scale: self.scale,
        });
        let apart = |h: [[f64; 3]; 2]| len(std::array::from_fn(|a| h[1][a] - h[0][a]));
        let mid =
            |h: [[f64; 3]; 2]| -> [f64; 3] { std::array::from_fn(|a| (h[0][a] + h[1][a]) / 2.0) };
        let (d0, d) = (apart(g.hands), apart(h));
        self.scale = if d0 > 1e-6 && d > 1e-6 {
            g.scale * d / d0
        } else {
            g.scale
        };
        // The data point under the first midpoint, as the grab began.
        let m0 = to_data_axes(mid(g.hands));
        let held: [f64; 3] = std::array::from_fn(|a| g.origin[a] + m0[a] / g.scale);
        let m = to_data_axes(mid(h));
        self.origin = std::array::from_fn(|a| held[a] - m[a] / self.scale);
    }
}

/// An eye's field of view as the tangents of its four half angles (left and down negative).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tangents {
    pub left: f64,
    pub right: f64,
    pub up: f64,
    pub down: f64,
}

/// How eyes with off-axis (asymmetric) fields of view are drawn with symmetric frusta: one
/// symmetric image per eye holding both eyes' fields, `width` x `height` pixels of `fov_y`
/// degrees, and per eye the corner of its own field in that image, from which its swapchain's
/// `w` x `h` pixels are cut. Pixels are square, of the swapchain's vertical size; `drawn` is the
/// field each cut covers (the eye's own, to a pixel, where the swapchain's pixels are square),
/// what the projection layer must say. The pixels cut are those an off-axis projection of that
/// field would draw (the same eye, orientation and image plane).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cover {
    pub width: u32,
    pub height: u32,
    pub fov_y: f64,
    pub corners: [(u32, u32); 2],
    pub drawn: [Tangents; 2],
}

impl Cover {
    /// Eye `k`'s hidden pixels in its symmetric image, row by row: those outside its cut of
    /// `w` x `h` pixels (no eye shows them) and those whose centres lie in one of `hidden` (the
    /// runtime's hidden-area triangles, XR_KHR_visibility_mask: tangents, x right, y up).
    pub fn mask(&self, k: usize, w: u32, h: u32, hidden: &[[[f64; 2]; 3]]) -> Vec<bool> {
        let p = 2.0 * (self.fov_y / 2.0).to_radians().tan() / self.height as f64;
        let (half_w, half_h) = (self.width as f64 * p / 2.0, self.height as f64 * p / 2.0);
        let pixels: Vec<[[f64; 2]; 3]> = hidden
            .iter()
            .map(|t| t.map(|v| [(v[0] + half_w) / p, (half_h - v[1]) / p]))
            .collect();
        let mut mask = myriad_render::stereo::triangles_mask(self.width, self.height, &pixels);
        let (x0, y0) = self.corners[k];
        for (i, m) in mask.iter_mut().enumerate() {
            let (x, y) = (
                (i % self.width as usize) as u32,
                (i / self.width as usize) as u32,
            );
            if x < x0 || x >= x0 + w || y < y0 || y >= y0 + h {
                *m = true;
            }
        }
        mask
    }
}

pub fn cover(eyes: [Tangents; 2], w: u32, h: u32) -> Cover {
    let (w, h) = (w.max(1), h.max(1));
    let u = eyes
        .iter()
        .map(|t| t.left.abs().max(t.right.abs()))
        .fold(0.0, f64::max);
    let v = eyes
        .iter()
        .map(|t| t.up.abs().max(t.down.abs()))
        .fold(0.0, f64::max);
    let p = (eyes[0].up - eyes[0].down) / h as f64;
    let width = ((2.0 * u / p).ceil() as u32).max(w);
    let height = ((2.0 * v / p).ceil() as u32).max(h);
    let (half_w, half_h) = (width as f64 * p / 2.0, height as f64 * p / 2.0);
    let corners = eyes.map(|t| {
        let x = ((t.left + half_w) / p).round().max(0.0) as u32;
        let y = ((half_h - t.up) / p).round().max(0.0) as u32;
        (x.min(width - w), y.min(height - h))
    });
    let drawn = corners.map(|(x, y)| {
        let left = x as f64 * p - half_w;
        let up = half_h - y as f64 * p;
        Tangents {
            left,
            right: left + w as f64 * p,
            up,
            down: up - h as f64 * p,
        }
    });
    Cover {
        width,
        height,
        fov_y: 2.0 * half_h.atan().to_degrees(),
        corners,
        drawn,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() < 1e-9)
    }

    #[test]
    fn off_axis_eyes_are_cut_from_symmetric_images() {
        // A headset's eyes: wider outwards (52 degrees) than inwards (44), 40 up, 50 down.
        let t = |d: f64| d.to_radians().tan();
        let left = Tangents {
            left: -t(52.0),
            right: t(44.0),
            up: t(40.0),
            down: -t(50.0),
        };
        let right = Tangents {
            left: -t(44.0),
            right: t(52.0),
            ..left
        };
        // Square pixels: 1000 rows over the vertical field, as many columns as that pixel size
        // takes over the horizontal one.
        let h = 1000;
        let p = (left.up - left.down) / h as f64;
        let w = ((left.right - left.left) / p).round() as u32;
        let c = cover([left, right], w, h);
        // Symmetric: as wide as the outer half twice, as high as the lower half twice.
        assert!((c.width as f64 * p / 2.0 - t(52.0)).abs() < 2.0 * p);
        assert!(((c.fov_y / 2.0).to_radians().tan() - t(50.0)).abs() < 2.0 * p);
        // The left eye's field starts at the image's left side, the right eye's ends at its
        // right side; both start 10 degrees' worth below the top.
        assert_eq!(c.corners[0].0, 0);
        assert_eq!(c.corners[1].0 + w, c.width);
        let top = ((t(50.0) - t(40.0)) / p).round() as u32;
        assert!(c.corners[0].1.abs_diff(top) <= 1 && c.corners[1].1 == c.corners[0].1);
        // What each cut covers is the eye's field, to a pixel.
        for (d, e) in c.drawn.iter().zip([left, right]) {
            for (a, b) in [
                (d.left, e.left),
                (d.right, e.right),
                (d.up, e.up),
                (d.down, e.down),
            ] {
                assert!((a - b).abs() <= 1.5 * p, "{d:?} {e:?}");
            }
        }
        // A symmetric eye is cut from the middle.
        let sym = Tangents {
            left: -t(45.0),
            right: t(45.0),
            up: t(45.0),
            down: -t(45.0),
        };
        let c = cover([sym, sym], 100, 100);
        assert_eq!((c.width, c.height, c.corners[0]), (100, 100, (0, 0)));
        assert!((c.fov_y - 90.0).abs() < 1e-9);
    }

    #[test]
    fn an_eyes_mask_holds_the_runtimes_triangles_and_all_outside_its_cut() {
        let t = |d: f64| d.to_radians().tan();
        let left = Tangents {
            left: -t(50.0),
            right: t(40.0),
            up: t(45.0),
            down: -t(45.0),
        };
        let right = Tangents {
            left: -t(40.0),
            right: t(50.0),
            ..left
        };
        let h = 200;
        let p = (left.up - left.down) / h as f64;
        let w = ((left.right - left.left) / p).round() as u32;
        let c = cover([left, right], w, h);
        assert!(c.width > w);
        // No triangles: exactly the pixels outside the cut.
        let m = c.mask(0, w, h, &[]);
        assert_eq!(m.iter().filter(|&&b| !b).count(), (w * h) as usize);
        assert!(!m[0] && m[c.width as usize - 1]);
        // The runtime hides the eye's top left corner: a right triangle with legs of 20 pixels
        // from the field's corner (tangents), 20 * 21 / 2 = 210 pixel centres in it (the
        // hypotenuse's half), more or less a row.
        let (l, u) = (c.drawn[0].left, c.drawn[0].up);
        let corner = [[l, u], [l + 20.0 * p, u], [l, u - 20.0 * p]];
        let m = c.mask(0, w, h, &[corner]);
        let hidden = m.iter().filter(|&&b| b).count() - (c.width * h - w * h) as usize;
        assert!(hidden.abs_diff(210) <= 21, "{hidden}");
        assert!(m[0] && !m[(h as usize / 2) * c.width as usize + w as usize / 2]);
        // The right eye's cut is the image's right part; the same tangents, its own pixels.
        let m = c.mask(1, w, h, &[corner]);
        assert!(m[0] && !m[c.width as usize - 1]);
    }

    #[test]
    fn stage_axes_map_to_data_axes() {
        let n = StageNav::new([100.0, 200.0, 10.0], 0.5);
        // Up is data z, ahead (-Z) is data +y, right is data +x; 1 m is 2 data units.
        assert!(close(n.to_data([0.0, 1.0, 0.0]), [100.0, 200.0, 12.0]));
        assert!(close(n.to_data([0.0, 0.0, -1.0]), [100.0, 202.0, 10.0]));
        assert!(close(n.to_data([1.0, 0.0, 0.0]), [102.0, 200.0, 10.0]));
    }

    #[test]
    fn flying_moves_along_the_pointing_direction() {
        let mut n = StageNav::new([0.0; 3], 2.0);
        // 3 m/s for half a second ahead: 1.5 m, 0.75 data units at 2 m a unit.
        n.fly([0.0, 0.0, -5.0], 0.5, 3.0);
        assert!(close(n.origin, [0.0, 0.75, 0.0]));
        n.fly([0.0; 3], 1.0, 3.0);
        assert!(close(n.origin, [0.0, 0.75, 0.0]));
    }

    #[test]
    fn grabbing_with_both_hands_moves_and_scales_about_them() {
        let mut n = StageNav::new([10.0, 20.0, 0.0], 1.0);
        let h0 = [[-0.2, 1.0, -0.5], [0.2, 1.0, -0.5]];
        let between = n.to_data([0.0, 1.0, -0.5]);
        n.grab(Some(h0));
        assert!(close(n.to_data([0.0, 1.0, -0.5]), between));
        // Hands twice as far apart: the data twice as large, the point still between them.
        n.grab(Some([[-0.4, 1.0, -0.5], [0.4, 1.0, -0.5]]));
        assert!((n.scale - 2.0).abs() < 1e-12);
        assert!(close(n.to_data([0.0, 1.0, -0.5]), between));
        // Both hands a metre to the right: the point goes with them.
        n.grab(Some([[0.6, 1.0, -0.5], [1.4, 1.0, -0.5]]));
        assert!(close(n.to_data([1.0, 1.0, -0.5]), between));
        // Let go: a new grab starts from where things are.
        n.grab(None);
        let s = n;
        n.grab(Some(h0));
        assert!(close(n.origin, s.origin) && n.scale == s.scale);
    }
}
