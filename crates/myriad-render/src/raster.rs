//! Drawing a frame: the compute path (64-bit atomics) or the quad path into a g-buffer, then the
//! post passes (`post`) and the readback.

pub(crate) use crate::pipelines::{target, targets_pipeline};
use crate::post::gpu::{Buffers, Chain};
use crate::post::{Passes, View};
use crate::{Draw, Gpu, PointSize, QUADS_WGSL, RASTER_WGSL, Shape, Style};
use myriad_lod::Camera;
use std::sync::Mutex;
use wgpu::util::DeviceExt;

const WORKGROUP: u32 = 128;
const COMPUTE: &str = "compute targets";

/// Which way points reach the pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Path {
    /// The compute rasterizer; needs 64-bit integer atomics.
    Compute,
    /// Instanced quads through the fixed-function pipeline, for any adapter.
    Quads,
    /// No GPU: the compute path's algorithm on the CPU.
    Cpu,
}

/// One draw's uniforms (as `Draw` in raster.wgsl and quads.wgsl).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct DrawUniforms {
    view_proj: [[f32; 4]; 4],
    width: u32,
    height: u32,
    count: u32,
    shape: u32,
    point_size: f32,
    spacing: f32,
    focal: f32,
    max_size: f32,
    far: f32,
    near: f32,
    node: u32,
    mode: u32,
    cube: [f32; 4],
    clip: [[f32; 4]; 2],
    eye: [[f32; 4]; 3],
    radius: [f32; 4],
    offset: [f32; 4],
    unit: [f32; 4],
    layout: [u32; 4],
    /// Single-pass stereo (compute path): the right eye's view-projection and, in `stereo[0]`,
    /// each eye's width in the side-by-side frame (0: one eye).
    view_proj_right: [[f32; 4]; 4],
    stereo: [u32; 4],
}

/// A draw's range in the compute path's frame buffer (as `Range` in raster.wgsl).
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

/// Where a draw's points are for a frame drawn relative to `origin`: their origin there, the
/// first word's step, their words and how many to read, as `decode` in draw.wgsl takes them.
pub(crate) struct Layout {
    pub offset: [f32; 3],
    pub unit: [f32; 3],
    pub words: u32,
    pub read: u32,
}

impl Layout {
    pub(crate) fn of(draw: &Draw, origin: [f64; 3], camera: &Camera, precision: f32) -> Layout {
        let o = draw.points.origin;
        Layout {
            offset: std::array::from_fn(|a| (o[a] - origin[a]) as f32),
            unit: draw.points.unit(),
            words: draw.points.words,
            read: draw.points.read_words(camera, precision),
        }
    }
}

/// The origin a frame's positions are drawn relative to (on every path): the first draw's.
pub(crate) fn frame_origin(draws: &[Draw], camera: &Camera) -> [f64; 3] {
    draws.first().map_or(camera.position, |d| d.points.origin)
}

/// The default of [`Rasterizer::precision`]: a point read with its first position words only
/// may move by at most half of this many pixels.
pub const DEFAULT_PRECISION: f32 = 0.1;

/// Buffers and textures of one image size, kept from frame to frame.
pub(crate) struct Targets {
    /// The g-buffer's size and the supersampling factor.
    pub(crate) size: (u32, u32, u32),
    /// Compute path: one u64 per pixel, and the splats' normals.
    pub(crate) framebuffer: Option<wgpu::Buffer>,
    normal_fb: Option<wgpu::Buffer>,
    /// Quad path: colour, splat normals and depth.
    colour: Option<wgpu::TextureView>,
    normal: Option<wgpu::TextureView>,
    pub(crate) depth: Option<wgpu::TextureView>,
    /// The frame's depth as occlusion queries test against it (`queries.rs`).
    pub(crate) query_depth: Option<wgpu::TextureView>,
    /// The post passes' g-buffers and the image.
    post: Buffers,
    readback: wgpu::Buffer,
    /// Compute path: the frame's points, copied from the draws' buffers.
    merged: Option<wgpu::Buffer>,
    /// And their splat codes (only splat draws' are copied), at the same indices.
    merged_splats: Option<wgpu::Buffer>,
    /// What `merged` holds: (buffer, first thread, first word, count) of each range copied.
    copied: std::collections::HashSet<(wgpu::Buffer, u32, u32, u32)>,
}

