//! The renderer. Main path: a compute-shader rasterizer (one thread per point, the nearest point
//! per pixel kept by a 64-bit `atomicMax` of depth and colour, then a resolve pass; Schütz et al.
//! 2021), which PLATFORM.md measured 20-40x faster than fixed-function points on lavapipe. Adapters
//! without 64-bit atomics get instanced quads covering the same pixels, with a depth test. Both
//! draw square, round or paraboloid points of fixed or adaptive size into a g-buffer (depth,
//! colour, splat normals), and the same post passes follow (`post`: hole filling, normals,
//! shading, SSAO, eye-dome lighting, blur, supersampling), on a headless target read back to
//! RGBA. Shaders are in `src/shaders/*.wgsl` and `src/post/*.wgsl`, validated by a naga test that
//! needs no GPU.
//!
//! Reads no files: points arrive as [`Points`] (positions quantized per node in 4 to 12 bytes,
//! RGBA8 colour); [`NodeBuffers`] keeps them per node under a byte budget, and a [`Scene`] runs
//! frames of the whole pipeline (selection, loading, upload, drawing).

mod cpu;
mod pipelines;
mod points;
mod post;
mod queries;
mod raster;
pub mod scene;
pub mod selector;
pub mod stereo;
pub mod surface;

pub use myriad_core::colour::{ColorBy, class_colour, colours};
pub use myriad_lod::Clip;
pub use points::{Encoding, Points, WORD_BITS, splat_code};
pub use post::gpu::{PASS_SOURCES, gbuffer_source};
pub use post::{
    Blur, DEFAULT_PASSES, Fill, PASS_NAMES, Passes, Shade, Ssao, pack_normal, unpack_normal,
};
pub use queries::QueryTicket;
pub use raster::{Path, Rasterizer};
pub use scene::{FrameStats, Picked, Scene, frame_many, frame_many_threaded};

/// GPU buffers of nodes, least recently used evicted beyond a byte budget.
pub type NodeBuffers = myriad_lod::Lru<Points>;

pub const RASTER_WGSL: &str = concat!(
    include_str!("shaders/draw.wgsl"),
    include_str!("shaders/raster.wgsl")
);
pub const QUADS_WGSL: &str = concat!(
    include_str!("shaders/draw.wgsl"),
    include_str!("shaders/quads.wgsl")
);
/// The compute path's framebuffer as the g-buffer pass reads it ([`gbuffer_source`]).
pub const FB_ATOMIC_WGSL: &str = include_str!("shaders/fb_atomic.wgsl");
/// Occlusion queries' boxes and the compute path's depth for them (`queries.rs`).
pub const QUERIES_WGSL: &str = include_str!("shaders/queries.wgsl");
/// The quad path's render targets as the g-buffer pass reads them.
pub const FB_QUADS_WGSL: &str = include_str!("shaders/fb_quads.wgsl");

/// Where frames are drawn: a GPU device and queue (without a window), or the CPU.
pub struct Gpu {
    wgpu: Option<(wgpu::Device, wgpu::Queue)>,
    /// The adapter's name and type, e.g. "llvmpipe (LLVM 15.0.6, 256 bits) (Cpu)".
    pub name: String,
    /// The device has 64-bit integer atomics (the compute path).
    pub atomics: bool,
    /// A software rasterizer (lavapipe, llvmpipe, SwiftShader, WARP).
    pub software: bool,
}

impl Gpu {
    /// The best adapter there is (a real GPU, or lavapipe), without a surface; 64-bit atomics are
    /// asked for where the adapter has them.
    pub fn headless() -> Result<Gpu, String> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        }))
        .map_err(|e| format!("no GPU adapter: {e}"))?;
        let atomics_features =
            wgpu::Features::SHADER_INT64 | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX;
        let info = adapter.get_info();
        let atomics = adapter.features().contains(atomics_features);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("myriad"),
            required_features: if atomics {
                atomics_features
            } else {
                wgpu::Features::empty()
            },
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| format!("{}: {e}", info.name))?;
        Ok(Gpu {
            wgpu: Some((device, queue)),
            name: format!("{} ({:?})", info.name, info.device_type),
            atomics,
            software: info.device_type == wgpu::DeviceType::Cpu,
        })
    }

    /// The features the compute path needs (64-bit integer atomics), for a device made elsewhere.
    pub fn atomics_features() -> wgpu::Features {
        wgpu::Features::SHADER_INT64 | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX
    }

    /// A device made elsewhere (a window's), with the features it was made with.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue, info: &wgpu::AdapterInfo) -> Gpu {
        let atomics = device.features().contains(Gpu::atomics_features());
        Gpu {
            wgpu: Some((device, queue)),
            name: format!("{} ({:?})", info.name, info.device_type),
            atomics,
            software: info.device_type == wgpu::DeviceType::Cpu,
        }
    }

    /// The CPU: the compute path's algorithm on all cores.
    pub fn cpu() -> Gpu {
        Gpu {
            wgpu: None,
            name: format!(
                "CPU ({} threads)",
                std::thread::available_parallelism().map_or(1, |n| n.get())
            ),
            atomics: false,
            software: true,
        }
    }

    /// For headless images: a hardware GPU if there is one, else the CPU, with why there is no
    /// adapter at all. A software adapter is passed over: on the 2-core machines here the CPU
    /// path draws the same frames in half of lavapipe's time (`myriad bench render --cpu`).
    pub fn best() -> (Gpu, Option<String>) {
        match Gpu::headless() {
            Ok(g) if !g.software => (g, None),
            Ok(_) => (Gpu::cpu(), None),
            // wgpu's reason lists every backend; its first clause says it.
            Err(e) => (
                Gpu::cpu(),
                Some(e.split(';').next().unwrap_or(&e).trim().to_string()),
            ),
        }
    }

    pub fn is_cpu(&self) -> bool {
        self.wgpu.is_none()
    }

    /// The wgpu device and queue; None on the CPU.
    pub fn wgpu(&self) -> Option<(&wgpu::Device, &wgpu::Queue)> {
        self.wgpu.as_ref().map(|(d, q)| (d, q))
    }

    fn device(&self) -> &wgpu::Device {
        &self.wgpu.as_ref().expect("a GPU path on a GPU").0
    }
    fn queue(&self) -> &wgpu::Queue {
        &self.wgpu.as_ref().expect("a GPU path on a GPU").1
    }
}

