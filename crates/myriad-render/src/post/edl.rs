//! Eye-dome lighting (Boucheny 2009): shading from the log-depth differences to neighbours in
//! eight directions, so that edges and relief show without normals. GPU: edl.wgsl; CPU mirror:
//! [`pixel`].

use super::gbuffer::{AROUND, GBuffer, at, keep, scale_colour, xy};

/// edl.wgsl after common.wgsl.
pub(crate) const SOURCE: &str = concat!(include_str!("common.wgsl"), include_str!("edl.wgsl"));

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

/// As edl.wgsl.
pub(crate) fn pixel(g: &GBuffer, i: usize, e: &Edl) -> (f32, u32, u32) {
    let d = g.depth[i];
    if d <= 0.0 {
        return keep(g, i);
    }
    let (x, y) = xy(g, i);
    let l = d.log2();
    let mut sum = 0.0;
    for a in AROUND {
        let (nx, ny) = (
            x + (a[0] * e.radius).round() as i32,
            y + (a[1] * e.radius).round() as i32,
        );
        if let Some(j) = at(g, nx, ny)
            && g.depth[j] > 0.0
        {
            sum += (l - g.depth[j].log2()).max(0.0);
        }
    }
    let shade = (-sum / 8.0 * 300.0 * e.strength).exp();
    (d, scale_colour(g.colour[i], shade), g.normal[i])
}
