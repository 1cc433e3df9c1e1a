//! A simple polygon in plan (x, y): the footprint of a volume or a clip. Its edges are indexed
//! ([`crate::edges`]): a point's test and a node's cost about the same for 4 vertices or 100 k.

use crate::Region;
use crate::corridor::{segment_to_rect, segments_meet, to_segment};
use crate::edges::{Cells, Segment, Strips};
use myriad_core::Aabb;

#[derive(Debug, Clone)]
pub struct Polygon {
    /// Vertices, not closed (the last joins the first).
    pts: Vec<[f64; 2]>,
    /// The edges by band of y (the even-odd rule) and by cell (boxes, crossings).
    strips: Strips,
    cells: Cells,
    plan: ([f64; 2], [f64; 2]),
}

impl PartialEq for Polygon {
    fn eq(&self, o: &Polygon) -> bool {
        self.pts == o.pts
    }
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
        let n = v.len();
        let segments: Vec<Segment> = (0..n).map(|i| (v[i], v[(i + 1) % n])).collect();
        let mut plan = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for q in &v {
            for a in 0..2 {
                plan.0[a] = plan.0[a].min(q[a]);
                plan.1[a] = plan.1[a].max(q[a]);
            }
        }
        let p = Polygon {
            strips: Strips::new(&segments),
            cells: Cells::new(&segments, 0.0),
            pts: v,
            plan,
        };
        // Edges that meet share a cell; the first crossing (in the edges' order) is named.
        let mut first: Option<(usize, usize)> = None;
        p.cells.each_cell(|edges| {
            for (k, &i) in edges.iter().enumerate() {
                for &j in &edges[k + 1..] {
                    let (i, j) = (i as usize, j as usize);
                    // Neighbouring edges share a vertex; only others may not meet.
                    if j == i + 1 || (i == 0 && j == n - 1) || first.is_some_and(|f| f <= (i, j)) {
                        continue;
                    }
                    let (a, b) = segments[i];
                    let (c, d) = segments[j];
                    if segments_meet(a, b, c, d) {
                        first = Some((i, j));
                    }
                }
            }
        });
        if let Some((i, j)) = first {
            let (a, c) = (segments[i].0, segments[j].0);
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
        let area = p.area();
        if !area.is_finite() {
            return Err("--polygon: coordinates too large (an area beyond f64's range)".into());
        }
        if area <= 0.0 {
            return Err("--polygon: its points are on one line (no area)".into());
        }
        Ok(p)
    }

    pub fn vertices(&self) -> &[[f64; 2]] {
        &self.pts
    }

    fn edges(&self) -> impl Iterator<Item = ([f64; 2], [f64; 2])> + '_ {
        let n = self.pts.len();
        (0..n).map(move |i| self.edge(i as u32))
    }

    fn edge(&self, i: u32) -> Segment {
        let i = i as usize;
        (self.pts[i], self.pts[(i + 1) % self.pts.len()])
    }

    /// Its area (shoelace).
    pub fn area(&self) -> f64 {
        self.edges()
            .map(|(a, b)| a[0] * b[1] - b[0] * a[1])
            .sum::<f64>()
            .abs()
            / 2.0
    }

    /// Whether (x, y) is inside (even-odd rule; only the edges of its band of y are tried).
    pub fn contains_xy(&self, x: f64, y: f64) -> bool {
        let mut inside = false;
        for &i in self.strips.at(y) {
            let (a, b) = self.edge(i);
            if (a[1] > y) != (b[1] > y) && x < a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0]) {
                inside = !inside;
            }
        }
        inside
    }

    /// The plan box holding it.
    pub fn plan_bounds(&self) -> ([f64; 2], [f64; 2]) {
        self.plan
    }

    /// The polygon grown by `margin` as a region: the points inside it or within `margin` of
    /// its edges (indexed for that reach).
    pub fn with_margin(&self, margin: f64) -> Margin<'_> {
        let margin = margin.max(0.0);
        let cells = (margin > 0.0).then(|| {
            let segments: Vec<Segment> = self.edges().collect();
            Cells::new(&segments, margin)
        });
        Margin {
            polygon: self,
            margin,
            cells,
        }
    }
}

/// A polygon and a band around it.
#[derive(Debug, Clone)]
pub struct Margin<'a> {
    polygon: &'a Polygon,
    margin: f64,
    /// The edges by cell for the margin's reach (the polygon's own for none).
    cells: Option<Cells>,
}

impl Margin<'_> {
    fn cells(&self) -> &Cells {
        self.cells.as_ref().unwrap_or(&self.polygon.cells)
    }

    /// Whether (x, y) lies within the margin of an edge, inside or outside.
    pub fn near_edge(&self, x: f64, y: f64) -> bool {
        self.cells().near(x, y).iter().any(|&i| {
            let (a, b) = self.polygon.edge(i);
            to_segment([x, y], a, b).0 <= self.margin
        })
    }
}

