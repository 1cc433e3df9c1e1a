//! The surface's triangles into the g-buffer on the CPU: each triangle projected, the pixels
//! whose centres it covers (edge functions, a top-left rule for shared edges) take its linear eye
//! depth (1/z interpolated across the screen, so perspective-correct), its colour and its
//! normal where nearer than what is there. Bands of rows in parallel.

use crate::post::{GBuffer, pack_normal};
use myriad_core::Mesh;
use myriad_lod::Camera;
use rayon::prelude::*;

/// A triangle on screen: pixel x, y and 1/z per corner, its colour and eye normal.
struct Projected {
    xy: [[f64; 2]; 3],
    inv_z: [f64; 3],
    colour: u32,
    normal: u32,
    rows: (i64, i64),
}

const BAND: usize = 16;

/// The g-buffer of `mesh` seen by `camera` (`camera.width` x `camera.height`).
pub(crate) fn gbuffer(camera: &Camera, mesh: &Mesh) -> GBuffer {
    let (w, h) = (camera.width.max(1), camera.height.max(1));
    let (r, u, f) = camera.basis();
    let o = camera.position;
    let focal = camera.focal();
    let eye = |p: [f64; 3]| {
        let d = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
        let dot = |v: [f64; 3]| d[0] * v[0] + d[1] * v[1] + d[2] * v[2];
        [dot(r), dot(u), dot(f)]
    };
    let dir = |n: [f32; 3]| {
        let n = n.map(|v| v as f64);
        let dot = |v: [f64; 3]| (n[0] * v[0] + n[1] * v[1] + n[2] * v[2]) as f32;
        [dot(r), dot(u), dot(f)]
    };
    let tris: Vec<Projected> = mesh
        .triangles
        .par_iter()
        .filter_map(|t| {
            let e = t.map(|i| eye(mesh.positions[i as usize]));
            // Clipping is not needed for surfaces of points in view: a triangle reaching behind
            // the near plane is left out.
            if e.iter().any(|p| p[2] <= camera.near) {
                return None;
            }
            let xy = e.map(|p| {
                [
                    w as f64 / 2.0 + p[0] * focal / p[2],
                    h as f64 / 2.0 - p[1] * focal / p[2],
                ]
            });
            let lo = xy.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
            let hi = xy.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max);
            let rows = ((lo - 0.5).ceil() as i64, (hi - 0.5).floor() as i64);
            if rows.1 < 0 || rows.0 >= h as i64 {
                return None;
            }
            let i0 = t[0] as usize;
            let c = mesh.colours[i0];
            Some(Projected {
                xy,
                inv_z: e.map(|p| 1.0 / p[2]),
                colour: u32::from_le_bytes(c),
                normal: pack_normal(dir(mesh.normals[i0])),
                rows,
            })
        })
        .collect();
    let mut g = GBuffer::new(w, h);
    let band_pixels = BAND * w as usize;
    g.depth
        .par_chunks_mut(band_pixels)
        .zip(g.colour.par_chunks_mut(band_pixels))
        .zip(g.normal.par_chunks_mut(band_pixels))
        .enumerate()
        .for_each(|(band, ((depth, colour), normal))| {
            let y0 = (band * BAND) as i64;
            let y1 = y0 + (depth.len() / w as usize) as i64 - 1;
            for t in &tris {
                if t.rows.1 < y0 || t.rows.0 > y1 {
                    continue;
                }
                draw(t, w, h, y0, y1, depth, colour, normal);
            }
        });
    g
}

/// Edge function: twice the signed area of (a, b, p).
fn edge(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

#[allow(clippy::too_many_arguments)]
fn draw(
    t: &Projected,
    w: u32,
    h: u32,
    y0: i64,
    y1: i64,
    depth: &mut [f32],
    colour: &mut [u32],
    normal: &mut [u32],
) {
    let [a, b, c] = t.xy;
    let area = edge(a, b, c);
    if area == 0.0 {
        return;
    }
    // Counter-clockwise either way: both faces are drawn.
    let (b, c, iz) = if area < 0.0 {
        (c, b, [t.inv_z[0], t.inv_z[2], t.inv_z[1]])
    } else {
        (b, c, t.inv_z)
    };
    let area = area.abs();
    let xs = [a[0], b[0], c[0]];
    let x_lo = (xs.iter().copied().fold(f64::INFINITY, f64::min) - 0.5)
        .ceil()
        .max(0.0) as i64;
    let x_hi = ((xs.iter().copied().fold(f64::NEG_INFINITY, f64::max) - 0.5).floor() as i64)
        .min(w as i64 - 1);
    // Top-left rule: a pixel centre on an edge belongs to the triangle on one side only.
    let owns = |p: [f64; 2], q: [f64; 2], e: f64| {
        e > 0.0 || (e == 0.0 && ((p[1] == q[1] && q[0] < p[0]) || q[1] > p[1]))
    };
    for y in t.rows.0.max(y0).max(0)..=t.rows.1.min(y1).min(h as i64 - 1) {
        let row = ((y - y0) * w as i64) as usize;
        for x in x_lo..=x_hi {
            let p = [x as f64 + 0.5, y as f64 + 0.5];
            let (e0, e1, e2) = (edge(b, c, p), edge(c, a, p), edge(a, b, p));
            if !(owns(b, c, e0) && owns(c, a, e1) && owns(a, b, e2)) {
                continue;
            }
            let z = 1.0 / ((e0 * iz[0] + e1 * iz[1] + e2 * iz[2]) / area);
            let i = row + x as usize;
            let d = z as f32;
            if depth[i] == 0.0 || d < depth[i] {
                depth[i] = d;
                colour[i] = t.colour;
                normal[i] = t.normal;
            }
        }
    }
}
