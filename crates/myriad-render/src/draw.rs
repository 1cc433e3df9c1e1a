//! What both GPU point paths hand their shaders (draw.wgsl, shared by compute.wgsl and
//! quads.wgsl): one draw's uniforms, built from a frame's camera and style, packed at aligned
//! offsets into one buffer, and the drawn tree for adaptive point sizes.

use crate::points::Layout;
use crate::{Clip, Gpu, PointSize, Shape, Style};
use myriad_core::Aabb;
use myriad_lod::Camera;
use wgpu::util::DeviceExt;

/// One draw's uniforms (as `Draw` in draw.wgsl).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct DrawUniforms {
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

/// What every draw of a frame shares: the (supersampled) camera, both eyes for single-pass
/// stereo, the style, the origin positions are drawn relative to, the drawn tree the draws'
/// nodes index and the precision their positions are read with
/// ([`crate::Rasterizer::precision`]).
pub(crate) struct Frame<'a> {
    pub camera: &'a Camera,
    pub eyes: Option<[Camera; 2]>,
    pub style: &'a Style,
    pub origin: [f64; 3],
    pub tree: &'a [[u32; 4]],
    pub precision: f32,
}

impl Frame<'_> {
    /// The frame's size in pixels (at least 1 x 1).
    pub fn size(&self) -> (u32, u32) {
        (self.camera.width.max(1), self.camera.height.max(1))
    }

    /// Fixed point size, largest size and the adaptive sizes' scale.
    fn sizes(&self) -> (f32, f32, f64) {
        match self.style.size {
            PointSize::Fixed(px) => (px.max(1.0), px.max(1.0), 1.0),
            PointSize::Adaptive { scale, max } => (0.0, max.max(1.0), scale as f64),
        }
    }

    /// A draw's spacing as the shaders take it (times the adaptive scale).
    pub fn spacing(&self, spacing: f64) -> f32 {
        (spacing * self.sizes().2) as f32
    }

    /// A node's cube relative to the frame's origin: its lowest corner and side.
    pub fn relative(&self, node: Option<(u32, Aabb)>) -> [f32; 4] {
        let o = self.origin;
        node.map_or([0.0; 4], |(_, c)| {
            [
                (c.min[0] - o[0]) as f32,
                (c.min[1] - o[1]) as f32,
                (c.min[2] - o[2]) as f32,
                c.size()[0] as f32,
            ]
        })
    }

    /// One draw's uniforms: `count` points (the compute path: workgroups), their spacing, node
    /// and splat radius range, the compute pass's `mode` and, on the quad path, where the
    /// draw's points are and how far apart its arrays lie.
    pub fn uniforms(
        &self,
        count: u32,
        spacing: f64,
        node: Option<(u32, Aabb)>,
        radius: [f32; 4],
        mode: u32,
        layout: Option<(Layout, u32)>,
    ) -> DrawUniforms {
        let (camera, origin) = (self.camera, self.origin);
        let (w, h) = self.size();
        let (point_size, max_size, _) = self.sizes();
        let eye = {
            let (r, u, f) = camera.basis();
            [r, u, f].map(|v| [v[0] as f32, v[1] as f32, v[2] as f32, 0.0])
        };
        DrawUniforms {
            view_proj: self
                .eyes
                .map_or(camera.view_proj(origin), |e| e[0].view_proj(origin)),
            width: w,
            height: h,
            count,
            shape: match self.style.shape {
                Shape::Square => 0,
                Shape::Round => 1,
                Shape::Paraboloid => 2,
            },
            point_size,
            spacing: self.spacing(spacing),
            focal: camera.focal() as f32,
            max_size,
            far: camera.far as f32,
            near: camera.near as f32,
            node: node.map_or(u32::MAX, |n| n.0),
            mode,
            cube: self.relative(node),
            clip: Clip::uniforms(self.style.clip, origin),
            eye,
            radius,
            offset: layout.as_ref().map_or([0.0; 4], |(l, _)| {
                [l.offset[0], l.offset[1], l.offset[2], 0.0]
            }),
            unit: layout
                .as_ref()
                .map_or([0.0; 4], |(l, _)| [l.unit[0], l.unit[1], l.unit[2], 0.0]),
            layout: layout.map_or([0; 4], |(l, stride)| [0, stride, l.words, l.read]),
            view_proj_right: self.eyes.map_or([[0.0; 4]; 4], |e| e[1].view_proj(origin)),
            stereo: [self.eyes.map_or(0, |e| e[0].width), 0, 0, 0],
        }
    }
}

/// A draw's splat radius range as the shaders take it (zeros: no splats), and in w 1 where its
/// lone points are drawn small ([`crate::Draw::lone`]).
pub(crate) fn radius_of(draw: &crate::Draw) -> [f32; 4] {
    let whole = draw.lone as u32 as f32;
    (draw.points.splat_range()).map_or([0.0, 0.0, 0.0, whole], |[lo, hi]| [lo, hi, 1.0, whole])
}

/// Every draw's (quads) or batch's (compute) uniforms in one buffer, at aligned offsets.
pub(crate) struct UniformArray {
    buffer: wgpu::Buffer,
    stride: u64,
}

impl UniformArray {
    pub fn new(gpu: &Gpu, all: &[DrawUniforms]) -> UniformArray {
        let d = gpu.device();
        let size = std::mem::size_of::<DrawUniforms>();
        let stride =
            (size as u64).next_multiple_of(d.limits().min_uniform_buffer_offset_alignment as u64);
        let mut bytes = vec![0u8; (stride as usize * all.len()).max(stride as usize)];
        for (i, u) in all.iter().enumerate() {
            bytes[i * stride as usize..][..size].copy_from_slice(bytemuck::bytes_of(u));
        }
        let buffer = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("draws"),
            contents: &bytes,
            usage: wgpu::BufferUsages::UNIFORM,
        });
        UniformArray { buffer, stride }
    }

    /// The binding of the `i`th uniforms.
    pub fn at(&self, i: usize) -> wgpu::BindingResource<'_> {
        wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: &self.buffer,
            offset: i as u64 * self.stride,
            size: wgpu::BufferSize::new(std::mem::size_of::<DrawUniforms>() as u64),
        })
    }
}

/// The drawn tree (`myriad_lod::DrawnTree::entries`) as a storage buffer; a few zeros when empty.
pub(crate) fn tree_buffer(gpu: &Gpu, tree: &[[u32; 4]]) -> wgpu::Buffer {
    gpu.device()
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("drawn tree"),
            contents: if tree.is_empty() {
                &[0u8; 16]
            } else {
                bytemuck::cast_slice(tree)
            },
            usage: wgpu::BufferUsages::STORAGE,
        })
}
