//! The post passes on the GPU: one compute dispatch per pass over the g-buffer, ping-ponging
//! between two sets of buffers (depth, colour, normal: one array each, so that a g-buffer of
//! 2160 x 2160 supersampled twice still fits a storage binding), then the finish pass into the
//! image. The same passes as `mod.rs`'s `run` on the CPU.

use super::gbuffer::{View, gbuffer_source};
use super::passes::Passes;
use super::{blur, edl, fill, finish, normals, shade, ssao};
use crate::Gpu;
use crate::pipelines::{compute, compute_in, groups, module};

/// The WGSL of every pass (common.wgsl with the pass, from the pass's file), by entry point;
/// the g-buffer pass is [`gbuffer_source`].
pub const PASS_SOURCES: [(&str, &str); 9] = [
    ("fill_rows", fill::SOURCE),
    ("fill_columns", fill::SOURCE),
    ("normals", normals::SOURCE),
    ("shade", shade::SOURCE),
    ("ssao", ssao::SOURCE),
    ("edl", edl::SOURCE),
    ("blur", blur::SOURCE),
    ("finish", finish::SOURCE),
    ("finish_texture", finish::SOURCE),
];

/// As `Post` in common.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Uniforms {
    width: u32,
    height: u32,
    out_width: u32,
    out_height: u32,
    background: u32,
    factor: u32,
    fill_radius: u32,
    fill_min: u32,
    fill_threshold: f32,
    focal: f32,
    far: f32,
    near: f32,
    ambient: f32,
    headlight: f32,
    sun: f32,
    ssao_radius: f32,
    sun_eye: [f32; 4],
    ssao_strength: f32,
    edl_strength: f32,
    edl_radius: f32,
    blur_threshold: f32,
    eye_width: u32,
    pad: [u32; 3],
}

/// The compute pipelines of the chain, kept for the rasterizer's life.
pub(crate) struct Chain {
    gbuffer: wgpu::ComputePipeline,
    passes: Vec<(&'static str, wgpu::ComputePipeline)>,
}

/// A hidden area as the GPU passes take it: one mask per eye (image pixels, row by row,
/// `width` a row), the eyes side by side in the frame.
#[derive(Clone, Copy)]
pub(crate) struct Hidden<'a> {
    pub eyes: &'a [&'a [bool]],
    pub width: usize,
}

/// The supersampling factor, the eye's width and the masks [`Buffers::hide`] last made bits of.
type Made = (usize, usize, Vec<Vec<bool>>);

/// The g-buffer's two sets of (depth, colour, normal) arrays and the image.
pub(crate) struct Buffers {
    sets: [[wgpu::Buffer; 3]; 2],
    pub image: wgpu::Buffer,
    /// The hidden area, one bit a pixel of the g-buffer ([`Buffers::hide`]); `none`: a few
    /// words of zeros, bound when nothing is hidden.
    hidden: wgpu::Buffer,
    /// Where the quad path rejects a point before drawing it ([`rejected`]), one bit a pixel.
    reject: wgpu::Buffer,
    none: wgpu::Buffer,
    masked: std::sync::atomic::AtomicBool,
    /// The masks and supersampling `hidden` and `reject` were made from: made again only when
    /// they change (a runtime's masks stay for a session, the ellipse for a size).
    made: std::sync::Mutex<Option<Made>>,
}

