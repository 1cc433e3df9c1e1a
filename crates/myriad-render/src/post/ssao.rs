//! Screen-space ambient occlusion: neighbours at two radii in eight directions, taken as
//! points in eye space; those above the pixel's tangent plane occlude it, less with distance.
//! GPU: ssao.wgsl; CPU mirror: [`pixel`].

use super::gbuffer::{
    AROUND, GBuffer, View, at, dot, eye_position, keep, scale_colour, sub, unpack_normal, xy,
};

/// ssao.wgsl after common.wgsl.
pub(crate) const SOURCE: &str = concat!(include_str!("common.wgsl"), include_str!("ssao.wgsl"));

/// Screen-space ambient occlusion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ssao {
    /// The outer sampling radius in pixels.
    pub radius: f32,
    /// 1: a pixel with every sample fully occluding goes black.
    pub strength: f32,
}

impl Default for Ssao {
    fn default() -> Ssao {
        Ssao {
            radius: 10.0,
            strength: 1.5,
        }
    }
}

/// As ssao.wgsl.
pub(crate) fn pixel(g: &GBuffer, i: usize, v: &View, s: &Ssao) -> (f32, u32, u32) {
    let d = g.depth[i];
    if d <= 0.0 {
        return keep(g, i);
    }
    let (x, y) = xy(g, i);
    let p = eye_position(v, x, y, d);
    let n = unpack_normal(g.normal[i]);
    // The sampling radius in eye units at this depth.
    let reach = s.radius * d / v.focal;
    let mut occlusion = 0.0;
    for (k, a) in AROUND.iter().enumerate() {
        // Every other direction at half the radius.
        let r = if k % 2 == 0 { s.radius } else { s.radius * 0.5 };
        let (nx, ny) = (x + (a[0] * r).round() as i32, y + (a[1] * r).round() as i32);
        let Some(j) = at(g, nx, ny) else { continue };
        if g.depth[j] <= 0.0 {
            continue;
        }
        let q = eye_position(v, nx, ny, g.depth[j]);
        let t = sub(q, p);
        let dist = dot(t, t).sqrt();
        if dist <= 0.0 {
            continue;
        }
        let rise = (dot(n, t) / dist - 0.1).max(0.0);
        occlusion += rise * (1.0 - dist / (2.0 * reach)).clamp(0.0, 1.0);
    }
    let ao = (1.0 - s.strength * occlusion / 8.0).clamp(0.0, 1.0);
    (d, scale_colour(g.colour[i], ao), g.normal[i])
}
