//! The procedural world. Everything is a pure function of position and seed: terrain height is a
//! sum of smooth waves, and buildings, trees and roads are decided per grid cell by hashing the
//! cell's coordinates. Nothing is stored, so a scene of any extent costs no memory.

use crate::rng::{hash3, sub, unit};

/// ASPRS classes used by the scenes.
pub const GROUND: u8 = 2;
pub const HIGH_VEGETATION: u8 = 5;
pub const BUILDING: u8 = 6;
pub const ROAD: u8 = 11;
pub const UNCLASSIFIED: u8 = 1;

/// City blocks are BLOCK metres square with a road of ROAD_WIDTH along their south and west sides.
pub const BLOCK: f64 = 100.0;
pub const ROAD_WIDTH: f64 = 14.0;
/// Trees are placed one per TREE_CELL cell at most; crowns stay inside their cell's neighbourhood.
pub const TREE_CELL: f64 = 9.0;
pub const MAX_CROWN: f64 = 4.2;
/// Tallest object above the terrain, so rays can skip the empty sky quickly.
pub const MAX_OBJECT_HEIGHT: f64 = 45.0;

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    City,
    Terrain,
}

/// The y-dependent factors of the terrain's waves along one row (see [`Scene::terrain_row`]).
#[derive(Debug, Clone, Copy)]
pub struct TerrainRow {
    y: f64,
    sin: [f64; 3],
    cos: [f64; 3],
    phase: f64,
}

impl TerrainRow {
    pub fn y(&self) -> f64 {
        self.y
    }
}

#[derive(Debug, Clone, Copy)]
pub struct Box3 {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

#[derive(Debug, Clone, Copy)]
pub struct Tree {
    pub center: [f64; 3],
    pub radius: f64,
    pub trunk_base: f64,
}

/// What a ray hit: distance along the ray, surface normal, class and colour.
#[derive(Debug, Clone, Copy)]
pub struct Hit {
    pub t: f64,
    pub normal: [f64; 3],
    pub class: u8,
    pub rgb: [u16; 3],
    /// Fraction of pulse energy reflected (0..1).
    pub reflectance: f64,
    /// Trees let part of the pulse through.
    pub transparent: bool,
}

pub struct Scene {
    pub kind: Kind,
    pub seed: u64,
    amp: f64,
}

impl Scene {
    pub fn new(kind: Kind, seed: u64) -> Scene {
        Scene {
            kind,
            seed,
            amp: if kind == Kind::City { 4.0 } else { 35.0 },
        }
    }

    /// The terrain's waves: (x frequency, y frequency, amplitude, phase). The flat city needs no
    /// fine ripples; the hills get all three octaves.
    fn waves(&self) -> &'static [(f64, f64, f64)] {
        const WAVES: [(f64, f64, f64); 3] = [
            (0.0021, 0.0017, 1.0),
            (0.0063, 0.0049, 0.35),
            (0.0190, 0.0230, 0.08),
        ];
        if self.kind == Kind::City {
            &WAVES[..2]
        } else {
            &WAVES[..]
        }
    }

    /// The terrain's y-dependent factors along the row `y`: a ray of an airborne pulse has no y
    /// component, so every Newton step of one pulse shares them.
    pub fn terrain_row(&self, y: f64) -> TerrainRow {
        let mut row = TerrainRow {
            y,
            sin: [0.0; 3],
            cos: [0.0; 3],
            phase: (self.seed % 1000) as f64,
        };
        for (k, &(_, fy, _)) in self.waves().iter().enumerate() {
            (row.sin[k], row.cos[k]) = sin_cos(fy * y - row.phase * (1.0 + 0.7 * k as f64));
        }
        row
    }

    /// The row at `y`, derived from `near` (a row less than a metre away) by a second-order
    /// Taylor step of each wave's sine and cosine (height error below 10 µm): consecutive pulses of a
    /// scan line differ in y by millimetres, so this replaces two to three `sin_cos` per pulse.
    pub fn terrain_row_from(&self, near: &TerrainRow, y: f64) -> TerrainRow {
        let mut row = *near;
        row.y = y;
        for (k, &(_, fy, _)) in self.waves().iter().enumerate() {
            let d = fy * (y - near.y);
            let (s, c) = (near.sin[k], near.cos[k]);
            row.sin[k] = s + d * c - 0.5 * d * d * s;
            row.cos[k] = c - d * s - 0.5 * d * d * c;
        }
        row
    }

