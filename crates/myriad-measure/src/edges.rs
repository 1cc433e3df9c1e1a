//! Spatial indexes of a polygon's or a polyline's segments in plan, so that a tool's cost grows
//! with points plus vertices rather than their product (a parcel or a road from a GIS has
//! thousands of vertices; a point cloud, millions of points).
//!
//! - [`Strips`]: the segments by the horizontal band of y they span, for the even-odd rule (a
//!   ray to +x from a point crosses only segments of its band);
//! - [`Cells`]: the segments by the square cells of a uniform grid they come within a reach of,
//!   for distances up to that reach (a corridor's half width, a volume's rim band) and for the
//!   segments meeting a box.
//!
//! Both are uniform grids written here rather than an R-tree crate: a lookup is an index
//! computation and one slice, with no tree descent per point, and both are built in one pass
//! (counting sort). Sizes follow the count of segments, capped, so that a 4-vertex polygon
//! costs what it did without an index.

/// A segment: its two ends.
pub type Segment = ([f64; 2], [f64; 2]);

/// Lists of segment indices per bucket, in ascending order within each (a query visits the
/// segments in their order, as a scan of all would).
#[derive(Debug, Clone, PartialEq)]
struct Buckets {
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Buckets {
    /// Buckets of `n` lists; `each(i, push)` calls `push(bucket)` for every bucket segment `i`
    /// goes in.
    fn build(n: usize, segments: usize, each: impl Fn(usize, &mut dyn FnMut(usize))) -> Buckets {
        let mut count = vec![0u32; n + 1];
        for i in 0..segments {
            each(i, &mut |b| count[b + 1] += 1);
        }
        for b in 0..n {
            count[b + 1] += count[b];
        }
        let mut fill = count.clone();
        let mut items = vec![0u32; count[n] as usize];
        for i in 0..segments {
            each(i, &mut |b| {
                items[fill[b] as usize] = i as u32;
                fill[b] += 1;
            });
        }
        Buckets {
            start: count,
            items,
        }
    }

    fn get(&self, b: usize) -> &[u32] {
        &self.items[self.start[b] as usize..self.start[b + 1] as usize]
    }
}

/// At most this many buckets per segment (and a few for a handful of segments): memory and
/// build time stay linear in the vertices.
const PER_SEGMENT: usize = 16;

/// The segments by horizontal band.
#[derive(Debug, Clone, PartialEq)]
pub struct Strips {
    y0: f64,
    y1: f64,
    /// Bands per unit of y.
    inv: f64,
    buckets: Buckets,
}

impl Strips {
    pub fn new(segments: &[Segment]) -> Strips {
        let (lo, hi) = segments
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), s| {
                (l.min(s.0[1]).min(s.1[1]), h.max(s.0[1]).max(s.1[1]))
            });
        let n = (segments.len() * 2).clamp(1, 1 << 22);
        let span = hi - lo;
        let inv = if span > 0.0 { n as f64 / span } else { 0.0 };
        let band = |y: f64| (((y - lo) * inv) as usize).min(n - 1);
        let buckets = Buckets::build(n, segments.len(), |i, push| {
            let (a, b) = segments[i];
            for k in band(a[1].min(b[1]))..=band(a[1].max(b[1])) {
                push(k);
            }
        });
        Strips {
            y0: lo,
            y1: hi,
            inv,
            buckets,
        }
    }

    /// The segments whose y-span may hold `y` (none where `y` is outside them all).
    pub fn at(&self, y: f64) -> &[u32] {
        // Outside the span by y itself, not by the band number: rounding put y = max a hair
        // past the last band, which the build had clamped into it (found by fuzzing).
        if !(y >= self.y0 && y <= self.y1) {
            return &[];
        }
        let n = self.buckets.start.len() - 1;
        let f = (y - self.y0) * self.inv;
        self.buckets.get((f.max(0.0) as usize).min(n - 1))
    }
}

/// The segments by grid cell, each in every cell it comes within `reach` of.
#[derive(Debug, Clone, PartialEq)]
pub struct Cells {
    lo: [f64; 2],
    size: f64,
    n: [usize; 2],
    reach: f64,
    buckets: Buckets,
}

