//! Surfaces from points, every frame (Schiffner, Stockhausen, Ritter 2015): the points a
//! frame draws are clustered into a grid laid in the camera's view frustum, the grid made
//! curvilinear by moving points to a neighbouring cell by relative density, each cell reduced to
//! one representative, and one surface element made per cell.
//!
//! - cluster (`cluster.rs`): a point's cell is its pixel column and row scaled to the grid's
//!   columns and rows, and its depth layer, the layers growing with distance (logarithmic
//!   between the nearest and the farthest point in view, so that a cell is about as deep as it is
//!   wide on screen: fine near the eye, coarse far away, the paper's figure 2); per cell its
//!   density: the point count, or the planarity of its point distribution tensor.
//! - move: equations 6-9, the boundary towards each neighbour at
//!   `w = clamp((2 dens(c) / (dens(c) + dens(n)))^gamma, lb, 1 - lb)` of the half cell (1: the
//!   cell's face); a point whose offset from the centre, in half cells, is beyond it, on the axis of its
//!   largest offset (`neighbours` 1) or on each axis (3), goes to the neighbour; 0 skips the
//!   move. Then the points are clustered again by their new cells (as the paper does).
//! - reduce: per occupied cell the mean, the bounding box of its points along the eye axes, the
//!   mean colour, and a normal: the minor eigenvector of the point distribution tensor, or the
//!   sum of the directions to the empty neighbour cells; turned towards the eye.
//! - reconstruct (`reconstruct.rs`): per cell a box, an oriented splat (a disc of the cell's
//!   radius on the normal's plane, an octagon in 3-D, so perspective-correct), or a cell-filling
//!   quad (four corners on the normal's plane within the cell's box), as a [`Mesh`] in world
//!   coordinates: what `myriad mesh` writes and what the frame draws.
//! - draw (`cpu.rs`): the mesh's triangles into the g-buffer (depth, colour, normal), then the
//!   post passes with a headlight (`shade`), as the paper lights its surfaces.
//!
//! Everything here runs on the CPU with rayon, in f64; `gpu.rs` and `gpu_draw.rs` are the same
//! steps as compute shaders and the draw through the quad path's g-buffer (not blended:
//! `--passes blend` blends points only).

pub mod cluster;
mod cpu;
mod drawn;
pub mod gpu;
mod gpu_draw;
mod reconstruct;
#[cfg(test)]
mod tests;
mod worker;

pub use cluster::{Cell, Clustering, cluster, moved_cell, weight};
pub(crate) use cpu::gbuffer;
pub use drawn::drawn_scene;
pub use gpu_draw::{DRAW_WGSL, Drawer};
pub use reconstruct::{distances, reconstruct};
pub use worker::{Made, Worker};

use myriad_core::{Aabb, Mesh};
use myriad_lod::Camera;
use std::time::{Duration, Instant};

/// The surface element made per cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Boxes,
    Splats,
    Quads,
}

/// How a cell's normal is estimated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Normals {
    /// The minor eigenvector of the point distribution tensor (smoother, slower).
    Tensor,
    /// The sum of the directions to the empty neighbour cells.
    Cells,
}

/// What `dens(c)` of the move is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Density {
    Count,
    Planarity,
}

/// The parameters of a surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Surface {
    pub kind: Kind,
    /// Columns, rows and depth layers (the paper's 150x150x50 by default).
    pub grid: [u32; 3],
    pub normals: Normals,
    /// 0 (no move), 1 or 3 neighbours looked at per point.
    pub neighbours: u32,
    pub density: Density,
    /// Equation 8's exponent and lower bound.
    pub gamma: f64,
    pub lb: f64,
}

impl Default for Surface {
    fn default() -> Surface {
        Surface {
            kind: Kind::Quads,
            grid: [150, 150, 50],
            normals: Normals::Tensor,
            neighbours: 3,
            density: Density::Count,
            gamma: 2.0,
            lb: 0.1,
        }
    }
}

impl Kind {
    pub fn parse(s: &str) -> Result<Kind, String> {
        Ok(match s {
            "boxes" => Kind::Boxes,
            "splats" => Kind::Splats,
            "quads" => Kind::Quads,
            _ => return Err(format!("unknown surface {s:?} (boxes, splats, quads)")),
        })
    }
}

impl Normals {
    pub fn parse(s: &str) -> Result<Normals, String> {
        Ok(match s {
            "tensor" => Normals::Tensor,
            "cells" => Normals::Cells,
            _ => return Err(format!("unknown normals {s:?} (tensor, cells)")),
        })
    }
}