    /// Terrain height and its gradient at (x, row). Uses [`sin_cos`], good to 1e-7, which is
    /// plenty for a landscape and cheaper than libm's.
    pub fn terrain_at(&self, row: &TerrainRow, x: f64) -> (f64, [f64; 2]) {
        let (mut h, mut gx, mut gy) = (0.0, 0.0, 0.0);
        for (k, &(fx, fy, a)) in self.waves().iter().enumerate() {
            let (sx, cx) = sin_cos(fx * x + row.phase * (1.0 + 0.7 * k as f64));
            h += a * sx * row.cos[k];
            gx += a * fx * cx * row.cos[k];
            gy += -a * fy * sx * row.sin[k];
        }
        (self.amp * h, [self.amp * gx, self.amp * gy])
    }

    /// Terrain height and its gradient at (x, y).
    pub fn terrain(&self, x: f64, y: f64) -> (f64, [f64; 2]) {
        self.terrain_at(&self.terrain_row(y), x)
    }

    /// The terrain never leaves [-relief, relief].
    pub fn relief(&self) -> f64 {
        self.amp * self.waves().iter().map(|w| w.2).sum::<f64>() + 0.01
    }

    /// Is (x, y) on a road? City: the grid streets; terrain: one winding road.
    pub fn on_road(&self, x: f64, y: f64) -> bool {
        match self.kind {
            Kind::City => wrap(x, BLOCK) < ROAD_WIDTH || wrap(y, BLOCK) < ROAD_WIDTH,
            Kind::Terrain => {
                // One road every 1500 m, the first meandering through the first flight strip.
                let cx = 120.0 * sin_cos(y * 0.004).0 + 60.0 * sin_cos(y * 0.0093).1;
                (wrap(x + 1300.0, 1500.0) - 1300.0 - cx).abs() < 4.0
            }
        }
    }

    /// Up to four buildings of city block (bx, by), inside the block's non-road area.
    pub fn buildings(&self, bx: i64, by: i64, out: &mut Vec<(Box3, u64)>) {
        out.clear();
        if self.kind != Kind::City {
            return;
        }
        let h = hash3(self.seed ^ 0xB1D, bx, by);
        if h.is_multiple_of(7) {
            return; // a park
        }
        let n = 1 + (h >> 8) % 4;
        let x0 = bx as f64 * BLOCK + ROAD_WIDTH + 4.0;
        let y0 = by as f64 * BLOCK + ROAD_WIDTH + 4.0;
        let room = BLOCK - ROAD_WIDTH - 8.0;
        // Split the block into n lots along x; each lot holds one building.
        for i in 0..n {
            let hi = hash3(h, i as i64, 7);
            let lot = room / n as f64;
            let w = lot * (0.55 + 0.35 * unit(hi));
            let d = room * (0.4 + 0.55 * sub(hi, 7));
            let lx = x0 + lot * i as f64 + (lot - w) * 0.5;
            let ly = y0 + (room - d) * sub(hi, 13);
            let height = 6.0 + (MAX_OBJECT_HEIGHT - 8.0) * sub(hi, 19).powi(2);
            let (ground, _) = self.terrain(lx + w * 0.5, ly + d * 0.5);
            out.push((
                Box3 {
                    min: [lx, ly, ground - 1.0],
                    max: [lx + w, ly + d, ground + height],
                },
                hi,
            ));
        }
    }

