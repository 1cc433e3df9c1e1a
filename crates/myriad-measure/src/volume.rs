//! Volumes over a polygon: the surface's height on a grid of square cells (the mean elevation
//! of the points in each cell; a cell without points takes its neighbours' mean), less a base:
//! a plane fitted (least squares) to the points on the polygon's rim, a given elevation, or an
//! earlier dataset's surface on the same grid. Material above the base is fill, below it cut.

use crate::{Bound, Polygon, Region, read_region};
use myriad_format::Dataset;

/// The surface volumes are measured down to.
#[derive(Clone, Copy)]
pub enum Base<'a> {
    /// A plane fitted to the points within a band of the polygon's edges.
    Rim,
    /// A horizontal plane at this elevation.
    Elevation(f64),
    /// Another dataset's surface (an earlier survey of the same ground).
    Surface(&'a Dataset),
    /// The dataset's own ground: its points of classes 2 and 11 (as its edits leave them, so
    /// after `myriad ground`), the cells without one filled from around them.
    Ground,
}

/// At most this many grid cells (about 1.2 GB of sums per surface).
pub const MAX_CELLS: u64 = 100_000_000;

#[derive(Debug, Clone, Default, PartialEq)]
pub struct Volume {
    /// The grid's cell size.
    pub cell: f64,
    /// The polygon's area, and that of the cells whose centres are inside it.
    pub area: f64,
    pub cells: u64,
    /// Cells inside the polygon without a point of the surface (filled from their neighbours),
    /// and of the base surface where it is a dataset.
    pub empty_cells: u64,
    pub base_empty_cells: u64,
    /// Material above the base (fill) and below it (cut), both positive.
    pub fill: f64,
    pub cut: f64,
    /// The rim's plane `z = a + b (x - x0) + c (y - y0)` about the polygon's first vertex
    /// (`[a, b, c]`), and how many points it was fitted to.
    pub plane: Option<[f64; 3]>,
    pub rim_points: u64,
    /// Points of the surface inside the polygon.
    pub points: u64,
    pub nodes_read: u64,
}

impl Volume {
    /// Fill less cut.
    pub fn net(&self) -> f64 {
        self.fill - self.cut
    }

    /// The base's height at `(x, y)`: `elevation` where the base was one, else the rim's plane
    /// (about `polygon`'s first vertex); `None` for a dataset's surface.
    pub fn base_at(
        &self,
        polygon: &Polygon,
        elevation: Option<f64>,
        x: f64,
        y: f64,
    ) -> Option<f64> {
        if let Some(z) = elevation {
            return Some(z);
        }
        let [a, b, c] = self.plane?;
        let o = polygon.vertices()[0];
        Some(a + b * (x - o[0]) + c * (y - o[1]))
    }

    /// The figures on one line, lengths in `units` (as the viewers show them).
    pub fn summary(&self, units: &str) -> String {
        let u = units;
        format!(
            "fill {:.3} {u}³, cut {:.3} {u}³, net {:.3} {u}³ over {:.3} {u}², {} cells of {} {u} ({} without points)",
            self.fill,
            self.cut,
            self.net(),
            self.area,
            self.cells,
            self.cell,
            self.empty_cells
        )
    }
}

/// The grid over the polygon's box.
struct Grid {
    origin: [f64; 2],
    cell: f64,
    nx: usize,
    ny: usize,
    sum: Vec<f64>,
    count: Vec<u32>,
}

impl Grid {
    fn new(polygon: &Polygon, cell: f64) -> Result<Grid, String> {
        let (lo, hi) = polygon.plan_bounds();
        // Counted in floating point: a tiny cell (1e-20) makes more cells than any integer.
        let nx = ((hi[0] - lo[0]) / cell).ceil().max(1.0);
        let ny = ((hi[1] - lo[1]) / cell).ceil().max(1.0);
        if !(nx * ny <= MAX_CELLS as f64) {
            return Err(format!(
                "--cell {cell}: {:.3e} cells over the polygon, more than {MAX_CELLS}: a larger cell",
                nx * ny
            ));
        }
        let (nx, ny) = (nx as u64, ny as u64);
        let n = (nx * ny) as usize;
        Ok(Grid {
            origin: lo,
            cell,
            nx: nx as usize,
            ny: ny as usize,
            sum: vec![0.0; n],
            count: vec![0; n],
        })
    }

