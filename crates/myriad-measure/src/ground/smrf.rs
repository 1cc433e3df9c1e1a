//! The simple morphological filter (SMRF: Pingel, Clarke and McBride 2013, "An improved simple
//! morphological filter for the terrain classification of airborne LIDAR data") on one grid of
//! lowest points: low outliers taken out, empty cells filled from their neighbours, openings of
//! growing windows flagging the cells that stand above the terrain, and the terrain made again
//! from the cells left.
//!
//! Two choices make a grid cut into tiles give, in each tile's core, exactly what the whole grid
//! gives (`myriad ground` works in tiles with overlap, and so shows no seam):
//! - the windows are squares, so the opening by a window of radius k of the opening by radius
//!   k - 1 is the opening by radius k (a square of radius k is a square of radius k - 1 grown by
//!   one cell): each opening is made from the filled grid directly, and reaches 2k cells;
//! - empty cells are filled by rounds that each give a cell the mean of its filled neighbours,
//!   at most [`Params::fill`] rounds: a cell's value reaches no further than that.
//!
//! A cell's terrain so depends only on the cells within [`margin`] of it.

/// The filter's parameters, in cells and in the grid's units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Params {
    /// The cell's side.
    pub cell: f64,
    /// The terrain's steepest slope (rise over run): how much higher than its opening a cell
    /// may be, per cell of the window's radius.
    pub slope: f64,
    /// The largest window's radius, in cells (the widest building, halved).
    pub window: usize,
    /// Rounds of filling empty cells (how far a terrain reaches from the cells that have one).
    pub fill: usize,
    /// How far below its neighbours' lowest point a cell's is a low outlier.
    pub low: f64,
}

/// How many cells around a tile's core a tile needs so that its core is as the whole grid's.
pub fn margin(p: &Params) -> usize {
    // Low outliers (a closing: 2), the first filling, the openings (2 x window), the second
    // filling, and the cell a point's bilinear terrain reads beyond its own.
    2 + p.fill + 2 * p.window + p.fill + 1
}

/// A grid of `nx` x `ny` cells, row by row; NaN: no value.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    pub nx: usize,
    pub ny: usize,
    pub z: Vec<f32>,
}

impl Grid {
    pub fn empty(nx: usize, ny: usize) -> Grid {
        Grid {
            nx,
            ny,
            z: vec![f32::NAN; nx * ny],
        }
    }
}

/// The terrain of a grid of lowest points: low outliers and the cells standing above the terrain
/// left out, the rest filled in (NaN where no cell with a terrain is within `fill` rounds).
/// Also the cells found to be low outliers.
pub fn terrain(zmin: &Grid, p: &Params) -> (Grid, Vec<bool>) {
    let (nx, ny) = (zmin.nx, zmin.ny);
    // Low outliers: cells far below the closing of their 3 x 3 neighbourhood.
    let closed = erode(&dilate(&zmin.z, nx, ny, 1), nx, ny, 1);
    let low: Vec<bool> = (zmin.z.iter().zip(&closed))
        .map(|(&z, &c)| (c - z) as f64 > p.low)
        .collect();
    let mut base = zmin.clone();
    for (z, &l) in base.z.iter_mut().zip(&low) {
        if l {
            *z = f32::NAN;
        }
    }
    let mut filled = base.clone();
    fill(&mut filled, p.fill);
    // Openings of growing windows: a cell rising more than the slope allows over the last
    // opening is an object.
    let mut object = vec![false; nx * ny];
    let mut last = filled.z.clone();
    for k in 1..=p.window {
        let opened = dilate(&erode(&filled.z, nx, ny, k), nx, ny, k);
        let dh = (p.slope * k as f64 * p.cell) as f32;
        for i in 0..nx * ny {
            if last[i] - opened[i] > dh {
                object[i] = true;
            }
        }
        last = opened;
    }
    for (z, &o) in base.z.iter_mut().zip(&object) {
        if o {
            *z = f32::NAN;
        }
    }
    fill(&mut base, p.fill);
    (base, low)
}

/// Fills empty cells by rounds: each gives every empty cell with a filled neighbour (of eight)
/// the mean of those neighbours, as they were before the round.
pub fn fill(g: &mut Grid, rounds: usize) {
    let (nx, ny) = (g.nx, g.ny);
    let mut todo: Vec<usize> = (0..nx * ny).filter(|&i| g.z[i].is_nan()).collect();
    for _ in 0..rounds {
        let mut set = Vec::new();
        todo.retain(|&i| {
            let (x, y) = (i % nx, i / nx);
            let (mut sum, mut n) = (0.0f64, 0u32);
            for yy in y.saturating_sub(1)..=(y + 1).min(ny - 1) {
                for xx in x.saturating_sub(1)..=(x + 1).min(nx - 1) {
                    let v = g.z[yy * nx + xx];
                    if !v.is_nan() {
                        sum += v as f64;
                        n += 1;
                    }
                }
            }
            if n == 0 {
                return true;
            }
            set.push((i, (sum / n as f64) as f32));
            false
        });
        if set.is_empty() {
            break;
        }
        for (i, v) in set {
            g.z[i] = v;
        }
    }
}

/// The lowest value within `k` cells (a square), empty cells left out (NaN where all are).
pub fn erode(z: &[f32], nx: usize, ny: usize, k: usize) -> Vec<f32> {
    square(z, nx, ny, k, true)
}