    /// The tree of tree cell (cx, cy), if any.
    pub fn tree(&self, cx: i64, cy: i64) -> Option<Tree> {
        let h = hash3(self.seed ^ 0x7EE, cx, cy);
        let p = match self.kind {
            Kind::City => 0.18,
            Kind::Terrain => 0.55,
        };
        if unit(h) > p {
            return None;
        }
        let r = 2.0 + (MAX_CROWN - 2.0) * sub(h, 9);
        let m = TREE_CELL - 2.0 * r;
        let x = cx as f64 * TREE_CELL + r + m.max(0.0) * sub(h, 17);
        let y = cy as f64 * TREE_CELL + r + m.max(0.0) * sub(h, 25);
        if self.on_road(x, y) {
            return None;
        }
        if self.kind == Kind::City {
            let mut b = Vec::new();
            self.buildings(
                (x / BLOCK).floor() as i64,
                (y / BLOCK).floor() as i64,
                &mut b,
            );
            if b.iter().any(|(bb, _)| {
                x > bb.min[0] - r && x < bb.max[0] + r && y > bb.min[1] - r && y < bb.max[1] + r
            }) {
                return None;
            }
        }
        let (g, _) = self.terrain(x, y);
        let trunk = 2.0 + 6.0 * sub(h, 33);
        Some(Tree {
            center: [x, y, g + trunk + r],
            radius: r,
            trunk_base: g,
        })
    }

    /// Colour and reflectance of the ground at (x, y).
    /// Class, colour and reflectance of the ground at (x, y), whose terrain height is `h`.
    pub fn ground_material(&self, x: f64, y: f64, h: f64) -> (u8, [u16; 3], f64) {
        if self.on_road(x, y) {
            let marking = self.kind == Kind::City && {
                let u = (wrap(x, BLOCK) - ROAD_WIDTH * 0.5).abs();
                let v = (wrap(y, BLOCK) - ROAD_WIDTH * 0.5).abs();
                (u < 0.15 || v < 0.15) && wrap(x + y, 6.0) < 3.0
            };
            return if marking {
                (ROAD, [60000, 60000, 58000], 0.8)
            } else {
                (ROAD, [16000, 16000, 17000], 0.12)
            };
        }
        // Patchy fields: a product of triangle waves (cheap, no trigonometry).
        let tri = |u: f64| (2.0 * (u - floor_fast(u) as f64) - 1.0).abs();
        let mut n = tri(x * 0.013 + 0.3 * tri(y * 0.0051)) * tri(y * 0.011 + 0.3 * tri(x * 0.0043));
        if self.kind == Kind::Terrain {
            // Meadows in the valleys, dry grass and rock on the tops.
            n = (0.6 * n + 0.5 * (h / self.relief() + 0.4)).clamp(0.0, 1.0);
        }
        let rgb = [
            (18000.0 + 14000.0 * n) as u16,
            (26000.0 + 12000.0 * (1.0 - n)) as u16,
            (12000.0 + 6000.0 * n) as u16,
        ];
        (GROUND, rgb, 0.35 + 0.2 * n)
    }
}

/// Nearest integer, by truncating conversion: `f64::round` and `floor` are library calls on
/// baseline x86-64 (no SSE4.1) and showed up in profiles.
#[inline]
pub fn round_fast(q: f64) -> f64 {
    (if q >= 0.0 { q + 0.5 } else { q - 0.5 }) as i64 as f64
}

/// Largest integer not above `q` (for |q| < 2^62).
#[inline]
pub fn floor_fast(q: f64) -> i64 {
    let t = q as i64;
    if (t as f64) > q { t - 1 } else { t }
}

/// sin and cos from one range reduction to [-pi/2, pi/2] and Taylor polynomials of degree
/// 11 (sin) and 12 (cos); absolute error below 1e-7.
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    use std::f64::consts::{FRAC_PI_2, PI, TAU};
    let r = x - TAU * round_fast(x * (1.0 / TAU));
    // cos(pi - a) = -cos(a), sin(pi - a) = sin(a)
    let (a, sign) = if r > FRAC_PI_2 {
        (PI - r, -1.0)
    } else if r < -FRAC_PI_2 {
        (-PI - r, -1.0)
    } else {
        (r, 1.0)
    };
    let a2 = a * a;
    let s = a
        * (1.0
            + a2 * (-1.0 / 6.0
                + a2 * (1.0 / 120.0
                    + a2 * (-1.0 / 5040.0 + a2 * (1.0 / 362_880.0 + a2 * (-1.0 / 39_916_800.0))))));
    let c = 1.0
        + a2 * (-0.5
            + a2 * (1.0 / 24.0
                + a2 * (-1.0 / 720.0
                    + a2 * (1.0 / 40_320.0
                        + a2 * (-1.0 / 3_628_800.0 + a2 * (1.0 / 479_001_600.0))))));
    (s, sign * c)
}

