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
    let limit = d.limits().max_storage_buffer_binding_size;
    if cells * STRIDE * 4 > limit || cells > u32::MAX as u64 / 2 {
        return Err(format!(
            "a grid of {cells} cells needs {} MB a binding, the device allows {} MB",
            (cells * STRIDE * 4) >> 20,
            limit >> 20
        ));
    }
    // The pipelines (compiled once in a session that keeps them) are not counted in the steps'
    // times; uploads and readbacks are.
    let module = crate::pipelines::module(gpu, "cluster.wgsl", RECONSTRUCT_WGSL);
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
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        })
    };
    let [clear, first, density, moved, spread, reduce] =
        ["clear", "first", "density", "moved", "spread", "reduce"].map(pipeline);
    let t = Instant::now();
    let eye: Vec<[f32; 4]> = super::cluster::to_eye(camera, points)
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
        .collect();
    let chunk = ((limit / 16).min(1 << 24) as usize).max(1);
    let (r, u, f) = camera.basis();
    let v4 = |v: [f64; 3]| [v[0] as f32, v[1] as f32, v[2] as f32, 0.0];
    let params = |n: usize| Params {
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
            n as u32,
            (s.density == super::Density::Planarity) as u32,
            (s.normals == Normals::Cells) as u32,
            cells as u32,
        ],
    };
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
        contents: bytemuck::bytes_of(&params(0)),
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
    });
    let n_chunk = chunk.min(eye.len()).max(1) as u64;
    let point_buf = storage("surface points", n_chunk * 16);
    let cell_of = storage("surface cell of", n_chunk * 4);
    let acc = storage("surface sums", cells * STRIDE * 4);
    let dens = storage("surface density", cells * 4);
    let counter = storage("surface counter", 16);
    let max_out = cells.min(eye.len() as u64).max(1);
    let out = storage("surface cells", max_out * CELL_WORDS as u64 * 4);

    let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("surface"),
        layout: &bgl,
        entries: &[&uniform, &point_buf, &cell_of, &acc, &dens, &counter, &out]
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect::<Vec<_>>(),
    });
    let run = |p: &wgpu::ComputePipeline, threads: u64| {
        let mut enc = d.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(p);
            pass.set_bind_group(0, &bind, &[]);
            let (x, y) = groups(threads as u32);
            pass.dispatch_workgroups(x, y, 1);
        }
        q.submit([enc.finish()]);
    };
    let wait = || {
        d.poll(wgpu::PollType::wait_indefinitely())
            .expect("wait for the surface");
    };
    // Each chunk: its points up, the pass, the cells they went to back; then, the means known,
    // each chunk again (points and cells up where there are several) for the tensor.
    let per_point = |p: &wgpu::ComputePipeline| -> Vec<u32> {
        let mut keys = Vec::with_capacity(eye.len());
        let parts = eye.len().div_ceil(chunk);
        for part in eye.chunks(chunk) {
            q.write_buffer(&point_buf, 0, bytemuck::cast_slice(part));
            q.write_buffer(&uniform, 0, bytemuck::bytes_of(&params(part.len())));
            run(p, part.len() as u64);
            keys.extend(
                bytemuck::cast_slice::<u8, u32>(&read(gpu, &cell_of, part.len() as u64 * 4))
                    .iter()
                    .copied(),
            );
        }
        for (part, k) in eye.chunks(chunk).zip(keys.chunks(chunk)) {
            if parts > 1 {
                q.write_buffer(&point_buf, 0, bytemuck::cast_slice(part));
                q.write_buffer(&cell_of, 0, bytemuck::cast_slice(k));
                q.write_buffer(&uniform, 0, bytemuck::bytes_of(&params(part.len())));
            }
            run(&spread, part.len() as u64);
        }
        q.write_buffer(&uniform, 0, bytemuck::bytes_of(&params(0)));
        keys
    };
    q.write_buffer(&uniform, 0, bytemuck::bytes_of(&params(0)));
    run(&clear, cells);
    let first_keys = per_point(&first);
    wait();
    let cluster_time = t.elapsed();

    let t = Instant::now();
    let (keys, moved_count) = if s.neighbours == 0 {
        (first_keys, 0)
    } else {
        run(&density, cells);
        run(&clear, cells);
        let keys = per_point(&moved);
        wait();
        let n = keys.iter().zip(&first_keys).filter(|(a, b)| a != b).count();
        (keys, n)
    };
    let moving = t.elapsed();

    let t = Instant::now();
    q.write_buffer(&counter, 0, &[0; 16]);
    run(&reduce, cells);
    let n = bytemuck::cast_slice::<u8, u32>(&read(gpu, &counter, 4))[0] as usize;
    let words = read(gpu, &out, (n * CELL_WORDS * 4) as u64);
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
    let reduce_time = t.elapsed();
    let most = n as u64 * 36 * 28;
    if triangles && most > limit {
        return Err(format!(
            "{n} cells' triangles need up to {} MB a binding, the device allows {} MB",
            most >> 20,
            limit >> 20
        ));
    }
    let mesh = triangles.then(|| {
        // As reconstruct.wgsl numbers the kinds, and the vertices each makes a cell.
        let (kind, per) = match s.kind {
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
            module: &module,
            entry_point: Some("reconstruct"),
            compilation_options: Default::default(),
            cache: None,
        });
        // As for the other steps, the pipeline is not counted.
        let t = Instant::now();
        let mut p = params(0);
        p.flags = [n as u32, kind, 0, 0];
        q.write_buffer(&uniform, 0, bytemuck::bytes_of(&p));
        let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("reconstruct"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[(0, &uniform), (6, &out), (7, &buffer)].map(|(b, buf)| {
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
        wait();
        (GpuMesh { buffer, vertices }, t.elapsed())
    });
    Ok((
        Clustering {
            cells: cells_out.into_iter().map(|c| c.1).collect(),
            of_point,
            inside,
            moved: moved_count,
            cluster: cluster_time,
            moving,
            reduce: reduce_time,
        },
        mesh,
    ))
}
