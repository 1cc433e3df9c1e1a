//! Deferred shading: an ambient term, a headlight along the view direction and a sun. GPU:
//! shade.wgsl; CPU mirror: [`pixel`].

use super::gbuffer::{GBuffer, View, dot, keep, scale_colour, unpack_normal};

/// shade.wgsl after common.wgsl.
pub(crate) const SOURCE: &str = concat!(include_str!("common.wgsl"), include_str!("shade.wgsl"));

/// Deferred shading with a headlight and a sun.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shade {
    pub ambient: f32,
    /// Weight of the light along the view direction.
    pub headlight: f32,
    /// Weight of the sun.
    pub sun: f32,
    /// Towards the sun, in world coordinates.
    pub sun_direction: [f64; 3],
}

impl Default for Shade {
    fn default() -> Shade {
        Shade {
            ambient: 0.2,
            headlight: 0.8,
            sun: 0.0,
            sun_direction: [0.5, 0.3, 0.8],
        }
    }
}

/// As shade.wgsl.
pub(crate) fn pixel(g: &GBuffer, i: usize, v: &View, s: &Shade) -> (f32, u32, u32) {
    if g.depth[i] <= 0.0 {
        return keep(g, i);
    }
    let n = unpack_normal(g.normal[i]);
    let light = s.ambient + s.headlight * (-n[2]).max(0.0) + s.sun * dot(n, v.sun).max(0.0);
    (g.depth[i], scale_colour(g.colour[i], light), g.normal[i])
}
