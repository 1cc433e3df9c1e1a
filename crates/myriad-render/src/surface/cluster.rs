//! Cluster, move and reduce (Schiffner et al. 2015, sections 3.1 and 3.2), on the CPU.
//!
//! Cells are found by sorting the points by cell key (a run of equal keys is a cell), so the
//! work is O(N log N) in the points and the memory O(N), whatever the grid's size; a neighbour
//! cell is found by binary search among the occupied keys.

use super::{Density, Grid, Normals, Surface};
use myriad_core::pca::Pca;
use myriad_lod::Camera;
use rayon::prelude::*;
use std::time::{Duration, Instant};

/// One occupied cell reduced to its representative, in eye coordinates (x right, y up, z the
/// depth).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    /// Column, row and depth layer in the grid.
    pub index: [u32; 3],
    pub count: u32,
    /// Mean position of the cell's points.
    pub mean: [f64; 3],
    /// Their bounding box along the eye axes.
    pub min: [f64; 3],
    pub max: [f64; 3],
    /// Unit normal towards the eye; None where none can be derived (fewer than three points
    /// for the tensor, no empty neighbour for the cells' method).
    pub normal: Option<[f64; 3]>,
    /// Mean colour of the points.
    pub colour: [u8; 4],
}

/// What clustering a set of points made, and what each step took.
#[derive(Debug, Clone, Default)]
pub struct Clustering {
    pub cells: Vec<Cell>,
    /// Per input point, its cell in `cells` after the move (u32::MAX: outside the grid).
    pub of_point: Vec<u32>,
    /// Points inside the grid, and those the move gave to a neighbour.
    pub inside: usize,
    pub moved: usize,
    pub cluster: Duration,
    pub moving: Duration,
    pub reduce: Duration,
}

const OUTSIDE: u64 = u64::MAX;

/// Occupied cells: point indices sorted by key, where each cell's run starts, the keys.
struct Runs {
    order: Vec<u32>,
    starts: Vec<u32>,
    keys: Vec<u64>,
}

impl Runs {
    fn of(keys: &[u64]) -> Runs {
        let mut pairs: Vec<(u64, u32)> = keys
            .par_iter()
            .enumerate()
            .filter(|(_, k)| **k != OUTSIDE)
            .map(|(i, &k)| (k, i as u32))
            .collect();
        pairs.par_sort_unstable();
        let mut starts = Vec::new();
        let mut run_keys = Vec::new();
        for (i, &(k, _)) in pairs.iter().enumerate() {
            if run_keys.last() != Some(&k) {
                starts.push(i as u32);
                run_keys.push(k);
            }
        }
        starts.push(pairs.len() as u32);
        Runs {
            order: pairs.into_iter().map(|(_, i)| i).collect(),
            starts,
            keys: run_keys,
        }
    }

    fn len(&self) -> usize {
        self.keys.len()
    }

    fn points(&self, cell: usize) -> &[u32] {
        &self.order[self.starts[cell] as usize..self.starts[cell + 1] as usize]
    }

    fn find(&self, key: u64) -> Option<usize> {
        self.keys.binary_search(&key).ok()
    }
}

/// Eye coordinates of world points, with the camera's basis computed once.
pub(crate) fn to_eye(camera: &Camera, points: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let (r, u, f) = camera.basis();
    let o = camera.position;
    points
        .par_iter()
        .map(|p| {
            let d = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
            let dot = |v: [f64; 3]| d[0] * v[0] + d[1] * v[1] + d[2] * v[2];
            [dot(r), dot(u), dot(f)]
        })
        .collect()
}

/// Equations 7 and 8: where, as a fraction of the half cell, the boundary between cell c and
/// its neighbour n lies seen from c. Unclamped (gamma 1) the boundary seen from c and from n is
/// one plane: f(c, n) + f(n, c) = 2 half cells, the distance between the centres; f = 1 (equal
/// densities) is the cell's own face, and the clamp to 1 - lb lets the outer tenth of each half
/// cell cross it. A denser neighbour pulls the boundary towards c's centre (down to lb); an
/// empty one pushes it out to 1 - lb.
pub fn weight(dens_c: f64, dens_n: f64, gamma: f64, lb: f64) -> f64 {
    let total = dens_c + dens_n;
    let f = if total > 0.0 {
        2.0 * dens_c / total
    } else {
        1.0
    };
    f.powf(gamma).clamp(lb, 1.0 - lb)
}