    fn index(&self, x: f64, y: f64) -> Option<usize> {
        let i = ((x - self.origin[0]) / self.cell).floor();
        let j = ((y - self.origin[1]) / self.cell).floor();
        (i >= 0.0 && j >= 0.0 && (i as usize) < self.nx && (j as usize) < self.ny)
            .then(|| j as usize * self.nx + i as usize)
    }

    fn centre(&self, k: usize) -> (f64, f64) {
        (
            self.origin[0] + ((k % self.nx) as f64 + 0.5) * self.cell,
            self.origin[1] + ((k / self.nx) as f64 + 0.5) * self.cell,
        )
    }

    /// Each cell's height (`None` where neither it nor any cell near it has a point), and how
    /// many of the cells in `inside` had no point of their own.
    fn heights(&self, inside: &[bool]) -> (Vec<Option<f64>>, u64) {
        let mut h: Vec<Option<f64>> = (0..self.sum.len())
            .map(|k| (self.count[k] > 0).then(|| self.sum[k] / self.count[k] as f64))
            .collect();
        let empty = (0..h.len())
            .filter(|&k| inside[k] && h[k].is_none())
            .count() as u64;
        // Holes filled from the cells around them, ring after ring (at most 32).
        for _ in 0..32 {
            let holes: Vec<usize> = (0..h.len())
                .filter(|&k| inside[k] && h[k].is_none())
                .collect();
            if holes.is_empty() {
                break;
            }
            let filled: Vec<(usize, f64)> = holes
                .iter()
                .filter_map(|&k| {
                    let (i, j) = ((k % self.nx) as i64, (k / self.nx) as i64);
                    let mut s = (0.0, 0);
                    for dj in -1..=1 {
                        for di in -1..=1 {
                            let (a, b) = (i + di, j + dj);
                            let inside = a >= 0
                                && b >= 0
                                && (a as usize) < self.nx
                                && (b as usize) < self.ny;
                            if inside && let Some(v) = h[b as usize * self.nx + a as usize] {
                                s = (s.0 + v, s.1 + 1);
                            }
                        }
                    }
                    (s.1 > 0).then(|| (k, s.0 / s.1 as f64))
                })
                .collect();
            if filled.is_empty() {
                break;
            }
            for (k, v) in filled {
                h[k] = Some(v);
            }
        }
        (h, empty)
    }
}

/// A cell size about twice the points' spacing in the polygon, from the nodes' counts (no page
/// read): 1, 2 or 5 times a power of ten.
pub fn default_cell(ds: &Dataset, polygon: &Polygon) -> f64 {
    let (lo, hi) = polygon.plan_bounds();
    let (nodes, _) = ds.nodes_where(&|cube| polygon.meets(cube));
    let mut points = 0.0;
    for n in nodes.iter().filter(|n| !n.aggregate()) {
        let c = n.bounds_in(&ds.meta.root);
        let ox = (c.max[0].min(hi[0]) - c.min[0].max(lo[0])).max(0.0);
        let oy = (c.max[1].min(hi[1]) - c.min[1].max(lo[1])).max(0.0);
        let a = (c.max[0] - c.min[0]) * (c.max[1] - c.min[1]);
        if a > 0.0 {
            points += n.points as f64 * ox * oy / a;
        }
    }
    let area = ((hi[0] - lo[0]) * (hi[1] - lo[1])).max(1e-12);
    if points < 1.0 {
        return crate::profile::nice_step(((hi[0] - lo[0]).max(hi[1] - lo[1]) / 100.0).max(0.01));
    }
    let spacing = (area / points).sqrt();
    crate::profile::nice_step(2.0 * spacing)
}