/// The highest value within `k` cells (a square), empty cells left out.
pub fn dilate(z: &[f32], nx: usize, ny: usize, k: usize) -> Vec<f32> {
    square(z, nx, ny, k, false)
}

/// A square window's extreme, as two passes of a sliding window (rows, then columns).
fn square(z: &[f32], nx: usize, ny: usize, k: usize, min: bool) -> Vec<f32> {
    // Empty cells never win: +inf for a minimum, -inf for a maximum, and back to NaN after.
    let none = if min {
        f32::INFINITY
    } else {
        f32::NEG_INFINITY
    };
    let mut a: Vec<f32> = z
        .iter()
        .map(|&v| if v.is_nan() { none } else { v })
        .collect();
    let mut line = Vec::new();
    let mut out = Vec::new();
    for y in 0..ny {
        line.clear();
        line.extend_from_slice(&a[y * nx..(y + 1) * nx]);
        slide(&line, k, min, &mut out);
        a[y * nx..(y + 1) * nx].copy_from_slice(&out);
    }
    for x in 0..nx {
        line.clear();
        line.extend((0..ny).map(|y| a[y * nx + x]));
        slide(&line, k, min, &mut out);
        for (y, &v) in out.iter().enumerate() {
            a[y * nx + x] = v;
        }
    }
    for v in &mut a {
        if *v == none {
            *v = f32::NAN;
        }
    }
    a
}

/// The extreme of `v[i - k ..= i + k]` (clipped to the line) for every `i`: a monotonic queue.
fn slide(v: &[f32], k: usize, min: bool, out: &mut Vec<f32>) {
    let n = v.len();
    out.clear();
    out.resize(n, 0.0);
    let better = |a: f32, b: f32| if min { a <= b } else { a >= b };
    let mut q = std::collections::VecDeque::with_capacity(2 * k + 2);
    let mut next = 0;
    for (i, o) in out.iter_mut().enumerate() {
        while next < n && next <= i + k {
            while q.back().is_some_and(|&j: &usize| better(v[next], v[j])) {
                q.pop_back();
            }
            q.push_back(next);
            next += 1;
        }
        while q.front().is_some_and(|&j| j + k < i) {
            q.pop_front();
        }
        *o = v[*q.front().expect("the window holds i")];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(z: &[f32], nx: usize, ny: usize, k: usize, min: bool) -> Vec<f32> {
        let mut out = vec![f32::NAN; nx * ny];
        for y in 0..ny {
            for x in 0..nx {
                let mut best = f32::NAN;
                for yy in y.saturating_sub(k)..=(y + k).min(ny - 1) {
                    for xx in x.saturating_sub(k)..=(x + k).min(nx - 1) {
                        let v = z[yy * nx + xx];
                        if !v.is_nan() && (best.is_nan() || (min && v < best) || (!min && v > best))
                        {
                            best = v;
                        }
                    }
                }
                out[y * nx + x] = best;
            }
        }
        out
    }

    #[test]
    fn square_windows_are_the_brute_force_ones() {
        let (nx, ny) = (13, 9);
        let mut seed = 7u32;
        let z: Vec<f32> = (0..nx * ny)
            .map(|_| {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                if seed.is_multiple_of(5) {
                    f32::NAN
                } else {
                    (seed >> 16) as f32 / 100.0
                }
            })
            .collect();
        for k in [1, 2, 4, 20] {
            let same = |a: &[f32], b: &[f32]| {
                a.iter()
                    .zip(b)
                    .all(|(x, y)| x == y || (x.is_nan() && y.is_nan()))
            };
            assert!(
                same(&erode(&z, nx, ny, k), &brute(&z, nx, ny, k, true)),
                "{k}"
            );
            assert!(
                same(&dilate(&z, nx, ny, k), &brute(&z, nx, ny, k, false)),
                "{k}"
            );
        }
    }

    #[test]
    fn a_building_on_a_slope_is_taken_out_and_a_pit_is_low() {
        // A plane rising 0.1 a cell, a 10 x 10 building 8 high, one cell 5 below.
        let (nx, ny) = (60, 40);
        let mut g = Grid::empty(nx, ny);
        for y in 0..ny {
            for x in 0..nx {
                g.z[y * nx + x] = 0.1 * x as f32;
            }
        }
        for y in 15..25 {
            for x in 20..30 {
                g.z[y * nx + x] += 8.0;
            }
        }
        g.z[5 * nx + 50] -= 5.0;
        let p = Params {
            cell: 1.0,
            slope: 0.15,
            window: 8,
            fill: 20,
            low: 1.0,
        };
        let (t, low) = terrain(&g, &p);
        assert!(low[5 * nx + 50] && low.iter().filter(|l| **l).count() == 1);
        for y in 0..ny {
            for x in 0..nx {
                // Off the building, the plane; under it, filled from around it (within a few
                // cells' rise), the building's 8 gone.
                let want = 0.1 * x as f32;
                let under = (20..30).contains(&x) && (15..25).contains(&y);
                let tol = if under { 0.6 } else { 1e-5 };
                assert!(
                    (t.z[y * nx + x] - want).abs() < tol,
                    "{x},{y}: {}",
                    t.z[y * nx + x]
                );
            }
        }
    }
}
