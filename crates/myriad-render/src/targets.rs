//! A frame's buffers and textures of one image size, kept from frame to frame while the size
//! stays: the point pass's framebuffer (compute path) or render targets (quad path), the post
//! passes' g-buffers, the readback, and the compute path's copy of the frame's points.

use crate::Gpu;
use crate::pipelines::target;
use crate::post::Buffers;

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

/// Buffers and textures of one image size, kept from frame to frame.
pub(crate) struct Targets {
    /// The g-buffer's size and the supersampling factor.
    pub(crate) size: (u32, u32, u32),
    /// Compute path: one u64 per pixel, and the splats' normals.
    pub(crate) framebuffer: Option<wgpu::Buffer>,
    pub(crate) normal_fb: Option<wgpu::Buffer>,
    /// Quad path: colour, splat normals and depth.
    pub(crate) colour: Option<wgpu::TextureView>,
    pub(crate) normal: Option<wgpu::TextureView>,
    pub(crate) depth: Option<wgpu::TextureView>,
    /// Blending, made when a frame first blends: the compute path's sums (four u32 a pixel),
    /// the quad path's (an `Rgba16Float` target added to); bound instead when a frame does not
    /// blend, four words of zeros and a texel of zeros.
    pub(crate) blend_fb: Option<wgpu::Buffer>,
    pub(crate) blend: Option<wgpu::TextureView>,
    pub(crate) no_blend: wgpu::Buffer,
    pub(crate) no_blend_target: wgpu::TextureView,
    /// The frame's depth as occlusion queries test against it (`queries.rs`).
    pub(crate) query_depth: Option<wgpu::TextureView>,
    /// The post passes' g-buffers and the image.
    pub(crate) post: Buffers,
    pub(crate) readback: wgpu::Buffer,
    /// Compute path: the frame's points, copied from the draws' buffers.
    pub(crate) merged: Option<wgpu::Buffer>,
    /// And their splat codes (only splat draws' are copied), at the same indices.
    pub(crate) merged_splats: Option<wgpu::Buffer>,
    /// What `merged` holds: (buffer, first thread, first word, count) of each range copied.
    pub(crate) copied: std::collections::HashSet<(wgpu::Buffer, u32, u32, u32)>,
}

impl Targets {
    /// For a g-buffer of `w` x `h` pixels, supersampled `f` times, drawn by `path`.
    pub fn new(gpu: &Gpu, path: Path, w: u32, h: u32, f: u32) -> Targets {
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
        let quads = path == Path::Quads;
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
            blend_fb: None,
            blend: None,
            no_blend: buffer("no blend", 16, wgpu::BufferUsages::STORAGE),
            no_blend_target: target(
                gpu,
                "no blend",
                (1, 1),
                BLEND_FORMAT,
                wgpu::TextureUsages::TEXTURE_BINDING,
            ),
        }
    }

    /// The compute path's blend sums, made on first use.
    pub fn blend_buffer(&mut self, gpu: &Gpu) {
        let (w, h, _) = self.size;
        self.blend_fb.get_or_insert_with(|| {
            gpu.device().create_buffer(&wgpu::BufferDescriptor {
                label: Some("blend"),
                size: (w * h) as u64 * 16,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        });
    }

    /// The quad path's blend target, made on first use.
    pub fn blend_target(&mut self, gpu: &Gpu) {
        let (w, h, _) = self.size;
        self.blend.get_or_insert_with(|| {
            target(
                gpu,
                "blend",
                (w, h),
                BLEND_FORMAT,
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            )
        });
    }
}

/// The quad path's blend target: red, green, blue times weight and the weights, added to by
/// blending (16-bit floats blend on every adapter).
pub(crate) const BLEND_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
