//! The rasterizer on the CPU, for machines without any Vulkan, Metal or DX12 driver: the compute
//! path's algorithm (each point projected, the nearest per pixel kept by a 64-bit atomic max of
//! depth and colour; with blending, a pass adding the fragments near the nearest, `blend.rs`;
//! splats' normals by a pass where a splat's value won; then the g-buffer for the post passes,
//! `post`) over all cores with rayon, in f32 as the shaders
//! compute, so that it draws the same images. It is the reference the GPU paths are tested
//! against, and what `myriad render` uses when there is no GPU adapter.

use crate::points::{Draw, LONE_BIT, LONE_PIXELS, Layout, frame_origin};
use crate::post::{GBuffer, pack_normal};
use crate::{Clip, PointSize, Shape, Style};
use myriad_lod::Camera;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

/// As `depth_key` in compute.wgsl.
fn depth_key(w: f32, far: f32) -> u32 {
    ((1.0 - w / far).clamp(0.0, 1.0) * 4294967040.0) as u32 + 1
}

/// As `key_depth` in compute.wgsl (and `depth_at` in fb_atomic.wgsl).
fn key_depth(key: u32, far: f32) -> f32 {
    (1.0 - (key - 1) as f32 / 4294967040.0) * far
}

/// As `point_pixels` in draw.wgsl for adaptive sizes (fixed sizes are decided once per frame);
/// `lone`: the point is ([`crate::points::LONE_BIT`]).
#[allow(clippy::too_many_arguments)]
fn adaptive_pixels(
    lone: bool,
    p: [f32; 3],
    w: f32,
    draw_spacing: f32,
    node: u32,
    cube: [f32; 4],
    tree: &[[u32; 4]],
    max_size: f32,
    focal: f32,
) -> f32 {
    let mut spacing = draw_spacing;
    if node != u32::MAX {
        let mut i = node as usize;
        let mut lo = [cube[0], cube[1], cube[2]];
        let mut side = cube[3];
        let own = f32::from_bits(tree[i][2]);
        let scale = if own > 0.0 { draw_spacing / own } else { 1.0 };
        for _ in 0..32 {
            let [mask, first, _, _] = tree[i];
            side *= 0.5;
            let o = (0..3)
                .map(|a| ((p[a] >= lo[a] + side) as u32) << a)
                .sum::<u32>();
            if mask & (1 << o) == 0 {
                break;
            }
            i = (first + (mask & ((1 << o) - 1)).count_ones()) as usize;
            for (a, l) in lo.iter_mut().enumerate() {
                *l += ((o >> a) & 1) as f32 * side;
            }
            let s = f32::from_bits(tree[i][2]);
            if s > 0.0 {
                spacing = s * scale;
            }
        }
    }
    let s = (spacing * focal / w).round().clamp(1.0, max_size);
    if lone { s.min(LONE_PIXELS) } else { s }
}

/// As `splat_shape` in draw.wgsl: radius in pixels and the eye normal of a splat at depth `w`.
fn splat_shape(
    code: u32,
    range: [f32; 2],
    w: f32,
    eye: &[[f32; 3]; 3],
    focal: f32,
    max_size: f32,
) -> [f32; 4] {
    let n = myriad_format::splat::normal_from_code((code & 0xffff) as u16);
    let r = range[0] + (range[1] - range[0]) * ((code >> 16) & 0xff) as f32 / 255.0;
    let dot = |v: &[f32; 3]| n[0] * v[0] + n[1] * v[1] + n[2] * v[2];
    let mut nf = dot(&eye[2]);
    if nf.abs() < 0.05 {
        nf = if nf < 0.0 { -0.05 } else { 0.05 };
    }
    let rho = (r * focal / w).min((max_size - 1.0) * 0.5);
    [rho, dot(&eye[0]), dot(&eye[1]), nf]
}

/// As `splat_pixels` in draw.wgsl.
fn splat_pixels(rho: f32, max_size: f32) -> i32 {
    let s = (2.0 * rho.round() + 1.0).clamp(1.0, max_size) as i32;
    s - 1 + (s & 1)
}

fn mul(m: &[[f32; 4]; 4], p: [f32; 3]) -> [f32; 4] {
    std::array::from_fn(|r| m[0][r] * p[0] + m[1][r] * p[1] + m[2][r] * p[2] + m[3][r])
}

