//! Cluster, move and reduce on the GPU (`cluster.wgsl`), the same steps as `cluster.rs`: the
//! points go up in eye coordinates (f32, relative to the eye, so precise where it matters) in
//! chunks a storage binding holds; per cell sums by 32-bit integer atomics in a dense array over
//! the grid (20 words a cell: 90 MB for the paper's 150x150x50), the tensor in a second pass over
//! the points once the means are known (a sum of products about the cell's centre would lose the
//! flat cells' thickness to quantization); the reduced cells come back and are sorted by key, so
//! that both paths list the same cells in the same order.

use super::{Cell, Clustering, Grid, Normals, Surface};
use crate::Gpu;
use myriad_lod::Camera;
use std::time::{Duration, Instant};
use wgpu::util::DeviceExt;

pub const CLUSTER_WGSL: &str = include_str!("cluster.wgsl");
/// cluster.wgsl with the reconstruct step after it (one module for every step).
pub const RECONSTRUCT_WGSL: &str = concat!(
    include_str!("cluster.wgsl"),
    include_str!("reconstruct.wgsl")
);

const STRIDE: u64 = 20;
const CELL_WORDS: usize = 16;
const WORKGROUP: u32 = 128;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    dims: [u32; 4],
    view: [f32; 4],
    more: [f32; 4],
    flags: [u32; 4],
    right: [f32; 4],
    up: [f32; 4],
    forward: [f32; 4],
}

/// A surface's triangles made on the GPU: `vertices` vertices of 28 bytes (position relative to
/// the eye in world axes and normal as f32, RGBA8), three a triangle, for [`super::Drawer`].
#[derive(Debug, Clone)]
pub struct GpuMesh {
    pub buffer: wgpu::Buffer,
    pub vertices: u32,
}

fn groups(n: u32) -> (u32, u32) {
    let g = n.div_ceil(WORKGROUP).max(1);
    let x = g.min(65535);
    (x, g.div_ceil(x))
}