impl Cells {
    pub fn new(segments: &[Segment], reach: f64) -> Cells {
        let reach = reach.max(0.0);
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        let mut length = 0.0;
        for &(a, b) in segments {
            for k in 0..2 {
                lo[k] = lo[k].min(a[k]).min(b[k]);
                hi[k] = hi[k].max(a[k]).max(b[k]);
            }
            length += ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        }
        for k in 0..2 {
            lo[k] -= reach;
            hi[k] += reach;
        }
        let w = [(hi[0] - lo[0]).max(0.0), (hi[1] - lo[1]).max(0.0)];
        // Cells no smaller than the mean segment or the reach (a segment then lies in a few),
        // and no more than PER_SEGMENT per segment in all.
        let cap = (segments.len() * PER_SEGMENT).max(16) as f64;
        let mean = length / segments.len().max(1) as f64;
        // sqrt(w0) sqrt(w1), not sqrt(w0 w1): extents of 1e300 must not overflow to a cell of
        // any size (a client's corridor reaches this: found by an audit).
        let mut size = mean.max(reach).max(w[0].sqrt() * w[1].sqrt() / cap.sqrt());
        for k in 0..2 {
            size = size.max(w[k] / cap);
        }
        let n = if size > 0.0 && size.is_finite() {
            [0, 1].map(|k| ((w[k] / size).min(cap) as usize + 1).max(1))
        } else {
            // Extents beyond f64 (or none): one cell.
            size = f64::MAX;
            [1, 1]
        };
        let mut c = Cells {
            lo,
            size,
            n,
            reach,
            buckets: Buckets {
                start: vec![0],
                items: Vec::new(),
            },
        };
        c.buckets = Buckets::build(n[0] * n[1], segments.len(), |i, push| {
            c.cells_near(segments[i], &mut |k| push(k))
        });
        c
    }

    fn column(&self, x: f64) -> usize {
        (((x - self.lo[0]) / self.size).max(0.0) as usize).min(self.n[0] - 1)
    }

    fn row(&self, y: f64) -> usize {
        (((y - self.lo[1]) / self.size).max(0.0) as usize).min(self.n[1] - 1)
    }

    /// Every cell that may hold a point within `reach` of the segment: row by row, the part of
    /// the segment within the row's band (widened by the reach), widened by the reach.
    fn cells_near(&self, (a, b): Segment, push: &mut dyn FnMut(usize)) {
        let r = self.reach;
        let (r0, r1) = (self.row(a[1].min(b[1]) - r), self.row(a[1].max(b[1]) + r));
        for row in r0..=r1 {
            let y0 = self.lo[1] + row as f64 * self.size - r;
            let y1 = y0 + self.size + 2.0 * r;
            let (xa, xb) = if a[1] == b[1] {
                (a[0].min(b[0]), a[0].max(b[0]))
            } else {
                let at = |y: f64| {
                    let t = ((y - a[1]) / (b[1] - a[1])).clamp(0.0, 1.0);
                    a[0] + t * (b[0] - a[0])
                };
                let (p, q) = (at(y0), at(y1));
                (p.min(q), p.max(q))
            };
            for col in self.column(xa - r)..=self.column(xb + r) {
                push(row * self.n[0] + col);
            }
        }
    }

    /// The segments that may come within the reach of (x, y) (none far outside them all).
    pub fn near(&self, x: f64, y: f64) -> &[u32] {
        let fx = (x - self.lo[0]) / self.size;
        let fy = (y - self.lo[1]) / self.size;
        if !(fx >= 0.0 && fy >= 0.0) || fx >= self.n[0] as f64 || fy >= self.n[1] as f64 {
            return &[];
        }
        self.buckets.get(fy as usize * self.n[0] + fx as usize)
    }

    /// Calls `f` with each cell's segments (cells without any skipped).
    pub fn each_cell(&self, mut f: impl FnMut(&[u32])) {
        for b in 0..self.buckets.start.len() - 1 {
            let s = self.buckets.get(b);
            if !s.is_empty() {
                f(s);
            }
        }
    }