/// The eye normal of a splat (`splat_shape`'s) facing the eye, packed, as `splat_normal_code` in
/// compute.wgsl.
fn splat_normal_code(sp: [f32; 4]) -> u32 {
    let len = (sp[1] * sp[1] + sp[2] * sp[2] + sp[3] * sp[3]).sqrt();
    let k = if sp[3] > 0.0 { -1.0 } else { 1.0 } / len;
    pack_normal([sp[1] * k, sp[2] * k, sp[3] * k])
}

/// Draws the points into a g-buffer, as [`crate::Rasterizer::render`]'s point pass and
/// gbuffer.wgsl do; `normals`: with the splats' normals.
pub(crate) fn gbuffer(
    camera: &Camera,
    draws: &[Draw],
    tree: &[[u32; 4]],
    style: &Style,
    normals: bool,
    precision: f32,
) -> GBuffer {
    gbuffers(&[(*camera, None)], draws, tree, style, normals, precision)
        .pop()
        .expect("one eye")
}

/// [`gbuffer`] for several eyes in one pass over the points (single-pass stereo,
/// Discher et al. 2018, section 4.3): each point decoded once, then projected into each eye's own
/// framebuffer, so that a point never spills into the other eye's image. An eye's mask (true:
/// hidden, the hidden area of a headset's lens) keeps the points off its pixels.
pub(crate) fn gbuffers(
    eyes: &[(Camera, Option<&[bool]>)],
    draws: &[Draw],
    tree: &[[u32; 4]],
    style: &Style,
    normals: bool,
    precision: f32,
) -> Vec<GBuffer> {
    let blend = style.passes.blend;
    let fbs: Vec<(Vec<AtomicU64>, Vec<AtomicU32>, Vec<AtomicU64>)> = eyes
        .iter()
        .map(|(camera, _)| {
            let n = camera.width.max(1) as usize * camera.height.max(1) as usize;
            (
                (0..n).map(|_| AtomicU64::new(0)).collect(),
                (0..if normals { n } else { 0 })
                    .map(|_| AtomicU32::new(0))
                    .collect(),
                (0..if blend { 2 * n } else { 0 })
                    .map(|_| AtomicU64::new(0))
                    .collect(),
            )
        })
        .collect();
    let targets: Vec<Target> = eyes
        .iter()
        .zip(&fbs)
        .map(|((camera, mask), (fb, normal_fb, blend_fb))| Target {
            camera,
            fb,
            normal_fb,
            blend_fb,
            mask: *mask,
            // Once for every pass over the points.
            classes: mask.map(|m| {
                let w = camera.width.max(1) as usize;
                mask_classes(m, w, m.len() / w, sizes(style).2.ceil() as usize / 2 + 1)
            }),
        })
        .collect();
    // As the compute path: the nearest, the blend, the splats' normals.
    let splat_draws = draws.iter().any(|d| d.points.cpu_splats().is_some());
    let mut modes = vec![0];
    if blend {
        modes.push(2);
    }
    if normals && splat_draws {
        modes.push(1);
    }
    for mode in modes {
        points_pass(&targets, draws, tree, style, mode, precision);
    }
    targets
        .iter()
        .map(|t| {
            let (w, h) = (t.camera.width.max(1), t.camera.height.max(1));
            let far = t.camera.far as f32;
            let mut g = GBuffer::new(w, h);
            g.depth
                .par_iter_mut()
                .zip(g.colour.par_iter_mut())
                .zip(g.normal.par_iter_mut())
                .enumerate()
                .for_each(|(i, ((depth, colour), normal))| {
                    let v = t.fb[i].load(Ordering::Relaxed);
                    let key = (v >> 32) as u32;
                    if key != 0 {
                        // As `depth_at` in fb_atomic.wgsl.
                        *depth = key_depth(key, far);
                        *colour = match t.blend_fb.get(2 * i..2 * i + 2) {
                            Some(b) => {
                                let (rg, bw) =
                                    (b[0].load(Ordering::Relaxed), b[1].load(Ordering::Relaxed));
                                let sums =
                                    [rg as u32, (rg >> 32) as u32, bw as u32, (bw >> 32) as u32];
                                crate::blend::resolve(sums).unwrap_or(v as u32)
                            }
                            None => v as u32,
                        };
                        *normal = t.normal_fb.get(i).map_or(0, |n| n.load(Ordering::Relaxed));
                    }
                });
            g
        })
        .collect()
}

