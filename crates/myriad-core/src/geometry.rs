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

/// An affine transform `p' = R p + t`, stored as three rows `[r0 r1 r2 t]`. Named by what it maps
/// between, e.g. `project_from_scanner`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Affine {
    pub rows: [[f64; 4]; 3],
}

impl Affine {
    pub const IDENTITY: Affine = Affine {
        rows: [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ],
    };

    pub fn translation(t: [f64; 3]) -> Affine {
        let mut a = Affine::IDENTITY;
        for i in 0..3 {
            a.rows[i][3] = t[i];
        }
        a
    }

    /// Rotation from a 3x3 matrix given by rows.
    pub fn rotation(m: [[f64; 3]; 3]) -> Affine {
        Affine {
            rows: std::array::from_fn(|i| [m[i][0], m[i][1], m[i][2], 0.0]),
        }
    }

    /// Rotation about x, then the result by y, then by z, as matrices multiplied in the order
    /// Rx * Ry * Rz (Scheiblauer 2006, section 5.3); angles in degrees.
    pub fn rotation_xyz_degrees(a: [f64; 3]) -> Affine {
        let [x, y, z] = a.map(f64::to_radians);
        let rx = [
            [1.0, 0.0, 0.0],
            [0.0, x.cos(), -x.sin()],
            [0.0, x.sin(), x.cos()],
        ];
        let ry = [
            [y.cos(), 0.0, y.sin()],
            [0.0, 1.0, 0.0],
            [-y.sin(), 0.0, y.cos()],
        ];
        let rz = [
            [z.cos(), -z.sin(), 0.0],
            [z.sin(), z.cos(), 0.0],
            [0.0, 0.0, 1.0],
        ];
        Affine::rotation(mul3(mul3(rx, ry), rz))
    }

    /// `self` after `first`: (self * first)(p) = self(first(p)).
    pub fn then_after(&self, first: &Affine) -> Affine {
        let mut r = Affine {
            rows: [[0.0; 4]; 3],
        };
        for i in 0..3 {
            for j in 0..4 {
                let mut v = if j == 3 { self.rows[i][3] } else { 0.0 };
                for k in 0..3 {
                    v += self.rows[i][k] * first.rows[k][j];
                }
                r.rows[i][j] = v;
            }
        }
        r
    }

    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|i| {
            let r = &self.rows[i];
            r[0] * p[0] + r[1] * p[1] + r[2] * p[2] + r[3]
        })
    }

    /// The linear part only (for directions such as normals).
    pub fn apply_vector(&self, v: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|i| {
            let r = &self.rows[i];
            r[0] * v[0] + r[1] * v[1] + r[2] * v[2]
        })
    }

    /// The 3x3 linear part, by rows.
    pub fn linear(&self) -> [[f64; 3]; 3] {
        std::array::from_fn(|i| [self.rows[i][0], self.rows[i][1], self.rows[i][2]])
    }
}

