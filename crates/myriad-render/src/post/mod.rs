//! The frame's post passes over the g-buffer (seeds 002 section 5.3, 000 section 3.2.4): the
//! point pass leaves per pixel a linear eye depth, a colour and, where the points carry one
//! (splats), a normal; then, in this fixed order and in any combination:
//!
//! - `fill`: hole filling after Dobrev (002): two 1-D passes (rows, then columns); a pixel with
//!   nearer pixels (by more than a relative depth threshold) on both sides within `radius`, at
//!   least `min` of them, takes the nearest one's depth, colour and normal. A pixel at the edge
//!   of a near surface has nearer pixels on one side only, so a near surface never grows over a
//!   far one.
//! - normals: reconstructed in image space from depth where the points gave none (000), from
//!   the neighbour on each axis nearer in depth (so that edges do not bend them); run when
//!   `shade` or `ssao` needs them.
//! - `shade`: deferred shading, a headlight (light along the view direction: a plane seen
//!   head-on is lit uniformly) and a sun direction, over an ambient term.
//! - `ssao`: screen-space ambient occlusion, the neighbours at two radii in eight directions
//!   taken as points in eye space; those above the pixel's tangent plane occlude it, weighted
//!   down with distance.
//! - `edl`: eye-dome lighting (Boucheny 2009), as before, now one pass of the chain.
//! - `blur`: a 3x3 binomial filter over the pixels of the same surface (depth within a relative
//!   threshold), against aliasing and z-fighting (002).
//! - `aa`: supersampling: everything above drawn at `aa` times the width and height, the
//!   finish pass averaging each `aa` x `aa` block.
//!
//! Every pass is a WGSL file in this folder (`*.wgsl`, run by `gpu.rs`) and its mirror here, in
//! f32 as the shaders compute, so that the GPU paths and the CPU draw the same images (tested).

pub(crate) mod gpu;

use crate::Edl;
use rayon::prelude::*;

/// Hole filling parameters (002 section 5.3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fill {
    /// Neighbours looked at on each side, in pixels (2: a 5-pixel kernel, as 002's figure 8).
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

/// The passes of a frame, in the pipeline's order (fill, normals, shade, ssao, edl, blur, aa),
/// each on when set.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Passes {
    pub fill: Option<Fill>,
    pub shade: Option<Shade>,
    pub ssao: Option<Ssao>,
    pub edl: Option<Edl>,
    pub blur: Option<Blur>,
    /// Supersampling factor: 0 or 1 off, 2 draws four samples per pixel.
    pub aa: u32,
}

/// The default chain of `render` and `view`, chosen by `myriad bench passes` (README).
pub const DEFAULT_PASSES: &str = "fill,blur";

/// The names `Passes::parse` takes, in the pipeline's order.
pub const PASS_NAMES: [&str; 6] = ["fill", "shade", "ssao", "edl", "blur", "aa"];

impl Passes {
    /// [`DEFAULT_PASSES`].
    pub fn default_chain() -> Passes {
        Passes::parse(DEFAULT_PASSES).expect("valid names")
    }

    /// A comma-separated list of pass names (any order; `none` for no pass), each with its
    /// default parameters; an unknown name is the error.
    pub fn parse(s: &str) -> Result<Passes, String> {
        let mut p = Passes::default();
        for name in s.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            match name {
                "none" => {}
                "fill" => p.fill = Some(Fill::default()),
                "shade" => p.shade = Some(Shade::default()),
                "ssao" => p.ssao = Some(Ssao::default()),
                "edl" => p.edl = Some(Edl::default()),
                "blur" => p.blur = Some(Blur::default()),
                "aa" => p.aa = 2,
                _ => {
                    return Err(format!(
                        "unknown pass {name:?} (passes: {}, or none)",
                        PASS_NAMES.join(", ")
                    ));
                }
            }
        }
        Ok(p)
    }

    /// The passes' dispatches in the pipeline's order, by their entry points' names (the
    /// g-buffer's and the finish pass around them): one list for the CPU and the GPU.
    pub(crate) fn steps(&self) -> Vec<&'static str> {
        let mut steps = Vec::new();
        if self.fill.is_some() {
            steps.extend(["fill_rows", "fill_columns"]);
        }
        if self.normals() {
            steps.push("normals");
        }
        for (name, on) in [
            ("shade", self.shade.is_some()),
            ("ssao", self.ssao.is_some()),
            ("edl", self.edl.is_some_and(|e| e.strength > 0.0)),
            ("blur", self.blur.is_some()),
        ] {
            if on {
                steps.push(name);
            }
        }
        steps
    }

    /// Whether a pass needs normals.
    pub fn normals(&self) -> bool {
        self.shade.is_some() || self.ssao.is_some()
    }

    /// The supersampling factor (at least 1).
    pub fn factor(&self) -> u32 {
        self.aa.clamp(1, 4)
    }
}

