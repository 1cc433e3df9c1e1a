//! Making the long-lived GPU objects (shader modules, compute and render pipelines, targets)
//! that the point paths, the post passes, the queries and the surfaces keep from frame to frame.

use crate::Gpu;

/// Threads per workgroup of every compute pass (`@workgroup_size` in the shaders).
pub(crate) const WORKGROUP: u32 = 128;

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

/// A 2D texture of one image size and its view.
pub(crate) fn target(
    gpu: &Gpu,
    label: &str,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::TextureView {
    gpu.device()
        .create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
        .create_view(&Default::default())
}

/// A render pipeline (`vertex` and `fragment` of `module`) into the quad path's targets: colour
/// and normal (RGBA8), depth (f32, nearer passes).
pub(crate) fn targets_pipeline(
    gpu: &Gpu,
    label: &str,
    module: &wgpu::ShaderModule,
    buffers: &[Option<wgpu::VertexBufferLayout>],
) -> wgpu::RenderPipeline {
    let target = Some(wgpu::ColorTargetState {
        format: wgpu::TextureFormat::Rgba8Unorm,
        blend: None,
        write_mask: wgpu::ColorWrites::ALL,
    });
    gpu.device()
        .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: None,
            vertex: wgpu::VertexState {
                module,
                entry_point: Some("vertex"),
                compilation_options: Default::default(),
                buffers,
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: wgpu::TextureFormat::Depth32Float,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module,
                entry_point: Some("fragment"),
                compilation_options: Default::default(),
                // Colour and normals.
                targets: &[target.clone(), target],
            }),
            multiview_mask: None,
            cache: None,
        })
}