/// The grid a volume was measured on, for a view to draw: each cell's surface and base
/// heights, `None` outside the polygon (or where either is unknown).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Cells {
    pub origin: [f64; 2],
    pub cell: f64,
    pub nx: usize,
    pub ny: usize,
    pub heights: Vec<Option<(f64, f64)>>,
}

impl Cells {
    /// The centre of cell `k` (row after row from the origin).
    pub fn centre(&self, k: usize) -> (f64, f64) {
        (
            self.origin[0] + ((k % self.nx) as f64 + 0.5) * self.cell,
            self.origin[1] + ((k / self.nx) as f64 + 0.5) * self.cell,
        )
    }
}

/// A square of cells as a view draws it: its centre, half its side, the surface's height (of
/// its first cell) and whether that is above the base (fill) or below it (cut).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Block {
    pub centre: [f64; 2],
    pub half: f64,
    pub top: f64,
    pub fill: bool,
}

impl Cells {
    /// The cells inside the polygon in squares of `step` x `step` cells, `step` as small as
    /// keeps them to about `max`.
    pub fn blocks(&self, max: usize) -> Vec<Block> {
        let inside = self.heights.iter().filter(|h| h.is_some()).count().max(1);
        let step = ((inside as f64 / max.max(1) as f64).sqrt().ceil() as usize).max(1);
        let half = 0.5 * self.cell * step as f64;
        let mut out = Vec::new();
        for j in (0..self.ny).step_by(step) {
            for i in (0..self.nx).step_by(step) {
                let k = j * self.nx + i;
                let Some((top, under)) = self.heights[k] else {
                    continue;
                };
                let (x, y) = self.centre(k);
                out.push(Block {
                    centre: [x - 0.5 * self.cell + half, y - 0.5 * self.cell + half],
                    half,
                    top,
                    fill: top >= under,
                });
            }
        }
        out
    }
}

/// At most this many cells are kept for drawing ([`volume_and_cells`]).
pub const MAX_DRAWN_CELLS: u64 = 4_000_000;

/// The volume of `ds` over `polygon` above `base`, on cells of `cell` (or [`default_cell`]).
pub fn volume(
    ds: &Dataset,
    polygon: &Polygon,
    base: Base<'_>,
    cell: Option<f64>,
    filter: &Bound,
) -> Result<Volume, String> {
    measure(ds, polygon, base, cell, filter, false).map(|(v, _)| v)
}

/// [`volume`] and the grid it was measured on (none past [`MAX_DRAWN_CELLS`]).
pub fn volume_and_cells(
    ds: &Dataset,
    polygon: &Polygon,
    base: Base<'_>,
    cell: Option<f64>,
    filter: &Bound,
) -> Result<(Volume, Option<Cells>), String> {
    measure(ds, polygon, base, cell, filter, true)
}