/// `x mod m` in [0, m), without the library call behind `f64::rem_euclid`.
#[inline]
pub fn wrap(x: f64, m: f64) -> f64 {
    x - m * floor_fast(x / m) as f64
}

pub fn roof_colour(h: u64) -> [u16; 3] {
    const ROOFS: [[u16; 3]; 5] = [
        [42000, 20000, 16000],
        [30000, 30000, 32000],
        [50000, 48000, 45000],
        [22000, 22000, 24000],
        [38000, 28000, 20000],
    ];
    ROOFS[(h % 5) as usize]
}

/// Ray / box from outside: entry distance and normal.
pub fn ray_box(o: [f64; 3], d: [f64; 3], b: &Box3) -> Option<(f64, [f64; 3])> {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    let mut axis = 0;
    for a in 0..3 {
        if d[a].abs() < 1e-12 {
            if o[a] < b.min[a] || o[a] > b.max[a] {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d[a];
        let (mut ta, mut tb) = ((b.min[a] - o[a]) * inv, (b.max[a] - o[a]) * inv);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        if ta > t0 {
            t0 = ta;
            axis = a;
        }
        t1 = t1.min(tb);
        if t0 > t1 {
            return None;
        }
    }
    let mut n = [0.0; 3];
    n[axis] = -d[axis].signum();
    Some((t0, n))
}

/// Ray / sphere: nearest positive hit and normal.
pub fn ray_sphere(o: [f64; 3], d: [f64; 3], c: [f64; 3], r: f64) -> Option<(f64, [f64; 3])> {
    let oc = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
    let b = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
    let cc = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - r * r;
    let disc = b * b - cc;
    if disc < 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    if t <= 0.0 {
        return None;
    }
    let p = [
        o[0] + d[0] * t - c[0],
        o[1] + d[1] * t - c[1],
        o[2] + d[2] * t - c[2],
    ];
    Some((t, [p[0] / r, p[1] / r, p[2] / r]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_and_sphere_hits() {
        let b = Box3 {
            min: [0.0, 0.0, 0.0],
            max: [1.0, 1.0, 1.0],
        };
        let (t, n) = ray_box([0.5, 0.5, 10.0], [0.0, 0.0, -1.0], &b).unwrap();
        assert!((t - 9.0).abs() < 1e-12 && n == [0.0, 0.0, 1.0]);
        assert!(ray_box([2.0, 0.5, 10.0], [0.0, 0.0, -1.0], &b).is_none());
        let (t, _) = ray_sphere([0.0, 0.0, 10.0], [0.0, 0.0, -1.0], [0.0, 0.0, 0.0], 2.0).unwrap();
        assert!((t - 8.0).abs() < 1e-12);
    }

    #[test]
    fn fast_sin_cos_is_accurate() {
        let mut x = -1000.0;
        while x < 1000.0 {
            let (s, c) = sin_cos(x);
            assert!(
                (s - x.sin()).abs() < 1e-7 && (c - x.cos()).abs() < 1e-7,
                "{x}"
            );
            x += 0.0137;
        }
    }

    #[test]
    fn shifted_rows_match_direct_rows() {
        let s = Scene::new(Kind::Terrain, 11);
        let base = s.terrain_row(250.0);
        for dy in [0.0, 0.001, 0.3, -0.7, 0.99] {
            let (a, _) = s.terrain_at(&s.terrain_row_from(&base, 250.0 + dy), 40.0);
            let (b, _) = s.terrain_at(&s.terrain_row(250.0 + dy), 40.0);
            assert!((a - b).abs() < 1e-5, "dy {dy}: {a} vs {b}");
        }
    }

    #[test]
    fn terrain_gradient_matches_finite_difference() {
        let s = Scene::new(Kind::Terrain, 3);
        let (h, g) = s.terrain(120.0, -40.0);
        let (hx, _) = s.terrain(120.001, -40.0);
        let (hy, _) = s.terrain(120.0, -39.999);
        assert!(((hx - h) / 0.001 - g[0]).abs() < 1e-3);
        assert!(((hy - h) / 0.001 - g[1]).abs() < 1e-3);
    }
}
