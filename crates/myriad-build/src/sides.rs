//! Which side of a surface an airborne scanner saw, from what LAS records of each point: the
//! flight line (point source ID) and the scan angle. Within one flight line, the scan angle
//! moves a point across the track and nothing else does on average (the along-track position
//! does not depend on it), so a least-squares fit of the points' x and y on their scan angle
//! gives, per line, the horizontal direction in which a growing angle moves points: the side
//! the aircraft is not on. A point at angle `a` was then seen from the direction
//! `-g sin a + up cos a` (`g` that unit direction), whatever the file's sign convention for the
//! angle. Where a file records no scan angles (all 0, as KY's), a flight line's points still
//! form a strip along the track: the aircraft flew over its middle, so a point was seen from
//! the strip's centre line, at an angle that grows with its distance from it (up to
//! [`STRIP_HALF_ANGLE`] at the strip's edge). `mwkd` turns the normals it estimates towards
//! that side, so that they have a sign and the renderer's normal cones cull what faces away
//! (Goswami et al. 2010, section III).

use myriad_core::PointBatch;

/// Sums for one flight line's fit, relative to its first point (for precision).
#[derive(Debug, Clone, Copy, Default)]
struct Line {
    origin: [f64; 2],
    n: f64,
    a: f64,
    aa: f64,
    x: f64,
    y: f64,
    xa: f64,
    ya: f64,
    xx: f64,
    yy: f64,
    xy: f64,
}

/// The fits of every flight line, as points go by.
#[derive(Debug, Clone, Default)]
pub struct Sides {
    lines: Vec<Option<Line>>,
}

/// Least scan-angle variance (degrees squared) and correlation of the across-track position
/// with the angle for a line's direction to be trusted.
const MIN_ANGLE_VARIANCE: f64 = 1.0;
const MIN_CORRELATION: f64 = 0.8;
/// Without scan angles: how much longer than wide (in variance) a line's points must lie to be
/// a strip along its track, and the half angle of the field of view assumed at its edges (the
/// sign of a normal is what matters; the angle only tilts the direction it is taken against).
const MIN_ELONGATION: f64 = 2.5;
/// ... and at least this wide (half width, in the data's units: an airborne swath, not a street scanned from a
/// vehicle, whose ceilings and undersides were seen from below).
const MIN_HALF_WIDTH: f64 = 150.0;
pub const STRIP_HALF_ANGLE: f64 = 20.0;

/// The share of the points whose line's side is unknown (their normals turned up, as without
/// sides) that still lets the others' sides be used. A node is culled only where all its
/// normals face away, so such points lying among others whose side is known cannot hide it; a
/// node of them alone (a line's end cut off by a tile's edge, overlapping no other line) may
/// have the wrong sign on its walls: the reason for keeping them few.
pub const MAX_UNKNOWN: f64 = 0.01;

/// Where a flight line's points were seen from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Side {
    /// By scan angle: the unit horizontal direction a growing angle moves points.
    Angle([f64; 2]),
    /// By the strip: its across-track unit direction `across`, the across-track position of
    /// its centre line (`centre`, of `across . (x, y)`) and its half width.
    Strip {
        across: [f64; 2],
        centre: f64,
        half_width: f64,
    },
}

impl Side {
    /// The direction the point at `p`, scan angle `degrees`, was seen from.
    pub fn seen_from(&self, p: [f64; 3], degrees: f32) -> [f64; 3] {
        match *self {
            Side::Angle(g) => seen_from(g, degrees),
            Side::Strip {
                across,
                centre,
                half_width,
            } => {
                let off = centre - (across[0] * p[0] + across[1] * p[1]);
                let t = STRIP_HALF_ANGLE.to_radians().tan() * (off.abs() / half_width).min(1.0);
                let (s, c) = t.atan().sin_cos();
                let k = off.signum() * s;
                [across[0] * k, across[1] * k, c]
            }
        }
    }
}