impl Density {
    pub fn parse(s: &str) -> Result<Density, String> {
        Ok(match s {
            "count" => Density::Count,
            "planarity" => Density::Planarity,
            _ => return Err(format!("unknown density {s:?} (count, planarity)")),
        })
    }
}

/// `CxRxL`, e.g. 150x150x50.
pub fn parse_grid(s: &str) -> Result<[u32; 3], String> {
    let v: Vec<u32> = s
        .split(['x', 'X'])
        .map(|p| p.trim().parse::<u32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("{s:?}: a grid is COLUMNSxROWSxLAYERS, e.g. 150x150x50"))?;
    match v[..] {
        [c, r, l] if c > 0 && r > 0 && l > 0 && (c as u64 * r as u64 * l as u64) < 1 << 40 => {
            Ok([c, r, l])
        }
        _ => Err(format!(
            "{s:?}: a grid is COLUMNSxROWSxLAYERS, each at least 1"
        )),
    }
}

/// How points are mapped to cells.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Grid {
    /// The grid of Schiffner et al. 2015 in the view frustum: `dims[0]` columns and `dims[1]` rows
    /// over the image, `dims[2]` layers from depth `near` to `far`, each deeper by the same factor.
    Frustum {
        dims: [u32; 3],
        width: f64,
        height: f64,
        focal: f64,
        near: f64,
        far: f64,
    },
    /// The paper's baseline, a level of an octree: cubes of side `size` from `origin`, in world
    /// coordinates.
    Cubes {
        origin: [f64; 3],
        size: f64,
        dims: [u32; 3],
    },
}

impl Grid {
    /// The frustum grid of `camera` over the depths of the `points` (world) in view; None when
    /// no point is in view. One pass over the points, in parallel, keeping nothing.
    pub fn frustum(camera: &Camera, dims: [u32; 3], points: &[[f64; 3]]) -> Option<Grid> {
        use rayon::prelude::*;
        let (w, h, f) = (camera.width as f64, camera.height as f64, camera.focal());
        let (r, u, fw) = camera.basis();
        let o = camera.position;
        let (near, far) = points
            .par_iter()
            .filter_map(|p| {
                let d = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
                let dot = |v: [f64; 3]| d[0] * v[0] + d[1] * v[1] + d[2] * v[2];
                let e = [dot(r), dot(u), dot(fw)];
                if e[2] <= camera.near {
                    return None;
                }
                let (x, y) = (w / 2.0 + e[0] * f / e[2], h / 2.0 - e[1] * f / e[2]);
                ((0.0..w).contains(&x) && (0.0..h).contains(&y)).then_some((e[2], e[2]))
            })
            .reduce(
                || (f64::INFINITY, 0.0f64),
                |a, b| (a.0.min(b.0), a.1.max(b.1)),
            );
        (near <= far).then(|| Grid::Frustum {
            dims,
            width: w,
            height: h,
            focal: f,
            near,
            // The farthest point inside the last layer; some depth range however flat the view.
            far: far.max(near * 1.001) * (1.0 + 1e-9),
        })
    }

    /// The two octree levels of cube `root` whose cells holding `points` (world) bracket
    /// `cells` (the deepest with at most that many, and the one below it): the paper's baseline at
    /// about the same number of primitives, from below and from above.
    pub fn cubes_around(root: &Aabb, points: &[[f64; 3]], cells: usize) -> [Grid; 2] {
        const LEVELS: u32 = 12;
        let side = root.size().into_iter().fold(0.0f64, f64::max).max(1e-9);
        let n = (1u64 << LEVELS) as f64;
        let mut codes: Vec<u64> = points
            .iter()
            .map(|p| {
                let c = |a: usize| {
                    (((p[a] - root.min[a]) / side * n)
                        .floor()
                        .clamp(0.0, n - 1.0)) as u32
                };
                myriad_core::geometry::morton(c(0), c(1), c(2))
            })
            .collect();
        codes.sort_unstable();
        let occupied = |l: u32| {
            let shift = 3 * (LEVELS - l);
            let mut count = 0usize;
            let mut last = None;
            for &c in &codes {
                if last != Some(c >> shift) {
                    count += 1;
                    last = Some(c >> shift);
                }
            }
            count
        };
        let below = (1..LEVELS)
            .take_while(|&l| occupied(l) <= cells)
            .last()
            .unwrap_or(1);
        [below, below + 1].map(|l| Grid::Cubes {
            origin: root.min,
            size: side / (1u64 << l) as f64,
            dims: [1 << l; 3],
        })
    }

    pub fn dims(&self) -> [u32; 3] {
        match *self {
            Grid::Frustum { dims, .. } | Grid::Cubes { dims, .. } => dims,
        }
    }

