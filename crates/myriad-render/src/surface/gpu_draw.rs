//! The surface's triangles drawn on the GPU (`draw.wgsl`), the mirror of `cpu.rs`: a render
//! pipeline with a depth test into the quad path's targets, then the post passes on the GPU
//! (`post::chain`, the g-buffer read as `fb_quads.wgsl` reads the quad path's), read back.

use crate::post::View;
use crate::post::{Buffers, Chain};
use crate::{FB_QUADS_WGSL, Gpu, Style};
use myriad_core::Mesh;
use myriad_lod::Camera;
use wgpu::util::DeviceExt;

pub const DRAW_WGSL: &str = include_str!("draw.wgsl");

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Uniforms {
    view_proj: [[f32; 4]; 4],
    right: [f32; 4],
    up: [f32; 4],
    forward: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Vertex {
    position: [f32; 3],
    normal: [f32; 3],
    colour: [u8; 4],
}

/// The pipelines (made once, kept for every frame).
pub struct Drawer {
    pipeline: wgpu::RenderPipeline,
    chain: Chain,
    /// Surfaces are not blended: the g-buffer pass reads a texel of zeros.
    no_blend: wgpu::TextureView,
}

impl Drawer {
    pub fn new(gpu: &Gpu) -> Drawer {
        let module = crate::pipelines::module(gpu, "surface draw", DRAW_WGSL);
        let pipeline = crate::pipelines::targets_pipeline(
            gpu,
            "surface",
            &module,
            &[Some(wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<Vertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &wgpu::vertex_attr_array![
                    0 => Float32x3, 1 => Float32x3, 2 => Unorm8x4
                ],
            })],
        );
        Drawer {
            pipeline,
            chain: Chain::new(gpu, FB_QUADS_WGSL),
            no_blend: crate::pipelines::target(
                gpu,
                "no blend",
                (1, 1),
                crate::targets::BLEND_FORMAT,
                wgpu::TextureUsages::TEXTURE_BINDING,
            ),
        }
    }

    /// The image of `mesh` seen by `camera` with `style`'s passes and the headlight on (as
    /// [`super::draw`]): RGBA8, rows top to bottom.
    pub fn draw(&self, gpu: &Gpu, camera: &Camera, mesh: &Mesh, style: &Style) -> Vec<u8> {
        let o = camera.position;
        // Each triangle's own three vertices, its first vertex's normal and colour on each.
        let vertices: Vec<Vertex> = mesh
            .triangles
            .iter()
            .flat_map(|t| {
                let first = t[0] as usize;
                t.map(|i| {
                    let p = mesh.positions[i as usize];
                    Vertex {
                        position: [
                            (p[0] - o[0]) as f32,
                            (p[1] - o[1]) as f32,
                            (p[2] - o[2]) as f32,
                        ],
                        normal: mesh.normals[first],
                        colour: mesh.colours[first],
                    }
                })
            })
            .collect();
        let buffer = gpu
            .device()
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("surface vertices"),
                // Never an empty buffer (nothing is drawn from it then).
                contents: bytemuck::cast_slice(if vertices.is_empty() {
                    &[Vertex {
                        position: [0.0; 3],
                        normal: [0.0; 3],
                        colour: [0; 4],
                    }]
                } else {
                    &vertices[..]
                }),
                usage: wgpu::BufferUsages::VERTEX,
            });
        self.draw_vertices(gpu, camera, &buffer, vertices.len() as u32, style)
    }

    /// [`Drawer::draw`] of a surface built on this GPU: the triangles the reconstruct step left
    /// in GPU memory where there are any (relative to the eye they were made for: `camera` is
    /// that one), else its mesh.
    pub fn draw_built(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        built: &super::Built,
        style: &Style,
    ) -> Vec<u8> {
        match &built.gpu_mesh {
            Some(m) => self.draw_vertices(gpu, camera, &m.buffer, m.vertices, style),
            None => self.draw(gpu, camera, &built.mesh, style),
        }
    }

    /// Draws `count` vertices of `buffer` (28 bytes each, positions relative to `camera`'s).
    fn draw_vertices(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        buffer: &wgpu::Buffer,
        count: u32,
        style: &Style,
    ) -> Vec<u8> {
        let d = gpu.device();
        let mut passes = style.passes;
        passes.shade.get_or_insert_with(crate::Shade::default);
        let f = passes.factor();
        let c = crate::style::supersampled(camera, style, f).0;
        let (w, h) = (c.width, c.height);
        let view = View::new(&c, passes.sun(), style.background, f);
        let (r, u, fw) = c.basis();
        let o = c.position;
        let v4 = |v: [f64; 3]| [v[0] as f32, v[1] as f32, v[2] as f32, 0.0];
        let uniforms = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("surface uniforms"),
            contents: bytemuck::bytes_of(&Uniforms {
                view_proj: c.view_proj(o),
                right: v4(r),
                up: v4(u),
                forward: v4(fw),
            }),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
        let target = |label, format| crate::pipelines::target(gpu, label, (w, h), format, usage);
        let colour = target("surface colour", wgpu::TextureFormat::Rgba8Unorm);
        let normal = target("surface normal", wgpu::TextureFormat::Rgba8Unorm);
        let depth = target("surface depth", wgpu::TextureFormat::Depth32Float);
        let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("surface"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: uniforms.as_entire_binding(),
            }],
        });
        let mut enc = d.create_command_encoder(&Default::default());
        {
            let attachment = |v| {
                Some(wgpu::RenderPassColorAttachment {
                    view: v,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })
            };
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("surface"),
                color_attachments: &[attachment(&colour), attachment(&normal)],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            if count > 0 {
                pass.set_vertex_buffer(0, buffer.slice(..));
                pass.draw(0..count, 0..1);
            }
        }
        let out_pixels = ((w / f) * (h / f)) as u64;
        let buffers = Buffers::new(gpu, (w * h) as u64, out_pixels);
        let framebuffer = vec![
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(&colour),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::TextureView(&depth),
            },
            wgpu::BindGroupEntry {
                binding: 4,
                resource: wgpu::BindingResource::TextureView(&normal),
            },
            wgpu::BindGroupEntry {
                binding: 5,
                resource: wgpu::BindingResource::TextureView(&self.no_blend),
            },
        ];
        self.chain.encode(
            gpu,
            &mut enc,
            &buffers,
            framebuffer,
            &passes,
            &view,
            c.far as f32,
            c.near as f32,
            None,
        );
        gpu.queue().submit([enc.finish()]);
        super::gpu::read(gpu, &buffers.image, out_pixels * 4)
    }
}
