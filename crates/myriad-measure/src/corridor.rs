//! A cross-section's corridor: a polyline in plan (x, y) and a width; a point's station is its
//! distance along the line (to the foot of the perpendicular on the nearest segment) and its
//! signed offset across it (left of the direction of travel positive).

use crate::Region;
use crate::edges::{Cells, Segment};
use myriad_core::Aabb;

/// Parses `X1,Y1,X2,Y2[,X3,Y3...]`.
pub fn parse_xy_list(s: &str, what: &str, at_least: usize) -> Result<Vec<[f64; 2]>, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("{what} \"{s}\": \"{}\" is not a number", t.trim()))
        })
        .collect::<Result<_, _>>()?;
    if !v.len().is_multiple_of(2) {
        return Err(format!(
            "{what} \"{s}\": an odd count of numbers ({}); expected X,Y pairs",
            v.len()
        ));
    }
    if v.len() / 2 < at_least {
        return Err(format!(
            "{what} \"{s}\": {} point{}; at least {at_least} needed",
            v.len() / 2,
            if v.len() == 2 { "" } else { "s" }
        ));
    }
    Ok(v.chunks(2).map(|c| [c[0], c[1]]).collect())
}

#[derive(Debug, Clone)]
pub struct Corridor {
    line: Vec<[f64; 2]>,
    half: f64,
    /// Distance along the line at each vertex.
    along: Vec<f64>,
    /// The segments by the cells they come within half the width of ([`crate::edges`]): a
    /// point tries only its cell's, whatever the line's vertex count.
    cells: Cells,
}

impl PartialEq for Corridor {
    fn eq(&self, o: &Corridor) -> bool {
        self.line == o.line && self.half == o.half
    }
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}
fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}
fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// Distance from `p` to the segment `a`-`b`, the parameter of the foot (0..1) and the signed
/// perpendicular distance (left positive).
pub(crate) fn to_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> (f64, f64, f64) {
    let d = sub(b, a);
    let len2 = dot(d, d);
    let t = (dot(sub(p, a), d) / len2).clamp(0.0, 1.0);
    let foot = [a[0] + t * d[0], a[1] + t * d[1]];
    let dist = dot(sub(p, foot), sub(p, foot)).sqrt();
    let side = cross(d, sub(p, a)) / len2.sqrt();
    (dist, t, side)
}

/// Whether segments `a`-`b` and `c`-`d` cross or touch.
pub(crate) fn segments_meet(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let o = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| cross(sub(q, p), sub(r, p));
    let (d1, d2, d3, d4) = (o(c, d, a), o(c, d, b), o(a, b, c), o(a, b, d));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    let on = |p: [f64; 2], q: [f64; 2], r: [f64; 2], o: f64| {
        o == 0.0
            && r[0] >= p[0].min(q[0])
            && r[0] <= p[0].max(q[0])
            && r[1] >= p[1].min(q[1])
            && r[1] <= p[1].max(q[1])
    };
    on(c, d, a, d1) || on(c, d, b, d2) || on(a, b, c, d3) || on(a, b, d, d4)
}

/// Distance from segment `a`-`b` to the rectangle `lo`..`hi` (0 where they meet).
pub(crate) fn segment_to_rect(a: [f64; 2], b: [f64; 2], lo: [f64; 2], hi: [f64; 2]) -> f64 {
    let inside = |p: [f64; 2]| p[0] >= lo[0] && p[0] <= hi[0] && p[1] >= lo[1] && p[1] <= hi[1];
    if inside(a) || inside(b) {
        return 0.0;
    }
    let corners = [lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]];
    for k in 0..4 {
        if segments_meet(a, b, corners[k], corners[(k + 1) % 4]) {
            return 0.0;
        }
    }
    let to_rect = |p: [f64; 2]| {
        let dx = (lo[0] - p[0]).max(p[0] - hi[0]).max(0.0);
        let dy = (lo[1] - p[1]).max(p[1] - hi[1]).max(0.0);
        (dx * dx + dy * dy).sqrt()
    };
    let ends = to_rect(a).min(to_rect(b));
    corners
        .iter()
        .map(|&c| to_segment(c, a, b).0)
        .fold(ends, f64::min)
}