/// The first `bytes` of `source` (copied to a staging buffer, after what was submitted before).
pub(super) fn read(gpu: &Gpu, source: &wgpu::Buffer, bytes: u64) -> Vec<u8> {
    let d = gpu.device();
    let staging = d.create_buffer(&wgpu::BufferDescriptor {
        label: Some("surface readback"),
        size: bytes.max(4).next_multiple_of(4),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = d.create_command_encoder(&Default::default());
    enc.copy_buffer_to_buffer(source, 0, &staging, 0, bytes.max(4).next_multiple_of(4));
    gpu.queue().submit([enc.finish()]);
    let slice = staging.slice(..);
    slice.map_async(wgpu::MapMode::Read, |r| r.expect("map the surface's cells"));
    d.poll(wgpu::PollType::wait_indefinitely())
        .expect("wait for the surface");
    let out = slice.get_mapped_range().expect("mapped").to_vec();
    staging.unmap();
    out
}

/// [`super::cluster`] on the GPU, for the frustum grid; an error where the device cannot (no
/// wgpu device, another grid, a grid beyond a storage binding).
pub fn cluster(
    gpu: &Gpu,
    camera: &Camera,
    grid: &Grid,
    points: &[[f64; 3]],
    colours: &[[u8; 4]],
    s: &Surface,
) -> Result<Clustering, String> {
    run(gpu, camera, grid, points, colours, s, false).map(|r| r.0)
}

/// [`cluster`], then the reconstruct step on the GPU too (`reconstruct.wgsl`): the cells, the
/// triangles of `s.kind` in a vertex buffer, and what the reconstruct step took.
pub fn build(
    gpu: &Gpu,
    camera: &Camera,
    grid: &Grid,
    points: &[[f64; 3]],
    colours: &[[u8; 4]],
    s: &Surface,
) -> Result<(Clustering, GpuMesh, Duration), String> {
    let (c, mesh) = run(gpu, camera, grid, points, colours, s, true)?;
    let (mesh, took) = mesh.expect("asked for");
    Ok((c, mesh, took))
}

#[allow(clippy::type_complexity)]
fn run(
    gpu: &Gpu,
    camera: &Camera,
    grid: &Grid,
    points: &[[f64; 3]],
    colours: &[[u8; 4]],
    s: &Surface,
    triangles: bool,
) -> Result<(Clustering, Option<(GpuMesh, Duration)>), String> {
    let Some((d, q)) = gpu.wgpu() else {
        return Err("no GPU device".into());
    };
    let limit = d.limits().max_storage_buffer_binding_size;
    let (dims, view, cells) = frustum(grid, limit)?;
    // The pipelines (compiled once in a session that keeps them) are not counted in the steps'
    // times; uploads and readbacks are.
    let module = crate::pipelines::module(gpu, "cluster.wgsl", RECONSTRUCT_WGSL);
    let steps = Steps::new(d, &module);
    let t = Instant::now();
    let eye = eye_points(camera, points, colours);
    let chunk = ((limit / 16).min(1 << 24) as usize).max(1);
    let base = uniform(camera, s, dims, view, cells);
    let bound = Bound::new(gpu, (d, q), &steps.bgl, base, chunk, eye.len(), cells);
    q.write_buffer(&bound.uniform, 0, bytemuck::bytes_of(&bound.params(0)));
    bound.dispatch(&steps.clear, cells);
    let first_keys = bound.per_point(&steps.first, &steps.spread, &eye);
    bound.wait();
    let cluster_time = t.elapsed();

    let t = Instant::now();
    let (keys, moved_count) = if s.neighbours == 0 {
        (first_keys, 0)
    } else {
        bound.dispatch(&steps.density, cells);
        bound.dispatch(&steps.clear, cells);
        let keys = bound.per_point(&steps.moved, &steps.spread, &eye);
        bound.wait();
        let n = keys.iter().zip(&first_keys).filter(|(a, b)| a != b).count();
        (keys, n)
    };
    let moving = t.elapsed();

    let t = Instant::now();
    let reduced = bound.reduce(&steps.reduce, cells, dims, &keys);
    let reduce_time = t.elapsed();
    let n = reduced.n;
    let most = n as u64 * 36 * 28;
    if triangles && most > limit {
        return Err(format!(
            "{n} cells' triangles need up to {} MB a binding, the device allows {} MB",
            most >> 20,
            limit >> 20
        ));
    }
    let mesh = triangles.then(|| bound.reconstruct(&module, n, s.kind));
    Ok((
        Clustering {
            cells: reduced.cells.into_iter().map(|c| c.1).collect(),
            of_point: reduced.of_point,
            inside: reduced.inside,
            moved: moved_count,
            cluster: cluster_time,
            moving,
            reduce: reduce_time,
        },
        mesh,
    ))
}

/// The frustum grid's dimensions, its view (width, height, focal length, near and far) and its
/// cell count; refused for another grid, or one whose sums a storage binding of `limit` bytes
/// cannot hold.
fn frustum(grid: &Grid, limit: u64) -> Result<([u32; 3], [f64; 5], u64), String> {
    let Grid::Frustum {
        dims,
        width,
        height,
        focal,
        near,
        far,
    } = *grid
    else {
        return Err("the GPU clusters in the frustum grid only".into());
    };
    let cells = dims.iter().map(|&v| v as u64).product::<u64>();
    if cells * STRIDE * 4 > limit || cells > u32::MAX as u64 / 2 {
        return Err(format!(
            "a grid of {cells} cells needs {} MB a binding, the device allows {} MB",
            (cells * STRIDE * 4) >> 20,
            limit >> 20
        ));
    }
    Ok((dims, [width, height, focal, near, far], cells))
}

/// The compute pipelines of the clustering steps (`cluster.wgsl`), and the layout of what they
/// bind.
struct Steps {
    bgl: wgpu::BindGroupLayout,
    clear: wgpu::ComputePipeline,
    first: wgpu::ComputePipeline,
    density: wgpu::ComputePipeline,
    moved: wgpu::ComputePipeline,
    spread: wgpu::ComputePipeline,
    reduce: wgpu::ComputePipeline,
}

impl Steps {
    /// The steps' pipelines from `module`: a uniform at binding 0, the points read-only at 1,
    /// the other buffers read and written.
    fn new(d: &wgpu::Device, module: &wgpu::ShaderModule) -> Steps {
        let entries: Vec<wgpu::BindGroupLayoutEntry> = (0..7)
            .map(|b| wgpu::BindGroupLayoutEntry {
                binding: b,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: match b {
                    0 => wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    1 => wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    _ => wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: false },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                },
                count: None,
            })
            .collect();
        let bgl = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("surface"),
            entries: &entries,
        });
        let layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("surface"),
            bind_group_layouts: &[Some(&bgl)],
            immediate_size: 0,
        });
        let pipeline = |entry: &str| {
            d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&layout),
                module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let [clear, first, density, moved, spread, reduce] =
            ["clear", "first", "density", "moved", "spread", "reduce"].map(pipeline);
        Steps {
            bgl,
            clear,
            first,
            density,
            moved,
            spread,
            reduce,
        }
    }
}

