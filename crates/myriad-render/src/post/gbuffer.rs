//! The g-buffer: what the point pass leaves per pixel (linear eye depth, colour, normal) as
//! the post passes read it. On the GPU the g-buffer pass (gbuffer.wgsl) turns a path's
//! framebuffer (fb_atomic.wgsl: the compute path's 64-bit words; fb_quads.wgsl: the quad path's
//! targets) into it; on the CPU, `cpu.rs` writes it directly. Also the helpers every pass's CPU
//! mirror shares with common.wgsl.

/// The compute path's framebuffer as the g-buffer pass reads it ([`gbuffer_source`]).
pub const FB_ATOMIC_WGSL: &str = include_str!("fb_atomic.wgsl");
/// The quad path's render targets as the g-buffer pass reads them.
pub const FB_QUADS_WGSL: &str = include_str!("fb_quads.wgsl");

/// The g-buffer pass reading a path's framebuffer ([`FB_ATOMIC_WGSL`] or [`FB_QUADS_WGSL`]).
pub fn gbuffer_source(framebuffer: &str) -> String {
    concat!(include_str!("common.wgsl"), include_str!("gbuffer.wgsl")).to_string() + framebuffer
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
    /// `sun`: towards the sun in world coordinates (None: along the view).
    pub fn new(
        camera: &myriad_lod::Camera,
        sun: Option<[f64; 3]>,
        background: [u8; 4],
        factor: u32,
    ) -> View {
        let (r, u, f) = camera.basis();
        let s = sun.unwrap_or([0.0, 0.0, 1.0]);
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
pub(crate) fn pack_colour(c: [f32; 4]) -> u32 {
    let b = |v: f32| (0.5 + 255.0 * v.clamp(0.0, 1.0)).floor() as u32;
    b(c[0]) | b(c[1]) << 8 | b(c[2]) << 16 | b(c[3]) << 24
}

/// As `unpack4x8unorm`.
pub(crate) fn unpack_colour(c: u32) -> [f32; 4] {
    std::array::from_fn(|k| ((c >> (8 * k)) & 0xff) as f32 / 255.0)
}

/// The colour with its RGB times `k`.
pub(crate) fn scale_colour(c: u32, k: f32) -> u32 {
    let v = unpack_colour(c);
    pack_colour([v[0] * k, v[1] * k, v[2] * k, v[3]])
}

/// The eye-space position (right, up, forward) of pixel (x, y) at depth `d`, as `eye_position`
/// in common.wgsl.
pub(crate) fn eye_position(v: &View, x: i32, y: i32, d: f32) -> [f32; 3] {
    [
        (x as f32 + 0.5 - v.width as f32 * 0.5) / v.focal * d,
        (v.height as f32 * 0.5 - y as f32 - 0.5) / v.focal * d,
        d,
    ]
}

pub(crate) fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn at(g: &GBuffer, x: i32, y: i32) -> Option<usize> {
    (x >= 0 && y >= 0 && x < g.width as i32 && y < g.height as i32)
        .then(|| y as usize * g.width as usize + x as usize)
}

pub(crate) fn xy(g: &GBuffer, i: usize) -> (i32, i32) {
    ((i % g.width as usize) as i32, (i / g.width as usize) as i32)
}

pub(crate) fn keep(g: &GBuffer, i: usize) -> (f32, u32, u32) {
    (g.depth[i], g.colour[i], g.normal[i])
}

/// Eight directions around the circle, unit length (as AROUND in common.wgsl).
pub(crate) const AROUND: [[f32; 2]; 8] = {
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