impl Corridor {
    /// The corridor of `width` around `line` (at least two vertices; repeated vertices are
    /// dropped).
    pub fn new(line: &[[f64; 2]], width: f64) -> Result<Corridor, String> {
        if !(width.is_finite() && width > 0.0) {
            return Err(format!(
                "--width {width}: a corridor needs a positive width"
            ));
        }
        let mut v: Vec<[f64; 2]> = Vec::with_capacity(line.len());
        for &p in line {
            if v.last() != Some(&p) {
                v.push(p);
            }
        }
        if v.len() < 2 {
            return Err("--line: the line has no length (its points are all the same)".into());
        }
        let mut along = vec![0.0];
        for w in v.windows(2) {
            let d = sub(w[1], w[0]);
            along.push(along.last().expect("one") + dot(d, d).sqrt());
        }
        // Coordinates so large that a segment's squared length overflows (found by fuzzing:
        // stations of NaN).
        if !along.last().is_some_and(|l| l.is_finite()) {
            return Err("--line: coordinates too large (a length beyond 1e150)".into());
        }
        let segments: Vec<Segment> = v.windows(2).map(|w| (w[0], w[1])).collect();
        Ok(Corridor {
            cells: Cells::new(&segments, width / 2.0),
            line: v,
            half: width / 2.0,
            along,
        })
    }

    pub fn line(&self) -> &[[f64; 2]] {
        &self.line
    }

    pub fn width(&self) -> f64 {
        2.0 * self.half
    }

    pub fn length(&self) -> f64 {
        *self.along.last().expect("two vertices")
    }

    /// Distance along at vertex `i`.
    pub fn along_at(&self, i: usize) -> f64 {
        self.along[i]
    }

    /// Where (x, y) lies: (distance along, signed offset across) on its nearest segment, or
    /// `None` outside the corridor (farther than half the width from the line).
    pub fn station(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let p = [x, y];
        let mut best: Option<(f64, f64, f64)> = None;
        for &i in self.cells.near(x, y) {
            let i = i as usize;
            let (dist, t, side) = to_segment(p, self.line[i], self.line[i + 1]);
            if dist <= self.half && best.is_none_or(|b| dist < b.0) {
                let len = self.along[i + 1] - self.along[i];
                // Its offset is its distance from the segment (beyond a segment's end, from the
                // joint), on the side it lies: the same number the corridor was tested with
                // (the cross product's own rounding, at coordinates of 1e29, put a point 5 %
                // outside the corridor it was kept in; found by fuzzing).
                let across = dist.copysign(side);
                best = Some((dist, self.along[i] + t * len, across));
            }
        }
        best.map(|(_, a, c)| (a, c))
    }

    /// The plan box holding the corridor.
    pub fn plan_bounds(&self) -> ([f64; 2], [f64; 2]) {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for p in &self.line {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a] - self.half);
                hi[a] = hi[a].max(p[a] + self.half);
            }
        }
        (lo, hi)
    }
}

