//! Where the headset's stage stands in the data, and the controllers' navigation (002: fly,
//! rotate and scale the clouds): pure arithmetic, tested without a runtime.
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

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() < 1e-9)
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