impl Buffers {
    /// For a g-buffer of `pixels` and an image of `out_pixels`.
    pub fn new(gpu: &Gpu, pixels: u64, out_pixels: u64) -> Buffers {
        let d = gpu.device();
        let buffer = |label, size: u64, usage| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size.max(16),
                usage,
                mapped_at_creation: false,
            })
        };
        let set = || {
            ["g-buffer depth", "g-buffer colour", "g-buffer normal"]
                .map(|l| buffer(l, pixels * 4, wgpu::BufferUsages::STORAGE))
        };
        Buffers {
            sets: [set(), set()],
            image: buffer(
                "image",
                out_pixels * 4,
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            ),
            hidden: buffer(
                "hidden area",
                pixels.div_ceil(32) * 4,
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            ),
            reject: buffer(
                "rejected area",
                pixels.div_ceil(32) * 4,
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            ),
            // Zeroed at creation.
            none: buffer("nothing hidden", 16, wgpu::BufferUsages::STORAGE),
            masked: Default::default(),
            made: Default::default(),
        }
    }

    /// The pixels the point pass (compute path) and every post pass skip from now on (a
    /// headset's hidden area), for a g-buffer supersampled `factor` times; None: none. The bits
    /// are made and uploaded again only when the masks or the size change.
    pub fn hide(&self, gpu: &Gpu, hidden: Option<Hidden>, factor: u32) {
        use std::sync::atomic::Ordering::Relaxed;
        self.masked.store(hidden.is_some(), Relaxed);
        let Some(h) = hidden else {
            return;
        };
        let f = factor.max(1) as usize;
        let mut made = self.made.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((mf, mw, masks)) = made.as_ref()
            && *mf == f
            && *mw == h.width
            && masks.len() == h.eyes.len()
            && masks.iter().zip(h.eyes).all(|(a, b)| a[..] == **b)
        {
            return;
        }
        // Each eye's mask at the g-buffer's size.
        let big: Vec<Vec<bool>> = h.eyes.iter().map(|m| upsampled(m, h.width, f)).collect();
        let eye = h.width * f;
        let reject: Vec<Vec<bool>> = big.iter().map(|m| rejected(m, eye)).collect();
        for (buffer, masks) in [(&self.hidden, &big), (&self.reject, &reject)] {
            let words = frame_bits(masks, eye);
            gpu.queue()
                .write_buffer(buffer, 0, bytemuck::cast_slice(&words));
        }
        *made = Some((f, h.width, h.eyes.iter().map(|m| m.to_vec()).collect()));
    }

    /// The binding of the pixels where the quad path rejects points, as [`Buffers::hide`]
    /// last set them (none where nothing is hidden).
    pub fn reject_binding(&self) -> wgpu::BindingResource<'_> {
        if self.masked.load(std::sync::atomic::Ordering::Relaxed) {
            self.reject.as_entire_binding()
        } else {
            self.none.as_entire_binding()
        }
    }

    /// The binding of the hidden area as [`Buffers::hide`] last set it.
    pub fn hidden_binding(&self) -> wgpu::BindingResource<'_> {
        if self.masked.load(std::sync::atomic::Ordering::Relaxed) {
            self.hidden.as_entire_binding()
        } else {
            self.none.as_entire_binding()
        }
    }
}

impl Chain {
    pub fn new(gpu: &Gpu, framebuffer: &str) -> Chain {
        // One module per source: fill.wgsl and finish.wgsl hold two entry points each.
        let mut modules: Vec<(&str, wgpu::ShaderModule)> = Vec::new();
        let mut passes = Vec::new();
        for &(entry, src) in &PASS_SOURCES {
            if !modules.iter().any(|m| m.0 == src) {
                modules.push((src, module(gpu, entry, src)));
            }
            let m = &modules
                .iter()
                .find(|m| m.0 == src)
                .expect("compiled above")
                .1;
            passes.push((entry, compute_in(gpu, m, entry)));
        }
        Chain {
            gbuffer: compute(gpu, &gbuffer_source(framebuffer), "gbuffer"),
            passes,
        }
    }

    fn pass(&self, name: &str) -> &wgpu::ComputePipeline {
        &self.passes.iter().find(|p| p.0 == name).expect("a pass").1
    }