/// What the passes know of the frame.
#[derive(Debug, Clone, Copy)]
pub(crate) struct View {
    /// The g-buffer's size (the image's times the supersampling factor).
    pub width: u32,
    pub height: u32,
    pub factor: u32,
    /// Pixels per unit of length at depth 1, at the g-buffer's size.
    pub focal: f32,
    /// Towards the sun in eye coordinates (right, up, forward).
    pub sun: [f32; 3],
    pub background: [u8; 4],
    /// Side-by-side stereo on the GPU: each eye's width (the passes read no pixel across the
    /// eyes' border, and place pixels in eye space from their own eye's centre); 0: one image.
    /// The CPU runs the passes on each eye's own g-buffer instead.
    pub eye_width: u32,
}

impl View {
    /// The view of a g-buffer drawn by `camera` (already supersampled `factor` times).
    pub fn new(
        camera: &myriad_lod::Camera,
        passes: &Passes,
        background: [u8; 4],
        factor: u32,
    ) -> View {
        let (r, u, f) = camera.basis();
        let s = passes.shade.map_or([0.0, 0.0, 1.0], |s| s.sun_direction);
        let len = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt().max(1e-30);
        let dot = |v: [f64; 3]| ((v[0] * s[0] + v[1] * s[1] + v[2] * s[2]) / len) as f32;
        View {
            width: camera.width.max(1),
            height: camera.height.max(1),
            factor,
            focal: camera.focal() as f32,
            sun: [dot(r), dot(u), dot(f)],
            eye_width: 0,
            background,
        }
    }
}

/// Per pixel, row by row: linear eye depth (0: nothing drawn), RGBA8 colour, normal
/// ([`pack_normal`]; 0: none).
#[derive(Clone)]
pub(crate) struct GBuffer {
    pub width: u32,
    pub height: u32,
    pub depth: Vec<f32>,
    pub colour: Vec<u32>,
    pub normal: Vec<u32>,
}

impl GBuffer {
    pub fn new(width: u32, height: u32) -> GBuffer {
        let n = width as usize * height as usize;
        GBuffer {
            width,
            height,
            depth: vec![0.0; n],
            colour: vec![0; n],
            normal: vec![0; n],
        }
    }
}

/// A unit normal in eye coordinates (right, up, forward) as WGSL's `pack4x8snorm` of (n, 1): the
/// top byte is non-zero for every normal, so 0 means none.
pub fn pack_normal(n: [f32; 3]) -> u32 {
    let b = |v: f32| ((0.5 + 127.0 * v.clamp(-1.0, 1.0)).floor() as i32 as i8 as u8) as u32;
    b(n[0]) | b(n[1]) << 8 | b(n[2]) << 16 | b(1.0) << 24
}

/// As WGSL's `unpack4x8snorm(code).xyz`.
pub fn unpack_normal(code: u32) -> [f32; 3] {
    std::array::from_fn(|k| ((code >> (8 * k)) as u8 as i8 as f32 / 127.0).max(-1.0))
}

/// As `pack4x8unorm`.
fn pack_colour(c: [f32; 4]) -> u32 {
    let b = |v: f32| (0.5 + 255.0 * v.clamp(0.0, 1.0)).floor() as u32;
    b(c[0]) | b(c[1]) << 8 | b(c[2]) << 16 | b(c[3]) << 24
}

/// As `unpack4x8unorm`.
fn unpack_colour(c: u32) -> [f32; 4] {
    std::array::from_fn(|k| ((c >> (8 * k)) & 0xff) as f32 / 255.0)
}

/// The colour with its RGB times `k`.
fn scale_colour(c: u32, k: f32) -> u32 {
    let v = unpack_colour(c);
    pack_colour([v[0] * k, v[1] * k, v[2] * k, v[3]])
}

