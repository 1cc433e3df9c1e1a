//! The finish pass: each image pixel the mean of its supersampled block, the background where
//! nothing was drawn; into the image buffer, or a window's texture. GPU: finish.wgsl; CPU
//! mirror: [`image`].

use super::gbuffer::{GBuffer, View, pack_colour, unpack_colour};
use rayon::prelude::*;

/// finish.wgsl after common.wgsl.
pub(crate) const SOURCE: &str = concat!(include_str!("common.wgsl"), include_str!("finish.wgsl"));

/// As finish.wgsl: each image pixel the mean of its `factor` x `factor` block, the background
/// where nothing was drawn, opaque black where `mask` (the g-buffer's pixels) hides the block.
pub(crate) fn image(g: &GBuffer, v: &View, mask: Option<&[bool]>) -> Vec<u8> {
    let f = v.factor.max(1) as usize;
    let (w, h) = (g.width as usize / f, g.height as usize / f);
    let background = u32::from_le_bytes(v.background);
    let mut out = vec![0u8; w * h * 4];
    out.par_chunks_mut(w.max(1) * 4)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                if mask.is_some_and(|m| m[y * f * g.width as usize + x * f]) {
                    row[x * 4..x * 4 + 4].copy_from_slice(&[0, 0, 0, 255]);
                    continue;
                }
                let mut sum = [0.0f32; 4];
                for sy in 0..f {
                    for sx in 0..f {
                        let i = (y * f + sy) * g.width as usize + x * f + sx;
                        let c = if g.depth[i] > 0.0 {
                            g.colour[i]
                        } else {
                            background
                        };
                        let c = unpack_colour(c);
                        for k in 0..4 {
                            sum[k] += c[k];
                        }
                    }
                }
                let n = (f * f) as f32;
                let c = pack_colour(sum.map(|s| s / n));
                row[x * 4..x * 4 + 4].copy_from_slice(&c.to_le_bytes());
            }
        });
    out
}
