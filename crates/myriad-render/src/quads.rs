//! The quad path, for adapters without 64-bit atomics: each point an instanced quad through the
//! fixed-function pipeline (quads.wgsl), covering the pixels the compute path's point covers,
//! into colour, normal and depth targets with a depth test. Nodes are drawn front to back when
//! asked (the depth test then rejects what lies behind before it is shaded). Blending draws the
//! points again, each fragment near enough behind the depth the first pass left added to the
//! blend target. Its CPU mirror is `cpu.rs`, as the compute path's.

use crate::Gpu;
use crate::draw::{Frame, UniformArray, radius_of, tree_buffer};
use crate::pipelines::{module, targets_pipeline};
use crate::points::{Draw, Layout};
use crate::targets::{BLEND_FORMAT, Targets};
use std::sync::OnceLock;

/// The quad path's shader: draw.wgsl, blend.wgsl, then quads.wgsl.
pub const QUADS_WGSL: &str = concat!(
    include_str!("draw.wgsl"),
    include_str!("blend.wgsl"),
    include_str!("quads.wgsl")
);

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

/// The quad path's pipelines, kept for the rasterizer's life (blending's made when first used).
pub(crate) struct QuadPass {
    module: wgpu::ShaderModule,
    quads: wgpu::RenderPipeline,
    blend: OnceLock<wgpu::RenderPipeline>,
}

impl QuadPass {
    pub fn new(gpu: &Gpu) -> QuadPass {
        // The points are read from storage by instance index (`decode`): no vertex buffer.
        let module = module(gpu, "quads", QUADS_WGSL);
        QuadPass {
            quads: targets_pipeline(gpu, "quads", &module, &[]),
            module,
            blend: OnceLock::new(),
        }
    }

    /// Blending's pipeline: the same quads, no depth test, each fragment added to the target.
    fn blend_pipeline(&self, gpu: &Gpu) -> &wgpu::RenderPipeline {
        self.blend.get_or_init(|| {
            let add = wgpu::BlendComponent {
                src_factor: wgpu::BlendFactor::One,
                dst_factor: wgpu::BlendFactor::One,
                operation: wgpu::BlendOperation::Add,
            };
            gpu.device()
                .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some("blend"),
                    layout: None,
                    vertex: wgpu::VertexState {
                        module: &self.module,
                        entry_point: Some("vertex"),
                        compilation_options: Default::default(),
                        buffers: &[],
                    },
                    primitive: wgpu::PrimitiveState::default(),
                    depth_stencil: None,
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &self.module,
                        entry_point: Some("blend"),
                        compilation_options: Default::default(),
                        targets: &[Some(wgpu::ColorTargetState {
                            format: BLEND_FORMAT,
                            blend: Some(wgpu::BlendState {
                                color: add,
                                alpha: add,
                            }),
                            write_mask: wgpu::ColorWrites::ALL,
                        })],
                    }),
                    multiview_mask: None,
                    cache: None,
                })
        })
    }

    /// Records the point pass of `draws` into the targets' colour, normal and depth; with
    /// `blend`, the second pass into the blend target.
    pub fn encode(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        t: &mut Targets,
        frame: &Frame,
        draws: &[&Draw],
        blend: bool,
    ) {
        if blend {
            t.blend_target(gpu);
        }
        let t = &*t;
        let d = gpu.device();
        let uniforms: Vec<_> = draws
            .iter()
            .map(|dr| {
                let layout = Layout::of(dr, frame.origin, frame.camera, frame.precision);
                frame.uniforms(
                    dr.count,
                    dr.spacing,
                    dr.node,
                    radius_of(dr),
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
        let depth = t.depth.as_ref().expect(QUADS);
        // Each draw's bindings in `pipeline`'s layout (blending's also reads the depth).
        let binds = |pipeline: &wgpu::RenderPipeline, near: bool| -> Vec<wgpu::BindGroup> {
            let layout = pipeline.get_bind_group_layout(0);
            (0..draws.len())
                .map(|i| {
                    let splats = draws[i].points.splat_buffer().unwrap_or(&no_splats);
                    let mut entries = vec![
                        entry(0, uniforms.at(i)),
                        entry(1, draws[i].points.buffer().as_entire_binding()),
                        entry(3, tree.as_entire_binding()),
                        entry(6, splats.as_entire_binding()),
                        entry(7, t.post.reject_binding()),
                    ];
                    if near {
                        entries.push(entry(9, wgpu::BindingResource::TextureView(depth)));
                    }
                    d.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("quads"),
                        layout: &layout,
                        entries: &entries,
                    })
                })
                .collect()
        };
        // Single-pass stereo: each point once per eye (instances beyond `count` are the right
        // eye's).
        let eyes_drawn = if frame.eyes.is_some() { 2 } else { 1 };
        let quads = binds(&self.quads, false);
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
        for (draw, bind) in draws.iter().zip(&quads) {
            pass.set_bind_group(0, bind, &[]);
            pass.draw(0..6, 0..draw.count * eyes_drawn);
        }
        drop(pass);
        if !blend {
            return;
        }
        let pipeline = self.blend_pipeline(gpu);
        let blends = binds(pipeline, true);
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("blend"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: t.blend.as_ref().expect("made above"),
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            ..Default::default()
        });
        pass.set_pipeline(pipeline);
        for (draw, bind) in draws.iter().zip(&blends) {
            pass.set_bind_group(0, bind, &[]);
            pass.draw(0..6, 0..draw.count * eyes_drawn);
        }
    }

    /// The targets as the g-buffer pass reads them (fb_quads.wgsl's bindings): the blend
    /// target where the frame blends.
    pub fn framebuffer(t: &Targets, blend: bool) -> Vec<wgpu::BindGroupEntry<'_>> {
        fn view(v: &Option<wgpu::TextureView>) -> wgpu::BindingResource<'_> {
            wgpu::BindingResource::TextureView(v.as_ref().expect(QUADS))
        }
        let entry = |binding, resource| wgpu::BindGroupEntry { binding, resource };
        vec![
            entry(1, view(&t.colour)),
            entry(2, view(&t.depth)),
            entry(4, view(&t.normal)),
            entry(
                5,
                wgpu::BindingResource::TextureView(match &t.blend {
                    Some(b) if blend => b,
                    _ => &t.no_blend_target,
                }),
            ),
        ]
    }
}