    /// Grid coordinates (the cell is their floor) of a point at `world`, `eye` in eye
    /// coordinates; None outside the grid.
    pub fn coords(&self, world: [f64; 3], eye: [f64; 3]) -> Option<[f64; 3]> {
        let g = match *self {
            Grid::Frustum {
                dims,
                width,
                height,
                focal,
                near,
                far,
            } => {
                if eye[2] < near {
                    return None;
                }
                let x = width / 2.0 + eye[0] * focal / eye[2];
                let y = height / 2.0 - eye[1] * focal / eye[2];
                [
                    x / width * dims[0] as f64,
                    y / height * dims[1] as f64,
                    (eye[2] / near).ln() / (far / near).ln() * dims[2] as f64,
                ]
            }
            Grid::Cubes { origin, size, .. } => {
                std::array::from_fn(|a| (world[a] - origin[a]) / size)
            }
        };
        let dims = self.dims();
        (0..3)
            .all(|a| g[a] >= 0.0 && g[a] < dims[a] as f64)
            .then_some(g)
    }

    /// The centre of a cell in eye coordinates.
    pub fn centre(&self, camera: &Camera, cell: [u32; 3]) -> [f64; 3] {
        let c = cell.map(|v| v as f64 + 0.5);
        match *self {
            Grid::Frustum {
                dims,
                width,
                height,
                focal,
                near,
                far,
            } => {
                let z = near * (far / near).powf(c[2] / dims[2] as f64);
                let x = c[0] / dims[0] as f64 * width;
                let y = c[1] / dims[1] as f64 * height;
                [
                    (x - width / 2.0) * z / focal,
                    (height / 2.0 - y) * z / focal,
                    z,
                ]
            }
            Grid::Cubes { origin, size, .. } => {
                camera.to_eye(std::array::from_fn(|a| origin[a] + c[a] * size))
            }
        }
    }

    /// A cell's sides at eye depth `z`: across, up and along the view.
    pub fn extent(&self, z: f64) -> [f64; 3] {
        match *self {
            Grid::Frustum {
                dims,
                width,
                height,
                focal,
                near,
                far,
            } => [
                width / dims[0] as f64 * z / focal,
                height / dims[1] as f64 * z / focal,
                z * ((far / near).powf(1.0 / dims[2] as f64) - 1.0),
            ],
            Grid::Cubes { size, .. } => [size; 3],
        }
    }

    /// A cell's box along the eye axes: for the frustum grid, its columns' and rows' span at
    /// eye depth `z` and its layer's depths; for cubes, the box of the cube's corners.
    pub fn cell_box(&self, camera: &Camera, cell: [u32; 3], z: f64) -> ([f64; 3], [f64; 3]) {
        match *self {
            Grid::Frustum {
                dims, near, far, ..
            } => {
                // The centre's column and row at depth z, half a side either way; the layer's
                // depths a half layer's factor either side of the centre's.
                let c = self.centre(camera, cell);
                let e = self.extent(z);
                let (x, y) = (c[0] * z / c[2], c[1] * z / c[2]);
                let half = (far / near).powf(0.5 / dims[2] as f64);
                (
                    [x - e[0] / 2.0, y - e[1] / 2.0, c[2] / half],
                    [x + e[0] / 2.0, y + e[1] / 2.0, c[2] * half],
                )
            }
            Grid::Cubes { origin, size, .. } => {
                let mut lo = [f64::INFINITY; 3];
                let mut hi = [f64::NEG_INFINITY; 3];
                for corner in 0..8 {
                    let w = std::array::from_fn(|a| {
                        origin[a] + (cell[a] + ((corner >> a) & 1)) as f64 * size
                    });
                    let e = camera.to_eye(w);
                    for a in 0..3 {
                        lo[a] = lo[a].min(e[a]);
                        hi[a] = hi[a].max(e[a]);
                    }
                }
                (lo, hi)
            }
        }
    }

    /// Half the diagonal of a cell's face across the view at eye depth `z`: the radius of a
    /// splat that reaches its neighbours' splats.
    pub fn radius(&self, z: f64) -> f64 {
        let [w, h, _] = self.extent(z);
        0.5 * (w * w + h * h).sqrt()
    }
}

/// A surface made from some points, and what each step took.
#[derive(Debug, Clone, Default)]
pub struct Built {
    pub clustering: Clustering,
    pub mesh: Mesh,
    pub reconstruct: Duration,
    /// The grid used (None: no point in view).
    pub grid: Option<Grid>,
    /// Made on a GPU: the triangles in its memory, as the reconstruct step left them there.
    pub gpu_mesh: Option<gpu::GpuMesh>,
}