impl Sides {
    /// Adds the points `picked` of `b` (nothing where it lacks source IDs).
    pub fn add(&mut self, b: &PointBatch, picked: &[u32]) {
        let Some(ids) = &b.point_source_id else {
            return;
        };
        let angles = b.scan_angle.as_deref();
        for &i in picked {
            let i = i as usize;
            let id = ids[i] as usize;
            if self.lines.len() <= id {
                self.lines.resize(id + 1, None);
            }
            let p = b.positions[i];
            let l = self.lines[id].get_or_insert(Line {
                origin: [p[0], p[1]],
                ..Line::default()
            });
            let a = angles.map_or(0.0, |a| a[i] as f64);
            let (x, y) = (p[0] - l.origin[0], p[1] - l.origin[1]);
            l.n += 1.0;
            l.a += a;
            l.aa += a * a;
            l.x += x;
            l.y += y;
            l.xa += x * a;
            l.ya += y * a;
            l.xx += x * x;
            l.yy += y * y;
            l.xy += x * y;
        }
    }

    /// Adds another pass's sums (points of other inputs or threads).
    pub fn merge(&mut self, other: &Sides) {
        for (id, l) in other.lines.iter().enumerate() {
            let Some(o) = l else { continue };
            if self.lines.len() <= id {
                self.lines.resize(id + 1, None);
            }
            match &mut self.lines[id] {
                None => self.lines[id] = Some(*o),
                Some(m) => {
                    // Move `o`'s sums to `m`'s origin: x' = x + d.
                    let d = [o.origin[0] - m.origin[0], o.origin[1] - m.origin[1]];
                    m.n += o.n;
                    m.a += o.a;
                    m.aa += o.aa;
                    m.x += o.x + d[0] * o.n;
                    m.y += o.y + d[1] * o.n;
                    m.xa += o.xa + d[0] * o.a;
                    m.ya += o.ya + d[1] * o.a;
                    m.xx += o.xx + 2.0 * d[0] * o.x + d[0] * d[0] * o.n;
                    m.yy += o.yy + 2.0 * d[1] * o.y + d[1] * d[1] * o.n;
                    m.xy += o.xy + d[0] * o.y + d[1] * o.x + d[0] * d[1] * o.n;
                }
            }
        }
    }

    /// Per source ID, where its points were seen from: by scan angle where the angles explain
    /// where the line's points lie, else by the strip they form; `None` unless the lines with
    /// neither (a scan from one place; a line's end cut off by a tile's edge) hold at most
    /// [`MAX_UNKNOWN`] of the points: otherwise no normal gets a sign from here.
    pub fn directions(&self) -> Option<Vec<Option<Side>>> {
        let mut out = Vec::with_capacity(self.lines.len());
        let (mut all, mut unknown) = (0.0, 0.0);
        for l in &self.lines {
            let side = l
                .as_ref()
                .and_then(|l| l.by_angle().or_else(|| l.by_strip()));
            if let Some(l) = l {
                all += l.n;
                if side.is_none() {
                    unknown += l.n;
                }
            }
            out.push(side);
        }
        (all > 0.0 && unknown <= MAX_UNKNOWN * all).then_some(out)
    }
}

impl Line {
    /// The side by the fit of position on scan angle, where it explains the points.
    fn by_angle(&self) -> Option<Side> {
        let l = self;
        {
            let n = l.n;
            let var_a = l.aa / n - (l.a / n).powi(2);
            if n < 2.0 || var_a < MIN_ANGLE_VARIANCE {
                return None;
            }
            let cov = [l.xa / n - l.x / n * l.a / n, l.ya / n - l.y / n * l.a / n];
            let g = [cov[0] / var_a, cov[1] / var_a];
            let len = g[0].hypot(g[1]);
            if len <= 0.0 || !len.is_finite() {
                return None;
            }
            let u = [g[0] / len, g[1] / len];
            // The position across (along u) against the angle: how well the fit explains it.
            let (mx, my) = (l.x / n, l.y / n);
            let cxx = l.xx / n - mx * mx;
            let cyy = l.yy / n - my * my;
            let cxy = l.xy / n - mx * my;
            let var_s = u[0] * u[0] * cxx + 2.0 * u[0] * u[1] * cxy + u[1] * u[1] * cyy;
            let cov_s = u[0] * cov[0] + u[1] * cov[1];
            if var_s <= 0.0 || cov_s / (var_s * var_a).sqrt() < MIN_CORRELATION {
                return None;
            }
            Some(Side::Angle(u))
        }
    }

