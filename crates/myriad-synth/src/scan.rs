//! The scanners. A scan is a sequence of pulses numbered 0, 1, 2, ...; pulse k's origin and
//! direction follow from k alone (flight line and scan line for airborne, station and angular
//! step for terrestrial), so any range of pulses can be generated independently.
//!
//! - Airborne (`city`, `terrain`): parallel flight lines at 600 m, an oscillating mirror sweeping
//!   ±20° across track (zig-zag), 30 % side overlap. Trees are semi-transparent and give several
//!   returns; buildings cast occlusion shadows on the off-nadir side.
//! - Terrestrial (`indoor`): rooms with furniture, two stations per room at tripod height, each a
//!   full panorama with elevations from -60° to +90°; density falls off with range.

use crate::rng::{Rng, hash3, mix, sub, unit};
use crate::scene::{self, Box3, Hit, Kind, Scene};
use myriad_core::PointBatch;

/// Returns of one pulse, in order along the ray.
pub struct Return {
    pub pos: [f64; 3],
    pub class: u8,
    pub rgb: [u16; 3],
    pub intensity: u16,
}

/// A direct-mapped memo keyed by grid cell: one slot per hash bucket, overwritten on collision.
/// Cheaper than a hash map for the few cells each pulse asks for, and bounded in size.
struct CellCache<T> {
    slots: Vec<Option<((i64, i64), T)>>,
}

