//! Points on the GPU (or in memory for the CPU path): positions quantized per node
//! (Kanzok et al. 2015: x = o + x̂∘r) and RGBA8 colour.
//!
//! A node's points are integers on a grid relative to the node's own corner (`origin`, `step`
//! per axis): on the dataset's grid where the node's extent fits 30 bits an axis, so that no
//! position changes, else as fine as 30 bits allow. They are held in 1, 2 or 3 words of 10 bits
//! an axis, as the node needs, most significant word first (Schütz et al. 2022's batches of
//! precision): where a node's points project small, a rasterizer reads the first word alone and
//! takes the rest of each coordinate at the middle of its range ([`Points::read_words`]). The
//! words are laid out array by array (all points' first words, then their second, ..., then the
//! colours), so that a pass that reads the first word reads only that array.
//!
//! `Encoding::F32` keeps the layout before quantization (f32 x, y, z relative to an origin, 16
//! bytes a point with colour), for comparisons.

use crate::Gpu;
use myriad_format::page::Quantization;
use myriad_lod::Camera;
use wgpu::util::DeviceExt;

/// Bits of an axis in one position word.
pub const WORD_BITS: u32 = 10;

/// The bit of a point's first position word (above its three axes) that marks it lone: no
/// other point of its node within its [`myriad_lod::lone_radius`]
/// ([`myriad_core::geometry::lone_points`]).
/// Its adaptive size is then at most [`LONE_PIXELS`], on every path: a square as wide as its
/// level's spacing closes the gaps of a surface, and a lone point (an outlier in a sparse node,
/// a bird, a stray return) has none around it to close; drawn that wide near the camera, it is
/// a block dozens of pixels across.
pub const LONE_BIT: u32 = 1 << 30;

/// The widest a lone point is drawn with adaptive sizes, in pixels (fixed sizes are as asked).
pub const LONE_PIXELS: f32 = 3.0;

/// How positions are held.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Encoding {
    /// On a grid (the dataset's quantization), relative to each node's corner.
    Grid(Quantization),
    /// f32 relative to an origin (the layout before quantization).
    F32 { origin: [f64; 3] },
}

impl Encoding {
    /// A grid anchored at `origin` whose step puts the extent of `positions` into 20 bits an
    /// axis (for points that are not on a grid of their own).
    pub fn fitted(origin: [f64; 3], positions: &[[f64; 3]]) -> Encoding {
        let (lo, hi) = bounds(positions);
        let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        let step = if extent > 0.0 {
            extent / ((1u64 << 20) - 4) as f64
        } else {
            1.0
        };
        Encoding::Grid(Quantization {
            scale: [step; 3],
            offset: origin,
        })
    }
}

fn bounds(positions: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in positions {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (lo, hi)
}

/// Points to draw: positions relative to `origin` (quantized or f32) and an RGBA8 colour each,
/// in a GPU buffer (or in memory, for the CPU).
pub struct Points {
    /// What the positions are relative to (a quantized node: its grid corner).
    pub origin: [f64; 3],
    /// World length of one integer step per axis (quantized; zero for f32).
    pub step: [f64; 3],
    /// Position words per point: 1 to 3 of 10 bits an axis; 0: f32 x, y, z (three words).
    pub words: u32,
    /// Quantized: the points' box relative to `origin`, its far corner (f32: zero).
    pub extent: [f64; 3],
    storage: Storage,
    pub len: u32,
    /// Splats (`mwkd`): per point a normal's cube-map code and an 8-bit radius
    /// ([`splat_code`]), and the radius range the codes span.
    splats: Option<(Storage, [f32; 2])>,
}

enum Storage {
    Gpu(wgpu::Buffer),
    Cpu(Vec<u32>),
}

impl Storage {
    fn new(gpu: &Gpu, label: &str, words: Vec<u32>) -> Storage {
        match gpu.wgpu() {
            None => Storage::Cpu(words),
            Some(_) => Storage::copied(gpu, label, &words),
        }
    }

    /// [`Storage::new`] of words kept elsewhere (copied into the CPU path's storage).
    fn copied(gpu: &Gpu, label: &str, words: &[u32]) -> Storage {
        match gpu.wgpu() {
            None => Storage::Cpu(words.to_vec()),
            Some((device, _)) => Storage::Gpu(device.create_buffer_init(
                &wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    // An empty storage binding is not allowed: keep one dummy element.
                    contents: if words.is_empty() {
                        &[0u8; 16]
                    } else {
                        bytemuck::cast_slice(words)
                    },
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                },
            )),
        }
    }

    fn bytes(&self) -> usize {
        match self {
            Storage::Gpu(b) => b.size() as usize,
            Storage::Cpu(v) => v.len() * 4,
        }
    }
}