    /// Records the g-buffer pass (reading the framebuffer bound by `framebuffer`, entries at
    /// bindings 1, 2 and 4), every pass that is on, and the finish pass into `buffers.image`,
    /// or into `texture` (RGBA8 storage, the image's size) when given.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        buffers: &Buffers,
        framebuffer: Vec<wgpu::BindGroupEntry>,
        passes: &Passes,
        view: &View,
        far: f32,
        near: f32,
        texture: Option<&wgpu::TextureView>,
    ) {
        let d = gpu.device();
        let f = view.factor;
        let fill = passes.fill.unwrap_or_default();
        let shade = passes.shade.unwrap_or_default();
        let ssao = passes.ssao.unwrap_or_default();
        let edl = passes.edl.unwrap_or_default();
        let uniforms = Uniforms {
            width: view.width,
            height: view.height,
            out_width: view.width / f,
            out_height: view.height / f,
            background: u32::from_le_bytes(view.background),
            factor: f,
            fill_radius: fill.radius * f,
            fill_min: fill.min,
            fill_threshold: fill.threshold,
            focal: view.focal,
            far,
            near,
            ambient: shade.ambient,
            headlight: shade.headlight,
            sun: shade.sun,
            ssao_radius: ssao.radius * f as f32,
            sun_eye: [view.sun[0], view.sun[1], view.sun[2], 0.0],
            ssao_strength: ssao.strength,
            edl_strength: edl.strength,
            edl_radius: edl.radius * f as f32,
            blur_threshold: passes.blur.unwrap_or_default().threshold,
            eye_width: view.eye_width,
            pad: [0; 3],
        };
        let uniforms = wgpu::util::DeviceExt::create_buffer_init(
            d,
            &wgpu::util::BufferInitDescriptor {
                label: Some("post"),
                contents: bytemuck::bytes_of(&uniforms),
                usage: wgpu::BufferUsages::UNIFORM,
            },
        );
        fn entry(binding: u32, resource: wgpu::BindingResource<'_>) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry { binding, resource }
        }
        fn set_entries(
            set: &[wgpu::Buffer; 3],
            first: u32,
            n: usize,
        ) -> Vec<wgpu::BindGroupEntry<'_>> {
            set.iter()
                .take(n)
                .enumerate()
                .map(|(k, b)| entry(first + k as u32, b.as_entire_binding()))
                .collect()
        }
        let dispatch = |enc: &mut wgpu::CommandEncoder,
                        pipeline: &wgpu::ComputePipeline,
                        entries: Vec<wgpu::BindGroupEntry>,
                        pixels: u32| {
            let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("post"),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &entries,
            });
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &bind, &[]);
            let (x, y) = groups(pixels);
            pass.dispatch_workgroups(x, y, 1);
        };
        let pixels = view.width * view.height;
        let mut entries = vec![entry(0, uniforms.as_entire_binding())];
        entries.extend(framebuffer);
        entries.extend(set_entries(&buffers.sets[0], 13, 3));
        entries.push(entry(16, buffers.hidden_binding()));
        dispatch(enc, &self.gbuffer, entries, pixels);
        let mut current = 0;
        for name in passes.steps() {
            let mut entries = vec![entry(0, uniforms.as_entire_binding())];
            entries.extend(set_entries(&buffers.sets[current], 10, 3));
            entries.extend(set_entries(&buffers.sets[1 - current], 13, 3));
            entries.push(entry(16, buffers.hidden_binding()));
            dispatch(enc, self.pass(name), entries, pixels);
            current = 1 - current;
        }
        let (finish, out) = match texture {
            None => ("finish", entry(3, buffers.image.as_entire_binding())),
            Some(t) => (
                "finish_texture",
                entry(5, wgpu::BindingResource::TextureView(t)),
            ),
        };
        let mut entries = vec![entry(0, uniforms.as_entire_binding()), out];
        entries.extend(set_entries(&buffers.sets[current], 10, 2));
        entries.push(entry(16, buffers.hidden_binding()));
        dispatch(
            enc,
            self.pass(finish),
            entries,
            (view.width / f) * (view.height / f),
        );
    }
}

/// How far inside the hidden area, in g-buffer pixels every way, a point's centre must lie for
/// the quad path to reject it before it is drawn (quads.wgsl): its square, at most
/// `2 * (REJECT_REACH - 1)` pixels across, then covers hidden pixels alone.
pub(crate) const REJECT_REACH: usize = 8;