    /// The side by the strip the points form: its long axis the track, its middle the line
    /// flown over.
    fn by_strip(&self) -> Option<Side> {
        let n = self.n;
        if n < 2.0 {
            return None;
        }
        let (mx, my) = (self.x / n, self.y / n);
        let cxx = self.xx / n - mx * mx;
        let cyy = self.yy / n - my * my;
        let cxy = self.xy / n - mx * my;
        // The 2x2 covariance's eigenvalues; the smaller one's axis is across the track.
        let half = (cxx + cyy) / 2.0;
        let r = (((cxx - cyy) / 2.0).powi(2) + cxy * cxy).sqrt();
        let (along, across_var) = (half + r, half - r);
        if across_var <= 0.0 || along < MIN_ELONGATION * across_var {
            return None;
        }
        let axis = if cxy.abs() > 1e-12 {
            [along - cyy, cxy]
        } else if cxx >= cyy {
            [1.0, 0.0]
        } else {
            [0.0, 1.0]
        };
        let len = axis[0].hypot(axis[1]);
        let across = [-axis[1] / len, axis[0] / len];
        // Points spread evenly across a swath: its half width is sqrt(3) standard deviations.
        let centre = across[0] * (mx + self.origin[0]) + across[1] * (my + self.origin[1]);
        let half_width = (3.0 * across_var).sqrt();
        (half_width >= MIN_HALF_WIDTH).then_some(Side::Strip {
            across,
            centre,
            half_width,
        })
    }
}