/// A splat's normal and radius in one word: the normal's cube-map index
/// (`myriad_format::splat::normal_code`) in the low 16 bits, the radius in 8 bits above, from
/// `range[0]` (0) to `range[1]` (255).
pub fn splat_code(normal: [f32; 3], radius: f32, range: [f32; 2]) -> u32 {
    use myriad_format::splat::{normal_code, radius_code};
    normal_code(normal) as u32 | (radius_code(radius, range[0], range[1]) as u32) << 16
}

/// The positions of points `first..first + out.len()` relative to the frame's origin from their
/// words (`points`, the layout of [`Points`]), as `decode` in draw.wgsl computes each, in f32
/// and in the same order: `offset` is the draw's origin relative to the frame's, `unit` the
/// world length of the first word's step per axis. Word array by word array, so that the loops
/// vectorize.
#[allow(clippy::too_many_arguments)]
pub(crate) fn decode(
    points: &[u32],
    first: usize,
    stride: usize,
    words: u32,
    read: u32,
    offset: [f32; 3],
    unit: [f32; 3],
    out: &mut [[f32; 3]],
) {
    let n = out.len();
    if n == 0 {
        return;
    }
    if words == 0 {
        for (a, array) in points.chunks_exact(stride).take(3).enumerate() {
            for (p, &v) in out.iter_mut().zip(&array[first..first + n]) {
                p[a] = offset[a] + f32::from_bits(v);
            }
        }
        return;
    }
    out.fill(offset);
    let mut u = unit;
    for array in points.chunks_exact(stride).take(read as usize) {
        for (p, &w) in out.iter_mut().zip(&array[first..first + n]) {
            for a in 0..3 {
                p[a] += ((w >> (WORD_BITS * a as u32)) & 1023) as f32 * u[a];
            }
        }
        u = u.map(|v| v * (1.0 / 1024.0));
    }
    if read < words {
        // The middle of what was not read.
        for p in out.iter_mut() {
            for a in 0..3 {
                p[a] += u[a] * 512.0;
            }
        }
    }
}

/// Splats' codes ([`splat_code`]) and the radius range they span.
fn splat_codes(normals: &[[f32; 3]], radii: &[f32]) -> (Vec<u32>, [f32; 2]) {
    let lo = radii.iter().copied().fold(f32::INFINITY, f32::min);
    let range = if lo.is_finite() {
        [lo, radii.iter().copied().fold(lo, f32::max)]
    } else {
        [0.0, 0.0]
    };
    let codes = normals
        .iter()
        .zip(radii)
        .map(|(&n, &r)| splat_code(n, r, range))
        .collect();
    (codes, range)
}

/// Points' words as [`Points`] holds them, made on any thread (the loader's: no frame does the
/// per-point work) and handed to the GPU by [`Encoded::upload`].
#[derive(Debug, Clone)]
pub struct Encoded {
    origin: [f64; 3],
    step: [f64; 3],
    words: u32,
    extent: [f64; 3],
    data: Vec<u32>,
    len: u32,
    splats: Option<(Vec<u32>, [f32; 2])>,
}

