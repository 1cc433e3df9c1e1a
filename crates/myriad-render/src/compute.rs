//! The compute path (Schütz et al. 2021): one thread per point, the nearest point per pixel kept
//! by a 64-bit `atomicMax` of depth and colour (compute.wgsl). The frame's draws are copied into
//! one buffer in batches, each drawn by one dispatch; a second dispatch per batch blends the
//! fragments near each pixel's nearest (`Passes::blend`), another writes the splats' normals
//! where the passes need them. Its CPU mirror is `cpu.rs`.

use crate::Gpu;
use crate::draw::{Frame, UniformArray, radius_of, tree_buffer};
use crate::pipelines::{WORKGROUP, compute, groups};
use crate::points::{Draw, Layout};
use crate::targets::Targets;
use wgpu::util::DeviceExt;

/// The compute path's shader: draw.wgsl, blend.wgsl, then compute.wgsl.
pub const RASTER_WGSL: &str = concat!(
    include_str!("draw.wgsl"),
    include_str!("blend.wgsl"),
    include_str!("compute.wgsl")
);

const COMPUTE: &str = "compute targets";

/// A draw's range in the frame's buffer (as `Range` in compute.wgsl).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Range {
    cube: [f32; 4],
    offset: [f32; 4],
    unit: [f32; 4],
    spacing: f32,
    node: u32,
    start: u32,
    count: u32,
    radius: [f32; 4],
    base: u32,
    stride: u32,
    words: u32,
    read: u32,
}

/// The frame's draws in batches, each copied into one buffer (ranges starting on workgroup
/// boundaries) and drawn by one dispatch: on lavapipe every dispatch costs about 2 ms of
/// synchronisation, and a frame has hundreds of nodes. A batch is as large as a storage binding
/// may be.
struct Batches {
    /// Per batch its draws: (index, first thread, first word).
    draws: Vec<Vec<(usize, u32, u32)>>,
    /// Per batch its threads and words.
    points: Vec<u64>,
    words: Vec<u64>,
    /// Per draw in batch order: whether its points must be copied this frame.
    fresh: Vec<bool>,
}

impl Batches {
    /// Batches `draws`, growing the targets' frame buffers where they are too small; what they
    /// already hold from the last frame (one batch only: with several, each overwrites the
    /// last) is not copied again.
    fn plan(gpu: &Gpu, t: &mut Targets, draws: &[&Draw]) -> Batches {
        let d = gpu.device();
        let mut b = Batches {
            draws: Vec::new(),
            points: Vec::new(),
            words: Vec::new(),
            fresh: Vec::new(),
        };
        let limit = d.limits().max_storage_buffer_binding_size / 4;
        let (mut threads, mut words) = (0u64, 0u64);
        for (i, draw) in draws.iter().enumerate() {
            let n = (draw.count as u64).next_multiple_of(WORKGROUP as u64);
            let w = draw.count as u64 * (draw.points.arrays() as u64 + 1);
            if b.draws.is_empty() || words + w > limit || threads + n > limit {
                b.draws.push(Vec::new());
                b.points.push(0);
                b.words.push(0);
                (threads, words) = (0, 0);
            }
            b.draws
                .last_mut()
                .expect("pushed")
                .push((i, threads as u32, words as u32));
            threads += n;
            words += w;
            *b.points.last_mut().expect("pushed") = threads;
            *b.words.last_mut().expect("pushed") = words;
        }
        let need = |v: &[u64]| v.iter().copied().max().unwrap_or(0).max(WORKGROUP as u64) * 4;
        let buffer = |label, need: u64| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (need + need / 4).min(limit * 4).max(need),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        if t.merged.as_ref().is_none_or(|m| m.size() < need(&b.words)) {
            t.merged = Some(buffer("frame points", need(&b.words)));
            t.copied.clear();
        }
        if t.merged_splats
            .as_ref()
            .is_none_or(|m| m.size() < need(&b.points))
        {
            t.merged_splats = Some(buffer("frame splats", need(&b.points)));
            t.copied.clear();
        }
        let previous = std::mem::take(&mut t.copied);
        let single = b.draws.len() == 1;
        for batch in &b.draws {
            for &(i, start, base) in batch {
                let item = (
                    draws[i].points.buffer().clone(),
                    start,
                    base,
                    draws[i].count,
                );
                b.fresh.push(!single || !previous.contains(&item));
                if single {
                    t.copied.insert(item);
                }
            }
        }
        b
    }
}

/// The compute path's pipeline, kept for the rasterizer's life.
pub(crate) struct ComputePass {
    raster: wgpu::ComputePipeline,
}

impl ComputePass {
    pub fn new(gpu: &Gpu) -> ComputePass {
        ComputePass {
            raster: compute(gpu, RASTER_WGSL, "rasterize"),
        }
    }