/// The points in eye coordinates (f32, relative to the eye), each with its colour's bits as
/// the fourth.
fn eye_points(camera: &Camera, points: &[[f64; 3]], colours: &[[u8; 4]]) -> Vec<[f32; 4]> {
    super::cluster::to_eye(camera, points)
        .iter()
        .zip(colours)
        .map(|(e, c)| {
            [
                e[0] as f32,
                e[1] as f32,
                e[2] as f32,
                f32::from_bits(u32::from_le_bytes(*c)),
            ]
        })
        .collect()
}

/// The steps' uniform with no points counted: the camera's axes, the grid's `dims` and `view`
/// (width, height, focal length, near, far), the surface's options, the `cells`.
fn uniform(camera: &Camera, s: &Surface, dims: [u32; 3], view: [f64; 5], cells: u64) -> Params {
    let [width, height, focal, near, far] = view;
    let (r, u, f) = camera.basis();
    let v4 = |v: [f64; 3]| [v[0] as f32, v[1] as f32, v[2] as f32, 0.0];
    Params {
        right: v4(r),
        up: v4(u),
        forward: v4(f),
        dims: [dims[0], dims[1], dims[2], s.neighbours],
        view: [width as f32, height as f32, focal as f32, near as f32],
        more: [
            far as f32,
            s.gamma as f32,
            s.lb as f32,
            (far / near).ln() as f32,
        ],
        flags: [
            0,
            (s.density == super::Density::Planarity) as u32,
            (s.normals == Normals::Cells) as u32,
            cells as u32,
        ],
    }
}

/// The reduced cells as read back, sorted by key, each point's cell among them (u32::MAX:
/// none), the points inside the grid, and the cells' count.
struct Reduced {
    cells: Vec<(u32, Cell)>,
    of_point: Vec<u32>,
    inside: usize,
    n: usize,
}

/// The buffers the steps share, bound as `cluster.wgsl` numbers them: the uniform, a chunk of
/// points and their cells, the cells' sums and densities, the reduced cells' counter and words.
struct Bound<'a> {
    gpu: &'a Gpu,
    d: &'a wgpu::Device,
    q: &'a wgpu::Queue,
    uniform: wgpu::Buffer,
    point_buf: wgpu::Buffer,
    cell_of: wgpu::Buffer,
    counter: wgpu::Buffer,
    out: wgpu::Buffer,
    /// The cells' sums and densities: only the steps use them, held as long as the others.
    _sums: [wgpu::Buffer; 2],
    bind: wgpu::BindGroup,
    /// The uniform with no points counted.
    base: Params,
    /// Points a chunk holds.
    chunk: usize,
}