/// An eye's framebuffer for [`points_pass`].
struct Target<'a> {
    camera: &'a Camera,
    fb: &'a [AtomicU64],
    normal_fb: &'a [AtomicU32],
    /// With blending: per pixel the sums of red, green, blue times weight, and the weights, in
    /// two words of two sums each (each sum stays below 2^32, as the compute path's words).
    blend_fb: &'a [AtomicU64],
    mask: Option<&'a [bool]>,
    /// Its mask's [`mask_classes`] for the largest point, by tile.
    classes: Option<Vec<u8>>,
}

/// What [`points_pass`] needs of an eye, computed once a pass.
struct Eye<'a> {
    t: &'a Target<'a>,
    w: u32,
    h: u32,
    far: f32,
    focal: f32,
    m: [[f32; 4]; 4],
    basis: [[f32; 3]; 3],
}

/// A style's point sizes: the adaptive scale, the fixed size (the same for every point) or
/// none, and the largest size in pixels.
fn sizes(style: &Style) -> (f64, Option<f32>, f32) {
    match style.size {
        PointSize::Adaptive { scale, max } => (scale as f64, None, max.max(1.0)),
        PointSize::Fixed(px) => (1.0, Some(px.max(1.0).round()), px.max(1.0)),
    }
}

/// Side of the tiles of [`mask_classes`], pixels.
const MASK_TILE: usize = 8;