/// The direction a point at scan angle `degrees` was seen from, its line's direction `g`.
pub fn seen_from(g: [f64; 2], degrees: f32) -> [f64; 3] {
    let (s, c) = (degrees as f64).to_radians().sin_cos();
    [-g[0] * s, -g[1] * s, c]
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_core::{Attribute, Schema};

    /// A line flown along `heading` at 1,000 m, points at angles -30..30 on flat ground;
    /// `sign`: the file's convention (+1: positive angles to the right of the track).
    fn line(id: u16, heading: [f64; 2], sign: f64, start: [f64; 2]) -> PointBatch {
        let schema = Schema::new(vec![Attribute::ScanAngle, Attribute::PointSourceId]);
        let mut b = PointBatch::with_schema(&schema, 0);
        let right = [heading[1], -heading[0]];
        for k in 0..200 {
            for a in -30..=30 {
                let along = k as f64 * 20.0;
                let across = 1000.0 * (a as f64).to_radians().tan() * sign;
                b.positions.push([
                    start[0] + heading[0] * along + right[0] * across,
                    start[1] + heading[1] * along + right[1] * across,
                    0.0,
                ]);
                b.scan_angle.as_mut().unwrap().push(a as f32);
                b.point_source_id.as_mut().unwrap().push(id);
            }
        }
        b
    }

    #[test]
    fn the_scanner_side_is_found_whatever_the_convention() {
        let mut s = Sides::default();
        let north = line(1, [0.0, 1.0], 1.0, [5e6, 4e6]);
        let east = line(2, [1.0, 0.0], -1.0, [5e6 + 300.0, 4e6]);
        // In two passes (threads, inputs), merged.
        let half: Vec<u32> = (0..north.len() as u32 / 2).collect();
        let rest: Vec<u32> = (north.len() as u32 / 2..north.len() as u32).collect();
        let mut other = Sides::default();
        s.add(&north, &half);
        other.add(&north, &rest);
        other.add(&east, &(0..east.len() as u32).collect::<Vec<_>>());
        s.merge(&other);
        let d = s.directions().unwrap();
        let angle = |s: Option<Side>| match s {
            Some(Side::Angle(g)) => g,
            other => panic!("{other:?}"),
        };
        // Flying north, positive angles to the right: they move points east.
        let g1 = angle(d[1]);
        assert!((g1[0] - 1.0).abs() < 1e-6 && g1[1].abs() < 1e-6, "{g1:?}");
        // Flying east, positive angles to the left (north).
        let g2 = angle(d[2]);
        assert!(g2[0].abs() < 1e-6 && (g2[1] - 1.0).abs() < 1e-6, "{g2:?}");
        // A point 20 degrees east of the northbound track was seen from the west, above.
        let v = seen_from(g1, 20.0);
        assert!(v[0] < -0.3 && v[1].abs() < 1e-9 && v[2] > 0.9, "{v:?}");
        // A wall facing west is on the seen side: its normal (-1, 0, 0) faces the scanner.
        assert!(-v[0] > 0.0);
    }

    #[test]
    fn without_scan_angles_the_strip_says_the_side() {
        // A 4 km line flown north over a swath 1,155 m wide, its angles not recorded.
        let mut b = line(1, [0.0, 1.0], 1.0, [5e6, 4e6]);
        b.scan_angle.as_mut().unwrap().fill(0.0);
        let mut s = Sides::default();
        s.add(&b, &(0..b.len() as u32).collect::<Vec<_>>());
        let side = s.directions().unwrap()[1].unwrap();
        let Side::Strip { half_width, .. } = side else {
            panic!("{side:?}")
        };
        assert!((half_width - 577.0).abs() < 60.0, "{half_width}");
        // A point 500 m east of the track was seen from the west, above: about 17 degrees.
        let v = side.seen_from([5e6 + 500.0, 4e6 + 100.0, 0.0], 0.0);
        assert!(
            v[0] < -0.2 && v[0] > -0.4 && v[1].abs() < 1e-6 && v[2] > 0.9,
            "{v:?}"
        );
        let w = side.seen_from([5e6 - 500.0, 4e6 + 100.0, 0.0], 0.0);
        assert!(w[0] > 0.2, "{w:?}");
    }

    #[test]
    fn a_line_neither_swept_nor_a_strip_leaves_the_sides_unknown() {
        let mut s = Sides::default();
        let b = line(1, [0.0, 1.0], 1.0, [0.0, 0.0]);
        s.add(&b, &(0..b.len() as u32).collect::<Vec<_>>());
        assert!(s.directions().is_some());
        // A scan from one place: every angle 0, its points a square around it.
        let schema = Schema::new(vec![Attribute::ScanAngle, Attribute::PointSourceId]);
        let mut t = PointBatch::with_schema(&schema, 0);
        for k in 0..10_000 {
            t.positions.push([(k % 100) as f64, (k / 100) as f64, 0.0]);
            t.scan_angle.as_mut().unwrap().push(0.0);
            t.point_source_id.as_mut().unwrap().push(3);
        }
        s.add(&t, &(0..t.len() as u32).collect::<Vec<_>>());
        assert!(s.directions().is_none());
        // A few such points among many whose side is known: those are used, these turned up.
        let mut s = Sides::default();
        for _ in 0..2 {
            s.add(&b, &(0..b.len() as u32).collect::<Vec<_>>());
        }
        s.add(&t, &(0..200).collect::<Vec<_>>());
        let d = s.directions().unwrap();
        assert!(d[1].is_some() && d[3].is_none());
        // No points with source IDs: nothing to go on.
        assert!(Sides::default().directions().is_none());
    }
}