/// Equation 9: the cell a point at grid coordinates `g` (cell `c` = floor(g)) belongs to after
/// the move. Its offset from the cell's centre, per axis in half cells (-1 to 1: equation 6's
/// delta in the unit of equation 8's weight, 1 at the cell's face), is compared with the
/// boundary weight towards the neighbour on that side (in cells, as before December 4, a point
/// moved only for a neighbour three times as dense, and the move opened holes where the paper's
/// figure 9 shows it closing them: docs/guide/surfaces.md); `neighbours` 1 looks along the
/// largest offset only (equations 1-5), 3 along each axis (so a point may move diagonally).
pub fn moved_cell(
    g: [f64; 3],
    dims: [u32; 3],
    neighbours: u32,
    gamma: f64,
    lb: f64,
    density: &dyn Fn([u32; 3]) -> f64,
) -> [u32; 3] {
    let c = g.map(|v| v.floor().max(0.0) as u32);
    let d: [f64; 3] = std::array::from_fn(|a| 2.0 * (g[a] - (c[a] as f64 + 0.5)));
    let largest = (0..3)
        .max_by(|&a, &b| d[a].abs().total_cmp(&d[b].abs()))
        .expect("three axes");
    let dens_c = density(c);
    let mut out = c;
    for a in 0..3 {
        if neighbours == 0 || (neighbours == 1 && a != largest) {
            continue;
        }
        let step_up = d[a] >= 0.0;
        if (step_up && c[a] + 1 >= dims[a]) || (!step_up && c[a] == 0) {
            continue;
        }
        let mut n = c;
        n[a] = if step_up { c[a] + 1 } else { c[a] - 1 };
        if d[a].abs() > weight(dens_c, density(n), gamma, lb) {
            out[a] = n[a];
        }
    }
    out
}

/// Mean, eye-axis bounds, covariance and mean colour of some points.
struct Moments {
    mean: [f64; 3],
    min: [f64; 3],
    max: [f64; 3],
    covariance: [[f64; 3]; 3],
    colour: [u8; 4],
}

/// The point distribution tensor's weight of a point `d` (eye units) from its cell's mean, in a
/// cell of sides `e` (Schiffner et al. 2015 after Ritter and Benger: the tensor "includes distance
/// weighting functions"): a Gaussian of the distance in the cell's mean side, sigma half of it, so
/// that a cell's far points (another surface reaching into it, points moved in from a neighbour)
/// turn its normal less. As `tensor_weight` in cluster.wgsl.
pub fn tensor_weight(d: [f64; 3], e: [f64; 3]) -> f64 {
    let side2 = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]) / 3.0;
    let r2 = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) / side2.max(1e-300);
    (-r2 / (2.0 * TENSOR_SIGMA * TENSOR_SIGMA)).exp()
}

/// The tensor weight's sigma, in the cell's mean side.
pub const TENSOR_SIGMA: f64 = 0.5;

/// `extent`: the cell's sides, for the tensor's weights.
fn moments(eye: &[[f64; 3]], colours: &[[u8; 4]], points: &[u32], extent: [f64; 3]) -> Moments {
    let n = points.len().max(1) as f64;
    let mut mean = [0.0; 3];
    let mut min = [f64::INFINITY; 3];
    let mut max = [f64::NEG_INFINITY; 3];
    let mut rgba = [0u64; 4];
    for &i in points {
        let p = eye[i as usize];
        for a in 0..3 {
            mean[a] += p[a];
            min[a] = min[a].min(p[a]);
            max[a] = max[a].max(p[a]);
        }
        if let Some(c) = colours.get(i as usize) {
            for k in 0..4 {
                rgba[k] += c[k] as u64;
            }
        }
    }
    mean = mean.map(|v| v / n);
    let mut covariance = [[0.0; 3]; 3];
    for &i in points {
        let p = eye[i as usize];
        let d = [p[0] - mean[0], p[1] - mean[1], p[2] - mean[2]];
        let w = tensor_weight(d, extent);
        for r in 0..3 {
            for c in 0..3 {
                covariance[r][c] += w * d[r] * d[c] / n;
            }
        }
    }
    let k = points.len().max(1) as u64;
    Moments {
        mean,
        min,
        max,
        covariance,
        colour: rgba.map(|v| ((v + k / 2) / k) as u8),
    }
}