impl<T> CellCache<T> {
    const BITS: u32 = 10;
    fn new() -> Self {
        CellCache {
            slots: (0..1 << Self::BITS).map(|_| None).collect(),
        }
    }
    #[inline]
    fn get_or_insert_with(&mut self, key: (i64, i64), f: impl FnOnce() -> T) -> &T {
        // Multiplicative hashing of the cell: two multiplies, enough to spread neighbouring cells.
        let h = (key.0 as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (key.1 as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        let i = (h >> (64 - Self::BITS)) as usize;
        let slot = &mut self.slots[i];
        if !matches!(slot, Some((k, _)) if *k == key) {
            *slot = Some((key, f()));
        }
        &slot.as_ref().expect("filled above").1
    }
}

pub const ALTITUDE: f64 = 600.0;
const HALF_ANGLE_DEG: f64 = 20.0;
const SPACING: f64 = 0.3;
const PULSE_PERIOD: f64 = 1.0 / 250_000.0;

/// The plan of an airborne survey covering a square of side `side` metres.
#[derive(Debug, Clone, Copy)]
pub struct Flight {
    pub side: f64,
    pub half_angle: f64,
    pub swath: f64,
    pub line_spacing: f64,
    pub pulses_per_scanline: u64,
    pub scanlines_per_line: u64,
}

impl Flight {
    /// Plans a survey of whole flight lines that yields about `points` returns at ~0.3 m pulse
    /// spacing: the area is about square, and the line length is chosen so that the last line
    /// ends about where the points run out (no half-flown strip). `returns_per_pulse` is the
    /// scene's average (more where trees let pulses through), estimated low on purpose: the scan
    /// then stops a little before the end of its last line rather than starting another.
    pub fn plan(points: u64, returns_per_pulse: f64) -> Flight {
        let pulses = points as f64 / returns_per_pulse;
        let max_swath = 2.0 * ALTITUDE * HALF_ANGLE_DEG.to_radians().tan();
        // Area covered per pulse, counting the 30 % side overlap once.
        let area = pulses * SPACING * SPACING * 0.7;
        let side = area.sqrt().max(20.0);
        let swath = max_swath.min(side / 0.7);
        let line_spacing = swath * 0.7;
        let lines = (side / line_spacing).round().max(1.0);
        let pulses_per_scanline = (swath / SPACING).ceil() as u64;
        let scanlines_per_line = (pulses / lines / pulses_per_scanline as f64)
            .ceil()
            .max(1.0) as u64;
        Flight {
            side: scanlines_per_line as f64 * SPACING,
            half_angle: (swath * 0.5 / ALTITUDE).atan(),
            swath,
            line_spacing,
            pulses_per_scanline,
            scanlines_per_line,
        }
    }
}

/// Per-block memo of the scene's hashed objects (buildings per block, tree per cell).
pub struct Cache {
    buildings: CellCache<Vec<(Box3, u64)>>,
    trees: CellCache<Option<scene::Tree>>,
    furniture: CellCache<Vec<(Box3, u64)>>,
    /// Height of the previous ground hit: the next pulse lands 0.3 m away, so Newton starts there.
    last_ground: f64,
    /// The terrain row of the previous pulse, from which the next one is derived.
    last_row: Option<scene::TerrainRow>,
    crowns: Vec<Hit>,
    hits: Vec<Hit>,
}

impl Default for Cache {
    fn default() -> Cache {
        Cache {
            buildings: CellCache::new(),
            trees: CellCache::new(),
            furniture: CellCache::new(),
            last_ground: 0.0,
            last_row: None,
            crowns: Vec::new(),
            hits: Vec::new(),
        }
    }
}

pub struct Airborne<'a> {
    scene: &'a Scene,
    flight: Flight,
    /// Per position across the swath (west to east): mirror angle, its sine and cosine, and the
    /// scan angle rank in degrees. Every scan line uses the same angles, so they are computed once.
    mirror: Vec<(f64, f64, f64, f32)>,
}

impl<'a> Airborne<'a> {
    pub fn new(scene: &'a Scene, flight: Flight) -> Airborne<'a> {
        let n = flight.pulses_per_scanline;
        let mirror = (0..n)
            .map(|i| {
                let u = (i as f64 + 0.5) / n as f64;
                let angle = (u * 2.0 - 1.0) * flight.half_angle;
                let (s, c) = scene::sin_cos(angle);
                (angle, s, c, scene::round_fast(angle.to_degrees()) as f32)
            })
            .collect();
        Airborne {
            scene,
            flight,
            mirror,
        }
    }

    /// Generates pulse k's returns into `out` (appending).
    pub fn pulse(&self, k: u64, cache: &mut Cache, out: &mut PointBatch) {
        let f = &self.flight;
        let per_line = f.pulses_per_scanline * f.scanlines_per_line;
        let line = k / per_line;
        let in_line = k % per_line;
        let scanline = in_line / f.pulses_per_scanline;
        let i = in_line % f.pulses_per_scanline;
        let mut rng = Rng::new(k ^ 0x5EED_0000_0000 ^ self.scene.seed.rotate_left(17));
        // Zig-zag: even scan lines sweep west to east, odd ones back.
        let u = (i as f64 + 0.5) / f.pulses_per_scanline as f64;
        let across = if scanline.is_multiple_of(2) {
            i
        } else {
            f.pulses_per_scanline - 1 - i
        };
        let (_, sa, ca, angle_rank) = self.mirror[across as usize];
        let along = (scanline as f64 + u) * SPACING;
        let northbound = line.is_multiple_of(2);
        let y = if northbound { along } else { f.side - along };
        let x = line as f64 * f.line_spacing;
        let origin = [x, y, ALTITUDE + rng.normal() * 0.05];
        let dir = [sa, 0.0, -ca];
        let gps = 1.0e6 + k as f64 * PULSE_PERIOD + line as f64 * 60.0;
        self.cast(origin, dir, cache, &mut rng);
        let n = cache.hits.len() as u8;
        for (r, h) in cache.hits.iter().enumerate() {
            let noise = rng.normal() * 0.02;
            let t = h.t + noise;
            let pos = [
                origin[0] + dir[0] * t,
                origin[1] + dir[1] * t,
                origin[2] + dir[2] * t,
            ];
            let cos = -(h.normal[0] * dir[0] + h.normal[1] * dir[1] + h.normal[2] * dir[2]);
            let energy = 0.5f64.powi(r as i32);
            let range_falloff = (ALTITUDE / h.t).powi(2);
            let intensity = (h.reflectance
                * cos.abs().max(0.05)
                * range_falloff
                * energy
                * 60000.0
                * (1.0 + 0.06 * rng.normal()))
            .clamp(1.0, 65535.0) as u16;
            out.positions.push(pos);
            push(&mut out.intensity, intensity);
            push(&mut out.return_number, r as u8 + 1);
            push(&mut out.number_of_returns, n);
            push(&mut out.classification, h.class);
            push(&mut out.classification_flags, 0);
            let edge = (i == 0 || i + 1 == f.pulses_per_scanline) as u8;
            push(
                &mut out.scan_flags,
                scanline.is_multiple_of(2) as u8 | edge << 1,
            );
            push(&mut out.scan_angle, angle_rank);
            push(&mut out.user_data, 0);
            push(&mut out.point_source_id, line as u16 + 1);
            push(&mut out.gps_time, gps);
            push(&mut out.rgb, jitter(h.rgb, &mut rng));
        }
    }

    /// Casts one pulse: semi-transparent crowns first, then the first opaque surface.
    /// Fills `cache.hits`.
    fn cast(&self, o: [f64; 3], d: [f64; 3], cache: &mut Cache, rng: &mut Rng) {
        let s = self.scene;
        let relief = s.relief();
        let top = relief + scene::MAX_OBJECT_HEIGHT + 1.0;
        let (t0, t1) = ((o[2] - top) / -d[2], (o[2] + relief + 1.0) / -d[2]);
        let (xa, xb) = (o[0] + d[0] * t0, o[0] + d[0] * t1);
        let (xlo, xhi) = (xa.min(xb), xa.max(xb));
        let (ylo, yhi) = (o[1] - 0.01, o[1] + 0.01);
        let mut opaque: Option<Hit> =
            Some(self.terrain_hit(o, d, &mut cache.last_ground, &mut cache.last_row));
        if s.kind == Kind::City {
            let bs = scene::BLOCK;
            for bx in scene::floor_fast(xlo / bs)..=scene::floor_fast(xhi / bs) {
                for by in scene::floor_fast(ylo / bs)..=scene::floor_fast(yhi / bs) {
                    let list = cache.buildings.get_or_insert_with((bx, by), || {
                        let mut v = Vec::new();
                        s.buildings(bx, by, &mut v);
                        v
                    });
                    for (b, h) in list.iter() {
                        if let Some((t, n)) = scene::ray_box(o, d, b)
                            && opaque.as_ref().is_none_or(|x| t < x.t)
                        {
                            let roof = n[2] > 0.5;
                            opaque = Some(Hit {
                                t,
                                normal: n,
                                class: scene::BUILDING,
                                rgb: if roof {
                                    scene::roof_colour(*h)
                                } else {
                                    [52000, 50000, 46000]
                                },
                                reflectance: if roof { 0.3 } else { 0.5 },
                                transparent: false,
                            });
                        }
                    }
                }
            }
        }
        let tc = scene::TREE_CELL;
        let m = scene::MAX_CROWN;
        let mut crowns = std::mem::take(&mut cache.crowns);
        crowns.clear();
        for cx in scene::floor_fast((xlo - m) / tc)..=scene::floor_fast((xhi + m) / tc) {
            for cy in scene::floor_fast((ylo - m) / tc)..=scene::floor_fast((yhi + m) / tc) {
                let tree = *cache.trees.get_or_insert_with((cx, cy), || s.tree(cx, cy));
                let Some(tree) = tree else { continue };
                if let Some((t, n)) = scene::ray_sphere(o, d, tree.center, tree.radius)
                    && opaque.as_ref().is_none_or(|x| t < x.t)
                {
                    let h = hash3(s.seed, cx, cy);
                    let g = 0.7 + 0.3 * unit(h);
                    crowns.push(Hit {
                        // Leaves are hit somewhere inside the crown's outer shell.
                        t: t + rng.f64() * tree.radius * 0.5,
                        normal: n,
                        class: scene::HIGH_VEGETATION,
                        rgb: [
                            (14000.0 * g) as u16,
                            (34000.0 * g) as u16,
                            (12000.0 * g) as u16,
                        ],
                        reflectance: 0.45,
                        transparent: true,
                    });
                }
            }
        }
        crowns.sort_by(|a, b| a.t.total_cmp(&b.t));
        let hits = &mut cache.hits;
        hits.clear();
        for &c in &crowns {
            if hits.is_empty() || rng.f64() < 0.55 {
                hits.push(c);
            }
            if hits.len() == 3 {
                break;
            }
        }
        if let Some(op) = opaque
            && (hits.is_empty() || rng.f64() < 0.6)
        {
            hits.push(op);
        }
        cache.crowns = crowns;
    }

    fn terrain_hit(
        &self,
        o: [f64; 3],
        d: [f64; 3],
        last_ground: &mut f64,
        last_row: &mut Option<scene::TerrainRow>,
    ) -> Hit {
        let s = self.scene;
        // Newton on f(t) = z(t) - h(x(t), y(t)); the terrain is smooth, so a few steps converge.
        let mut t = (o[2] - *last_ground) / -d[2];
        debug_assert!(d[1] == 0.0, "airborne rays sweep across track only");
        let y = o[1];
        let row = match last_row {
            Some(r) if (r.y() - y).abs() < 1.0 => s.terrain_row_from(r, y),
            _ => s.terrain_row(y),
        };
        *last_row = Some(row);
        let mut x = o[0] + d[0] * t;
        let (mut h, mut g) = s.terrain_at(&row, x);
        for _ in 0..4 {
            let f = o[2] + d[2] * t - h;
            if f.abs() < 2e-3 {
                break;
            }
            t -= f / (d[2] - (g[0] * d[0] + g[1] * d[1]));
            x = o[0] + d[0] * t;
            (h, g) = s.terrain_at(&row, x);
        }
        let len = (g[0] * g[0] + g[1] * g[1] + 1.0).sqrt();
        let (class, rgb, reflectance) = s.ground_material(x, y, h);
        *last_ground = h;
        Hit {
            t,
            normal: [-g[0] / len, -g[1] / len, 1.0 / len],
            class,
            rgb,
            reflectance,
            transparent: false,
        }
    }
}

/// A point of a single return with no flags set (terrestrial stations, the stockpile site).
pub(crate) fn push_single(
    out: &mut PointBatch,
    position: [f64; 3],
    intensity: u16,
    class: u8,
    source: u16,
    gps_time: f64,
    rgb: [u16; 3],
) {
    out.positions.push(position);
    push(&mut out.intensity, intensity);
    push(&mut out.return_number, 1);
    push(&mut out.number_of_returns, 1);
    push(&mut out.classification, class);
    push(&mut out.classification_flags, 0);
    push(&mut out.scan_flags, 0);
    push(&mut out.scan_angle, 0.0);
    push(&mut out.user_data, 0);
    push(&mut out.point_source_id, source);
    push(&mut out.gps_time, gps_time);
    push(&mut out.rgb, rgb);
}

#[inline]
pub(crate) fn push<T>(c: &mut Option<Vec<T>>, v: T) {
    if let Some(c) = c {
        c.push(v);
    }
}

fn jitter(c: [u16; 3], rng: &mut Rng) -> [u16; 3] {
    let k = 1.0 + 0.08 * rng.normal();
    c.map(|v| (v as f64 * k).clamp(0.0, 65535.0) as u16)
}

/// Terrestrial scans of furnished rooms.
pub struct Indoor {
    pub seed: u64,
    pub pulses_per_station: u64,
    pub n_el: u64,
}

pub const ROOM: [f64; 3] = [12.0, 8.0, 3.0];
const ROOM_PITCH: [f64; 2] = [14.0, 10.0];
const ROOMS_PER_ROW: u64 = 16;

impl Indoor {
    pub fn plan(points: u64, seed: u64) -> Indoor {
        let stations = points.div_ceil(2_000_000).max(1);
        let per = points.div_ceil(stations).max(64);
        // Elevation covers 150 of the azimuth's 360 degrees: choose equal angular steps.
        let n_el = ((per as f64 * 150.0 / 360.0).sqrt().round() as u64).max(4);
        Indoor {
            seed,
            pulses_per_station: per,
            n_el,
        }
    }

