//! The renderer. Main path: a compute-shader rasterizer (one thread per point, the nearest point
//! per pixel kept by a 64-bit `atomicMax` of depth and colour, then a resolve pass; Schütz et al.
//! 2021), which PLATFORM.md measured 20-40x faster than fixed-function points on lavapipe. Adapters
//! without 64-bit atomics get instanced quads covering the same pixels, with a depth test; with
//! no GPU, the CPU runs the compute path's algorithm. All three draw square, round or paraboloid
//! points of fixed or adaptive size into a g-buffer (depth, colour, splat normals), and the same
//! post passes follow (`post`: hole filling, normals, shading, SSAO, eye-dome lighting, blur,
//! supersampling), on a headless target read back to RGBA. Each shader sits beside the Rust file
//! that runs it, validated by a naga test that needs no GPU.
//!
//! Reads no files: points arrive as [`Points`] (positions quantized per node in 4 to 12 bytes,
//! RGBA8 colour); [`NodeBuffers`] keeps them per node under a byte budget, and a [`Scene`] runs
//! frames of the whole pipeline (selection, loading, upload, drawing).
//!
//! The layout, from the bottom up (a module imports only from those above it in this list):
//! `device` (the GPU or the CPU), `pipelines` (making long-lived GPU objects), `points` (a
//! node's points and a draw of them), `style`, `post` (the g-buffer and the passes, one file
//! each), `targets` (a frame's buffers of one size), `draw` (the uniforms both GPU paths share),
//! the three point paths `compute`, `quads` and `cpu` (each beside its `.wgsl`), `queries`
//! (occlusion queries), `frame` (the [`Rasterizer`]: a frame from end to end), then `stereo`,
//! `surface`, `preview`, `selector` and `scene` on top.

mod blend;
mod compute;
mod cpu;
mod device;
mod draw;
mod frame;
mod pipelines;
mod points;
mod post;
mod quads;
mod queries;
mod style;
mod targets;

pub mod args;
pub mod legend;
pub mod preview;
pub mod scene;
pub mod selector;
pub mod stereo;
pub mod still;
pub mod surface;

pub use compute::RASTER_WGSL;
pub use device::Gpu;
pub use frame::Rasterizer;
pub use myriad_core::colour::{ColorBy, class_colour, colours};
pub use myriad_lod::Clip;
pub use points::{Draw, Encoded, Encoding, Points, WORD_BITS, splat_code};
pub use post::{
    Blur, DEFAULT_PASSES, Edl, FB_ATOMIC_WGSL, FB_QUADS_WGSL, Fill, PASS_NAMES, PASS_SOURCES,
    Passes, Shade, Ssao, gbuffer_source, pack_normal, unpack_normal,
};
pub use quads::QUADS_WGSL;
pub use queries::{QUERIES_WGSL, QueryTicket};
pub use scene::{FrameStats, Picked, Scene, frame_many, frame_many_threaded};
pub use style::{PointSize, Shape, Style};
pub use targets::Path;

/// GPU buffers of nodes, least recently used evicted beyond a byte budget.
pub type NodeBuffers = myriad_lod::Lru<Points>;

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