/// Part of a [`Points`] to draw in a frame.
#[derive(Clone, Copy)]
pub struct Draw<'a> {
    pub points: &'a Points,
    pub count: u32,
    /// World spacing of these points, for adaptive point sizes.
    pub spacing: f64,
    /// The node these points belong to, as its index in the drawn tree passed to
    /// [`Rasterizer::render`] and its cube: each point then takes the spacing of the finest
    /// drawn node around it ([`myriad_lod::DrawnTree`]). None: `spacing` for every point.
    pub node: Option<(u32, myriad_core::Aabb)>,
}

/// How big a point is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PointSize {
    /// This many pixels on a side.
    Fixed(f32),
    /// The spacing of the point's level of detail (pulled up, see `myriad_lod::select`) as seen
    /// at the point's depth, times `scale`, at most `max` pixels. Points one spacing apart
    /// leave holes between them (a level's points are one per cell, anywhere in it): the
    /// default scale closes them.
    Adaptive { scale: f32, max: f32 },
}

impl PointSize {
    pub const ADAPTIVE_SCALE: f32 = 1.5;

    /// Adaptive with the default scale, at most 32 pixels.
    pub fn adaptive() -> PointSize {
        PointSize::Adaptive {
            scale: PointSize::ADAPTIVE_SCALE,
            max: 32.0,
        }
    }
}

/// The shape of a point on screen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    Square,
    /// A disc: the pixels whose centres lie within the point's size.
    Round,
    /// A disc whose centre stands out towards the eye (by half its size), so that overlapping
    /// points meet in curved seams, as splats would.
    Paraboloid,
}

impl Shape {
    pub fn parse(s: &str) -> Option<Shape> {
        Some(match s {
            "square" => Shape::Square,
            "round" | "circle" => Shape::Round,
            "paraboloid" => Shape::Paraboloid,
            _ => return None,
        })
    }
}

/// Eye-dome lighting (Boucheny 2009): shading from depth differences between neighbouring pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edl {
    /// 1 is the usual strength; 0 leaves the colours as they are.
    pub strength: f32,
    /// Neighbour distance in pixels.
    pub radius: f32,
}

impl Default for Edl {
    fn default() -> Edl {
        Edl {
            strength: 1.0,
            radius: 1.4,
        }
    }
}

/// How points are drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Style {
    pub size: PointSize,
    pub shape: Shape,
    /// The post passes over the g-buffer (eye-dome lighting among them).
    pub passes: Passes,
    pub background: [u8; 4],
    pub clip: Option<Clip>,
}

impl Default for Style {
    fn default() -> Style {
        Style {
            size: PointSize::adaptive(),
            shape: Shape::Square,
            passes: Passes::default(),
            background: [0, 0, 0, 255],
            clip: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_core::Aabb;

    #[test]
    fn a_clipping_box_keeps_the_cubes_that_can_show_through_it() {
        let b = Aabb::new([0.0; 3], [10.0; 3]);
        let inside = Some(Clip {
            bounds: b,
            inside: true,
        });
        let outside = Some(Clip {
            bounds: b,
            inside: false,
        });
        let within = Aabb::new([2.0; 3], [4.0; 3]);
        let across = Aabb::new([8.0; 3], [12.0; 3]);
        let away = Aabb::new([20.0; 3], [30.0; 3]);
        assert!(Clip::keeps(None, &away));
        assert!(Clip::keeps(inside, &within) && Clip::keeps(inside, &across));
        assert!(!Clip::keeps(inside, &away));
        assert!(!Clip::keeps(outside, &within));
        assert!(Clip::keeps(outside, &across) && Clip::keeps(outside, &away));
    }
}
