//! The renderer's main path: a compute-shader rasterizer (one thread per point, the nearest point
//! per pixel kept by a 64-bit `atomicMax` of depth and colour, then a resolve pass; Schütz et al.
//! 2021), on a headless target read back to RGBA. PLATFORM.md measured it 20-40x faster than
//! fixed-function points on lavapipe. Shaders are in `src/shaders/*.wgsl`, validated by a naga
//! test that needs no GPU.
//!
//! Reads no files: points arrive as [`Points`] (positions relative to an origin, RGBA8 colour).

use myriad_lod::Camera;
use wgpu::util::DeviceExt;

pub const RASTER_WGSL: &str = include_str!("shaders/raster.wgsl");
pub const RESOLVE_WGSL: &str = include_str!("shaders/resolve.wgsl");

const WORKGROUP: u32 = 128;

/// A device and queue, without a window.
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub adapter: wgpu::AdapterInfo,
}

impl Gpu {
    /// The first adapter with 64-bit integer atomics (a real GPU or lavapipe), without a surface.
    pub fn headless() -> Result<Gpu, String> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        }))
        .map_err(|e| format!("no GPU adapter: {e}"))?;
        let needed = wgpu::Features::SHADER_INT64 | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX;
        let info = adapter.get_info();
        if !adapter.features().contains(needed) {
            return Err(format!(
                "adapter {} lacks 64-bit atomics (the quad path for such adapters is not built yet)",
                info.name
            ));
        }
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("myriad"),
            required_features: needed,
            required_limits: limits,
            ..Default::default()
        }))
        .map_err(|e| format!("{}: {e}", info.name))?;
        Ok(Gpu {
            device,
            queue,
            adapter: info,
        })
    }
}

/// Points on the GPU: positions relative to `origin` (f32) and an RGBA8 colour each.
pub struct Points {
    pub origin: [f64; 3],
    buffer: wgpu::Buffer,
    pub count: u32,
    /// World spacing of these points, for adaptive point sizes.
    pub spacing: f64,
}

impl Points {
    pub fn upload(gpu: &Gpu, origin: [f64; 3], positions: &[[f64; 3]], rgba: &[[u8; 4]]) -> Points {
        assert_eq!(positions.len(), rgba.len());
        let data: Vec<[f32; 4]> = positions
            .iter()
            .zip(rgba)
            .map(|(p, c)| {
                [
                    (p[0] - origin[0]) as f32,
                    (p[1] - origin[1]) as f32,
                    (p[2] - origin[2]) as f32,
                    f32::from_bits(u32::from_le_bytes(*c)),
                ]
            })
            .collect();
        let buffer = gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("points"),
                // An empty storage binding is not allowed: keep one dummy element.
                contents: if data.is_empty() {
                    &[0u8; 16]
                } else {
                    bytemuck::cast_slice(&data)
                },
                usage: wgpu::BufferUsages::STORAGE,
            });
        Points {
            origin,
            buffer,
            count: positions.len() as u32,
            spacing: 0.0,
        }
    }
}

/// What a point's colour shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColorBy {
    /// Its RGB (16-bit, scaled down; 8-bit values stored in 16-bit fields taken as they are);
    /// the elevation ramp where there is none.
    Rgb,
    /// Grey levels.
    Intensity,
    /// A blue-green-yellow-red ramp over the dataset's height.
    Elevation,
    /// The usual colours of the ASPRS classes (ground brown, vegetation greens, building red,
    /// water blue, ...).
    Classification,
    ReturnNumber,
    PointSource,
    /// The node's level in the tree.
    Level,
}

impl ColorBy {
    pub fn parse(s: &str) -> Option<ColorBy> {
        Some(match s {
            "rgb" => ColorBy::Rgb,
            "intensity" => ColorBy::Intensity,
            "elevation" => ColorBy::Elevation,
            "classification" => ColorBy::Classification,
            "return" | "return-number" => ColorBy::ReturnNumber,
            "source" | "point-source" => ColorBy::PointSource,
            "level" | "lod" => ColorBy::Level,
            _ => return None,
        })
    }
}

/// Colour of ASPRS class `c` (LAS 1.4 table 17 names them; the colours are the usual ones).
pub fn class_colour(c: u8) -> [u8; 3] {
    match c {
        0 => [128, 128, 128],
        1 => [170, 170, 170],
        2 => [166, 120, 72],
        3 => [144, 238, 144],
        4 => [60, 179, 113],
        5 => [0, 110, 0],
        6 => [230, 90, 60],
        7 => [255, 0, 255],
        8 => [255, 255, 0],
        9 => [40, 100, 255],
        10 => [150, 75, 0],
        11 => [90, 90, 90],
        12 => [255, 215, 0],
        13 => [255, 255, 255],
        14 => [200, 200, 200],
        15 => [255, 140, 0],
        16 => [200, 100, 200],
        17 => [140, 140, 200],
        18 => [255, 0, 0],
        c => palette(c as u32),
    }
}

