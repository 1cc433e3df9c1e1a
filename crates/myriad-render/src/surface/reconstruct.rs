//! Reconstruct (Schiffner et al. 2015, section 3.3): one surface element per cell, from its mean,
//! its box and its normal, as polygons in eye coordinates turned into a world-coordinate [`Mesh`].

use super::{Cell, Clustering, Grid, Kind};
use myriad_core::Mesh;
use myriad_lod::Camera;
use rayon::prelude::*;

type V = [f64; 3];

fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn unit(a: V) -> V {
    let l = dot(a, a).sqrt();
    if l > 0.0 { a.map(|v| v / l) } else { a }
}

/// The cell's normal, or where it has none, facing the eye.
fn normal_of(c: &Cell) -> V {
    c.normal.unwrap_or_else(|| unit(c.mean.map(|v| -v)))
}

/// A cell's element as polygons (corners in order) with their normals, in eye coordinates.
fn polygons(camera: &Camera, grid: &Grid, c: &Cell, kind: Kind) -> Vec<(Vec<V>, V)> {
    match kind {
        Kind::Boxes => {
            let (lo, hi) = (c.min, c.max);
            let mut faces = Vec::with_capacity(6);
            for a in 0..3 {
                let (b, d) = ((a + 1) % 3, (a + 2) % 3);
                for (side, value) in [(-1.0, lo[a]), (1.0, hi[a])] {
                    let corner = |u: f64, v: f64| {
                        let mut p = [0.0; 3];
                        p[a] = value;
                        p[b] = u;
                        p[d] = v;
                        p
                    };
                    let mut quad = vec![
                        corner(lo[b], lo[d]),
                        corner(hi[b], lo[d]),
                        corner(hi[b], hi[d]),
                        corner(lo[b], hi[d]),
                    ];
                    if side < 0.0 {
                        quad.reverse();
                    }
                    let mut n = [0.0; 3];
                    n[a] = side;
                    faces.push((quad, n));
                }
            }
            faces
        }
        Kind::Splats => {
            let n = normal_of(c);
            let any = if n[0].abs() < 0.9 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            };
            let t1 = unit(cross(n, any));
            let t2 = cross(n, t1);
            let r = grid.radius(c.mean[2]);
            let corners = (0..8)
                .map(|k| {
                    let a = k as f64 * std::f64::consts::FRAC_PI_4;
                    let (s, co) = a.sin_cos();
                    std::array::from_fn(|i| c.mean[i] + r * (co * t1[i] + s * t2[i]))
                })
                .collect();
            vec![(corners, n)]
        }
        Kind::Quads => {
            // Cell-filling: the plane of the normal through the mean, over the cell's box (the
            // grid cell at the mean's depth, grown to the points' box where the move brought
            // points from beyond it) on the two axes most across the normal; the third
            // coordinate solved from the plane, kept within the box. Neighbouring cells' quads
            // so meet where the surface runs on.
            let n = normal_of(c);
            let (mut lo, mut hi) = grid.cell_box(camera, c.index, c.mean[2]);
            for a in 0..3 {
                lo[a] = lo[a].min(c.min[a]);
                hi[a] = hi[a].max(c.max[a]);
            }
            let k = (0..3)
                .max_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs()))
                .expect("three axes");
            let (a, b) = ((k + 1) % 3, (k + 2) % 3);
            let corner = |u: f64, v: f64| {
                let mut p = [0.0; 3];
                p[a] = u;
                p[b] = v;
                p[k] = (c.mean[k] - (n[a] * (u - c.mean[a]) + n[b] * (v - c.mean[b])) / n[k])
                    .clamp(lo[k], hi[k]);
                p
            };
            let quad = vec![
                corner(lo[a], lo[b]),
                corner(hi[a], lo[b]),
                corner(hi[a], hi[b]),
                corner(lo[a], hi[b]),
            ];
            vec![(quad, n)]
        }
    }
}

/// The surface of `cells` (eye coordinates of `camera`) as a mesh in world coordinates.
pub fn reconstruct(camera: &Camera, grid: &Grid, cells: &[Cell], kind: Kind) -> Mesh {
    let (r, u, f) = camera.basis();
    let o = camera.position;
    let world = |e: V| std::array::from_fn(|a| o[a] + e[0] * r[a] + e[1] * u[a] + e[2] * f[a]);
    let direction =
        |e: V| std::array::from_fn(|a| (e[0] * r[a] + e[1] * u[a] + e[2] * f[a]) as f32);
    let parts: Vec<Mesh> = cells
        .par_chunks(4096)
        .map(|chunk| {
            let mut m = Mesh::default();
            for c in chunk {
                for (corners, n) in polygons(camera, grid, c, kind) {
                    let corners: Vec<V> = corners.into_iter().map(world).collect();
                    m.polygon(&corners, direction(n), c.colour);
                }
            }
            m
        })
        .collect();
    let mut mesh = Mesh::default();
    for p in parts {
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(p.positions);
        mesh.normals.extend(p.normals);
        mesh.colours.extend(p.colours);
        mesh.triangles
            .extend(p.triangles.into_iter().map(|t| t.map(|i| i + base)));
    }
    mesh
}

/// Distance from `p` to a convex polygon (corners in order).
fn polygon_distance(p: V, corners: &[V]) -> f64 {
    let segment = |a: V, b: V| {
        let ab = sub(b, a);
        let l = dot(ab, ab);
        let t = if l > 0.0 {
            (dot(sub(p, a), ab) / l).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = std::array::from_fn(|i| a[i] + t * ab[i]);
        dot(sub(p, q), sub(p, q)).sqrt()
    };
    let edges = || (0..corners.len()).map(|i| (corners[i], corners[(i + 1) % corners.len()]));
    // Newell's normal: robust for any convex polygon, zero for a degenerate one.
    let mut n = [0.0; 3];
    for (a, b) in edges() {
        n[0] += (a[1] - b[1]) * (a[2] + b[2]);
        n[1] += (a[2] - b[2]) * (a[0] + b[0]);
        n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    if dot(n, n) > 0.0 {
        let n = unit(n);
        if edges().all(|(a, b)| dot(cross(sub(b, a), sub(p, a)), n) >= 0.0) {
            return dot(sub(p, corners[0]), n).abs();
        }
    }
    edges()
        .map(|(a, b)| segment(a, b))
        .fold(f64::INFINITY, f64::min)
}

/// Per point in a cell, its distance to its own cell's element (`points` in world coordinates,
/// as clustered): how far the surface lies from what was drawn.
pub fn distances(
    camera: &Camera,
    grid: &Grid,
    clustering: &Clustering,
    points: &[[f64; 3]],
    kind: Kind,
) -> Vec<f64> {
    let eye = super::cluster::to_eye(camera, points);
    let elements: Vec<Vec<(Vec<V>, V)>> = clustering
        .cells
        .par_iter()
        .map(|c| polygons(camera, grid, c, kind))
        .collect();
    eye.par_iter()
        .zip(&clustering.of_point)
        .filter(|(_, c)| **c != u32::MAX)
        .map(|(&p, &c)| {
            if kind == Kind::Boxes {
                let cell = &clustering.cells[c as usize];
                let d: V =
                    std::array::from_fn(|a| (cell.min[a] - p[a]).max(p[a] - cell.max[a]).max(0.0));
                return dot(d, d).sqrt();
            }
            elements[c as usize]
                .iter()
                .map(|(corners, _)| polygon_distance(p, corners))
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}