fn measure(
    ds: &Dataset,
    polygon: &Polygon,
    base: Base<'_>,
    cell: Option<f64>,
    filter: &Bound,
    keep: bool,
) -> Result<(Volume, Option<Cells>), String> {
    let cell = match cell {
        Some(c) if c.is_finite() && c > 0.0 => c,
        Some(c) => return Err(format!("--cell {c}: a cell size must be positive")),
        None => default_cell(ds, polygon),
    };
    let mut grid = Grid::new(polygon, cell)?;
    let inside: Vec<bool> = (0..grid.sum.len())
        .map(|k| {
            let (x, y) = grid.centre(k);
            polygon.contains_xy(x, y)
        })
        .collect();
    let mut v = Volume {
        cell,
        area: polygon.area(),
        cells: inside.iter().filter(|&&i| i).count() as u64,
        ..Volume::default()
    };
    if v.cells == 0 {
        return Err(format!(
            "--cell {cell}: no cell's centre is inside the polygon: a smaller cell"
        ));
    }
    // The rim: points within a cell of the edges, on both sides.
    let band = cell;
    let x0 = polygon.vertices()[0];
    let mut rim = [0.0f64; 9]; // n, x, y, z, xx, xy, yy, xz, yz
    let want_rim = matches!(base, Base::Rim);
    let region = polygon.with_margin(if want_rim { band } else { 0.0 });
    let read = read_region(ds, &region, filter, |b| {
        for p in &b.positions {
            if polygon.contains_xy(p[0], p[1]) {
                if let Some(k) = grid.index(p[0], p[1]) {
                    grid.sum[k] += p[2];
                    grid.count[k] += 1;
                }
                v.points += 1;
            }
            if want_rim && region.near_edge(p[0], p[1]) {
                let (x, y, z) = (p[0] - x0[0], p[1] - x0[1], p[2]);
                for (s, t) in rim
                    .iter_mut()
                    .zip([1.0, x, y, z, x * x, x * y, y * y, x * z, y * z])
                {
                    *s += t;
                }
            }
        }
    })?;
    v.nodes_read = read.nodes;
    if v.points == 0 {
        return Err("the polygon holds no point of the dataset (is it in the dataset's coordinates? `myriad info` gives its bounds)".into());
    }
    let (top, empty) = grid.heights(&inside);
    v.empty_cells = empty;
    let base_at: Box<dyn Fn(usize) -> Option<f64>> = match base {
        Base::Elevation(z) => Box::new(move |_| Some(z)),
        Base::Rim => {
            let [n, sx, sy, sz, xx, xy, yy, xz, yz] = rim;
            v.rim_points = n as u64;
            if n < 3.0 {
                return Err(format!(
                    "--base rim: only {} point{} on the polygon's rim: a larger polygon, or --base Z",
                    n as u64,
                    if n == 1.0 { "" } else { "s" }
                ));
            }
            let plane = solve3([[n, sx, sy], [sx, xx, xy], [sy, xy, yy]], [sz, xz, yz])
                .ok_or("--base rim: the rim's points are on one line: --base Z instead")?;
            v.plane = Some(plane);
            let g = &grid;
            Box::new(move |k| {
                let (x, y) = g.centre(k);
                Some(plane[0] + plane[1] * (x - x0[0]) + plane[2] * (y - x0[1]))
            })
        }
        Base::Surface(_) | Base::Ground => {
            let (source, ground);
            let (from, which) = match base {
                Base::Surface(earlier) => (earlier, filter),
                _ => {
                    ground = crate::Filter::parse(Some("2,11"), &[])
                        .and_then(|f| f.bind(&ds.meta.schema))
                        .map_err(|m| format!("--base ground: {m}"))?;
                    source = ds;
                    (source, &ground)
                }
            };
            let mut g2 = Grid::new(polygon, cell)?;
            read_region(from, polygon, which, |b| {
                for p in &b.positions {
                    if let Some(k) = g2.index(p[0], p[1]) {
                        g2.sum[k] += p[2];
                        g2.count[k] += 1;
                    }
                }
            })?;
            let (h, empty) = g2.heights(&inside);
            v.base_empty_cells = empty;
            let what = match base {
                Base::Ground => {
                    "the ground points (classes 2 and 11; `myriad ground` finds them) do"
                }
                _ => "the earlier survey does",
            };
            uncovered_base(&h, &inside, v.cells, what)?;
            Box::new(move |k| h[k])
        }
    };
    let area = cell * cell;
    let keep = keep && (top.len() as u64) <= MAX_DRAWN_CELLS;
    let mut cells = keep.then(|| Cells {
        origin: grid.origin,
        cell,
        nx: grid.nx,
        ny: grid.ny,
        heights: vec![None; top.len()],
    });
    for k in (0..top.len()).filter(|&k| inside[k]) {
        if let (Some(t), Some(b)) = (top[k], base_at(k)) {
            let d = (t - b) * area;
            if d > 0.0 {
                v.fill += d;
            } else {
                v.cut -= d;
            }
            if let Some(c) = &mut cells {
                c.heights[k] = Some((t, b));
            }
        }
    }
    Ok((v, cells))
}