/// The eye-space position (right, up, forward) of pixel (x, y) at depth `d`, as `eye_position`
/// in common.wgsl.
fn eye_position(v: &View, x: i32, y: i32, d: f32) -> [f32; 3] {
    [
        (x as f32 + 0.5 - v.width as f32 * 0.5) / v.focal * d,
        (v.height as f32 * 0.5 - y as f32 - 0.5) / v.focal * d,
        d,
    ]
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Runs the passes on the g-buffer and returns the image (RGBA8, rows top to bottom), the
/// g-buffer's size divided by the supersampling factor.
pub(crate) fn run(g: GBuffer, passes: &Passes, v: &View) -> Vec<u8> {
    run_masked(g, passes, v, None)
}

/// [`run`], every pass skipping the pixels `mask` hides (a headset's hidden area: they stay as
/// the point pass left them, empty).
pub(crate) fn run_masked(
    mut g: GBuffer,
    passes: &Passes,
    v: &View,
    mask: Option<&[bool]>,
) -> Vec<u8> {
    let mut scratch = GBuffer::new(g.width, g.height);
    // Pixel sizes scale with the supersampling, as in gpu.rs's uniforms.
    let f = v.factor;
    let fill = passes.fill.unwrap_or_default();
    let radius = fill.radius * f;
    let shade = passes.shade.unwrap_or_default();
    let ssao = passes.ssao.map_or_else(Ssao::default, |s| Ssao {
        radius: s.radius * f as f32,
        ..s
    });
    let edl = passes.edl.map_or_else(Edl::default, |e| Edl {
        radius: e.radius * f as f32,
        ..e
    });
    let blur = passes.blur.unwrap_or_default();
    type Pass<'a> = Box<dyn Fn(&GBuffer, usize) -> (f32, u32, u32) + Sync + 'a>;
    for step in passes.steps() {
        let pass: Pass = match step {
            "fill_rows" => Box::new(|g, i| fill_pixel(g, i, 0, radius, &fill)),
            "fill_columns" => Box::new(|g, i| fill_pixel(g, i, 1, radius, &fill)),
            "normals" => Box::new(|g, i| normal_pixel(g, i, v)),
            "shade" => Box::new(|g, i| shade_pixel(g, i, v, &shade)),
            "ssao" => Box::new(|g, i| ssao_pixel(g, i, v, &ssao)),
            "edl" => Box::new(|g, i| edl_pixel(g, i, &edl)),
            "blur" => Box::new(|g, i| blur_pixel(g, i, &blur)),
            _ => unreachable!("a step of Passes::steps"),
        };
        each_pixel(&g, &mut scratch, &pass, mask);
        std::mem::swap(&mut g, &mut scratch);
    }
    finish(&g, v)
}

/// `dst` pixel by pixel from `src`: (depth, colour, normal).
fn each_pixel(
    src: &GBuffer,
    dst: &mut GBuffer,
    pass: &(dyn Fn(&GBuffer, usize) -> (f32, u32, u32) + Sync),
    mask: Option<&[bool]>,
) {
    let w = src.width as usize;
    dst.depth
        .par_chunks_mut(w)
        .zip(dst.colour.par_chunks_mut(w))
        .zip(dst.normal.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, ((d, c), n))| {
            for x in 0..w {
                let i = y * w + x;
                (d[x], c[x], n[x]) = if mask.is_some_and(|m| m[i]) {
                    keep(src, i)
                } else {
                    pass(src, i)
                };
            }
        });
}

fn at(g: &GBuffer, x: i32, y: i32) -> Option<usize> {
    (x >= 0 && y >= 0 && x < g.width as i32 && y < g.height as i32)
        .then(|| y as usize * g.width as usize + x as usize)
}

fn xy(g: &GBuffer, i: usize) -> (i32, i32) {
    ((i % g.width as usize) as i32, (i / g.width as usize) as i32)
}

fn keep(g: &GBuffer, i: usize) -> (f32, u32, u32) {
    (g.depth[i], g.colour[i], g.normal[i])
}

/// As fill.wgsl: `axis` 0 along rows, 1 along columns.
fn fill_pixel(g: &GBuffer, i: usize, axis: u32, radius: u32, p: &Fill) -> (f32, u32, u32) {
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

/// As normals.wgsl.
fn normal_pixel(g: &GBuffer, i: usize, v: &View) -> (f32, u32, u32) {
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

/// As shade.wgsl.
fn shade_pixel(g: &GBuffer, i: usize, v: &View, s: &Shade) -> (f32, u32, u32) {
    if g.depth[i] <= 0.0 {
        return keep(g, i);
    }
    let n = unpack_normal(g.normal[i]);
    let light = s.ambient + s.headlight * (-n[2]).max(0.0) + s.sun * dot(n, v.sun).max(0.0);
    (g.depth[i], scale_colour(g.colour[i], light), g.normal[i])
}

/// Eight directions around the circle, unit length (as AROUND in common.wgsl).
const AROUND: [[f32; 2]; 8] = {
    const H: f32 = std::f32::consts::FRAC_1_SQRT_2;
    [
        [1.0, 0.0],
        [H, H],
        [0.0, 1.0],
        [-H, H],
        [-1.0, 0.0],
        [-H, -H],
        [0.0, -1.0],
        [H, -H],
    ]
};

/// As ssao.wgsl.
fn ssao_pixel(g: &GBuffer, i: usize, v: &View, s: &Ssao) -> (f32, u32, u32) {
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

/// As edl.wgsl.
fn edl_pixel(g: &GBuffer, i: usize, e: &Edl) -> (f32, u32, u32) {
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

/// As blur.wgsl.
fn blur_pixel(g: &GBuffer, i: usize, b: &Blur) -> (f32, u32, u32) {
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

/// As finish.wgsl: each image pixel the mean of its `factor` x `factor` block, the background
/// where nothing was drawn.
fn finish(g: &GBuffer, v: &View) -> Vec<u8> {
    let f = v.factor.max(1) as usize;
    let (w, h) = (g.width as usize / f, g.height as usize / f);
    let background = u32::from_le_bytes(v.background);
    let mut out = vec![0u8; w * h * 4];
    out.par_chunks_mut(w.max(1) * 4)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
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

#[cfg(test)]
mod tests;