enum Pipelines {
    Compute {
        raster: wgpu::ComputePipeline,
        chain: Chain,
    },
    Quads {
        quads: wgpu::RenderPipeline,
        chain: Chain,
    },
    Cpu,
}

/// An image size and the hidden-area ellipse made for it.
type Ellipse = ((u32, u32), std::sync::Arc<Vec<bool>>);

/// The rasterizer's pipelines and frame targets.
pub struct Rasterizer {
    pipelines: Pipelines,
    pub(crate) targets: Mutex<Option<Targets>>,
    /// Occlusion queries' pipelines (made when first asked for) and what they need of the last
    /// frame.
    pub(crate) queries: std::sync::OnceLock<crate::queries::Pipelines>,
    pub(crate) last: Mutex<Option<crate::queries::Last>>,
    /// The CPU path keeps each frame's depth for occlusion queries once asked to
    /// ([`Rasterizer::keep_depth`]).
    keep_depth: std::sync::atomic::AtomicBool,
    /// Where frames go instead of being read back ([`Rasterizer::present_to`]).
    present: Mutex<Option<wgpu::TextureView>>,
    /// The last hidden-area ellipse made, by image size ([`crate::stereo::hidden_area`]).
    pub(crate) ellipse: Mutex<Option<Ellipse>>,
    pub path: Path,
    /// Precision per batch (Schütz 2022): a draw's points are read with as few position words
    /// as leave them within half this many pixels of where all words put them (0: all words).
    pub precision: f32,
    /// On the quad path, draw nodes front to back (002's reverse painter's order: the depth
    /// test then rejects what lies behind before it is shaded); else in the selection's order.
    pub front_to_back: bool,
}

/// Workgroups for `n` threads, as a 2D dispatch within the 65535 limit per dimension.
pub(crate) fn groups(n: u32) -> (u32, u32) {
    let g = n.div_ceil(WORKGROUP).max(1);
    let x = g.min(65535);
    (x, g.div_ceil(x))
}

pub(crate) fn module(gpu: &Gpu, label: &str, src: &str) -> wgpu::ShaderModule {
    gpu.device()
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(src.into()),
        })
}

pub(crate) fn compute(gpu: &Gpu, src: &str, entry: &str) -> wgpu::ComputePipeline {
    compute_in(gpu, &module(gpu, entry, src), entry)
}

/// The pipeline of one entry point of a compiled module.
pub(crate) fn compute_in(
    gpu: &Gpu,
    module: &wgpu::ShaderModule,
    entry: &str,
) -> wgpu::ComputePipeline {
    gpu.device()
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: None,
            module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        })
}

fn quads_pipeline(gpu: &Gpu) -> wgpu::RenderPipeline {
    // The points are read from storage by instance index (`decode`): no vertex buffer.
    targets_pipeline(gpu, "quads", &module(gpu, "quads", QUADS_WGSL), &[])
}

impl Rasterizer {
    /// The compute path where the device has 64-bit atomics, else quads; the CPU path on the
    /// CPU.
    pub fn new(gpu: &Gpu) -> Rasterizer {
        Rasterizer::with_path(
            gpu,
            if gpu.is_cpu() {
                Path::Cpu
            } else if gpu.atomics {
                Path::Compute
            } else {
                Path::Quads
            },
        )
    }

    /// A chosen path (the compute path needs `gpu.atomics`; the CPU path is the CPU's only).
    pub fn with_path(gpu: &Gpu, path: Path) -> Rasterizer {
        assert!(
            path != Path::Compute || gpu.atomics,
            "the compute path needs 64-bit atomics"
        );
        assert_eq!(
            path == Path::Cpu,
            gpu.is_cpu(),
            "the CPU path is for the CPU only"
        );
        let pipelines = match path {
            Path::Compute => Pipelines::Compute {
                raster: compute(gpu, RASTER_WGSL, "rasterize"),
                chain: Chain::new(gpu, include_str!("shaders/fb_atomic.wgsl")),
            },
            Path::Quads => Pipelines::Quads {
                quads: quads_pipeline(gpu),
                chain: Chain::new(gpu, include_str!("shaders/fb_quads.wgsl")),
            },
            Path::Cpu => Pipelines::Cpu,
        };
        Rasterizer {
            pipelines,
            targets: Mutex::new(None),
            queries: Default::default(),
            last: Mutex::new(None),
            keep_depth: Default::default(),
            present: Mutex::new(None),
            ellipse: Mutex::new(None),
            path,
            precision: DEFAULT_PRECISION,
            front_to_back: true,
        }
    }