/// `mask` (`w` pixels a row) at `f` times its size, each pixel's `f` x `f` alike.
pub(crate) fn upsampled(mask: &[bool], w: usize, f: usize) -> Vec<bool> {
    if f == 1 {
        return mask.to_vec();
    }
    let h = mask.len() / w.max(1);
    (0..h * f)
        .flat_map(|y| (0..w * f).map(move |x| mask[(y / f) * w + x / f]))
        .collect()
}

/// Per pixel of an eye's `mask` (`w` a row), whether every pixel within [`REJECT_REACH`] of it
/// across and down is hidden, those beyond the eye's edges counted hidden (nothing is drawn
/// there: the quad path cuts a square at its eye's edges).
pub(crate) fn rejected(mask: &[bool], w: usize) -> Vec<bool> {
    use rayon::prelude::*;
    let r = REJECT_REACH;
    let h = mask.len() / w.max(1);
    // Across: the open pixels in each row's window, from the row's running count.
    let across: Vec<bool> = mask
        .par_chunks(w.max(1))
        .flat_map_iter(|row| {
            let mut open = vec![0u32; w + 1];
            for x in 0..w {
                open[x + 1] = open[x] + u32::from(!row[x]);
            }
            (0..w).map(move |x| open[(x + r + 1).min(w)] == open[x.saturating_sub(r)])
        })
        .collect();
    // Down: a window of rows slid over the image, counting each column's open pixels in it.
    let mut open = vec![0u32; w];
    let mut out = vec![false; w * h];
    for y in 0..h + r {
        if y < h {
            for x in 0..w {
                open[x] += u32::from(!across[y * w + x]);
            }
        }
        if y > 2 * r {
            let gone = y - 2 * r - 1;
            for x in 0..w {
                open[x] -= u32::from(!across[gone * w + x]);
            }
        }
        if y >= r {
            let row = y - r;
            for x in 0..w {
                out[row * w + x] = open[x] == 0;
            }
        }
    }
    out
}

/// One bit a pixel of a frame of the eyes' masks side by side (each `eye` pixels a row).
fn frame_bits(masks: &[Vec<bool>], eye: usize) -> Vec<u32> {
    use rayon::prelude::*;
    let frame = eye * masks.len();
    let pixels = frame * (masks[0].len() / eye.max(1));
    (0..pixels.div_ceil(32))
        .into_par_iter()
        .map(|k| {
            (0..32)
                .filter(|b| k * 32 + b < pixels)
                .fold(0u32, |word, b| {
                    let (x, y) = ((k * 32 + b) % frame, (k * 32 + b) / frame);
                    word | (u32::from(masks[x / eye][y * eye + x % eye]) << b)
                })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_are_rejected_only_where_everything_within_reach_is_hidden() {
        // A 40 x 30 eye hidden left of column 20: rejected left of column 20 - REACH, where
        // the reach stays in the hidden columns (the eye's edges count hidden).
        let (w, h) = (40, 30);
        let mask: Vec<bool> = (0..w * h).map(|i| i % w < 20).collect();
        let r = rejected(&mask, w);
        for y in 0..h {
            for x in 0..w {
                assert_eq!(r[y * w + x], x + REJECT_REACH < 20, "({x}, {y})");
            }
        }
        // One open pixel keeps every pixel within reach of it drawn, and none farther.
        let mut holed = vec![true; w * h];
        holed[15 * w + 20] = false;
        let r = rejected(&holed, w);
        for y in 0..h {
            for x in 0..w {
                let near = x.abs_diff(20) <= REJECT_REACH && y.abs_diff(15) <= REJECT_REACH;
                assert_eq!(r[y * w + x], !near, "({x}, {y})");
            }
        }
    }

    #[test]
    fn the_quad_shader_reaches_as_far_as_the_rejected_mask() {
        let line = format!("const REJECT_REACH: f32 = {REJECT_REACH}.0;");
        assert!(crate::QUADS_WGSL.contains(&line), "{line}");
    }
}