    /// Whether `test` holds for a segment that may come within the reach of the box: the
    /// segments of every cell the box covers (a segment may be tested more than once).
    pub fn any_in_box(
        &self,
        lo: [f64; 2],
        hi: [f64; 2],
        mut test: impl FnMut(u32) -> bool,
    ) -> bool {
        if hi[0] < self.lo[0]
            || hi[1] < self.lo[1]
            || lo[0] > self.lo[0] + self.n[0] as f64 * self.size
            || lo[1] > self.lo[1] + self.n[1] as f64 * self.size
        {
            return false;
        }
        for row in self.row(lo[1])..=self.row(hi[1]) {
            for col in self.column(lo[0])..=self.column(hi[0]) {
                if self
                    .buckets
                    .get(row * self.n[0] + col)
                    .iter()
                    .any(|&i| test(i))
                {
                    return true;
                }
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring(n: usize, r: f64) -> Vec<Segment> {
        let p = |i: usize| {
            let t = i as f64 / n as f64 * std::f64::consts::TAU;
            // A wavy circle: not convex, so that bands and cells hold several segments.
            let rr = r * (1.0 + 0.2 * (t * 17.0).sin());
            [rr * t.cos(), rr * t.sin()]
        };
        (0..n).map(|i| (p(i), p((i + 1) % n))).collect()
    }

    fn dist(p: [f64; 2], (a, b): Segment) -> f64 {
        let d = [b[0] - a[0], b[1] - a[1]];
        let t = (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / (d[0] * d[0] + d[1] * d[1]))
            .clamp(0.0, 1.0);
        ((p[0] - a[0] - t * d[0]).powi(2) + (p[1] - a[1] - t * d[1]).powi(2)).sqrt()
    }

    #[test]
    fn buckets_hold_every_segment_a_scan_would_find() {
        for n in [3, 4, 50, 5000] {
            let segs = ring(n, 100.0);
            let strips = Strips::new(&segs);
            let reach = 1.5;
            let cells = Cells::new(&segs, reach);
            let mut state = 12345u64;
            for _ in 0..4000 {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let x = (state >> 11) as f64 / (1u64 << 53) as f64 * 260.0 - 130.0;
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let y = (state >> 11) as f64 / (1u64 << 53) as f64 * 260.0 - 130.0;
                let band = strips.at(y);
                for (i, s) in segs.iter().enumerate() {
                    let spans = s.0[1].min(s.1[1]) <= y && y <= s.0[1].max(s.1[1]);
                    if spans {
                        assert!(band.contains(&(i as u32)), "n {n}: band at {y} lacks {i}");
                    }
                    if dist([x, y], *s) <= reach {
                        assert!(
                            cells.near(x, y).contains(&(i as u32)),
                            "n {n}: cell at {x},{y} lacks {i}"
                        );
                    }
                }
                assert!(band.windows(2).all(|w| w[0] < w[1]));
            }
        }
    }

    #[test]
    fn sizes_stay_linear_in_the_segments() {
        let segs = ring(100_000, 1000.0);
        let strips = Strips::new(&segs);
        let cells = Cells::new(&segs, 2.0);
        assert!(
            strips.buckets.items.len() < 20 * segs.len(),
            "{}",
            strips.buckets.items.len()
        );
        assert!(
            cells.buckets.items.len() < 20 * segs.len(),
            "{}",
            cells.buckets.items.len()
        );
        assert!(cells.buckets.start.len() <= 4 * PER_SEGMENT * segs.len());
        // The grid spans the segments' box widened by the reach, once.
        assert!(
            cells.lo[0] >= -1200.0 - 2.0 && cells.lo[0] < -1000.0,
            "{:?}",
            cells.lo
        );
        // A cell near the ring holds a few segments, not all.
        let most = (0..cells.buckets.start.len() - 1)
            .map(|b| cells.buckets.get(b).len())
            .max();
        assert!(most.unwrap() < 200, "{most:?}");
        // A long thin sliver next to many short segments: the grid is still bounded.
        let mut s = ring(1000, 1.0);
        s.push(([0.0, 0.0], [1e6, 1.0]));
        let c = Cells::new(&s, 0.0);
        assert!(c.buckets.start.len() <= 4 * PER_SEGMENT * s.len());
        // Extents near f64's end: a few cells, not terabytes.
        for (seg, reach) in [
            (([0.0, 0.0], [1e300, 0.0]), 1e12),
            (([-1e308, -1e308], [1e308, 1e308]), 0.0),
            (([0.0, 0.0], [1e-300, 0.0]), 0.0),
        ] {
            let c = Cells::new(&[seg], reach);
            assert!(c.buckets.start.len() <= 4 * PER_SEGMENT + 1, "{seg:?}");
            assert_eq!(c.near(seg.0[0], seg.0[1]), &[0]);
        }
        assert!(c.buckets.items.len() <= 8 * PER_SEGMENT * s.len());
    }
}