impl Encoded {
    /// Positions held as `encoding` says, and their colours.
    pub fn new(encoding: Encoding, positions: &[[f64; 3]], rgba: &[[u8; 4]]) -> Encoded {
        assert_eq!(positions.len(), rgba.len());
        let n = positions.len();
        let (origin, step, words, extent, mut data) = match encoding {
            Encoding::F32 { origin } => {
                let mut data = vec![0u32; 4 * n];
                for (i, p) in positions.iter().enumerate() {
                    for a in 0..3 {
                        data[a * n + i] = ((p[a] - origin[a]) as f32).to_bits();
                    }
                }
                (origin, [0.0; 3], 0, [0.0; 3], data)
            }
            Encoding::Grid(g) => quantize(&g, positions),
        };
        let arrays = if words == 0 { 3 } else { words as usize };
        for (i, c) in rgba.iter().enumerate() {
            data[arrays * n + i] = u32::from_le_bytes(*c);
        }
        Encoded {
            origin,
            step,
            words,
            extent,
            data,
            len: n as u32,
            splats: None,
        }
    }

    /// Marks the points `lone` says ([`LONE_BIT`]); positions held as f32 (the layout before
    /// quantization, for comparisons) have no bit to spare and are not marked.
    pub fn with_lone(mut self, lone: &[bool]) -> Encoded {
        assert_eq!(lone.len(), self.len as usize);
        if self.words > 0 {
            for (w, _) in self.data.iter_mut().zip(lone).filter(|(_, l)| **l) {
                *w |= LONE_BIT;
            }
        }
        self
    }

    /// These points as splats: each also has a normal and a radius (world units).
    pub fn with_splats(mut self, normals: &[[f32; 3]], radii: &[f32]) -> Encoded {
        assert!(normals.len() == self.len as usize && radii.len() == self.len as usize);
        self.splats = Some(splat_codes(normals, radii));
        self
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        4 * (self.data.len() + self.splats.as_ref().map_or(0, |s| s.0.len()))
    }

    /// The points on `gpu` (a buffer made of these words; the CPU path keeps a copy).
    pub fn upload(&self, gpu: &Gpu) -> Points {
        Points {
            origin: self.origin,
            step: self.step,
            words: self.words,
            extent: self.extent,
            storage: Storage::copied(gpu, "points", &self.data),
            len: self.len,
            splats: (self.splats.as_ref())
                .map(|(c, range)| (Storage::copied(gpu, "splats", c), *range)),
        }
    }

    /// [`Encoded::upload`], these words moved into the CPU path's storage.
    pub fn into_points(self, gpu: &Gpu) -> Points {
        Points {
            origin: self.origin,
            step: self.step,
            words: self.words,
            extent: self.extent,
            storage: Storage::new(gpu, "points", self.data),
            len: self.len,
            splats: self
                .splats
                .map(|(c, range)| (Storage::new(gpu, "splats", c), range)),
        }
    }
}

impl Points {
    /// Points quantized on a grid anchored at `origin` that fits their extent into 20 bits an
    /// axis ([`Encoding::fitted`]).
    pub fn upload(gpu: &Gpu, origin: [f64; 3], positions: &[[f64; 3]], rgba: &[[u8; 4]]) -> Points {
        Points::encode(gpu, Encoding::fitted(origin, positions), positions, rgba)
    }

    /// Points held as `encoding` says.
    pub fn encode(
        gpu: &Gpu,
        encoding: Encoding,
        positions: &[[f64; 3]],
        rgba: &[[u8; 4]],
    ) -> Points {
        Encoded::new(encoding, positions, rgba).into_points(gpu)
    }

    /// [`Points::upload`] of splats: each point also has a normal and a radius (world units).
    pub fn upload_splats(
        gpu: &Gpu,
        origin: [f64; 3],
        positions: &[[f64; 3]],
        rgba: &[[u8; 4]],
        normals: &[[f32; 3]],
        radii: &[f32],
    ) -> Points {
        Points::upload(gpu, origin, positions, rgba).with_splats(gpu, normals, radii)
    }

