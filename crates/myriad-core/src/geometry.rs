//! f64 geometry: axis-aligned and oriented boxes. World coordinates of real scans (UTM, state
//! plane feet) need f64; GPU-side code works relative to a node origin in f32.

/// Axis-aligned bounding box. `Aabb::EMPTY` has min > max and grows with [`Aabb::extend`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: [f64::INFINITY; 3],
        max: [f64::NEG_INFINITY; 3],
    };

    pub fn new(min: [f64; 3], max: [f64; 3]) -> Aabb {
        Aabb { min, max }
    }
    pub fn is_empty(&self) -> bool {
        (0..3).any(|i| self.min[i] > self.max[i])
    }
    pub fn extend(&mut self, p: [f64; 3]) {
        for i in 0..3 {
            self.min[i] = self.min[i].min(p[i]);
            self.max[i] = self.max[i].max(p[i]);
        }
    }
    pub fn union(&self, other: &Aabb) -> Aabb {
        let mut b = *self;
        for i in 0..3 {
            b.min[i] = b.min[i].min(other.min[i]);
            b.max[i] = b.max[i].max(other.max[i]);
        }
        b
    }
    pub fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|i| p[i] >= self.min[i] && p[i] <= self.max[i])
    }
    pub fn size(&self) -> [f64; 3] {
        [
            self.max[0] - self.min[0],
            self.max[1] - self.min[1],
            self.max[2] - self.min[2],
        ]
    }
    pub fn center(&self) -> [f64; 3] {
        [
            0.5 * (self.min[0] + self.max[0]),
            0.5 * (self.min[1] + self.max[1]),
            0.5 * (self.min[2] + self.max[2]),
        ]
    }
    /// The eight corners, index bit i selects max on axis i.
    pub fn corners(&self) -> [[f64; 3]; 8] {
        std::array::from_fn(|c| {
            std::array::from_fn(|i| {
                if c >> i & 1 == 1 {
                    self.max[i]
                } else {
                    self.min[i]
                }
            })
        })
    }
}

/// Oriented bounding box: `center + axes * (±half_extents)`. `axes` are orthonormal rows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obb {
    pub center: [f64; 3],
    pub axes: [[f64; 3]; 3],
    pub half_extents: [f64; 3],
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl Obb {
    pub fn from_aabb(b: &Aabb) -> Obb {
        let s = b.size();
        Obb {
            center: b.center(),
            axes: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            half_extents: [s[0] * 0.5, s[1] * 0.5, s[2] * 0.5],
        }
    }
    pub fn contains(&self, p: [f64; 3]) -> bool {
        let d = [
            p[0] - self.center[0],
            p[1] - self.center[1],
            p[2] - self.center[2],
        ];
        (0..3).all(|i| dot(d, self.axes[i]).abs() <= self.half_extents[i])
    }
    pub fn corners(&self) -> [[f64; 3]; 8] {
        std::array::from_fn(|c| {
            let mut p = self.center;
            for i in 0..3 {
                let s = if c >> i & 1 == 1 { 1.0 } else { -1.0 } * self.half_extents[i];
                for k in 0..3 {
                    p[k] += self.axes[i][k] * s;
                }
            }
            p
        })
    }
    pub fn aabb(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for c in self.corners() {
            b.extend(c);
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aabb_grows_and_contains() {
        let mut b = Aabb::EMPTY;
        assert!(b.is_empty());
        b.extend([1.0, 2.0, 3.0]);
        b.extend([-1.0, 5.0, 0.0]);
        assert_eq!(b, Aabb::new([-1.0, 2.0, 0.0], [1.0, 5.0, 3.0]));
        assert!(b.contains([0.0, 3.0, 1.0]));
        assert!(!b.contains([0.0, 6.0, 1.0]));
        assert_eq!(b.corners()[7], [1.0, 5.0, 3.0]);
    }

    #[test]
    fn rotated_obb_contains_and_bounds() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let o = Obb {
            center: [10.0, 0.0, 0.0],
            axes: [[h, h, 0.0], [-h, h, 0.0], [0.0, 0.0, 1.0]],
            half_extents: [1.0, 1.0, 1.0],
        };
        assert!(o.contains([10.0, 1.3, 0.0]));
        assert!(!o.contains([11.0, 1.0, 0.0]));
        let b = o.aabb();
        assert!((b.max[0] - (10.0 + 2.0 * h)).abs() < 1e-12);
    }
}