fn mul3(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

/// The Morton code of a cell: the low 21 bits of x, y and z interleaved, x in bit 0 (so that
/// sorting by it walks the cells octant by octant, each octant's own octants in turn).
pub fn morton(x: u32, y: u32, z: u32) -> u64 {
    fn spread(v: u32) -> u64 {
        let mut x = v as u64 & 0x1f_ffff;
        x = (x | x << 32) & 0x1f_0000_0000_ffff;
        x = (x | x << 16) & 0x1f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        (x | x << 2) & 0x1249_2492_4924_9249
    }
    spread(x) | spread(y) << 1 | spread(z) << 2
}

/// Which of `positions` are lone: no other point within `radius` of them. A renderer that sizes
/// points by the spacing of their level of detail (a square as wide as the gap to the next
/// point, to close the surface) draws a lone point at that size too, where there is no surface
/// to close: a block. Points in cells of side `radius`; each looks in its own cell, then in the
/// 26 around it. A `radius` that is not positive and finite: none is lone.
pub fn lone_points(positions: &[[f64; 3]], radius: f64) -> Vec<bool> {
    use std::collections::HashMap;
    let n = positions.len();
    if n == 0 || !(radius.is_finite() && radius > 0.0) {
        return vec![false; n];
    }
    let cell = |p: &[f64; 3]| p.map(|v| (v / radius).floor() as i64);
    // Points sorted by cell, and each cell's run in that order.
    let mut order: Vec<u32> = (0..n as u32).collect();
    let cells: Vec<[i64; 3]> = positions.iter().map(cell).collect();
    order.sort_unstable_by_key(|&i| cells[i as usize]);
    let mut runs: HashMap<[i64; 3], (u32, u32), BuildCell> =
        HashMap::with_capacity_and_hasher(n / 2, BuildCell);
    let mut start = 0;
    while start < n {
        let c = cells[order[start] as usize];
        let mut end = start + 1;
        while end < n && cells[order[end] as usize] == c {
            end += 1;
        }
        runs.insert(c, (start as u32, end as u32));
        start = end;
    }
    let r2 = radius * radius;
    let near = |i: usize, run: (u32, u32)| {
        order[run.0 as usize..run.1 as usize].iter().any(|&j| {
            let (p, q) = (positions[i], positions[j as usize]);
            j as usize != i && (0..3).map(|a| (p[a] - q[a]) * (p[a] - q[a])).sum::<f64>() <= r2
        })
    };
    (0..n)
        .map(|i| {
            let c = cells[i];
            if near(i, runs[&c]) {
                return false;
            }
            !(0..27).any(|k| {
                let d = [k % 3 - 1, k / 3 % 3 - 1, k / 9 - 1];
                let o = [c[0] + d[0], c[1] + d[1], c[2] + d[2]];
                k != 13 && runs.get(&o).is_some_and(|&run| near(i, run))
            })
        })
        .collect()
}

/// A cheap hash of a cell's integer coordinates (for [`lone_points`]'s map).
#[derive(Clone, Copy, Default)]
struct BuildCell;

#[derive(Default)]
struct CellHasher(u64);

impl std::hash::BuildHasher for BuildCell {
    type Hasher = CellHasher;
    fn build_hasher(&self) -> CellHasher {
        CellHasher(0)
    }
}

impl std::hash::Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x517c_c1b7_2722_0a95);
    }
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn lone_points_have_no_neighbour_within_the_radius() {
        // A row 1 apart, a point 3 away from it, and two points 1.5 apart far off.
        let mut p: Vec<[f64; 3]> = (0..10).map(|i| [i as f64, 0.0, 0.0]).collect();
        p.push([4.0, 3.0, 0.0]);
        p.push([100.0, 100.0, -7.0]);
        p.push([101.5, 100.0, -7.0]);
        let lone = super::lone_points(&p, 2.0);
        assert_eq!(lone[..10], [false; 10]);
        assert_eq!(lone[10..], [true, false, false]);
        // Across cell borders and at negative coordinates, a neighbour just within counts.
        let q = [[-0.01, -0.01, -0.01], [1.98, -0.01, -0.01]];
        assert_eq!(super::lone_points(&q, 2.0), [false, false]);
        assert_eq!(super::lone_points(&q, 1.98), [true, true]);
        // Coincident points are not lone; no radius: none is.
        assert_eq!(
            super::lone_points(&[[5.0; 3], [5.0; 3]], 0.1),
            [false, false]
        );
        assert_eq!(super::lone_points(&q, 0.0), [false, false]);
        assert_eq!(super::lone_points(&q, f64::NAN), [false, false]);
    }
    #[test]
    fn morton_interleaves_x_first() {
        assert_eq!(super::morton(1, 0, 0), 1);
        assert_eq!(super::morton(0, 1, 0), 2);
        assert_eq!(super::morton(0, 0, 1), 4);
        assert_eq!(super::morton(2, 0, 0), 8);
        assert_eq!(
            super::morton(0x1f_ffff, 0x1f_ffff, 0x1f_ffff),
            (1 << 63) - 1
        );
    }

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
    fn affine_rotation_order_and_composition() {
        let close = |a: [f64; 3], b: [f64; 3]| (0..3).all(|i| (a[i] - b[i]).abs() < 1e-12);
        // A quarter turn about z maps x to y.
        let rz = Affine::rotation_xyz_degrees([0.0, 0.0, 90.0]);
        assert!(close(rz.apply([1.0, 0.0, 0.0]), [0.0, 1.0, 0.0]));
        // Rx * Ry * Rz applies Rz first: x -> y (Rz) -> y stays (Ry about y) -> z (Rx 90).
        let r = Affine::rotation_xyz_degrees([90.0, 90.0, 90.0]);
        assert!(close(r.apply([1.0, 0.0, 0.0]), [0.0, 0.0, 1.0]));
        let t = Affine::translation([10.0, 0.0, 0.0]).then_after(&rz);
        assert!(close(t.apply([1.0, 0.0, 0.0]), [10.0, 1.0, 0.0]));
        assert!(close(t.apply_vector([1.0, 0.0, 0.0]), [0.0, 1.0, 0.0]));
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

/// A node of an octree: a level and a cell index per axis at that level, over the root cube.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct NodeKey {
    pub level: u32,
    pub cell: [u32; 3],
}

impl NodeKey {
    pub const ROOT: NodeKey = NodeKey {
        level: 0,
        cell: [0; 3],
    };

    /// Child `octant` (bit 0: +x, bit 1: +y, bit 2: +z).
    pub fn child(&self, octant: usize) -> NodeKey {
        NodeKey {
            level: self.level + 1,
            cell: std::array::from_fn(|a| self.cell[a] * 2 + (octant >> a & 1) as u32),
        }
    }

    /// The node's cube, given the root cube.
    pub fn bounds(&self, root: &Aabb) -> Aabb {
        let side = root.size()[0] / (1u64 << self.level) as f64;
        let min: [f64; 3] = std::array::from_fn(|a| root.min[a] + self.cell[a] as f64 * side);
        Aabb::new(min, min.map(|m| m + side))
    }
}

impl NodeKey {
    /// The parent's key (the root's own for the root).
    pub fn parent(&self) -> NodeKey {
        if self.level == 0 {
            return *self;
        }
        NodeKey {
            level: self.level - 1,
            cell: self.cell.map(|c| c / 2),
        }
    }

    /// Is `self` `other` or one of its descendants?
    pub fn is_within(&self, other: &NodeKey) -> bool {
        self.level >= other.level
            && (0..3).all(|a| self.cell[a] >> (self.level - other.level) == other.cell[a])
    }
}

impl std::fmt::Display for NodeKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}-{}-{}-{}",
            self.level, self.cell[0], self.cell[1], self.cell[2]
        )
    }
}