    /// These points as splats: each also has a normal and a radius (world units).
    pub fn with_splats(mut self, gpu: &Gpu, normals: &[[f32; 3]], radii: &[f32]) -> Points {
        assert!(normals.len() == self.len as usize && radii.len() == self.len as usize);
        let (codes, range) = splat_codes(normals, radii);
        self.splats = Some((Storage::new(gpu, "splats", codes), range));
        self
    }

    /// The radius range of a splat upload.
    pub fn splat_range(&self) -> Option<[f32; 2]> {
        self.splats.as_ref().map(|s| s.1)
    }

    pub(crate) fn splat_buffer(&self) -> Option<&wgpu::Buffer> {
        match &self.splats {
            Some((Storage::Gpu(b), _)) => Some(b),
            _ => None,
        }
    }

    pub(crate) fn cpu_splats(&self) -> Option<&[u32]> {
        match &self.splats {
            Some((Storage::Cpu(v), _)) => Some(v),
            _ => None,
        }
    }

    /// Bytes this takes (on the GPU, or in memory for the CPU).
    pub fn bytes(&self) -> usize {
        self.splats.as_ref().map_or(0, |s| s.0.bytes()) + self.storage.bytes()
    }

    /// Position words a point has (f32: three).
    pub fn arrays(&self) -> u32 {
        if self.words == 0 { 3 } else { self.words }
    }

    /// Bytes a rasterizer reads per point when it reads `read` position words: those and the
    /// colour (and a splat's code).
    pub fn read_bytes(&self, read: u32) -> u32 {
        4 * (read + 1 + self.splats.is_some() as u32)
    }

    pub(crate) fn buffer(&self) -> &wgpu::Buffer {
        match &self.storage {
            Storage::Gpu(b) => b,
            Storage::Cpu(_) => panic!("points in memory drawn by a GPU path"),
        }
    }

    pub(crate) fn cpu_words(&self) -> &[u32] {
        match &self.storage {
            Storage::Cpu(v) => v,
            Storage::Gpu(_) => panic!("points on a GPU drawn by the CPU path"),
        }
    }

    /// The world length of the first word's step per axis (zero for f32).
    pub(crate) fn unit(&self) -> [f32; 3] {
        let k = (1u64 << (WORD_BITS * self.words.saturating_sub(1))) as f64;
        self.step.map(|s| (s * k) as f32)
    }

    /// How many position words a rasterizer needs to read for `camera` (Schütz 2022's precision
    /// per batch): the fewest whose unread rest spans at most `pixels` where the points' box
    /// is nearest to the eye (all of them when the box reaches the near plane, for f32, when
    /// `pixels` is 0, and for splats: many overlapping discs at nearly one depth, whose order
    /// the smallest shift changes).
    pub fn read_words(&self, camera: &Camera, pixels: f32) -> u32 {
        if self.words <= 1 || pixels <= 0.0 || self.splats.is_some() {
            return self.arrays();
        }
        // The nearest eye depth of the box's corners.
        let far = std::array::from_fn(|a| self.origin[a] + self.extent[a]);
        let (f, eye) = (camera.forward(), camera.position);
        let depth = (myriad_core::Aabb::new(self.origin, far).corners().iter())
            .map(|c| (0..3).map(|a| (c[a] - eye[a]) * f[a]).sum::<f64>())
            .fold(f64::INFINITY, f64::min);
        if depth <= camera.near {
            return self.words;
        }
        let largest = self.step.iter().copied().fold(0.0, f64::max);
        let per_unit = camera.focal() / depth;
        (1..self.words)
            .find(|&read| {
                let rest = largest * (1u64 << (WORD_BITS * (self.words - read))) as f64;
                rest * per_unit <= pixels as f64
            })
            .unwrap_or(self.words)
    }