    fn targets(&self, gpu: &Gpu, w: u32, h: u32, f: u32) -> Targets {
        let d = gpu.device();
        let pixels = (w * h) as u64;
        let out_pixels = ((w / f) * (h / f)) as u64;
        let buffer = |label, size, usage| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        let texture = |label, format| {
            target(
                gpu,
                label,
                (w, h),
                format,
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            )
        };
        let quads = self.path == Path::Quads;
        Targets {
            size: (w, h, f),
            framebuffer: (!quads).then(|| {
                buffer(
                    "framebuffer",
                    pixels * 8,
                    wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                )
            }),
            normal_fb: (!quads).then(|| {
                buffer(
                    "splat normals",
                    pixels * 4,
                    wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                )
            }),
            colour: quads.then(|| texture("colour", wgpu::TextureFormat::Rgba8Unorm)),
            normal: quads.then(|| texture("normal", wgpu::TextureFormat::Rgba8Unorm)),
            depth: quads.then(|| texture("depth", wgpu::TextureFormat::Depth32Float)),
            post: Buffers::new(gpu, pixels, out_pixels),
            readback: buffer(
                "readback",
                out_pixels * 4,
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
            merged: None,
            merged_splats: None,
            copied: Default::default(),
            query_depth: None,
        }
    }

    /// From now on, GPU paths draw each frame into `texture` (a view of an `Rgba8Unorm` texture
    /// with `STORAGE_BINDING` usage, on this device, of the camera's size) and return an empty
    /// image: no readback, for a window that shows the texture. None: read back again. The CPU
    /// path always returns its image.
    pub fn present_to(&self, texture: Option<wgpu::TextureView>) {
        *self.present.lock().unwrap_or_else(|e| e.into_inner()) = texture;
    }

    /// Draws `draws` seen by `camera` into a `camera.width` x `camera.height` image and reads it
    /// back: RGBA8, rows top to bottom. `tree` is the drawn tree the draws' nodes index
    /// (`myriad_lod::DrawnTree::entries`; empty when no draw has a node).
    pub fn render(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        draws: &[Draw],
        tree: &[[u32; 4]],
        style: &Style,
    ) -> Vec<u8> {
        self.render_eyes(gpu, camera, None, draws, tree, style, None)
    }

    /// [`Rasterizer::render`]; with `eyes` (the compute path), both eyes in one dispatch into
    /// a side-by-side frame: `camera` is then the left eye's, twice as wide. `hidden`: the
    /// pixels the point pass (compute path) and every post pass skip (a headset's hidden area;
    /// GPU paths only, the CPU's is `cpu::gbuffers`'s).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn render_eyes(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        eyes: Option<&[Camera; 2]>,
        draws: &[Draw],
        tree: &[[u32; 4]],
        style: &Style,
        hidden: Option<crate::post::gpu::Hidden>,
    ) -> Vec<u8> {
        let passes = style.passes;
        let f = self.factor(gpu, camera, &passes);
        let eyes = eyes.map(|e| e.map(|c| supersampled(&c, style, f).0));
        let (camera, style) = &supersampled(camera, style, f);
        let view = View {
            eye_width: eyes.map_or(0, |e| e[0].width),
            ..View::new(camera, &passes, style.background, f)
        };
        let normals = passes.normals();
        let origin = frame_origin(draws, camera);
        if self.path == Path::Cpu {
            let g = crate::cpu::gbuffer(camera, draws, tree, style, normals, self.precision);
            *self.last.lock().unwrap_or_else(|e| e.into_inner()) = Some(crate::queries::Last {
                camera: *camera,
                origin,
                depth: (self.keep_depth.load(std::sync::atomic::Ordering::Relaxed))
                    .then(|| g.depth.clone()),
            });
            return crate::post::run(g, &passes, &view);
        }
        *self.last.lock().unwrap_or_else(|e| e.into_inner()) = Some(crate::queries::Last {
            camera: *camera,
            origin,
            depth: None,
        });
        let (w, h) = (camera.width.max(1), camera.height.max(1));
        let out_pixels = ((w / f) * (h / f)) as u64;
        let d = gpu.device();
        let mut guard = self.targets.lock().unwrap_or_else(|e| e.into_inner());
        if guard.as_ref().is_none_or(|t| t.size != (w, h, f)) {
            *guard = Some(self.targets(gpu, w, h, f));
        }
        let mut draws: Vec<&Draw> = draws.iter().filter(|s| s.count > 0).collect();
        if self.path == Path::Quads && self.front_to_back && draws.iter().all(|d| d.node.is_some())
        {
            // Front to back by node (002's reverse painter's order): the depth test then rejects
            // the fragments of what lies behind before they are shaded. Ties keep their order.
            // Both eyes in one draw: from between them.
            let e = eyes.map_or(camera.position, |e| {
                std::array::from_fn(|a| (e[0].position[a] + e[1].position[a]) / 2.0)
            });
            let distance = |d: &Draw| {
                let b = d.node.expect("checked").1;
                (0..3)
                    .map(|a| (b.min[a] - e[a]).max(e[a] - b.max[a]).max(0.0).powi(2))
                    .sum::<f64>()
            };
            draws.sort_by(|a, b| distance(a).total_cmp(&distance(b)));
        }
        let (point_size, max_size, scale) = match style.size {
            PointSize::Fixed(px) => (px.max(1.0), px.max(1.0), 1.0),
            PointSize::Adaptive { scale, max } => (0.0, max.max(1.0), scale as f64),
        };
        let relative = |node: Option<(u32, myriad_core::Aabb)>, o: [f64; 3]| {
            node.map_or([0.0; 4], |(_, c)| {
                [
                    (c.min[0] - o[0]) as f32,
                    (c.min[1] - o[1]) as f32,
                    (c.min[2] - o[2]) as f32,
                    c.size()[0] as f32,
                ]
            })
        };
        let eye = {
            let (r, u, f) = camera.basis();
            [r, u, f].map(|v| [v[0] as f32, v[1] as f32, v[2] as f32, 0.0])
        };
        let radius_of = |p: &crate::Points| {
            p.splat_range()
                .map_or([0.0; 4], |[lo, hi]| [lo, hi, 1.0, 0.0])
        };
        let uniform = |count: u32,
                       spacing: f64,
                       node: Option<(u32, myriad_core::Aabb)>,
                       radius: [f32; 4],
                       mode: u32,
                       layout: Option<(Layout, u32)>| DrawUniforms {
            view_proj: eyes.map_or(camera.view_proj(origin), |e| e[0].view_proj(origin)),
            width: w,
            height: h,
            count,
            shape: match style.shape {
                Shape::Square => 0,
                Shape::Round => 1,
                Shape::Paraboloid => 2,
            },
            point_size,
            spacing: (spacing * scale) as f32,
            focal: camera.focal() as f32,
            max_size,
            far: camera.far as f32,
            near: camera.near as f32,
            node: node.map_or(u32::MAX, |n| n.0),
            mode,
            cube: relative(node, origin),
            clip: crate::Clip::uniforms(style.clip, origin),
            eye,
            radius,
            offset: layout.as_ref().map_or([0.0; 4], |(l, _)| {
                [l.offset[0], l.offset[1], l.offset[2], 0.0]
            }),
            unit: layout
                .as_ref()
                .map_or([0.0; 4], |(l, _)| [l.unit[0], l.unit[1], l.unit[2], 0.0]),
            layout: layout.map_or([0; 4], |(l, stride)| [0, stride, l.words, l.read]),
            view_proj_right: eyes.map_or([[0.0; 4]; 4], |e| e[1].view_proj(origin)),
            stereo: [eyes.map_or(0, |e| e[0].width), 0, 0, 0],
        };
        // The compute path draws batches of draws, each copied into one buffer (ranges starting
        // on workgroup boundaries) and drawn by one dispatch: on lavapipe every dispatch costs
        // about 2 ms of synchronisation, a frame has hundreds of nodes. A batch is as large as
        // a storage binding may be.
        // Per batch its draws (index, first thread, first word) and its threads and words.
        let mut batches: Vec<Vec<(usize, u32, u32)>> = Vec::new();
        let mut batch_points = Vec::new();
        let mut batch_words = Vec::new();
        // Per draw in batch order: whether its points must be copied this frame.
        let mut fresh: Vec<bool> = Vec::new();
        let limit = d.limits().max_storage_buffer_binding_size / 4;
        if self.path == Path::Compute {
            let (mut threads, mut words) = (0u64, 0u64);
            for (i, draw) in draws.iter().enumerate() {
                let n = (draw.count as u64).next_multiple_of(WORKGROUP as u64);
                let w = draw.count as u64 * (draw.points.arrays() as u64 + 1);
                if batches.is_empty() || words + w > limit || threads + n > limit {
                    batches.push(Vec::new());
                    batch_points.push(0);
                    batch_words.push(0);
                    (threads, words) = (0, 0);
                }
                batches
                    .last_mut()
                    .expect("pushed")
                    .push((i, threads as u32, words as u32));
                threads += n;
                words += w;
                *batch_points.last_mut().expect("pushed") = threads;
                *batch_words.last_mut().expect("pushed") = words;
            }
            let need = |v: &[u64]| v.iter().copied().max().unwrap_or(0).max(WORKGROUP as u64) * 4;
            let t = guard.as_mut().expect("targets made above");
            let buffer = |label, need: u64| {
                d.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: (need + need / 4).min(limit * 4).max(need),
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            if t.merged
                .as_ref()
                .is_none_or(|b| b.size() < need(&batch_words))
            {
                t.merged = Some(buffer("frame points", need(&batch_words)));
                t.copied.clear();
            }
            if t.merged_splats
                .as_ref()
                .is_none_or(|b| b.size() < need(&batch_points))
            {
                t.merged_splats = Some(buffer("frame splats", need(&batch_points)));
                t.copied.clear();
            }
            // What the frame buffer already holds from the last frame (one batch only: with
            // several, each overwrites the last) need not be copied again.
            let previous = std::mem::take(&mut t.copied);
            for batch in &batches {
                for &(i, start, base) in batch {
                    let item = (
                        draws[i].points.buffer().clone(),
                        start,
                        base,
                        draws[i].count,
                    );
                    fresh.push(batches.len() > 1 || !previous.contains(&item));
                    if batches.len() == 1 {
                        t.copied.insert(item);
                    }
                }
            }
        }
        let t = guard.as_ref().expect("targets made above");
        t.post.hide(gpu, hidden, f);
        // The compute path's second pass, for the splats' normals where the passes need them.
        let splats = draws.iter().any(|d| d.points.splat_buffer().is_some());
        let modes: &[u32] = if normals && splats { &[0, 1] } else { &[0] };

        // Every draw's (quads) or batch's (compute) uniforms in one buffer, at aligned offsets.
        let specs: Vec<DrawUniforms> = match self.path {
            Path::Quads => draws
                .iter()
                .map(|d| {
                    uniform(
                        d.count,
                        d.spacing,
                        d.node,
                        radius_of(d.points),
                        0,
                        Some((Layout::of(d, origin, camera, self.precision), d.points.len)),
                    )
                })
                .collect(),
            Path::Cpu => unreachable!("drawn above"),
            Path::Compute => modes
                .iter()
                .flat_map(|&mode| {
                    batch_points.iter().map(move |&n| {
                        uniform(
                            (n / WORKGROUP as u64) as u32,
                            0.0,
                            None,
                            [0.0; 4],
                            mode,
                            None,
                        )
                    })
                })
                .collect(),
        };
        let stride = (std::mem::size_of::<DrawUniforms>() as u64)
            .next_multiple_of(d.limits().min_uniform_buffer_offset_alignment as u64);
        let mut bytes = vec![0u8; (stride as usize * specs.len()).max(stride as usize)];
        for (i, u) in specs.iter().enumerate() {
            bytes[i * stride as usize..][..std::mem::size_of::<DrawUniforms>()]
                .copy_from_slice(bytemuck::bytes_of(u));
        }
        let uniforms = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("draws"),
            contents: &bytes,
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let uniform_at = |i: usize| {
            wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &uniforms,
                offset: i as u64 * stride,
                size: wgpu::BufferSize::new(std::mem::size_of::<DrawUniforms>() as u64),
            })
        };
        let entry = |binding, resource| wgpu::BindGroupEntry { binding, resource };
        let tree = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("drawn tree"),
            contents: if tree.is_empty() {
                &[0u8; 16]
            } else {
                bytemuck::cast_slice(tree)
            },
            usage: wgpu::BufferUsages::STORAGE,
        });
        // Bound where a draw has no splats (never read then).
        let no_splats = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("no splats"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });

        let mut enc = d.create_command_encoder(&Default::default());
        match &self.pipelines {
            Pipelines::Cpu => unreachable!("drawn above"),
            Pipelines::Compute { raster, .. } => {
                let fb = t.framebuffer.as_ref().expect(COMPUTE);
                let merged = t.merged.as_ref().expect("made above");
                let merged_splats = t.merged_splats.as_ref().expect("made with merged");
                let normal_fb = t.normal_fb.as_ref().expect(COMPUTE);
                enc.clear_buffer(fb, 0, None);
                enc.clear_buffer(normal_fb, 0, None);
                let layout = raster.get_bind_group_layout(0);
                let mut fresh = fresh.iter();
                for (u, (&mode, b)) in modes
                    .iter()
                    .flat_map(|m| std::iter::repeat(m).zip(0..batches.len()))
                    .enumerate()
                {
                    let (batch, total) = (&batches[b], batch_points[b]);
                    let mut ranges = Vec::with_capacity(batch.len());
                    let mut group_range = Vec::with_capacity((total / WORKGROUP as u64) as usize);
                    for (k, &(i, start, base)) in batch.iter().enumerate() {
                        let draw = draws[i];
                        // Mode 1 finds the points where mode 0 left them, unless later batches
                        // overwrote them.
                        let copy = if mode == 0 {
                            *fresh.next().expect("one per draw")
                        } else {
                            batches.len() > 1
                        };
                        let (n, len) = (draw.count as u64, draw.points.len as u64);
                        if copy {
                            // Array by array: the prefix of each (all of them in one copy when
                            // the draw is the whole node).
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
                        let l = Layout::of(draw, origin, camera, self.precision);
                        ranges.push(Range {
                            cube: relative(draw.node, origin),
                            offset: [l.offset[0], l.offset[1], l.offset[2], 0.0],
                            unit: [l.unit[0], l.unit[1], l.unit[2], 0.0],
                            spacing: (draw.spacing * scale) as f32,
                            node: draw.node.map_or(u32::MAX, |n| n.0),
                            start,
                            count: draw.count,
                            radius: radius_of(draw.points),
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
                    let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("raster"),
                        layout: &layout,
                        entries: &[
                            (0, uniform_at(u)),
                            (
                                1,
                                wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                                    buffer: merged,
                                    offset: 0,
                                    size: wgpu::BufferSize::new(batch_words[b].max(1) * 4),
                                }),
                            ),
                            (2, fb.as_entire_binding()),
                            (3, tree.as_entire_binding()),
                            (4, ranges.as_entire_binding()),
                            (5, group_range.as_entire_binding()),
                            (
                                6,
                                wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                                    buffer: merged_splats,
                                    offset: 0,
                                    size: wgpu::BufferSize::new(total * 4),
                                }),
                            ),
                            (7, normal_fb.as_entire_binding()),
                            (8, t.post.hidden_binding()),
                        ]
                        .map(|(binding, resource)| wgpu::BindGroupEntry { binding, resource }),
                    });
                    let mut pass = enc.begin_compute_pass(&Default::default());
                    pass.set_pipeline(raster);
                    pass.set_bind_group(0, &bind, &[]);
                    let (x, y) = groups(total as u32);
                    pass.dispatch_workgroups(x, y, 1);
                }
            }
            Pipelines::Quads { quads, .. } => {
                let layout = quads.get_bind_group_layout(0);
                let binds: Vec<wgpu::BindGroup> = (0..draws.len())
                    .map(|i| {
                        let splats = draws[i].points.splat_buffer().unwrap_or(&no_splats);
                        d.create_bind_group(&wgpu::BindGroupDescriptor {
                            label: Some("quads"),
                            layout: &layout,
                            entries: &[
                                entry(0, uniform_at(i)),
                                entry(1, draws[i].points.buffer().as_entire_binding()),
                                entry(3, tree.as_entire_binding()),
                                entry(6, splats.as_entire_binding()),
                            ],
                        })
                    })
                    .collect();
                let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("quads"),
                    color_attachments: &[t.colour.as_ref(), t.normal.as_ref()].map(|view| {
                        Some(wgpu::RenderPassColorAttachment {
                            view: view.expect("quad targets"),
                            depth_slice: None,
                            resolve_target: None,
                            ops: wgpu::Operations {
                                load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                                store: wgpu::StoreOp::Store,
                            },
                        })
                    }),
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: t.depth.as_ref().expect("quad targets"),
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Clear(1.0),
                            store: wgpu::StoreOp::Store,
                        }),
                        stencil_ops: None,
                    }),
                    ..Default::default()
                });
                pass.set_pipeline(quads);
                for (draw, bind) in draws.iter().zip(&binds) {
                    pass.set_bind_group(0, bind, &[]);
                    // Single-pass stereo: each point once per eye (instances beyond `count`
                    // are the right eye's).
                    let eyes_drawn = if eyes.is_some() { 2 } else { 1 };
                    pass.draw(0..6, 0..draw.count * eyes_drawn);
                }
            }
        }

        let present = self
            .present
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        let (framebuffer, chain) = match &self.pipelines {
            Pipelines::Cpu => unreachable!("drawn above"),
            Pipelines::Compute { chain, .. } => (
                vec![
                    entry(
                        2,
                        t.framebuffer.as_ref().expect(COMPUTE).as_entire_binding(),
                    ),
                    entry(4, t.normal_fb.as_ref().expect(COMPUTE).as_entire_binding()),
                ],
                chain,
            ),
            Pipelines::Quads { chain, .. } => {
                fn view(v: &Option<wgpu::TextureView>) -> wgpu::BindingResource<'_> {
                    wgpu::BindingResource::TextureView(v.as_ref().expect("quad targets"))
                }
                (
                    vec![
                        entry(1, view(&t.colour)),
                        entry(2, view(&t.depth)),
                        entry(4, view(&t.normal)),
                    ],
                    chain,
                )
            }
        };
        chain.encode(
            gpu,
            &mut enc,
            &t.post,
            framebuffer,
            &passes,
            &view,
            camera.far as f32,
            camera.near as f32,
            present.as_ref(),
        );
        if present.is_some() {
            gpu.queue().submit([enc.finish()]);
            return Vec::new();
        }
        enc.copy_buffer_to_buffer(&t.post.image, 0, &t.readback, 0, out_pixels * 4);
        gpu.queue().submit([enc.finish()]);
        let slice = t.readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |r| {
            r.expect("map the image for reading")
        });
        d.poll(wgpu::PollType::wait_indefinitely())
            .expect("wait for the frame");
        let out = slice.get_mapped_range().expect("mapped image").to_vec();
        t.readback.unmap();
        out
    }
}

