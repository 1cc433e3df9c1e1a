//! The frame's post passes over the g-buffer (Discher et al. 2018, section 5.3; Kanzok et al. 2015,
//! section 3.2.4): the point pass leaves per pixel a linear eye depth, a colour and, where the
//! points carry one (splats), a normal; then, in this fixed order and in any combination:
//!
//! - `fill`: hole filling after Dobrev (Discher et al. 2018): two 1-D passes (rows, then columns);
//!   a pixel with nearer pixels (by more than a relative depth threshold) on both sides within
//!   `radius`, at least `min` of them, takes the nearest one's depth, colour and normal. A pixel at
//!   the edge of a near surface has nearer pixels on one side only, so a near surface never grows
//!   over a far one.
//! - normals: reconstructed in image space from depth where the points gave none
//!   (Kanzok et al. 2015), from the neighbour on each axis nearer in depth (so that edges do not
//!   bend them); run when `shade` or `ssao` needs them.
//! - `shade`: deferred shading, a headlight (light along the view direction: a plane seen
//!   head-on is lit uniformly) and a sun direction, over an ambient term.
//! - `ssao`: screen-space ambient occlusion, the neighbours at two radii in eight directions
//!   taken as points in eye space; those above the pixel's tangent plane occlude it, weighted
//!   down with distance.
//! - `edl`: eye-dome lighting (Boucheny 2009), as before, now one pass of the chain.
//! - `blur`: a 3x3 binomial filter over the pixels of the same surface (depth within a relative
//!   threshold), against aliasing and z-fighting (Discher et al. 2018).
//! - `aa`: supersampling: everything above drawn at `aa` times the width and height, the
//!   finish pass averaging each `aa` x `aa` block.
//!
//! Every pass is a WGSL file in this folder and a Rust file beside it holding its parameters,
//! its source and its CPU mirror (`fill.rs` + `fill.wgsl`, ...), in f32 as the shaders compute,
//! so that the GPU paths and the CPU draw the same images (tested). `gbuffer.rs` holds what the
//! point pass leaves and the helpers they share; `chain.rs` runs them on the GPU (one dispatch
//! each), [`run`] on the CPU.

mod blur;
mod chain;
mod edl;
mod fill;
mod finish;
mod gbuffer;
mod normals;
mod passes;
mod shade;
mod ssao;

pub use blur::Blur;
pub use chain::PASS_SOURCES;
pub(crate) use chain::{Buffers, Chain, Hidden, upsampled};
pub use edl::Edl;
pub use fill::Fill;
pub use gbuffer::{FB_ATOMIC_WGSL, FB_QUADS_WGSL, gbuffer_source, pack_normal, unpack_normal};
pub(crate) use gbuffer::{GBuffer, View};
pub use passes::{DEFAULT_PASSES, PASS_NAMES, Passes};
pub use shade::Shade;
pub use ssao::Ssao;

use gbuffer::keep;
use rayon::prelude::*;

/// Runs the passes on the g-buffer and returns the image (RGBA8, rows top to bottom), the
/// g-buffer's size divided by the supersampling factor.
pub(crate) fn run(g: GBuffer, passes: &Passes, v: &View) -> Vec<u8> {
    run_masked(g, passes, v, None)
}

/// [`run`], every pass skipping the pixels `mask` hides (a headset's hidden area: they stay as
/// the point pass left them, empty, and the image is black there).
pub(crate) fn run_masked(
    mut g: GBuffer,
    passes: &Passes,
    v: &View,
    mask: Option<&[bool]>,
) -> Vec<u8> {
    let mut scratch = GBuffer::new(g.width, g.height);
    // Pixel sizes scale with the supersampling, as in chain.rs's uniforms.
    let f = v.factor;
    let fill = passes.fill.unwrap_or_default();
    let radius = fill.radius * f;
    let shade = passes.shade.unwrap_or_default();
    let ssao = passes.ssao.map_or_else(Ssao::default, |s| Ssao {
        radius: s.radius * f as f32,
        ..s
    });
    let edl = passes.edl.map_or_else(Edl::default, |e| Edl {
        radius: e.radius * f as f32,
        ..e
    });
    let blur = passes.blur.unwrap_or_default();
    // Each pass its own loop (generic, not a boxed closure a pixel): the pixel's function is
    // inlined into it.
    for step in passes.steps() {
        let (src, dst) = (&g, &mut scratch);
        match step {
            "fill_rows" => each_pixel(src, dst, |g, i| fill::pixel(g, i, 0, radius, &fill), mask),
            "fill_columns" => {
                each_pixel(src, dst, |g, i| fill::pixel(g, i, 1, radius, &fill), mask)
            }
            "normals" => each_pixel(src, dst, |g, i| normals::pixel(g, i, v), mask),
            "shade" => each_pixel(src, dst, |g, i| shade::pixel(g, i, v, &shade), mask),
            "ssao" => each_pixel(src, dst, |g, i| ssao::pixel(g, i, v, &ssao), mask),
            "edl" => each_pixel(src, dst, |g, i| edl::pixel(g, i, &edl), mask),
            "blur" => each_pixel(src, dst, |g, i| blur::pixel(g, i, &blur), mask),
            _ => unreachable!("a step of Passes::steps"),
        }
        std::mem::swap(&mut g, &mut scratch);
    }
    finish::image(&g, v, mask)
}

/// `dst` pixel by pixel from `src`: (depth, colour, normal).
fn each_pixel(
    src: &GBuffer,
    dst: &mut GBuffer,
    pass: impl Fn(&GBuffer, usize) -> (f32, u32, u32) + Sync,
    mask: Option<&[bool]>,
) {
    let w = src.width as usize;
    dst.depth
        .par_chunks_mut(w)
        .zip(dst.colour.par_chunks_mut(w))
        .zip(dst.normal.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, ((d, c), n))| {
            for x in 0..w {
                let i = y * w + x;
                (d[x], c[x], n[x]) = if mask.is_some_and(|m| m[i]) {
                    keep(src, i)
                } else {
                    pass(src, i)
                };
            }
        });
}

#[cfg(test)]
mod tests;