/// An earlier survey that leaves cells of the polygon without a height even from their
/// neighbours is no base for them: an error naming the share it does not cover, rather than a
/// volume that leaves those cells out (0 where it covers nothing).
fn uncovered_base(
    base: &[Option<f64>],
    inside: &[bool],
    cells: u64,
    what: &str,
) -> Result<(), String> {
    let uncovered = (base.iter().zip(inside))
        .filter(|(h, inside)| **inside && h.is_none())
        .count() as u64;
    if uncovered == 0 {
        return Ok(());
    }
    Err(format!(
        "--base: {what} not cover {:.1} % of the polygon ({uncovered} of its {cells} cells have no height there, even from their neighbours): a polygon within both surveys",
        100.0 * uncovered as f64 / cells.max(1) as f64
    ))
}

/// Solves a 3x3 system by Cramer's rule; `None` when it is singular.
fn solve3(m: [[f64; 3]; 3], r: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(m);
    let scale = m
        .iter()
        .flatten()
        .map(|v| v.abs())
        .fold(0.0, f64::max)
        .powi(3);
    if d.abs() <= 1e-12 * scale {
        return None;
    }
    let mut out = [0.0; 3];
    for c in 0..3 {
        let mut mc = m;
        for row in 0..3 {
            mc[row][c] = r[row];
        }
        out[c] = det(mc) / d;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_solve() {
        // z = 2 + 3x - y at (0,0), (1,0), (0,1), (1,1).
        let pts = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
        let mut s = [0.0; 9];
        for p in pts {
            let (x, y) = (p[0], p[1]);
            let z = 2.0 + 3.0 * x - y;
            for (a, t) in s
                .iter_mut()
                .zip([1.0, x, y, z, x * x, x * y, y * y, x * z, y * z])
            {
                *a += t;
            }
        }
        let [n, sx, sy, sz, xx, xy, yy, xz, yz] = s;
        let p = solve3([[n, sx, sy], [sx, xx, xy], [sy, xy, yy]], [sz, xz, yz]).unwrap();
        assert!(
            (p[0] - 2.0).abs() < 1e-12 && (p[1] - 3.0).abs() < 1e-12 && (p[2] + 1.0).abs() < 1e-12
        );
        assert!(
            solve3(
                [[1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [0.0, 0.0, 1.0]],
                [1.0; 3]
            )
            .is_none()
        );
    }

    /// A cell of 1e-20 over a 100 m polygon makes more cells than a u64 holds: refused, no
    /// overflow.
    #[test]
    fn a_tiny_cell_is_refused_not_overflowed() {
        let square = [[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]];
        let polygon = Polygon::new(&square).unwrap();
        for cell in [1e-20, 1e-200, f64::MIN_POSITIVE] {
            let e = Grid::new(&polygon, cell).err().expect("refused");
            assert!(e.contains("more than 100000000"), "{e}");
        }
        assert!(Grid::new(&polygon, 0.5).is_ok());
    }

    /// A base that covers part of the polygon is named with the share it misses; one that
    /// covers it all (holes filled from neighbours) passes.
    #[test]
    fn a_base_that_does_not_cover_the_polygon_is_an_error() {
        let inside = [true, true, true, true, false];
        let all = [Some(1.0), Some(2.0), Some(3.0), Some(4.0), None];
        assert_eq!(
            uncovered_base(&all, &inside, 4, "the earlier survey does"),
            Ok(())
        );
        let none = [None; 5];
        let e = uncovered_base(&none, &inside, 4, "the earlier survey does").unwrap_err();
        assert!(
            e.contains("100.0 %") && e.contains("4 of its 4 cells"),
            "{e}"
        );
        let half = [Some(1.0), None, Some(3.0), None, None];
        let e = uncovered_base(&half, &inside, 4, "the earlier survey does").unwrap_err();
        assert!(
            e.contains("50.0 %") && e.contains("2 of its 4 cells"),
            "{e}"
        );
    }
}
