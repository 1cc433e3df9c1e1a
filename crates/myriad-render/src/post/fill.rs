//! Hole filling after Dobrev (Discher et al. 2018, section 5.3): two 1-D passes, along rows then
//! columns; a pixel with nearer pixels on both sides within the radius, enough of them, takes the
//! nearest one's depth, colour and normal. GPU: fill.wgsl; CPU mirror: [`pixel`].

use super::gbuffer::{GBuffer, at, keep, xy};

/// fill.wgsl after common.wgsl.
pub(crate) const SOURCE: &str = concat!(include_str!("common.wgsl"), include_str!("fill.wgsl"));

/// Hole filling parameters (Discher et al. 2018, section 5.3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fill {
    /// Neighbours looked at on each side, in pixels (2: a 5-pixel kernel, as Discher et al. 2018's
    /// figure 8).
    pub radius: u32,
    /// A neighbour is nearer when its depth is below this fraction of the pixel's own.
    pub threshold: f32,
    /// Nearer neighbours needed (on both sides together).
    pub min: u32,
}

impl Default for Fill {
    fn default() -> Fill {
        Fill {
            radius: 2,
            threshold: 0.95,
            min: 2,
        }
    }
}

/// As fill.wgsl: `axis` 0 along rows, 1 along columns.
pub(crate) fn pixel(g: &GBuffer, i: usize, axis: u32, radius: u32, p: &Fill) -> (f32, u32, u32) {
    let (x, y) = xy(g, i);
    let d = g.depth[i];
    let mut best = usize::MAX;
    let (mut count, mut sides) = (0, 0u32);
    for k in 1..=radius as i32 {
        for (side, s) in [(-1i32, 1u32), (1, 2)] {
            let (nx, ny) = if axis == 0 {
                (x + side * k, y)
            } else {
                (x, y + side * k)
            };
            let Some(j) = at(g, nx, ny) else { continue };
            let n = g.depth[j];
            if n > 0.0 && (d == 0.0 || n < d * p.threshold) {
                count += 1;
                sides |= s;
                if best == usize::MAX || n < g.depth[best] {
                    best = j;
                }
            }
        }
    }
    if sides == 3 && count >= p.min {
        keep(g, best)
    } else {
        keep(g, i)
    }
}