/// The camera and style of a frame supersampled `f` times: `f` times the pixels on each side,
/// fixed point sizes and the largest adaptive size `f` times as many pixels.
pub(crate) fn supersampled(camera: &Camera, style: &Style, f: u32) -> (Camera, Style) {
    let mut c = *camera;
    c.width = camera.width.max(1) * f;
    c.height = camera.height.max(1) * f;
    let mut s = *style;
    let k = f as f32;
    s.size = match style.size {
        PointSize::Fixed(px) => PointSize::Fixed(px * k),
        PointSize::Adaptive { scale, max } => PointSize::Adaptive {
            scale,
            max: max * k,
        },
    };
    (c, s)
}

impl Rasterizer {
    /// From now on the CPU path keeps each frame's depth, for occlusion queries (the GPU paths
    /// keep theirs in any case).
    pub fn keep_depth(&self) {
        self.keep_depth
            .store(true, std::sync::atomic::Ordering::Relaxed);
    }

    /// Bytes the point pass reads for `draws` seen by `camera`: the position words each draw
    /// needs ([`crate::Points::read_words`] at the frame's supersampled size), the colours and
    /// splat codes.
    pub fn bytes_read(&self, gpu: &Gpu, camera: &Camera, draws: &[Draw], style: &Style) -> u64 {
        let f = self.factor(gpu, camera, &style.passes);
        let (camera, _) = supersampled(camera, style, f);
        draws
            .iter()
            .map(|d| {
                let read = d.points.read_words(&camera, self.precision);
                d.count as u64 * d.points.read_bytes(read) as u64
            })
            .sum()
    }

    /// The supersampling factor a frame gets: what the passes ask for, less where the GPU's
    /// framebuffer would not fit one storage binding or texture.
    pub(crate) fn factor(&self, gpu: &Gpu, camera: &Camera, passes: &Passes) -> u32 {
        let mut f = passes.factor();
        if let Some((d, _)) = gpu.wgpu() {
            let limits = d.limits();
            let (w, h) = (camera.width.max(1) as u64, camera.height.max(1) as u64);
            let fits = |f: u64| {
                w * h * f * f * 8 <= limits.max_storage_buffer_binding_size
                    && (w.max(h) * f) <= limits.max_texture_dimension_2d as u64
            };
            while f > 1 && !fits(f as u64) {
                f -= 1;
            }
        }
        f
    }
}