    fn room_box(&self, room: u64) -> Box3 {
        let x = (room % ROOMS_PER_ROW) as f64 * ROOM_PITCH[0];
        let y = (room / ROOMS_PER_ROW) as f64 * ROOM_PITCH[1];
        Box3 {
            min: [x, y, 0.0],
            max: [x + ROOM[0], y + ROOM[1], ROOM[2]],
        }
    }

    fn furniture(&self, room: u64, r: &Box3) -> Vec<(Box3, u64)> {
        let h = mix(self.seed ^ room.wrapping_mul(0xF00D));
        let n = 3 + h % 5;
        (0..n)
            .map(|i| {
                let hi = mix(h ^ i);
                let (w, d, ht) = match hi % 3 {
                    0 => (1.6, 0.8, 0.75),
                    1 => (1.0, 0.5, 2.0),
                    _ => (0.5, 0.5, 0.45),
                };
                let x = r.min[0] + 0.3 + (ROOM[0] - w - 0.6) * sub(hi, 8);
                let y = r.min[1] + 0.3 + (ROOM[1] - d - 0.6) * sub(hi, 20);
                (
                    Box3 {
                        min: [x, y, 0.0],
                        max: [x + w, y + d, ht],
                    },
                    hi,
                )
            })
            .collect()
    }