/// Planarity (λ2 - λ3) / λ1 of the point distribution tensor (0 below three points).
fn planarity(m: &Moments, count: usize) -> f64 {
    if count < 3 {
        return 0.0;
    }
    let [l1, l2, l3] = Pca::of_covariance(m.mean, m.covariance).eigenvalues;
    if l1 > 0.0 { (l2 - l3) / l1 } else { 0.0 }
}

/// Clusters `points` (world coordinates, with their colours) in `grid` seen by `camera`: the
/// cluster, move and reduce steps of Schiffner et al. 2015.
pub fn cluster(
    camera: &Camera,
    grid: &Grid,
    points: &[[f64; 3]],
    colours: &[[u8; 4]],
    s: &Surface,
) -> Clustering {
    let t = Instant::now();
    let dims = grid.dims();
    let eye = to_eye(camera, points);
    let coords: Vec<Option<[f64; 3]>> = points
        .par_iter()
        .zip(&eye)
        .map(|(&p, &e)| grid.coords(p, e))
        .collect();
    let key =
        |c: [u32; 3]| c[0] as u64 + dims[0] as u64 * (c[1] as u64 + dims[1] as u64 * c[2] as u64);
    let first: Vec<u64> = coords
        .par_iter()
        .map(|g| g.map_or(OUTSIDE, |g| key(g.map(|v| v.floor().max(0.0) as u32))))
        .collect();
    let inside = first.iter().filter(|&&k| k != OUTSIDE).count();
    let runs = Runs::of(&first);
    let index_of = |k: u64| {
        let x = (k % dims[0] as u64) as u32;
        let rest = k / dims[0] as u64;
        [
            x,
            (rest % dims[1] as u64) as u32,
            (rest / dims[1] as u64) as u32,
        ]
    };
    // A cell's sides at its centre's depth (the tensor's weights).
    let sides = |k: u64| grid.extent(grid.centre(camera, index_of(k))[2]);
    let density: Vec<f64> = (0..runs.len())
        .into_par_iter()
        .map(|c| {
            let p = runs.points(c);
            match s.density {
                Density::Count => p.len() as f64,
                Density::Planarity => {
                    planarity(&moments(&eye, &[], p, sides(runs.keys[c])), p.len())
                }
            }
        })
        .collect();
    let cluster_time = t.elapsed();

    let t = Instant::now();
    // Without a move the cells stay as they are: no second clustering.
    let (moved, runs) = if s.neighbours == 0 {
        (0, runs)
    } else {
        // Densities by cell key: a dense array where the grid is small enough (the frustum
        // grid's 1.1 M cells: 9 MB), else a binary search among the occupied cells.
        let cells = dims.iter().map(|&d| d as u64).product::<u64>();
        let dense: Option<Vec<f64>> = (cells <= 1 << 24).then(|| {
            let mut v = vec![0.0; cells as usize];
            for (k, d) in runs.keys.iter().zip(&density) {
                v[*k as usize] = *d;
            }
            v
        });
        let dens = |c: [u32; 3]| match &dense {
            Some(v) => v[key(c) as usize],
            None => runs.find(key(c)).map_or(0.0, |i| density[i]),
        };
        let keys: Vec<u64> = coords
            .par_iter()
            .map(|g| {
                g.map_or(OUTSIDE, |g| {
                    key(moved_cell(g, dims, s.neighbours, s.gamma, s.lb, &dens))
                })
            })
            .collect();
        let moved = keys.iter().zip(&first).filter(|(a, b)| a != b).count();
        drop(runs);
        (moved, Runs::of(&keys))
    };
    let moving = t.elapsed();

    let t = Instant::now();
    let mut cells: Vec<Cell> = (0..runs.len())
        .into_par_iter()
        .map(|c| {
            let p = runs.points(c);
            let m = moments(&eye, colours, p, sides(runs.keys[c]));
            let normal = match s.normals {
                Normals::Tensor if p.len() >= 3 => {
                    let pca = Pca::of_covariance(m.mean, m.covariance);
                    (pca.eigenvalues[0] > 0.0).then_some(pca.axes[2])
                }
                _ => None,
            };
            Cell {
                index: index_of(runs.keys[c]),
                count: p.len() as u32,
                mean: m.mean,
                min: m.min,
                max: m.max,
                normal,
                colour: m.colour,
            }
        })
        .collect();
    if s.normals == Normals::Cells {
        let normals: Vec<Option<[f64; 3]>> = cells
            .par_iter()
            .map(|c| {
                empty_neighbours_normal(grid, camera, c.index, &|n| runs.find(key(n)).is_some())
            })
            .collect();
        for (c, n) in cells.iter_mut().zip(normals) {
            c.normal = n;
        }
    }
    for c in &mut cells {
        // Towards the eye (at the origin of eye coordinates): Schiffner et al. 2015 favour normals
        // facing the observer.
        if let Some(n) = &mut c.normal
            && n[0] * c.mean[0] + n[1] * c.mean[1] + n[2] * c.mean[2] > 0.0
        {
            *n = n.map(|v| -v);
        }
    }
    let mut of_point = vec![u32::MAX; points.len()];
    for c in 0..runs.len() {
        for &i in runs.points(c) {
            of_point[i as usize] = c as u32;
        }
    }
    Clustering {
        cells,
        of_point,
        inside,
        moved,
        cluster: cluster_time,
        moving,
        reduce: t.elapsed(),
    }
}