impl Region for Margin<'_> {
    fn meets(&self, b: &Aabb) -> bool {
        let (lo, hi) = ([b.min[0], b.min[1]], [b.max[0], b.max[1]]);
        let (plo, phi) = self.polygon.plan_bounds();
        let m = self.margin;
        if lo[0] > phi[0] + m || lo[1] > phi[1] + m || hi[0] < plo[0] - m || hi[1] < plo[1] - m {
            return false;
        }
        if lo[0] <= plo[0] && lo[1] <= plo[1] && hi[0] >= phi[0] && hi[1] >= phi[1] {
            return true;
        }
        // The box is inside the polygon, or an edge comes within the margin of it.
        self.polygon.contains_xy(lo[0], lo[1])
            || self.cells().any_in_box(lo, hi, |i| {
                let (a, c) = self.polygon.edge(i);
                segment_to_rect(a, c, lo, hi) <= m
            })
    }
    fn contains(&self, p: [f64; 3]) -> bool {
        self.polygon.contains_xy(p[0], p[1]) || (self.margin > 0.0 && self.near_edge(p[0], p[1]))
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
        assert!(sq.with_margin(2.0).near_edge(5.0, 2.0));
        assert!(!sq.with_margin(1.9).near_edge(5.0, 2.0));
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
        assert!(Polygon::new(&[[0.0, 0.0], [1e300, 0.0], [0.0, 1e300]]).is_err());
        // A vertex at the top of the polygon's span of y, which rounding put past its band.
        let tall = Polygon::new(&[[21.0, 0.0], [0.0, -8.8888208288e22], [30010.0, 11.0]]).unwrap();
        assert!(tall.contains_xy(21.0, 0.0));
    }

    /// A wavy ring of `n` vertices about the origin.
    pub(crate) fn wavy(n: usize, r: f64) -> Vec<[f64; 2]> {
        (0..n)
            .map(|i| {
                let t = i as f64 / n as f64 * std::f64::consts::TAU;
                let rr = r * (1.0 + 0.2 * (t * 23.0).sin());
                [rr * t.cos(), rr * t.sin()]
            })
            .collect()
    }

    fn scan_contains(pts: &[[f64; 2]], x: f64, y: f64) -> bool {
        let n = pts.len();
        let mut inside = false;
        for i in 0..n {
            let (a, b) = (pts[i], pts[(i + 1) % n]);
            if (a[1] > y) != (b[1] > y) && x < a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0]) {
                inside = !inside;
            }
        }
        inside
    }

    #[test]
    fn many_vertices_answer_as_a_scan_of_every_edge() {
        let pts = wavy(100_000, 1000.0);
        let t = std::time::Instant::now();
        let poly = Polygon::new(&pts).unwrap();
        // The crossing check is no longer vertices squared (minutes at 100 k).
        assert!(t.elapsed().as_secs_f64() < 20.0, "{:?}", t.elapsed());
        let margin = poly.with_margin(3.0);
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2600.0 - 1300.0
        };
        let (mut inside, mut near) = (0, 0);
        for _ in 0..600 {
            let (x, y) = (next(), next());
            let c = scan_contains(&pts, x, y);
            assert_eq!(poly.contains_xy(x, y), c, "{x},{y}");
            inside += c as usize;
            let d = (0..pts.len())
                .map(|i| to_segment([x, y], pts[i], pts[(i + 1) % pts.len()]).0)
                .fold(f64::INFINITY, f64::min);
            assert_eq!(margin.near_edge(x, y), d <= 3.0, "{x},{y}: {d}");
            near += (d <= 3.0) as usize;
            let (w, h) = (next().abs() / 20.0, next().abs() / 20.0);
            let b = Aabb::new([x, y, 0.0], [x + w, y + h, 1.0]);
            let meets = scan_contains(&pts, x, y)
                || (0..pts.len()).any(|i| {
                    segment_to_rect(pts[i], pts[(i + 1) % pts.len()], [x, y], [x + w, y + h]) <= 3.0
                });
            assert_eq!(margin.meets(&b), meets, "{b:?}");
        }
        assert!(
            inside > 100 && near > 0,
            "{inside} inside, {near} near an edge"
        );
        // A crossing among 100 k edges is still found, and named.
        let mut bad = pts.clone();
        bad.swap(40_000, 40_001);
        let e = Polygon::new(&bad).unwrap_err();
        assert!(e.contains("crosses itself (edge 40000 "), "{e}");
    }
}