/// Per tile of `MASK_TILE` pixels of a `w` x `h` mask (true: hidden), what a point centred in
/// it needs: 0, every pixel within `r` of the tile hidden (it is not drawn); 2, none hidden
/// (drawn as it is); 1, some (each of its pixels looked up). Conservative (whole tiles around
/// it), and small enough to stay in cache while the points are drawn.
fn mask_classes(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<u8> {
    let (tw, th) = (w.div_ceil(MASK_TILE), h.div_ceil(MASK_TILE));
    // Hidden pixels and pixels per tile, a row of tiles per task.
    let counts: Vec<(u32, u32)> = (0..th)
        .into_par_iter()
        .flat_map_iter(|ty| {
            let mut row = vec![(0u32, 0u32); tw];
            for y in ty * MASK_TILE..((ty + 1) * MASK_TILE).min(h) {
                for (x, &m) in mask[y * w..(y + 1) * w].iter().enumerate() {
                    let c = &mut row[x / MASK_TILE];
                    c.0 += m as u32;
                    c.1 += 1;
                }
            }
            row
        })
        .collect();
    let k = r.div_ceil(MASK_TILE) as isize;
    (0..tw * th)
        .into_par_iter()
        .map(|t| {
            let (tx, ty) = ((t % tw) as isize, (t / tw) as isize);
            let (mut all, mut none) = (true, true);
            for y in (ty - k).max(0)..(ty + k + 1).min(th as isize) {
                for x in (tx - k).max(0)..(tx + k + 1).min(tw as isize) {
                    let (hidden, pixels) = counts[y as usize * tw + x as usize];
                    all &= hidden == pixels;
                    none &= hidden == 0;
                }
            }
            if all {
                0
            } else if none {
                2
            } else {
                1
            }
        })
        .collect()
}

/// One pass over the points: `mode` 0 keeps the nearest value per pixel in `fb`; 1 (splats
/// only) writes a splat's normal into `normal_fb` where its value is the one kept; 2 adds each
/// fragment within its point's size behind the nearest to `blend_fb` (`blend.rs`). Positions are
/// decoded relative to the frame's origin as the compute path does (`decode`).
fn points_pass(
    targets: &[Target],
    draws: &[Draw],
    tree: &[[u32; 4]],
    style: &Style,
    mode: u32,
    precision: f32,
) {
    // Positions decoded once, relative to the first eye's frame origin, for every eye.
    let camera = targets[0].camera;
    let (scale, fixed, max_size) = sizes(style);
    let o = frame_origin(draws, camera);
    let eyes: Vec<Eye> = targets
        .iter()
        .map(|t| Eye {
            t,
            w: t.camera.width.max(1),
            h: t.camera.height.max(1),
            far: t.camera.far as f32,
            focal: t.camera.focal() as f32,
            m: t.camera.view_proj(o),
            basis: {
                let (r, u, f) = t.camera.basis();
                [r, u, f].map(|v| [v[0] as f32, v[1] as f32, v[2] as f32])
            },
        })
        .collect();
    let [clip_min, clip_max] = Clip::uniforms(style.clip, o);
    for draw in draws.iter().filter(|d| d.count > 0) {
        let layout = Layout::of(draw, o, camera, precision);
        let (words, stride) = (draw.points.words, draw.points.len as usize);
        let spacing = (draw.spacing * scale) as f32;
        let node = draw.node.map_or(u32::MAX, |n| n.0);
        let cube = draw.node.map_or([0.0; 4], |(_, c)| {
            [
                (c.min[0] - o[0]) as f32,
                (c.min[1] - o[1]) as f32,
                (c.min[2] - o[2]) as f32,
                c.size()[0] as f32,
            ]
        });
        let data = draw.points.cpu_words();
        // Its lone points drawn small ([`Draw::lone`]).
        let lone_small = words > 0 && draw.lone;
        let colours = &data[draw.points.arrays() as usize * stride..][..draw.count as usize];
        // Oriented splats (as compute.wgsl) where the draw has them and sizes are adaptive.
        let splats = match (draw.points.cpu_splats(), draw.points.splat_range(), fixed) {
            (Some(codes), Some(range), None) => Some((&codes[..draw.count as usize], range)),
            _ => None,
        };
        if mode == 1 && splats.is_none() {
            continue;
        }
        // Keeps the nearest at a pixel (in the frame: the callers check). Most points are hidden
        // behind nearer ones: a plain load first spares their read-modify-write.
        // `edge`: the point lies across the border of its eye's hidden area (only there are
        // its pixels looked up in the mask).
        // `blend`: the point's centre, footprint and depth tolerance (mode 2).
        let plot = |e: &Eye,
                    edge: bool,
                    x: i32,
                    y: i32,
                    value: u64,
                    normal: u32,
                    blend: &([f32; 2], [f32; 4], f32)| {
            let i = y as usize * e.w as usize + x as usize;
            if edge && e.t.mask.is_some_and(|m| m[i]) {
                return;
            }
            let px = &e.t.fb[i];
            if mode == 2 {
                // As compute.wgsl's `plot` in mode 2.
                let near = (px.load(Ordering::Relaxed) >> 32) as u32;
                let (centre, shape, tol) = blend;
                if near == 0
                    || key_depth((value >> 32) as u32, e.far) > key_depth(near, e.far) + tol
                {
                    return;
                }
                let d = [x as f32 + 0.5 - centre[0], y as f32 + 0.5 - centre[1]];
                let w = crate::blend::weight(d, *shape);
                let c = value;
                let (r, g, b) = (c & 255, (c >> 8) & 255, (c >> 16) & 255);
                let w = w as u64;
                let sums = &e.t.blend_fb[2 * i..2 * i + 2];
                sums[0].fetch_add((r | g << 32) * w, Ordering::Relaxed);
                sums[1].fetch_add((b | 1 << 32) * w, Ordering::Relaxed);
            } else if mode == 1 {
                if px.load(Ordering::Relaxed) == value {
                    e.t.normal_fb[i].store(normal, Ordering::Relaxed);
                }
            } else if px.load(Ordering::Relaxed) < value {
                px.fetch_max(value, Ordering::Relaxed);
            }
        };
        colours
            .par_chunks(4096)
            .enumerate()
            .for_each(|(ci, chunk)| {
                let mut positions = vec![[0.0f32; 3]; chunk.len()];
                crate::points::decode(
                    data,
                    ci * 4096,
                    stride,
                    words,
                    layout.read,
                    layout.offset,
                    layout.unit,
                    &mut positions,
                );
                for (qi, (&colour, &p)) in chunk.iter().zip(&positions).enumerate() {
                    // As `clipped` in draw.wgsl.
                    if clip_min[3] != 0.0 {
                        let inside = (0..3).all(|a| p[a] >= clip_min[a] && p[a] <= clip_max[a]);
                        if inside == (clip_min[3] == 2.0) {
                            continue;
                        }
                    }
                    for e in &eyes {
                        let clip = mul(&e.m, p);
                        if clip[3] <= 0.0 {
                            continue;
                        }
                        let ndc = [clip[0] / clip[3], clip[1] / clip[3], clip[2] / clip[3]];
                        if ndc[0] < -1.0
                            || ndc[0] >= 1.0
                            || ndc[1] <= -1.0
                            || ndc[1] > 1.0
                            || ndc[2] < 0.0
                            || ndc[2] > 1.0
                        {
                            continue;
                        }
                        let fx = (ndc[0] * 0.5 + 0.5) * e.w as f32;
                        let fy = (0.5 - ndc[1] * 0.5) * e.h as f32;
                        // A point amid the hidden area is not drawn, one clear of it needs
                        // no mask, one near its border looks up each of its pixels.
                        let edge = match &e.t.classes {
                            None => false,
                            Some(c) => {
                                let x = (fx as usize).min(e.w as usize - 1) / MASK_TILE;
                                let y = (fy as usize).min(e.h as usize - 1) / MASK_TILE;
                                match c[y * (e.w as usize).div_ceil(MASK_TILE) + x] {
                                    0 => continue,
                                    1 => true,
                                    _ => false,
                                }
                            }
                        };
                        let colour = colour as u64;
                        if let Some((codes, range)) = splats {
                            let code = codes[ci * 4096 + qi];
                            let sp = splat_shape(code, range, clip[3], &e.basis, e.focal, max_size);
                            let normal = splat_normal_code(sp);
                            let s = splat_pixels(sp[0], max_size);
                            let blend = (
                                [fx, fy],
                                crate::blend::splat(sp),
                                s as f32 * clip[3] / e.focal,
                            );
                            let x0 = fx.floor() as i32 - (s - 1) / 2;
                            let y0 = fy.floor() as i32 - (s - 1) / 2;
                            let c = (s - 1) as f32 * 0.5;
                            let k = clip[3] / e.focal;
                            for dy in 0..s {
                                let y = y0 + dy;
                                if y < 0 || y >= e.h as i32 {
                                    continue;
                                }
                                for dx in 0..s {
                                    let x = x0 + dx;
                                    if x < 0 || x >= e.w as i32 {
                                        continue;
                                    }
                                    let (a, b) = (dx as f32 - c, dy as f32 - c);
                                    let ez = (a * sp[1] - b * sp[2]) / sp[3];
                                    if a * a + b * b + ez * ez > sp[0] * sp[0] {
                                        continue;
                                    }
                                    plot(
                                        e,
                                        edge,
                                        x,
                                        y,
                                        ((depth_key(clip[3] - k * ez, e.far) as u64) << 32)
                                            | colour,
                                        normal,
                                        &blend,
                                    );
                                }
                            }
                            continue;
                        }
                        let s = match fixed {
                            Some(px) => px,
                            None => adaptive_pixels(
                                lone_small && data[ci * 4096 + qi] & LONE_BIT != 0,
                                p,
                                clip[3],
                                spacing,
                                node,
                                cube,
                                tree,
                                max_size,
                                e.focal,
                            ),
                        } as i32;
                        let blend = (
                            [fx, fy],
                            crate::blend::point(s as f32),
                            s as f32 * clip[3] / e.focal,
                        );
                        let x0 = fx.floor() as i32 - (s - 1) / 2;
                        let y0 = fy.floor() as i32 - (s - 1) / 2;
                        let c = (s - 1) as f32 * 0.5;
                        let r2 = ((s * s) as f32 * 0.25).max(0.5);
                        let bulge = 0.5 * s as f32 * clip[3] / e.focal;
                        let flat = ((depth_key(clip[3], e.far) as u64) << 32) | colour;
                        for dy in 0..s {
                            let y = y0 + dy;
                            if y < 0 || y >= e.h as i32 {
                                continue;
                            }
                            for dx in 0..s {
                                let x = x0 + dx;
                                if x < 0 || x >= e.w as i32 {
                                    continue;
                                }
                                let mut value = flat;
                                if style.shape != Shape::Square {
                                    let (ox, oy) = (dx as f32 - c, dy as f32 - c);
                                    let d2 = ox * ox + oy * oy;
                                    if d2 > r2 {
                                        continue;
                                    }
                                    if style.shape == Shape::Paraboloid {
                                        let wp = clip[3] - bulge * (1.0 - d2 / r2);
                                        value = ((depth_key(wp, e.far) as u64) << 32) | colour;
                                    }
                                }
                                plot(e, edge, x, y, value, 0, &blend);
                            }
                        }
                    }
                }
            });
    }
}