/// A distinct colour for a small integer (return numbers, sources, levels).
fn palette(i: u32) -> [u8; 3] {
    const P: [[u8; 3]; 10] = [
        [230, 25, 75],
        [60, 180, 75],
        [255, 225, 25],
        [0, 130, 200],
        [245, 130, 48],
        [145, 30, 180],
        [70, 240, 240],
        [240, 50, 230],
        [210, 245, 60],
        [250, 190, 212],
    ];
    P[i as usize % P.len()]
}

fn ramp(t: f64) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    // Blue, green, yellow, red.
    let (r, g, b) = if t < 0.5 {
        (0.0, 2.0 * t, 1.0 - 2.0 * t)
    } else {
        (2.0 * t - 1.0, 2.0 - 2.0 * t, 0.0)
    };
    [(r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8]
}

/// RGBA8 colours of a batch's first `n` points by `scheme`; `z_range` spans the elevation ramp,
/// `level` is the node's level. A scheme whose attribute the batch lacks falls back to elevation.
pub fn colours(
    b: &myriad_core::PointBatch,
    n: usize,
    scheme: ColorBy,
    z_range: (f64, f64),
    level: u32,
) -> Vec<[u8; 4]> {
    let rgba = |c: [u8; 3]| [c[0], c[1], c[2], 255];
    let elevation = || {
        let (lo, hi) = z_range;
        b.positions[..n]
            .iter()
            .map(|p| rgba(ramp((p[2] - lo) / (hi - lo).max(1e-9))))
            .collect()
    };
    match scheme {
        ColorBy::Rgb => match &b.rgb {
            Some(rgb) => {
                let wide = rgb[..n].iter().any(|c| c.iter().any(|&v| v > 255));
                let f = |v: u16| if wide { (v >> 8) as u8 } else { v as u8 };
                rgb[..n].iter().map(|c| rgba(c.map(f))).collect()
            }
            None => elevation(),
        },
        ColorBy::Intensity => match &b.intensity {
            Some(i) => {
                let wide = i[..n].iter().any(|&v| v > 255);
                i[..n]
                    .iter()
                    .map(|&v| {
                        let g = if wide { (v >> 8) as u8 } else { v as u8 };
                        rgba([g, g, g])
                    })
                    .collect()
            }
            None => elevation(),
        },
        ColorBy::Elevation => elevation(),
        ColorBy::Classification => match &b.classification {
            Some(c) => c[..n].iter().map(|&c| rgba(class_colour(c))).collect(),
            None => elevation(),
        },
        ColorBy::ReturnNumber => match &b.return_number {
            Some(r) => r[..n].iter().map(|&r| rgba(palette(r as u32))).collect(),
            None => elevation(),
        },
        ColorBy::PointSource => match &b.point_source_id {
            Some(s) => s[..n].iter().map(|&s| rgba(palette(s as u32))).collect(),
            None => elevation(),
        },
        ColorBy::Level => vec![rgba(palette(level)); n],
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Uniforms {
    view_proj: [[f32; 4]; 4],
    width: u32,
    height: u32,
    count: u32,
    /// The background colour for the resolve pass (RGBA8 bits).
    background: u32,
    point_size: f32,
    spacing: f32,
    focal: f32,
    max_size: f32,
}

/// How big a point is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PointSize {
    /// This many pixels on a side.
    Fixed(f32),
    /// The spacing of the point's level of detail (pulled up, see `myriad_lod::select`) as seen
    /// at the point's depth, at most `max` pixels.
    Adaptive { max: f32 },
}

/// The compute rasterizer's pipelines.
pub struct Rasterizer {
    raster: wgpu::ComputePipeline,
    resolve: wgpu::ComputePipeline,
}

/// Workgroups for `n` threads, as a 2D dispatch within the 65535 limit per dimension.
fn groups(n: u32) -> (u32, u32) {
    let g = n.div_ceil(WORKGROUP).max(1);
    let x = g.min(65535);
    (x, g.div_ceil(x))
}

impl Rasterizer {
    pub fn new(gpu: &Gpu) -> Rasterizer {
        let pipeline = |src: &str, entry: &str| {
            let module = gpu
                .device
                .create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some(entry),
                    source: wgpu::ShaderSource::Wgsl(src.into()),
                });
            gpu.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: None,
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
        };
        Rasterizer {
            raster: pipeline(RASTER_WGSL, "rasterize"),
            resolve: pipeline(RESOLVE_WGSL, "resolve"),
        }
    }

    /// Draws `sets` of points seen by `camera` into a `camera.width` x `camera.height` image and
    /// reads it back: RGBA8, rows top to bottom. Points are squares of `size`.
    pub fn render(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        sets: &[&Points],
        background: [u8; 4],
        size: PointSize,
    ) -> Vec<u8> {
        let (w, h) = (camera.width.max(1), camera.height.max(1));
        let pixels = (w * h) as u64;
        let d = &gpu.device;
        let framebuffer = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("framebuffer"),
            size: pixels * 8,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let image = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("image"),
            size: pixels * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: pixels * 4,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = d.create_command_encoder(&Default::default());
        enc.clear_buffer(&framebuffer, 0, None);
        let uniforms = |set: Option<&Points>| {
            let origin = set.map_or(camera.position, |s| s.origin);
            d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("uniforms"),
                contents: bytemuck::bytes_of(&Uniforms {
                    view_proj: camera.view_proj(origin),
                    width: w,
                    height: h,
                    count: set.map_or(0, |s| s.count),
                    background: u32::from_le_bytes(background),
                    point_size: match size {
                        PointSize::Fixed(px) => px.max(1.0),
                        PointSize::Adaptive { .. } => 0.0,
                    },
                    spacing: set.map_or(0.0, |s| s.spacing as f32),
                    focal: camera.focal() as f32,
                    max_size: match size {
                        PointSize::Fixed(px) => px.max(1.0),
                        PointSize::Adaptive { max } => max.max(1.0),
                    },
                }),
                usage: wgpu::BufferUsages::UNIFORM,
            })
        };
        for set in sets.iter().filter(|s| s.count > 0) {
            let u = uniforms(Some(set));
            let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("raster"),
                layout: &self.raster.get_bind_group_layout(0),
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: u.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: set.buffer.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: framebuffer.as_entire_binding(),
                    },
                ],
            });
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.raster);
            pass.set_bind_group(0, &bind, &[]);
            let (x, y) = groups(set.count);
            pass.dispatch_workgroups(x, y, 1);
        }
        let u = uniforms(None);
        let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("resolve"),
            layout: &self.resolve.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: u.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: framebuffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: image.as_entire_binding(),
                },
            ],
        });
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.resolve);
            pass.set_bind_group(0, &bind, &[]);
            let (x, y) = groups(w * h);
            pass.dispatch_workgroups(x, y, 1);
        }
        enc.copy_buffer_to_buffer(&image, 0, &readback, 0, pixels * 4);
        gpu.queue.submit([enc.finish()]);
        let slice = readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |r| {
            r.expect("map the image for reading")
        });
        d.poll(wgpu::PollType::wait_indefinitely())
            .expect("wait for the frame");
        let out = slice.get_mapped_range().expect("mapped image").to_vec();
        readback.unmap();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_core::{Attribute, PointBatch, Schema};

    #[test]
    fn colour_schemes() {
        let schema = Schema::new(vec![
            Attribute::Classification,
            Attribute::Intensity,
            Attribute::Rgb,
        ]);
        let mut b = PointBatch::with_schema(&schema, 3);
        for (i, (class, int)) in [(2u8, 0u16), (6, 65535), (9, 256)].iter().enumerate() {
            b.positions.push([0.0, 0.0, i as f64]);
            b.classification.as_mut().unwrap().push(*class);
            b.intensity.as_mut().unwrap().push(*int);
            b.rgb.as_mut().unwrap().push([200, 100, 50]);
        }
        let c = colours(&b, 3, ColorBy::Classification, (0.0, 2.0), 0);
        assert_eq!(c[0], [166, 120, 72, 255], "ground is brown");
        assert_eq!(c[1], [230, 90, 60, 255], "building is red");
        assert_eq!(c[2], [40, 100, 255, 255], "water is blue");
        let c = colours(&b, 3, ColorBy::Intensity, (0.0, 2.0), 0);
        assert_eq!((c[0][0], c[1][0], c[2][0]), (0, 255, 1));
        // 8-bit colour in 16-bit fields is taken as it is.
        assert_eq!(
            colours(&b, 1, ColorBy::Rgb, (0.0, 2.0), 0)[0],
            [200, 100, 50, 255]
        );
        let e = colours(&b, 3, ColorBy::Elevation, (0.0, 2.0), 0);
        assert_eq!(e[0], [0, 0, 255, 255], "lowest is blue");
        assert_eq!(e[2], [255, 0, 0, 255], "highest is red");
        // Lacking the attribute: elevation.
        assert_eq!(colours(&b, 3, ColorBy::PointSource, (0.0, 2.0), 0), e);
        assert_eq!(colours(&b, 2, ColorBy::Level, (0.0, 2.0), 3).len(), 2);
        assert_eq!(
            ColorBy::parse("classification"),
            Some(ColorBy::Classification)
        );
        assert_eq!(ColorBy::parse("purple"), None);
    }
}
