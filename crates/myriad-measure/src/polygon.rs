//! A simple polygon in plan (x, y): the footprint of a volume or a clip.

use crate::Region;
use crate::corridor::{segment_to_rect, segments_meet};
use myriad_core::Aabb;

#[derive(Debug, Clone, PartialEq)]
pub struct Polygon {
    /// Vertices, not closed (the last joins the first).
    pts: Vec<[f64; 2]>,
}

impl Polygon {
    /// A polygon of these vertices (a repeated closing vertex is dropped): at least three, with
    /// an area, and no two edges crossing.
    pub fn new(pts: &[[f64; 2]]) -> Result<Polygon, String> {
        let mut v: Vec<[f64; 2]> = Vec::with_capacity(pts.len());
        for &p in pts {
            if v.last() != Some(&p) {
                v.push(p);
            }
        }
        if v.len() > 1 && v.first() == v.last() {
            v.pop();
        }
        if v.len() < 3 {
            return Err(format!(
                "--polygon: {} distinct point{}; a polygon needs at least 3",
                v.len(),
                if v.len() == 1 { "" } else { "s" }
            ));
        }
        let p = Polygon { pts: v };
        let n = p.pts.len();
        for i in 0..n {
            for j in i + 1..n {
                // Neighbouring edges share a vertex; only others may not meet.
                if j == i + 1 || (i == 0 && j == n - 1) {
                    continue;
                }
                let (a, b) = (p.pts[i], p.pts[(i + 1) % n]);
                let (c, d) = (p.pts[j], p.pts[(j + 1) % n]);
                if segments_meet(a, b, c, d) {
                    return Err(format!(
                        "--polygon: it crosses itself (edge {} from {},{} meets edge {} from {},{})",
                        i + 1,
                        a[0],
                        a[1],
                        j + 1,
                        c[0],
                        c[1]
                    ));
                }
            }
        }
        if p.area() <= 0.0 {
            return Err("--polygon: its points are on one line (no area)".into());
        }
        Ok(p)
    }

    pub fn vertices(&self) -> &[[f64; 2]] {
        &self.pts
    }

    fn edges(&self) -> impl Iterator<Item = ([f64; 2], [f64; 2])> + '_ {
        let n = self.pts.len();
        (0..n).map(move |i| (self.pts[i], self.pts[(i + 1) % n]))
    }

    /// Its area (shoelace).
    pub fn area(&self) -> f64 {
        self.edges()
            .map(|(a, b)| a[0] * b[1] - b[0] * a[1])
            .sum::<f64>()
            .abs()
            / 2.0
    }

    /// Whether (x, y) is inside (even-odd rule).
    pub fn contains_xy(&self, x: f64, y: f64) -> bool {
        let mut inside = false;
        for (a, b) in self.edges() {
            if (a[1] > y) != (b[1] > y) && x < a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0]) {
                inside = !inside;
            }
        }
        inside
    }

    /// Distance from (x, y) to the nearest edge.
    pub fn to_boundary(&self, x: f64, y: f64) -> f64 {
        self.edges()
            .map(|(a, b)| segment_to_rect(a, b, [x, y], [x, y]))
            .fold(f64::INFINITY, f64::min)
    }

    /// The plan box holding it.
    pub fn plan_bounds(&self) -> ([f64; 2], [f64; 2]) {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for p in &self.pts {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        (lo, hi)
    }

    /// The polygon grown by `margin` as a region: the points inside it or within `margin` of
    /// its edges.
    pub fn with_margin(&self, margin: f64) -> Margin<'_> {
        Margin {
            polygon: self,
            margin,
        }
    }
}

/// A polygon and a band around it.
#[derive(Debug, Clone)]
pub struct Margin<'a> {
    polygon: &'a Polygon,
    margin: f64,
}

impl Region for Margin<'_> {
    fn meets(&self, b: &Aabb) -> bool {
        let (lo, hi) = ([b.min[0], b.min[1]], [b.max[0], b.max[1]]);
        let (plo, phi) = self.polygon.plan_bounds();
        if lo[0] > phi[0] + self.margin
            || lo[1] > phi[1] + self.margin
            || hi[0] < plo[0] - self.margin
            || hi[1] < plo[1] - self.margin
        {
            return false;
        }
        // The box is inside the polygon, or an edge comes within the margin of it.
        self.polygon.contains_xy(lo[0], lo[1])
            || self
                .polygon
                .edges()
                .any(|(a, b)| segment_to_rect(a, b, lo, hi) <= self.margin)
    }
    fn contains(&self, p: [f64; 3]) -> bool {
        self.polygon.contains_xy(p[0], p[1]) || self.polygon.to_boundary(p[0], p[1]) <= self.margin
    }
}

impl Region for Polygon {
    fn meets(&self, b: &Aabb) -> bool {
        self.with_margin(0.0).meets(b)
    }
    fn contains(&self, p: [f64; 3]) -> bool {
        self.contains_xy(p[0], p[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_and_bow_tie() {
        let sq = Polygon::new(&[
            [0.0, 0.0],
            [10.0, 0.0],
            [10.0, 10.0],
            [0.0, 10.0],
            [0.0, 0.0],
        ])
        .unwrap();
        assert_eq!(sq.area(), 100.0);
        assert!(sq.contains_xy(5.0, 5.0) && !sq.contains_xy(11.0, 5.0));
        assert_eq!(sq.to_boundary(5.0, 2.0), 2.0);
        assert!(sq.meets(&Aabb::new([2.0, 2.0, 0.0], [3.0, 3.0, 1.0])));
        assert!(sq.meets(&Aabb::new([-5.0, -5.0, 0.0], [50.0, 50.0, 1.0])));
        assert!(!sq.meets(&Aabb::new([11.0, 2.0, 0.0], [13.0, 3.0, 1.0])));
        assert!(
            sq.with_margin(1.5)
                .meets(&Aabb::new([11.0, 2.0, 0.0], [13.0, 3.0, 1.0]))
        );
        let e = Polygon::new(&[[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]]).unwrap_err();
        assert!(e.contains("crosses itself"), "{e}");
        assert!(Polygon::new(&[[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]).is_err());
        assert!(Polygon::new(&[[0.0, 0.0], [1.0, 1.0]]).is_err());
    }
}
