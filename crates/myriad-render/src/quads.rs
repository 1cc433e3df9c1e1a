//! The quad path, for adapters without 64-bit atomics: each point an instanced quad through the
//! fixed-function pipeline (quads.wgsl), covering the pixels the compute path's point covers,
//! into colour, normal and depth targets with a depth test. Nodes are drawn front to back when
//! asked (the depth test then rejects what lies behind before it is shaded). Its CPU mirror is
//! `cpu.rs`, as the compute path's.

use crate::Gpu;
use crate::draw::{Frame, UniformArray, radius_of, tree_buffer};
use crate::pipelines::{module, targets_pipeline};
use crate::points::{Draw, Layout};
use crate::targets::Targets;

/// The quad path's shader: draw.wgsl, then quads.wgsl.
pub const QUADS_WGSL: &str = concat!(include_str!("draw.wgsl"), include_str!("quads.wgsl"));

const QUADS: &str = "quad targets";

/// Sorts draws front to back by their nodes' cubes, seen from `eye` (the reverse painter's
/// order); ties keep their order. Draws without a node leave the order as it is.
pub(crate) fn front_to_back(draws: &mut [&Draw], eye: [f64; 3]) {
    if !draws.iter().all(|d| d.node.is_some()) {
        return;
    }
    let distance = |d: &Draw| {
        let b = d.node.expect("checked").1;
        (0..3)
            .map(|a| (b.min[a] - eye[a]).max(eye[a] - b.max[a]).max(0.0).powi(2))
            .sum::<f64>()
    };
    draws.sort_by(|a, b| distance(a).total_cmp(&distance(b)));
}

/// The quad path's pipeline, kept for the rasterizer's life.
pub(crate) struct QuadPass {
    quads: wgpu::RenderPipeline,
}

impl QuadPass {
    pub fn new(gpu: &Gpu) -> QuadPass {
        // The points are read from storage by instance index (`decode`): no vertex buffer.
        QuadPass {
            quads: targets_pipeline(gpu, "quads", &module(gpu, "quads", QUADS_WGSL), &[]),
        }
    }

    /// Records the point pass of `draws` into the targets' colour, normal and depth.
    pub fn encode(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        t: &Targets,
        frame: &Frame,
        draws: &[&Draw],
    ) {
        let d = gpu.device();
        let uniforms: Vec<_> = draws
            .iter()
            .map(|dr| {
                let layout = Layout::of(dr, frame.origin, frame.camera, frame.precision);
                frame.uniforms(
                    dr.count,
                    dr.spacing,
                    dr.node,
                    radius_of(dr.points),
                    0,
                    Some((layout, dr.points.len)),
                )
            })
            .collect();
        let uniforms = UniformArray::new(gpu, &uniforms);
        let tree = tree_buffer(gpu, frame.tree);
        // Bound where a draw has no splats (never read then).
        let no_splats = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("no splats"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let entry = |binding, resource| wgpu::BindGroupEntry { binding, resource };
        let layout = self.quads.get_bind_group_layout(0);
        let binds: Vec<wgpu::BindGroup> = (0..draws.len())
            .map(|i| {
                let splats = draws[i].points.splat_buffer().unwrap_or(&no_splats);
                d.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("quads"),
                    layout: &layout,
                    entries: &[
                        entry(0, uniforms.at(i)),
                        entry(1, draws[i].points.buffer().as_entire_binding()),
                        entry(3, tree.as_entire_binding()),
                        entry(6, splats.as_entire_binding()),
                        entry(7, t.post.reject_binding()),
                    ],
                })
            })
            .collect();
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("quads"),
            color_attachments: &[t.colour.as_ref(), t.normal.as_ref()].map(|view| {
                Some(wgpu::RenderPassColorAttachment {
                    view: view.expect(QUADS),
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })
            }),
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: t.depth.as_ref().expect(QUADS),
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            ..Default::default()
        });
        pass.set_pipeline(&self.quads);
        // Single-pass stereo: each point once per eye (instances beyond `count` are the right
        // eye's).
        let eyes_drawn = if frame.eyes.is_some() { 2 } else { 1 };
        for (draw, bind) in draws.iter().zip(&binds) {
            pass.set_bind_group(0, bind, &[]);
            pass.draw(0..6, 0..draw.count * eyes_drawn);
        }
    }

    /// The targets as the g-buffer pass reads them (fb_quads.wgsl's bindings).
    pub fn framebuffer(t: &Targets) -> Vec<wgpu::BindGroupEntry<'_>> {
        fn view(v: &Option<wgpu::TextureView>) -> wgpu::BindingResource<'_> {
            wgpu::BindingResource::TextureView(v.as_ref().expect(QUADS))
        }
        let entry = |binding, resource| wgpu::BindGroupEntry { binding, resource };
        vec![
            entry(1, view(&t.colour)),
            entry(2, view(&t.depth)),
            entry(4, view(&t.normal)),
        ]
    }
}
