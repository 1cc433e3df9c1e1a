//! The CPU path's image on the window: written into a texture of its own each frame and drawn
//! by a paint callback whose fragment shader loads one texel (or, where the image is smaller
//! than the view, samples it bilinearly) and writes it, with no blending and no dithering.
//!
//! Why not an egui image: where the window's adapter is a software one (lavapipe: the machines
//! the CPU path draws on), egui's textured quad with blending and dithering cost about 22 ms a
//! frame over a 1050x720 view on two cores (measured by leaving it out); this pass about a
//! third of that (`view --orbit-frames`, figures in the guide). egui also makes a new texture
//! for each whole-image update. The pass's CPU mirror is the image itself: at the view's size
//! it is copied texel for texel (the viewer's test compares the window's screenshot with the
//! frame).

use eframe::egui;
use eframe::egui_wgpu::{self, CallbackResources, CallbackTrait, ScreenDescriptor};
use eframe::wgpu;

const SHADER: &str = "
@group(0) @binding(0) var image: texture_2d<f32>;
@group(0) @binding(1) var linear_sampler: sampler;

struct Out {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

// One triangle covering the viewport (egui sets it to the callback's rectangle).
@vertex
fn vs(@builtin(vertex_index) i: u32) -> Out {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    var o: Out;
    o.position = vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, 0.0, 1.0);
    o.uv = uv;
    return o;
}

// The image at the view's size: each pixel its texel.
@fragment
fn exact(o: Out) -> @location(0) vec4<f32> {
    let size = vec2<f32>(textureDimensions(image));
    let t = min(vec2<i32>(o.uv * size), vec2<i32>(size) - 1);
    return textureLoad(image, t, 0);
}

// A smaller image (drawn at a lower resolution while the camera moves): filtered.
@fragment
fn scaled(o: Out) -> @location(0) vec4<f32> {
    return textureSampleLevel(image, linear_sampler, o.uv, 0.0);
}
";

/// The pipelines and the texture, kept in egui's callback resources.
struct Resources {
    layout: wgpu::BindGroupLayout,
    exact: wgpu::RenderPipeline,
    scaled: wgpu::RenderPipeline,
    sampler: wgpu::Sampler,
    /// The view format the texture is read through: sRGB where the window's is, so that the
    /// bytes written are the image's bytes.
    view_format: wgpu::TextureFormat,
    texture: Option<(wgpu::Texture, wgpu::BindGroup)>,
}

/// Makes the pipelines for the window's format; once, when the window is made.
pub(crate) fn install(rs: &egui_wgpu::RenderState) {
    let device = &rs.device;
    let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("view blit"),
        source: wgpu::ShaderSource::Wgsl(SHADER.into()),
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("view blit"),
        entries: &[
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
        ],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("view blit"),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let pipeline = |entry: &str| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("view blit"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: rs.target_format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            primitive: Default::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            multiview_mask: None,
            cache: None,
        })
    };
    let resources = Resources {
        exact: pipeline("exact"),
        scaled: pipeline("scaled"),
        layout,
        sampler: device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("view blit"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        }),
        view_format: if rs.target_format.is_srgb() {
            wgpu::TextureFormat::Rgba8UnormSrgb
        } else {
            wgpu::TextureFormat::Rgba8Unorm
        },
        texture: None,
    };
    rs.renderer.write().callback_resources.insert(resources);
}

/// The frame's image (RGBA8, rows top to bottom) drawn over `rect`.
/// None: the image drawn last, again.
pub(crate) fn paint(
    painter: &egui::Painter,
    rect: egui::Rect,
    image: Option<Vec<u8>>,
    w: u32,
    h: u32,
) {
    painter.add(egui_wgpu::Callback::new_paint_callback(
        rect,
        Frame { image, w, h },
    ));
}

struct Frame {
    image: Option<Vec<u8>>,
    w: u32,
    h: u32,
}

impl CallbackTrait for Frame {
    fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        _screen: &ScreenDescriptor,
        _encoder: &mut wgpu::CommandEncoder,
        resources: &mut CallbackResources,
    ) -> Vec<wgpu::CommandBuffer> {
        let (Some(r), Some(image)) = (resources.get_mut::<Resources>(), &self.image) else {
            return Vec::new();
        };
        let size = wgpu::Extent3d {
            width: self.w.max(1),
            height: self.h.max(1),
            depth_or_array_layers: 1,
        };
        if image.len() != (size.width * size.height * 4) as usize {
            return Vec::new();
        }
        if r.texture.as_ref().is_none_or(|(t, _)| t.size() != size) {
            let texture = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("view blit"),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8Unorm,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[r.view_format],
            });
            let view = texture.create_view(&wgpu::TextureViewDescriptor {
                format: Some(r.view_format),
                ..Default::default()
            });
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("view blit"),
                layout: &r.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::TextureView(&view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::Sampler(&r.sampler),
                    },
                ],
            });
            r.texture = Some((texture, group));
        }
        let (texture, _) = r.texture.as_ref().expect("made above");
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            image,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * size.width),
                rows_per_image: Some(size.height),
            },
            size,
        );
        Vec::new()
    }

    fn paint(
        &self,
        info: egui::PaintCallbackInfo,
        pass: &mut wgpu::RenderPass<'static>,
        resources: &CallbackResources,
    ) {
        let Some(r) = resources.get::<Resources>() else {
            return;
        };
        let Some((texture, group)) = &r.texture else {
            return;
        };
        let view = info.viewport_in_pixels();
        let exact =
            texture.width() as i32 == view.width_px && texture.height() as i32 == view.height_px;
        pass.set_pipeline(if exact { &r.exact } else { &r.scaled });
        pass.set_bind_group(0, group, &[]);
        pass.draw(0..3, 0..1);
    }
}