/// The cells' normal (Schiffner et al. 2015, section 3.2): the sum of the directions to the empty
/// neighbours among the 26 (neighbours beyond the grid's sides are unknown, not empty), None when
/// there is none or they cancel. Summed in grid coordinates, where a cell is a unit cube (in eye
/// coordinates a frustum cell is several times deeper than wide, and the directions to its
/// nearer and farther layers would tilt every normal towards the eye), then carried into eye
/// coordinates as a normal (by the inverse transpose of the grid's local Jacobian).
fn empty_neighbours_normal(
    grid: &Grid,
    camera: &Camera,
    index: [u32; 3],
    occupied: &dyn Fn([u32; 3]) -> bool,
) -> Option<[f64; 3]> {
    let dims = grid.dims();
    let mut sum = [0.0; 3];
    for dz in -1i64..=1 {
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                if dx == 0 && dy == 0 && dz == 0 {
                    continue;
                }
                let d = [dx, dy, dz];
                let n: [i64; 3] = std::array::from_fn(|a| index[a] as i64 + d[a]);
                if (0..3).any(|a| n[a] < 0 || n[a] >= dims[a] as i64) {
                    continue;
                }
                if occupied(n.map(|v| v as u32)) {
                    continue;
                }
                let len = ((dx * dx + dy * dy + dz * dz) as f64).sqrt();
                for a in 0..3 {
                    sum[a] += d[a] as f64 / len;
                }
            }
        }
    }
    if sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2] < 1e-18 {
        return None;
    }
    let n = match grid {
        Grid::Frustum { .. } => {
            // Near the centre, one column is e[0] along eye x, one row -e[1] along eye y, one
            // layer e[2] along the line of sight (x/z and y/z of it sideways): solve
            // J^T n_eye = n_grid.
            let c = grid.centre(camera, index);
            let e = grid.extent(c[2]);
            let x = sum[0] / e[0];
            let y = -sum[1] / e[1];
            [x, y, sum[2] / e[2] - c[0] / c[2] * x - c[1] / c[2] * y]
        }
        Grid::Cubes { .. } => {
            let (r, u, f) = camera.basis();
            let dot = |v: [f64; 3]| sum[0] * v[0] + sum[1] * v[1] + sum[2] * v[2];
            [dot(r), dot(u), dot(f)]
        }
    };
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    Some(n.map(|v| v / len))
}