    /// Draw the first `count` points, `spacing` apart in the world (for adaptive sizes).
    pub fn prefix(&self, count: u32, spacing: f64) -> Draw<'_> {
        Draw {
            points: self,
            count: count.min(self.len),
            spacing,
            node: None,
            behind: 0.0,
            lone: false,
        }
    }

    /// Draw all points.
    pub fn all(&self, spacing: f64) -> Draw<'_> {
        self.prefix(self.len, spacing)
    }
}

/// Positions on the grid `g`, relative to the grid corner of their box: origin, step, words,
/// extent and the words array by array (with room for the colours after them).
fn quantize(
    g: &Quantization,
    positions: &[[f64; 3]],
) -> ([f64; 3], [f64; 3], u32, [f64; 3], Vec<u32>) {
    let n = positions.len();
    if n == 0 {
        return (g.offset, g.scale, 1, [0.0; 3], vec![0; 0]);
    }
    let (lo, hi) = bounds(positions);
    let k_lo = g.to_int(lo);
    let k_hi = g.to_int(hi);
    let span = (0..3)
        .map(|a| (k_hi[a] - k_lo[a]) as u64)
        .max()
        .unwrap_or(0);
    let bits = 64 - span.leading_zeros();
    // Beyond 30 bits an axis, steps of 2^shift grid units.
    let shift = bits.saturating_sub(3 * WORD_BITS);
    let bits = bits - shift;
    let words = bits.div_ceil(WORD_BITS).max(1);
    // The values fill their words from the top (shifted left by `fill`, the step divided as
    // much), so that the first word alone always places a point within 1/1024 to 1/512 of the
    // node's extent.
    let fill = WORD_BITS * words - bits;
    let step: [f64; 3] =
        std::array::from_fn(|a| g.scale[a] * (1u64 << shift) as f64 / (1u64 << fill) as f64);
    let origin = g.to_world(k_lo);
    let top = (1u64 << (WORD_BITS * words)) - 1;
    let mut data = vec![0u32; (words as usize + 1) * n];
    for (i, p) in positions.iter().enumerate() {
        let k = g.to_int(*p);
        let q: [u64; 3] = std::array::from_fn(|a| {
            let d = (k[a] - k_lo[a]).max(0) as u64;
            let rounded = if shift == 0 {
                d
            } else {
                (d + (1 << (shift - 1))) >> shift
            };
            (rounded << fill).min(top)
        });
        for w in 0..words {
            let at = WORD_BITS * (words - 1 - w);
            data[w as usize * n + i] = (0..3)
                .map(|a| (((q[a] >> at) & 1023) as u32) << (WORD_BITS * a as u32))
                .sum();
        }
    }
    let extent = std::array::from_fn(|a| (k_hi[a] - k_lo[a]) as f64 * g.scale[a]);
    (origin, step, words, extent, data)
}

/// Part of a [`Points`] to draw in a frame.
#[derive(Clone, Copy)]
pub struct Draw<'a> {
    pub points: &'a Points,
    pub count: u32,
    /// World spacing of these points, for adaptive point sizes.
    pub spacing: f64,
    /// The node these points belong to, as its index in the drawn tree passed to
    /// [`crate::Rasterizer::render`] and its cube: each point then takes the spacing of the finest
    /// drawn node around it ([`myriad_lod::DrawnTree`]). None: `spacing` for every point.
    pub node: Option<(u32, myriad_core::Aabb)>,
    /// How far behind where they are these points are drawn, as a share of their distance
    /// from the camera (0: where they are). Each moves along its ray from the camera, so it
    /// covers the same pixels, but loses the depth test to what is drawn where it is: a
    /// stand-in ([`crate::Scene`], `mwkd`) fills holes without covering loaded detail.
    pub behind: f32,
    /// Its lone points ([`LONE_BIT`]) are drawn at most [`LONE_PIXELS`] wide: it draws a leaf
    /// node whole (lone among all the node's points, with no descendant holding points around
    /// them: an inner node's point lone among its node's sample stands in for the points below
    /// it, and a coarser prefix's points may lie as far apart as its spacing).
    pub lone: bool,
}