impl Built {
    /// Cluster, move and reduce `points` (world, with their colours) in the frustum grid of
    /// `camera`, and reconstruct the surface.
    pub fn new(camera: &Camera, points: &[[f64; 3]], colours: &[[u8; 4]], s: &Surface) -> Built {
        let Some(grid) = Grid::frustum(camera, s.grid, points) else {
            return Built::default();
        };
        Built::in_grid(camera, &grid, points, colours, s)
    }

    /// [`Built::new`] with cluster, move and reduce on `gpu` (`gpu.rs`) where it is one, on the
    /// CPU otherwise; the error where the GPU cannot (a grid beyond its largest binding).
    pub fn on(
        gpu: &crate::Gpu,
        camera: &Camera,
        points: &[[f64; 3]],
        colours: &[[u8; 4]],
        s: &Surface,
    ) -> Result<Built, String> {
        if gpu.is_cpu() {
            return Ok(Built::new(camera, points, colours, s));
        }
        let Some(grid) = Grid::frustum(camera, s.grid, points) else {
            return Ok(Built::default());
        };
        Built::in_grid_on(gpu, camera, &grid, points, colours, s)
    }

    /// [`Built::in_grid`] on `gpu` where it is one (and the grid the frustum's).
    pub fn in_grid_on(
        gpu: &crate::Gpu,
        camera: &Camera,
        grid: &Grid,
        points: &[[f64; 3]],
        colours: &[[u8; 4]],
        s: &Surface,
    ) -> Result<Built, String> {
        if gpu.is_cpu() || !matches!(grid, Grid::Frustum { .. }) {
            return Ok(Built::in_grid(camera, grid, points, colours, s));
        }
        // Cluster, move, reduce and reconstruct on the GPU (its time is the reconstruct
        // step's); the same triangles made on the CPU from the cells read back, for the mesh.
        let (clustering, gpu_mesh, took) = gpu::build(gpu, camera, grid, points, colours, s)?;
        let mesh = reconstruct(camera, grid, &clustering.cells, s.kind);
        Ok(Built {
            clustering,
            mesh,
            reconstruct: took,
            grid: Some(*grid),
            gpu_mesh: Some(gpu_mesh),
        })
    }

    /// [`Built::new`] in a given grid.
    pub fn in_grid(
        camera: &Camera,
        grid: &Grid,
        points: &[[f64; 3]],
        colours: &[[u8; 4]],
        s: &Surface,
    ) -> Built {
        let clustering = cluster(camera, grid, points, colours, s);
        let t = Instant::now();
        let mesh = reconstruct(camera, grid, &clustering.cells, s.kind);
        Built {
            clustering,
            mesh,
            reconstruct: t.elapsed(),
            grid: Some(*grid),
            gpu_mesh: None,
        }
    }
}

/// The surface's image seen by `camera` (RGBA8, rows top to bottom): its triangles into the
/// g-buffer, then `style`'s post passes, with the headlight (`shade`) on where the style has none.
pub fn draw(camera: &Camera, mesh: &Mesh, style: &crate::Style) -> Vec<u8> {
    let mut passes = style.passes;
    passes.shade.get_or_insert_with(crate::Shade::default);
    let f = passes.factor();
    let c = crate::style::supersampled(camera, style, f).0;
    let view = crate::post::View::new(&c, passes.sun(), style.background, f);
    crate::post::run(gbuffer(&c, mesh), &passes, &view)
}

/// The points the last frame of `scene` drew, in world coordinates, with the colours they were
/// drawn in: what a surface is made from (those of its loaded nodes; a clipping box removes what
/// it hides).
pub fn drawn_points(
    scene: &crate::Scene,
    clip: Option<crate::Clip>,
) -> (Vec<[f64; 3]>, Vec<[u8; 4]>) {
    let mut positions = Vec::new();
    let mut colours = Vec::new();
    for n in &scene.last.nodes {
        let Some(batch) = scene.loader.get(&n.key) else {
            continue;
        };
        let k = (n.points as usize).min(batch.len());
        let c = crate::colours(&batch, k, scene.colour(), scene.z_range, n.key.level);
        for (p, c) in batch.positions[..k].iter().zip(c) {
            let keep = clip.is_none_or(|b| b.bounds.contains(*p) == b.inside);
            if keep {
                positions.push(*p);
                colours.push(c);
            }
        }
    }
    (positions, colours)
}

/// Per pixel of `camera`'s image, whether the surface covers it.
pub fn coverage(camera: &Camera, mesh: &Mesh) -> Vec<bool> {
    gbuffer(camera, mesh)
        .depth
        .iter()
        .map(|&d| d > 0.0)
        .collect()
}