impl Region for Corridor {
    fn meets(&self, b: &Aabb) -> bool {
        let (lo, hi) = ([b.min[0], b.min[1]], [b.max[0], b.max[1]]);
        let (plo, phi) = self.plan_bounds();
        if lo[0] <= plo[0] && lo[1] <= plo[1] && hi[0] >= phi[0] && hi[1] >= phi[1] {
            return true;
        }
        self.cells.any_in_box(lo, hi, |i| {
            let i = i as usize;
            segment_to_rect(self.line[i], self.line[i + 1], lo, hi) <= self.half
        })
    }
    fn contains(&self, p: [f64; 3]) -> bool {
        self.station(p[0], p[1]).is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stations_along_an_l() {
        let c = Corridor::new(&[[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]], 2.0).unwrap();
        assert_eq!(c.length(), 20.0);
        assert_eq!(c.station(5.0, 0.5), Some((5.0, 0.5)));
        assert_eq!(c.station(5.0, -0.5), Some((5.0, -0.5)));
        // On the second leg, going north: east of it is to the right.
        assert_eq!(c.station(10.5, 4.0), Some((14.0, -0.5)));
        assert_eq!(c.station(5.0, 1.5), None);
        assert_eq!(c.station(-0.5, 0.0).map(|s| s.0), Some(0.0));
        assert!(c.meets(&Aabb::new([4.0, 0.9, 0.0], [6.0, 3.0, 1.0])));
        assert!(!c.meets(&Aabb::new([4.0, 1.1, 0.0], [6.0, 3.0, 1.0])));
        assert!(c.meets(&Aabb::new([-5.0, -5.0, 0.0], [50.0, 50.0, 1.0])));
        assert!(Corridor::new(&[[1.0, 1.0], [1.0, 1.0]], 2.0).is_err());
        assert!(Corridor::new(&[[0.0, 0.0], [1.0, 1.0]], 0.0).is_err());
        assert!(Corridor::new(&[[0.0, 0.0], [11.0, 1e160], [0.0, 10.0]], 2.0).is_err());
    }

    #[test]
    fn xy_lists() {
        assert_eq!(
            parse_xy_list("1,2, 3,4", "--line", 2).unwrap(),
            vec![[1.0, 2.0], [3.0, 4.0]]
        );
        assert!(
            parse_xy_list("1,2,3", "--line", 2)
                .unwrap_err()
                .contains("odd")
        );
        assert!(
            parse_xy_list("1,2", "--line", 2)
                .unwrap_err()
                .contains("at least 2")
        );
        assert!(
            parse_xy_list("1,x", "--line", 1)
                .unwrap_err()
                .contains("\"x\"")
        );
    }

    #[test]
    fn a_long_line_answers_as_a_scan_of_every_segment() {
        // A road of 6,000 vertices winding east.
        let line: Vec<[f64; 2]> = (0..6000)
            .map(|i| {
                let x = i as f64 * 0.5;
                [x, 20.0 * (x / 37.0).sin() + 3.0 * (x / 3.0).cos()]
            })
            .collect();
        let c = Corridor::new(&line, 4.0).unwrap();
        let scan = |x: f64, y: f64| {
            let mut best: Option<(f64, f64, f64)> = None;
            for (i, w) in line.windows(2).enumerate() {
                let (dist, t, side) = to_segment([x, y], w[0], w[1]);
                if dist <= 2.0 && best.is_none_or(|b| dist < b.0) {
                    let across = dist.copysign(side);
                    best = Some((
                        dist,
                        c.along_at(i) + t * (c.along_at(i + 1) - c.along_at(i)),
                        across,
                    ));
                }
            }
            best.map(|(_, a, s)| (a, s))
        };
        let mut state = 3u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut inside = 0;
        for _ in 0..5000 {
            let x = next() * 3000.0;
            let y = (x / 37.0).sin() * 20.0 + (next() - 0.5) * 14.0;
            let s = scan(x, y);
            assert_eq!(c.station(x, y), s, "{x},{y}");
            inside += s.is_some() as usize;
            let b = Aabb::new([x, y, 0.0], [x + next() * 5.0, y + next() * 5.0, 1.0]);
            let meets = line.windows(2).any(|w| {
                segment_to_rect(w[0], w[1], [b.min[0], b.min[1]], [b.max[0], b.max[1]]) <= 2.0
            });
            assert_eq!(c.meets(&b), meets, "{b:?}");
        }
        assert!(inside > 500, "{inside}");
    }
}
