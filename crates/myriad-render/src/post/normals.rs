//! Normals reconstructed in image space from depth where the points gave none (Kanzok et al. 2015),
//! from the neighbour on each axis nearer in depth, facing the eye. GPU: normals.wgsl; CPU mirror:
//! [`pixel`].

use super::gbuffer::{GBuffer, View, at, dot, eye_position, keep, pack_normal, sub, xy};

/// normals.wgsl after common.wgsl.
pub(crate) const SOURCE: &str = concat!(include_str!("common.wgsl"), include_str!("normals.wgsl"));

/// As normals.wgsl.
pub(crate) fn pixel(g: &GBuffer, i: usize, v: &View) -> (f32, u32, u32) {
    let d = g.depth[i];
    if d <= 0.0 || g.normal[i] != 0 {
        return keep(g, i);
    }
    let (x, y) = xy(g, i);
    let p = eye_position(v, x, y, d);
    // The tangent along an axis: to the neighbour nearer in depth (towards +x or +y).
    let tangent = |dx: i32, dy: i32| -> Option<[f32; 3]> {
        let mut best: Option<(f32, [f32; 3])> = None;
        for s in [1, -1] {
            let (nx, ny) = (x + s * dx, y + s * dy);
            let Some(j) = at(g, nx, ny) else { continue };
            let n = g.depth[j];
            if n <= 0.0 {
                continue;
            }
            let diff = (n - d).abs();
            if best.is_none_or(|b| diff < b.0) {
                let q = eye_position(v, nx, ny, n);
                let t = if s == 1 { sub(q, p) } else { sub(p, q) };
                best = Some((diff, t));
            }
        }
        best.map(|b| b.1)
    };
    let n = match (tangent(1, 0), tangent(0, 1)) {
        (Some(a), Some(b)) => {
            let c = [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ];
            let len = dot(c, c).sqrt();
            if len > 0.0 {
                // Facing the eye.
                let k = if dot(c, p) > 0.0 { -1.0 } else { 1.0 } / len;
                [c[0] * k, c[1] * k, c[2] * k]
            } else {
                [0.0, 0.0, -1.0]
            }
        }
        _ => [0.0, 0.0, -1.0],
    };
    (d, g.colour[i], pack_normal(n))
}