impl<'a> Bound<'a> {
    /// The buffers for `points` points (uploaded `chunk` at a time) and a grid of `cells`
    /// cells, bound by `bgl`; the uniform set to `base`.
    fn new(
        gpu: &'a Gpu,
        (d, q): (&'a wgpu::Device, &'a wgpu::Queue),
        bgl: &wgpu::BindGroupLayout,
        base: Params,
        chunk: usize,
        points: usize,
        cells: u64,
    ) -> Bound<'a> {
        let storage = |label, size: u64| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size.max(16),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let uniform = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("surface params"),
            contents: bytemuck::bytes_of(&base),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let n_chunk = chunk.min(points).max(1) as u64;
        let point_buf = storage("surface points", n_chunk * 16);
        let cell_of = storage("surface cell of", n_chunk * 4);
        let acc = storage("surface sums", cells * STRIDE * 4);
        let dens = storage("surface density", cells * 4);
        let counter = storage("surface counter", 16);
        let max_out = cells.min(points as u64).max(1);
        let out = storage("surface cells", max_out * CELL_WORDS as u64 * 4);

        let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("surface"),
            layout: bgl,
            entries: &[&uniform, &point_buf, &cell_of, &acc, &dens, &counter, &out]
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupEntry {
                    binding: i as u32,
                    resource: b.as_entire_binding(),
                })
                .collect::<Vec<_>>(),
        });
        Bound {
            gpu,
            d,
            q,
            uniform,
            point_buf,
            cell_of,
            counter,
            out,
            _sums: [acc, dens],
            bind,
            base,
            chunk,
        }
    }

    /// The uniform for a chunk of `n` points.
    fn params(&self, n: usize) -> Params {
        let mut p = self.base;
        p.flags[0] = n as u32;
        p
    }

    /// Step `p` over `threads` threads, submitted.
    fn dispatch(&self, p: &wgpu::ComputePipeline, threads: u64) {
        let mut enc = self.d.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(p);
            pass.set_bind_group(0, &self.bind, &[]);
            let (x, y) = groups(threads as u32);
            pass.dispatch_workgroups(x, y, 1);
        }
        self.q.submit([enc.finish()]);
    }

    /// Waits for what was submitted.
    fn wait(&self) {
        self.d
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("wait for the surface");
    }

    /// Each chunk: its points up, the pass `p`, the cells they went to back; then, the means
    /// known, each chunk again (points and cells up where there are several) for the tensor
    /// (`spread`). The cell of every point.
    fn per_point(
        &self,
        p: &wgpu::ComputePipeline,
        spread: &wgpu::ComputePipeline,
        eye: &[[f32; 4]],
    ) -> Vec<u32> {
        let (q, chunk) = (self.q, self.chunk);
        let mut keys = Vec::with_capacity(eye.len());
        let parts = eye.len().div_ceil(chunk);
        for part in eye.chunks(chunk) {
            q.write_buffer(&self.point_buf, 0, bytemuck::cast_slice(part));
            q.write_buffer(
                &self.uniform,
                0,
                bytemuck::bytes_of(&self.params(part.len())),
            );
            self.dispatch(p, part.len() as u64);
            keys.extend(
                bytemuck::cast_slice::<u8, u32>(&read(
                    self.gpu,
                    &self.cell_of,
                    part.len() as u64 * 4,
                ))
                .iter()
                .copied(),
            );
        }
        for (part, k) in eye.chunks(chunk).zip(keys.chunks(chunk)) {
            if parts > 1 {
                q.write_buffer(&self.point_buf, 0, bytemuck::cast_slice(part));
                q.write_buffer(&self.cell_of, 0, bytemuck::cast_slice(k));
                q.write_buffer(
                    &self.uniform,
                    0,
                    bytemuck::bytes_of(&self.params(part.len())),
                );
            }
            self.dispatch(spread, part.len() as u64);
        }
        q.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&self.params(0)));
        keys
    }

    /// The reduce step over the grid's `cells` (`dims`), its cells read back and sorted by key,
    /// and each point's cell among them from its key (`keys`).
    fn reduce(
        &self,
        reduce: &wgpu::ComputePipeline,
        cells: u64,
        dims: [u32; 3],
        keys: &[u32],
    ) -> Reduced {
        self.q.write_buffer(&self.counter, 0, &[0; 16]);
        self.dispatch(reduce, cells);
        let n = bytemuck::cast_slice::<u8, u32>(&read(self.gpu, &self.counter, 4))[0] as usize;
        let words = read(self.gpu, &self.out, (n * CELL_WORDS * 4) as u64);
        let words: &[u32] = bytemuck::cast_slice(&words);
        let f = |w: u32| f32::from_bits(w) as f64;
        let mut cells_out: Vec<(u32, Cell)> = words
            .chunks_exact(CELL_WORDS)
            .map(|w| {
                let k = w[0];
                let index = [
                    k % dims[0],
                    (k / dims[0]) % dims[1],
                    k / (dims[0] * dims[1]),
                ];
                (
                    k,
                    Cell {
                        index,
                        count: w[1],
                        mean: [f(w[2]), f(w[3]), f(w[4])],
                        min: [f(w[5]), f(w[6]), f(w[7])],
                        max: [f(w[8]), f(w[9]), f(w[10])],
                        normal: (w[14] == 1).then(|| [f(w[11]), f(w[12]), f(w[13])]),
                        colour: w[15].to_le_bytes(),
                    },
                )
            })
            .collect();
        cells_out.sort_by_key(|c| c.0);
        let order: Vec<u32> = cells_out.iter().map(|c| c.0).collect();
        let of_point = keys
            .iter()
            .map(|k| order.binary_search(k).map_or(u32::MAX, |i| i as u32))
            .collect();
        let inside = keys.iter().filter(|&&k| k != u32::MAX).count();
        Reduced {
            cells: cells_out,
            of_point,
            inside,
            n,
        }
    }

    /// The reconstruct step (`reconstruct.wgsl` in `module`): the triangles of `kind` for the
    /// `n` reduced cells in a vertex buffer, and the time the step took (its pipeline not
    /// counted).
    fn reconstruct(
        &self,
        module: &wgpu::ShaderModule,
        n: usize,
        kind: super::Kind,
    ) -> (GpuMesh, Duration) {
        let (d, q) = (self.d, self.q);
        // As reconstruct.wgsl numbers the kinds, and the vertices each makes a cell.
        let (kind, per) = match kind {
            super::Kind::Quads => (0, 6),
            super::Kind::Boxes => (1, 36),
            super::Kind::Splats => (2, 18),
        };
        let vertices = (n * per) as u32;
        let buffer = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("surface vertices"),
            size: (vertices as u64 * 28).max(28),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::VERTEX,
            mapped_at_creation: false,
        });
        let pipeline = d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("reconstruct"),
            layout: None,
            module,
            entry_point: Some("reconstruct"),
            compilation_options: Default::default(),
            cache: None,
        });
        // As for the other steps, the pipeline is not counted.
        let t = Instant::now();
        let mut p = self.params(0);
        p.flags = [n as u32, kind, 0, 0];
        q.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&p));
        let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("reconstruct"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[(0, &self.uniform), (6, &self.out), (7, &buffer)].map(|(b, buf)| {
                wgpu::BindGroupEntry {
                    binding: b,
                    resource: buf.as_entire_binding(),
                }
            }),
        });
        let mut enc = d.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind, &[]);
            let (x, y) = groups(n as u32);
            pass.dispatch_workgroups(x, y, 1);
        }
        q.submit([enc.finish()]);
        self.wait();
        (GpuMesh { buffer, vertices }, t.elapsed())
    }
}