    /// Records the point pass of `draws` into the targets' framebuffer (with `blend`, the
    /// blend's sums; with `normals` and splats among the draws, the splats' normals).
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        t: &mut Targets,
        frame: &Frame,
        draws: &[&Draw],
        normals: bool,
        blend: bool,
    ) {
        let d = gpu.device();
        let batches = Batches::plan(gpu, t, draws);
        if blend {
            t.blend_buffer(gpu);
        }
        let t = &*t;
        // After the nearest: the blend, and the splats' normals where the passes need them.
        let splats = draws.iter().any(|d| d.points.splat_buffer().is_some());
        let mut modes = vec![0];
        if blend {
            modes.push(2);
        }
        if normals && splats {
            modes.push(1);
        }
        let uniforms: Vec<_> = modes
            .iter()
            .flat_map(|&mode| {
                batches.points.iter().map(move |&n| {
                    frame.uniforms(
                        (n / WORKGROUP as u64) as u32,
                        0.0,
                        None,
                        [0.0; 4],
                        mode,
                        None,
                    )
                })
            })
            .collect();
        let uniforms = UniformArray::new(gpu, &uniforms);
        let tree = tree_buffer(gpu, frame.tree);
        let fb = t.framebuffer.as_ref().expect(COMPUTE);
        let merged = t.merged.as_ref().expect("made by plan");
        let merged_splats = t.merged_splats.as_ref().expect("made with merged");
        let normal_fb = t.normal_fb.as_ref().expect(COMPUTE);
        enc.clear_buffer(fb, 0, None);
        enc.clear_buffer(normal_fb, 0, None);
        let blend_fb = Self::blend_fb(t, blend);
        if blend {
            enc.clear_buffer(blend_fb, 0, None);
        }
        let layout = self.raster.get_bind_group_layout(0);
        let mut fresh = batches.fresh.iter();
        let n_batches = batches.draws.len();
        for (u, (&mode, b)) in modes
            .iter()
            .flat_map(|m| std::iter::repeat(m).zip(0..n_batches))
            .enumerate()
        {
            let (batch, total) = (&batches.draws[b], batches.points[b]);
            let mut ranges = Vec::with_capacity(batch.len());
            let mut group_range = Vec::with_capacity((total / WORKGROUP as u64) as usize);
            for (k, &(i, start, base)) in batch.iter().enumerate() {
                let draw = draws[i];
                // Modes 1 and 2 find the points where mode 0 left them, unless later batches
                // overwrote them.
                let copy = if mode == 0 {
                    *fresh.next().expect("one per draw")
                } else {
                    n_batches > 1
                };
                let (n, len) = (draw.count as u64, draw.points.len as u64);
                if copy {
                    // Array by array: the prefix of each (all of them in one copy when the draw
                    // is the whole node).
                    let arrays = draw.points.arrays() as u64 + 1;
                    let runs = if n == len { 1 } else { arrays };
                    for a in 0..runs {
                        enc.copy_buffer_to_buffer(
                            draw.points.buffer(),
                            a * len * 4,
                            merged,
                            (base as u64 + a * n) * 4,
                            if runs == 1 { arrays * n * 4 } else { n * 4 },
                        );
                    }
                    if let Some(sb) = draw.points.splat_buffer() {
                        enc.copy_buffer_to_buffer(
                            sb,
                            0,
                            merged_splats,
                            start as u64 * 4,
                            draw.count as u64 * 4,
                        );
                    }
                }
                let l = Layout::of(draw, frame.origin, frame.camera, frame.precision);
                ranges.push(Range {
                    cube: frame.relative(draw.node),
                    offset: [l.offset[0], l.offset[1], l.offset[2], 0.0],
                    unit: [l.unit[0], l.unit[1], l.unit[2], 0.0],
                    spacing: frame.spacing(draw.spacing),
                    node: draw.node.map_or(u32::MAX, |n| n.0),
                    start,
                    count: draw.count,
                    radius: radius_of(draw),
                    base,
                    stride: draw.count,
                    words: l.words,
                    read: l.read,
                });
                let groups = draw.count.div_ceil(WORKGROUP);
                group_range.extend(std::iter::repeat_n(k as u32, groups as usize));
            }
            let storage = |label, contents: &[u8]| {
                d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage: wgpu::BufferUsages::STORAGE,
                })
            };
            let ranges = storage("ranges", bytemuck::cast_slice(&ranges));
            let group_range = storage("group ranges", bytemuck::cast_slice(&group_range));
            let part = |buffer, size| {
                wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer,
                    offset: 0,
                    size: wgpu::BufferSize::new(size),
                })
            };
            let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("raster"),
                layout: &layout,
                entries: &[
                    (0, uniforms.at(u)),
                    (1, part(merged, batches.words[b].max(1) * 4)),
                    (2, fb.as_entire_binding()),
                    (3, tree.as_entire_binding()),
                    (4, ranges.as_entire_binding()),
                    (5, group_range.as_entire_binding()),
                    (6, part(merged_splats, total * 4)),
                    (7, normal_fb.as_entire_binding()),
                    (8, t.post.hidden_binding()),
                    (9, blend_fb.as_entire_binding()),
                ]
                .map(|(binding, resource)| wgpu::BindGroupEntry { binding, resource }),
            });
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.raster);
            pass.set_bind_group(0, &bind, &[]);
            let (x, y) = groups(total as u32);
            pass.dispatch_workgroups(x, y, 1);
        }
    }

    /// The blend's sums where the frame blends (made by `encode`), else four words of zeros.
    fn blend_fb(t: &Targets, blend: bool) -> &wgpu::Buffer {
        match &t.blend_fb {
            Some(b) if blend => b,
            _ => &t.no_blend,
        }
    }

    /// The framebuffer as the g-buffer pass reads it (fb_atomic.wgsl's bindings).
    pub fn framebuffer(t: &Targets, blend: bool) -> Vec<wgpu::BindGroupEntry<'_>> {
        let entry = |binding, resource| wgpu::BindGroupEntry { binding, resource };
        vec![
            entry(
                2,
                t.framebuffer.as_ref().expect(COMPUTE).as_entire_binding(),
            ),
            entry(4, t.normal_fb.as_ref().expect(COMPUTE).as_entire_binding()),
            entry(5, Self::blend_fb(t, blend).as_entire_binding()),
        ]
    }
}