    /// Where station `station` stands (two per room), before the scene's origin is added.
    pub fn station(&self, station: u64) -> [f64; 3] {
        let rbox = self.room_box(station / 2);
        let sh = mix(self.seed ^ station.wrapping_mul(0x57A7));
        [
            rbox.min[0]
                + 2.0
                + (ROOM[0] - 4.0) * (0.2 + 0.6 * (station % 2) as f64 * 0.9 + 0.1 * unit(sh)),
            rbox.min[1] + 2.0 + (ROOM[1] - 4.0) * sub(sh, 16),
            1.5,
        ]
    }

    pub fn pulse(&self, k: u64, cache: &mut Cache, out: &mut PointBatch) {
        let station = k / self.pulses_per_station;
        let j = k % self.pulses_per_station;
        let room = station / 2;
        let rbox = self.room_box(room);
        let o = self.station(station);
        let n_az = self.pulses_per_station.div_ceil(self.n_el);
        let az = (j / self.n_el) as f64 / n_az as f64 * std::f64::consts::TAU;
        let el = (-60.0 + 150.0 * ((j % self.n_el) as f64 + 0.5) / self.n_el as f64).to_radians();
        let d = [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()];
        // Exit of the room box from inside.
        let (mut t, mut axis) = (f64::INFINITY, 0);
        for a in 0..3 {
            if d[a].abs() > 1e-12 {
                let ta = if d[a] > 0.0 {
                    (rbox.max[a] - o[a]) / d[a]
                } else {
                    (rbox.min[a] - o[a]) / d[a]
                };
                if ta < t {
                    t = ta;
                    axis = a;
                }
            }
        }
        let mut normal = [0.0; 3];
        normal[axis] = -d[axis].signum();
        let wall_tint = unit(mix(room ^ self.seed)) * 6000.0;
        let (mut class, mut rgb, mut refl) = match (axis, d[2] < 0.0) {
            (2, true) => (scene::GROUND, [30000, 22000, 14000], 0.4),
            (2, false) => (scene::BUILDING, [60000, 60000, 59000], 0.8),
            _ => (
                scene::BUILDING,
                [56000 - wall_tint as u16, 54000, 50000 + wall_tint as u16],
                0.7,
            ),
        };
        let furniture = cache
            .furniture
            .get_or_insert_with((room as i64, 0), || self.furniture(room, &rbox));
        for (b, h) in furniture.iter() {
            if let Some((tb, n)) = scene::ray_box(o, d, b)
                && tb < t
            {
                t = tb;
                normal = n;
                class = scene::UNCLASSIFIED;
                rgb = [
                    [20000, 12000, 8000],
                    [44000, 44000, 46000],
                    [9000, 20000, 40000],
                ][(h % 3) as usize];
                refl = 0.5;
            }
        }
        let mut rng = Rng::new(k ^ self.seed.rotate_left(29));
        let t = t + rng.normal() * 0.002;
        let cos = -(normal[0] * d[0] + normal[1] * d[1] + normal[2] * d[2]);
        let intensity = (refl * cos.abs().max(0.05) / (1.0 + (t / 8.0).powi(2)) * 60000.0)
            .clamp(1.0, 65535.0) as u16;
        let gps = 2.0e6 + station as f64 * 600.0 + j as f64 * 1e-6;
        let rgb = jitter(rgb, &mut rng);
        let p = [o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t];
        push_single(out, p, intensity, class, station as u16 + 1, gps, rgb);
    }
}