/// Where a draw's points are for a frame drawn relative to `origin`: their origin there, the
/// first word's step, their words and how many to read, as `decode` in draw.wgsl takes them.
pub(crate) struct Layout {
    pub offset: [f32; 3],
    pub unit: [f32; 3],
    pub words: u32,
    pub read: u32,
}

impl Layout {
    pub(crate) fn of(draw: &Draw, origin: [f64; 3], camera: &Camera, precision: f32) -> Layout {
        let o = draw.points.origin;
        // Pushed behind by b: p' = c + (p - c)(1 + b) for the camera at c, i.e. the offset and
        // unit scaled by 1 + b and the offset moved by -b c (exactly as they are for b = 0).
        let b = draw.behind as f64;
        let c: [f64; 3] = std::array::from_fn(|a| camera.position[a] - origin[a]);
        Layout {
            offset: std::array::from_fn(|a| ((o[a] - origin[a]) * (1.0 + b) - c[a] * b) as f32),
            unit: draw.points.unit().map(|u| (u as f64 * (1.0 + b)) as f32),
            words: draw.points.words,
            read: draw.points.read_words(camera, precision),
        }
    }
}

/// The origin a frame's positions are drawn relative to (on every path): the first draw's.
pub(crate) fn frame_origin(draws: &[Draw], camera: &Camera) -> [f64; 3] {
    draws.first().map_or(camera.position, |d| d.points.origin)
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_lod::Camera;

    /// Quantized positions back in f64, every word read.
    fn decoded(p: &Points) -> Vec<[f64; 3]> {
        let data = p.cpu_words();
        let n = p.len as usize;
        (0..n)
            .map(|i| {
                std::array::from_fn(|a| {
                    let mut q = 0u64;
                    for k in 0..p.words as usize {
                        q = q << WORD_BITS
                            | ((data[k * n + i] >> (WORD_BITS * a as u32)) & 1023) as u64;
                    }
                    p.origin[a] + q as f64 * p.step[a]
                })
            })
            .collect()
    }

    fn grid(scale: f64, offset: [f64; 3]) -> Encoding {
        Encoding::Grid(Quantization {
            scale: [scale; 3],
            offset,
        })
    }

    #[test]
    fn positions_on_the_grid_come_back_exactly_in_as_many_words_as_the_node_needs() {
        let gpu = Gpu::cpu();
        // UTM-like: millimetres, 5 km apart at most; a small node fits one word.
        let offset = [500_000.0, 4_000_000.0, 0.0];
        let on = |k: [i64; 3]| std::array::from_fn(|a| offset[a] + k[a] as f64 * 0.001);
        for (span, words) in [(1023i64, 1), (1024, 2), ((1 << 20) - 1, 2), (5_000_000, 3)] {
            let ks = [[17, 3, 9], [17 + span, 3, 9], [20, 3 + span / 2, 9 + span]];
            let positions: Vec<[f64; 3]> = ks.iter().map(|&k| on(k)).collect();
            let p = Points::encode(&gpu, grid(0.001, offset), &positions, &[[1, 2, 3, 4]; 3]);
            assert_eq!(p.words, words, "span {span}");
            assert_eq!(p.bytes(), 4 * (words as usize + 1) * 3);
            let back = decoded(&p);
            for (b, k) in back.iter().zip(&ks) {
                let k2 = myriad_format::page::Quantization {
                    scale: [0.001; 3],
                    offset,
                }
                .to_int(*b);
                assert_eq!(k2, *k, "span {span}");
            }
            // The colours follow the position words.
            assert_eq!(
                p.cpu_words()[words as usize * 3],
                u32::from_le_bytes([1, 2, 3, 4])
            );
        }
    }

    #[test]
    fn a_span_beyond_thirty_bits_takes_coarser_steps() {
        let gpu = Gpu::cpu();
        let positions = [[0.0, 0.0, 0.0], [6_378_137.0, 1.0, 2.0]];
        let p = Points::encode(&gpu, grid(0.001, [0.0; 3]), &positions, &[[0; 4]; 2]);
        assert_eq!(p.words, 3);
        // 6.4e9 mm needs 33 bits: steps of 8 mm.
        assert_eq!(p.step, [0.008; 3]);
        for (b, q) in decoded(&p).iter().zip(&positions) {
            for a in 0..3 {
                assert!((b[a] - q[a]).abs() <= 0.004 + 1e-9, "{b:?} {q:?}");
            }
        }
    }

    #[test]
    fn the_first_word_alone_is_read_where_its_rest_projects_small() {
        let gpu = Gpu::cpu();
        // A 100 m node on a millimetre grid (17 bits): two words; the first word's step and
        // the span of the rest are 2^7 mm.
        let positions = [[0.0, 0.0, 0.0], [100.0, 100.0, 10.0]];
        let p = Points::encode(&gpu, grid(0.001, [0.0; 3]), &positions, &[[0; 4]; 2]);
        assert_eq!(p.words, 2);
        let camera = |distance: f64| Camera {
            position: [50.0, 50.0 - distance, 5.0],
            target: [50.0, 50.0, 5.0],
            up: [0.0, 0.0, 1.0],
            fov_y: 60.0,
            width: 1000,
            height: 1000,
            near: 0.1,
            far: 1e6,
        };
        // focal ~866 px: 0.128 m is 0.1 px at about 1.1 km from the box's near face.
        assert_eq!(p.read_words(&camera(2_000.0), 0.1), 1);
        assert_eq!(p.read_words(&camera(1_000.0), 0.1), 2);
        assert_eq!(p.read_words(&camera(20_000.0), 0.0), 2);
        // Inside the box: everything.
        assert_eq!(p.read_words(&camera(-10.0), 0.1), 2);
        // Splats read every word (their order in depth decides which disc shows).
        let splats = Points::encode(&gpu, grid(0.001, [0.0; 3]), &positions, &[[0; 4]; 2])
            .with_splats(&gpu, &[[0.0, 0.0, 1.0]; 2], &[0.1; 2]);
        assert_eq!(splats.read_words(&camera(2_000.0), 0.1), 2);
        let f = Points::encode(
            &gpu,
            Encoding::F32 { origin: [0.0; 3] },
            &positions,
            &[[0; 4]; 2],
        );
        assert_eq!((f.read_words(&camera(20_000.0), 0.1), f.bytes()), (3, 32));
    }

    #[test]
    fn the_decoder_reads_what_the_encoder_wrote_and_the_middle_of_the_rest() {
        let gpu = Gpu::cpu();
        let positions = [[0.0, 0.0, 0.0], [100.0, 50.0, 10.0], [12.345, 67.891, 2.5]];
        let p = Points::encode(&gpu, grid(0.001, [0.0; 3]), &positions, &[[0; 4]; 3]);
        let n = p.len as usize;
        let (mut full, mut coarse) = ([[0.0; 3]; 3], [[0.0; 3]; 3]);
        decode(
            p.cpu_words(),
            0,
            n,
            p.words,
            2,
            [0.0; 3],
            p.unit(),
            &mut full,
        );
        decode(
            p.cpu_words(),
            0,
            n,
            p.words,
            1,
            [0.0; 3],
            p.unit(),
            &mut coarse,
        );
        for ((q, full), coarse) in positions.iter().zip(full).zip(coarse) {
            for a in 0..3 {
                assert!((full[a] as f64 - q[a]).abs() < 1e-4, "{full:?} {q:?}");
                assert!(
                    (coarse[a] as f64 - q[a]).abs() <= 0.0641,
                    "{coarse:?} {q:?}"
                );
            }
        }
    }
}
