//! Blending (`Passes::blend`): the deferred blending of Goswami et al. 2010 (after Zhang and
//! Pajarola 2007: splats smoothly interpolated where they overlap) with the EWA splats of
//! Schiffner et al. 2015 (after Zwicker et al. 2002: each splat a Gaussian on its plane, projected
//! to the screen and filtered). The point pass first keeps each pixel's nearest depth; a second
//! pass over the same points adds every fragment that lies within its point's own size behind that
//! depth, its colour times its weight; the pixel shows the weighted mean instead of the nearest
//! point's colour. Depth, normals and everything the post passes read are the first pass's.
//!
//! This file is the CPU mirror of blend.wgsl (the weight), of compute.wgsl's mode 2 and
//! quads.wgsl's `blend` (which fragments count) and of the fb_*.wgsl `colour_at` (the mean):
//! `cpu.rs` draws with it, and the tests hold the three paths to the same pixels.

/// The low-pass filter's variance in pixels² (EWA's screen-space prefilter; blend.wgsl's
/// `BLEND_PREFILTER`).
pub(crate) const PREFILTER: f32 = 0.5;

/// A fragment's weight, 1 to 255, by its offset `d` from its point's centre (pixels) and the
/// point's footprint (as `blend_weight` in blend.wgsl): the kernel's variance on its plane and
/// the splat's eye normal as (right, -up, forward).
pub(crate) fn weight(d: [f32; 2], shape: [f32; 4]) -> u32 {
    let v = [shape[1], shape[2]];
    let vv = v[0] * v[0] + v[1] * v[1];
    let alpha = shape[0] + PREFILTER;
    let beta = shape[0] / (shape[3] * shape[3] + vv);
    let vd = v[0] * d[0] + v[1] * d[1];
    let q = (d[0] * d[0] + d[1] * d[1] + beta * vd * vd / (alpha - beta * vv)) / alpha;
    (((-0.5 * q).exp() * 255.0 + 0.5) as u32).max(1)
}

/// The footprint of a point `s` pixels wide (`blend_point`).
pub(crate) fn point(s: f32) -> [f32; 4] {
    [s * s / 16.0, 0.0, 0.0, 1.0]
}

/// The footprint of a splat of `splat_shape`'s radius and eye normal (`blend_splat`).
pub(crate) fn splat(sp: [f32; 4]) -> [f32; 4] {
    [sp[0] * sp[0] * 0.25, sp[1], -sp[2], sp[3]]
}

/// A pixel's colour from its sums (red, green, blue times weight, and the weights), as
/// fb_atomic.wgsl's `colour_at`: the rounded mean, opaque; None where nothing was added.
pub(crate) fn resolve(sums: [u32; 4]) -> Option<u32> {
    let w = sums[3];
    (w > 0).then(|| {
        let c = |k: usize| (sums[k] + w / 2) / w;
        c(0) | (c(1) << 8) | (c(2) << 16) | (255 << 24)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_weight_falls_with_distance_and_along_a_tilted_splat() {
        // A 4-pixel point: variance 1 + 0.5, so at 1 pixel exp(-1 / 3) = 0.717 of 255.
        assert_eq!(weight([0.0, 0.0], point(4.0)), 255);
        assert_eq!(weight([1.0, 0.0], point(4.0)), 183);
        assert_eq!(weight([0.0, -1.0], point(4.0)), 183);
        // Never 0: the nearest fragment always counts.
        assert_eq!(weight([40.0, 0.0], point(4.0)), 1);
        // A splat of radius 4 facing the eye is the point's disc of twice the variance; tilted
        // 60 degrees about the vertical (normal towards the right) it is half as wide across
        // (x) and as tall: weights fall faster along x than along y.
        let facing = splat([4.0, 0.0, 0.0, -1.0]);
        assert_eq!(weight([2.0, 0.0], facing), weight([0.0, 2.0], facing));
        let tilted = splat([4.0, 0.866, 0.0, -0.5]);
        assert_eq!(weight([0.0, 2.0], tilted), weight([0.0, 2.0], facing));
        assert!(weight([2.0, 0.0], tilted) < weight([2.0, 0.0], facing) - 40);
        // By hand: variance across 4 x 0.25 + 0.5 = 1.5 at 2 px: exp(-4 / 3) = 0.264 -> 67.
        assert_eq!(weight([2.0, 0.0], tilted), 67);
    }

    #[test]
    fn the_mean_is_rounded_and_opaque() {
        assert_eq!(resolve([0, 0, 0, 0]), None);
        // 255 x 100 and 0 x 50 in red: 25500 / 150 = 170.
        let c = resolve([25500, 0, 150 * 7, 150]).unwrap();
        assert_eq!(c.to_le_bytes(), [170, 0, 7, 255]);
    }
}
