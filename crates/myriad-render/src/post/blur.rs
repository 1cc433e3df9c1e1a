//! A depth-aware 3x3 binomial blur over the pixels of the same surface (Discher et al. 2018),
//! against aliasing and z-fighting. GPU: blur.wgsl; CPU mirror: [`pixel`].

use super::gbuffer::{GBuffer, at, keep, pack_colour, unpack_colour, xy};

/// blur.wgsl after common.wgsl.
pub(crate) const SOURCE: &str = concat!(include_str!("common.wgsl"), include_str!("blur.wgsl"));

/// The depth-aware blur.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blur {
    /// Neighbours whose depth differs by more than this fraction of the pixel's are left out.
    pub threshold: f32,
}

impl Default for Blur {
    fn default() -> Blur {
        Blur { threshold: 0.02 }
    }
}

/// As blur.wgsl.
pub(crate) fn pixel(g: &GBuffer, i: usize, b: &Blur) -> (f32, u32, u32) {
    let d = g.depth[i];
    if d <= 0.0 {
        return keep(g, i);
    }
    let (x, y) = xy(g, i);
    let mut sum = [0.0f32; 3];
    let mut weight = 0.0;
    for dy in -1..=1i32 {
        for dx in -1..=1i32 {
            let Some(j) = at(g, x + dx, y + dy) else {
                continue;
            };
            let n = g.depth[j];
            if n <= 0.0 || (n - d).abs() > b.threshold * d {
                continue;
            }
            let w = ((2 - dx.abs()) * (2 - dy.abs())) as f32;
            let c = unpack_colour(g.colour[j]);
            for k in 0..3 {
                sum[k] += c[k] * w;
            }
            weight += w;
        }
    }
    let a = unpack_colour(g.colour[i])[3];
    let c = pack_colour([sum[0] / weight, sum[1] / weight, sum[2] / weight, a]);
    (d, c, g.normal[i])
}
