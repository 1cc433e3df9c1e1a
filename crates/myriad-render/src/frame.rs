//! A frame from end to end: the rasterizer keeps one path's pipelines (compute, quads or the
//! CPU) and the post chain for its life, and the targets of the last image size; each frame
//! runs the point pass into the g-buffer, the post passes, and reads the image back (or
//! presents it to a window's texture). Occlusion queries test boxes against the last frame.

use crate::Style;
use crate::compute::ComputePass;
use crate::device::{Gpu, lock};
use crate::draw::Frame;
use crate::points::{Draw, frame_origin};
use crate::post::{Chain, Hidden, Passes, View};
use crate::quads::{QuadPass, front_to_back};
use crate::queries::{Last, Queries, QueryTicket};
use crate::style::supersampled;
use crate::targets::{Path, Targets};
use myriad_lod::Camera;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

/// The default of [`Rasterizer::precision`]: a point read with its first position words only
/// may move by at most half of this many pixels.
pub const DEFAULT_PRECISION: f32 = 0.1;

/// A path's long-lived pipelines: its point pass and the post chain reading its framebuffer.
enum Pipelines {
    Compute { pass: ComputePass, chain: Chain },
    Quads { pass: QuadPass, chain: Chain },
    Cpu,
}

/// An image size and the hidden-area ellipse made for it.
type Ellipse = ((u32, u32), std::sync::Arc<Vec<bool>>);

/// The rasterizer's pipelines and frame targets.
pub struct Rasterizer {
    pipelines: Pipelines,
    pub(crate) targets: Mutex<Option<Targets>>,
    /// Occlusion queries' pipelines (made when first asked for) and what they need of the last
    /// frame.
    queries: Queries,
    /// The CPU path keeps each frame's depth for occlusion queries once asked to
    /// ([`Rasterizer::keep_depth`]).
    keep_depth: AtomicBool,
    /// Where frames go instead of being read back ([`Rasterizer::present_to`]).
    present: Mutex<Option<wgpu::TextureView>>,
    /// The last hidden-area ellipse made, by image size ([`crate::stereo::hidden_area`]).
    pub(crate) ellipse: Mutex<Option<Ellipse>>,
    pub path: Path,
    /// Precision per batch (Schütz 2022): a draw's points are read with as few position words
    /// as leave them within half this many pixels of where all words put them (0: all words).
    pub precision: f32,
    /// On the quad path, draw nodes front to back (Discher et al. 2018's reverse painter's order:
    /// the depth test then rejects what lies behind before it is shaded); else in the selection's
    /// order.
    pub front_to_back: bool,
}

impl Rasterizer {
    /// The compute path where the device has 64-bit atomics, else quads; the CPU path on the
    /// CPU.
    pub fn new(gpu: &Gpu) -> Rasterizer {
        Rasterizer::with_path(
            gpu,
            if gpu.is_cpu() {
                Path::Cpu
            } else if gpu.atomics {
                Path::Compute
            } else {
                Path::Quads
            },
        )
    }

    /// A chosen path (the compute path needs `gpu.atomics`; the CPU path is the CPU's only).
    pub fn with_path(gpu: &Gpu, path: Path) -> Rasterizer {
        assert!(
            path != Path::Compute || gpu.atomics,
            "the compute path needs 64-bit atomics"
        );
        assert_eq!(
            path == Path::Cpu,
            gpu.is_cpu(),
            "the CPU path is for the CPU only"
        );
        let pipelines = match path {
            Path::Compute => Pipelines::Compute {
                pass: ComputePass::new(gpu),
                chain: Chain::new(gpu, crate::FB_ATOMIC_WGSL),
            },
            Path::Quads => Pipelines::Quads {
                pass: QuadPass::new(gpu),
                chain: Chain::new(gpu, crate::FB_QUADS_WGSL),
            },
            Path::Cpu => Pipelines::Cpu,
        };
        Rasterizer {
            pipelines,
            targets: Mutex::new(None),
            queries: Queries::default(),
            keep_depth: Default::default(),
            present: Mutex::new(None),
            ellipse: Mutex::new(None),
            path,
            precision: DEFAULT_PRECISION,
            front_to_back: true,
        }
    }

    /// From now on, GPU paths draw each frame into `texture` (a view of an `Rgba8Unorm` texture
    /// with `STORAGE_BINDING` usage, on this device, of the camera's size) and return an empty
    /// image: no readback, for a window that shows the texture. None: read back again. The CPU
    /// path always returns its image.
    pub fn present_to(&self, texture: Option<wgpu::TextureView>) {
        *lock(&self.present) = texture;
    }

    /// Draws `draws` seen by `camera` into a `camera.width` x `camera.height` image and reads it
    /// back: RGBA8, rows top to bottom. `tree` is the drawn tree the draws' nodes index
    /// (`myriad_lod::DrawnTree::entries`; empty when no draw has a node).
    pub fn render(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        draws: &[Draw],
        tree: &[[u32; 4]],
        style: &Style,
    ) -> Vec<u8> {
        self.render_eyes(gpu, camera, None, draws, tree, style, None)
    }

    /// [`Rasterizer::render`]; with `eyes` (the compute path), both eyes in one dispatch into
    /// a side-by-side frame: `camera` is then the left eye's, twice as wide. `hidden`: the
    /// pixels the point pass (compute path) and every post pass skip (a headset's hidden area;
    /// GPU paths only, the CPU's is `cpu::gbuffers`'s).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn render_eyes(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        eyes: Option<&[Camera; 2]>,
        draws: &[Draw],
        tree: &[[u32; 4]],
        style: &Style,
        hidden: Option<Hidden>,
    ) -> Vec<u8> {
        let passes = style.passes;
        let f = self.factor(gpu, camera, &passes);
        let eyes = eyes.map(|e| e.map(|c| supersampled(&c, style, f).0));
        let (camera, style) = &supersampled(camera, style, f);
        let view = View {
            eye_width: eyes.map_or(0, |e| e[0].width),
            ..View::new(camera, passes.sun(), style.background, f)
        };
        let normals = passes.normals();
        let origin = frame_origin(draws, camera);
        if self.path == Path::Cpu {
            let g = crate::cpu::gbuffer(camera, draws, tree, style, normals, self.precision);
            self.queries.set_last(Last {
                camera: *camera,
                origin,
                depth: (self.keep_depth.load(Ordering::Relaxed)).then(|| g.depth.clone()),
            });
            return crate::post::run(g, &passes, &view);
        }
        self.queries.set_last(Last {
            camera: *camera,
            origin,
            depth: None,
        });
        let frame = Frame {
            camera,
            eyes,
            style,
            origin,
            tree,
            precision: self.precision,
        };
        let (w, h) = frame.size();
        let out_pixels = ((w / f) * (h / f)) as u64;
        let mut guard = lock(&self.targets);
        if guard.as_ref().is_none_or(|t| t.size != (w, h, f)) {
            *guard = Some(Targets::new(gpu, self.path, w, h, f));
        }
        let t = guard.as_mut().expect("targets made above");
        let mut draws: Vec<&Draw> = draws.iter().filter(|s| s.count > 0).collect();
        t.post.hide(gpu, hidden, f);
        let mut enc = gpu.device().create_command_encoder(&Default::default());
        let (framebuffer, chain) = match &self.pipelines {
            Pipelines::Cpu => unreachable!("drawn above"),
            Pipelines::Compute { pass, chain } => {
                pass.encode(gpu, &mut enc, t, &frame, &draws, normals, passes.blend);
                (ComputePass::framebuffer(t, passes.blend), chain)
            }
            Pipelines::Quads { pass, chain } => {
                if self.front_to_back {
                    // Both eyes in one draw: from between them.
                    let e = eyes.map_or(camera.position, |e| {
                        std::array::from_fn(|a| (e[0].position[a] + e[1].position[a]) / 2.0)
                    });
                    front_to_back(&mut draws, e);
                }
                pass.encode(gpu, &mut enc, t, &frame, &draws, passes.blend);
                (QuadPass::framebuffer(t, passes.blend), chain)
            }
        };
        let present = lock(&self.present).clone();
        chain.encode(
            gpu,
            &mut enc,
            &t.post,
            framebuffer,
            &passes,
            &view,
            camera.far as f32,
            camera.near as f32,
            present.as_ref(),
        );
        if present.is_some() {
            gpu.queue().submit([enc.finish()]);
            return Vec::new();
        }
        enc.copy_buffer_to_buffer(&t.post.image, 0, &t.readback, 0, out_pixels * 4);
        gpu.queue().submit([enc.finish()]);
        let slice = t.readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |r| {
            r.expect("map the image for reading")
        });
        gpu.device()
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("wait for the frame");
        let out = slice.get_mapped_range().expect("mapped image").to_vec();
        t.readback.unmap();
        out
    }

    /// Occlusion queries against the depth of the last frame [`Rasterizer::render`] drew: for
    /// each box (its corners as `myriad_core::Aabb::corners`), whether any pixel of it passes
    /// the depth test (hardware occlusion queries on the GPU paths, their mirror on the CPU). A
    /// box reaching the near plane is visible; before any frame, every box is. Waits for the
    /// results.
    pub fn query(&self, gpu: &Gpu, boxes: &[[[f64; 3]; 8]]) -> Vec<bool> {
        self.query_submit(gpu, boxes).wait(gpu)
    }

    /// [`Rasterizer::query`] without waiting: the results come from the ticket when the GPU
    /// has them (on the CPU path, at once).
    pub fn query_submit(&self, gpu: &Gpu, boxes: &[[[f64; 3]; 8]]) -> QueryTicket {
        self.keep_depth();
        self.queries.submit(gpu, self.path, &self.targets, boxes)
    }

    /// From now on the CPU path keeps each frame's depth, for occlusion queries (the GPU paths
    /// keep theirs in any case).
    pub fn keep_depth(&self) {
        self.keep_depth
            .store(true, std::sync::atomic::Ordering::Relaxed);
    }

    /// Bytes the point pass reads for `draws` seen by `camera`: the position words each draw
    /// needs ([`crate::Points::read_words`] at the frame's supersampled size), the colours and
    /// splat codes.
    pub fn bytes_read(&self, gpu: &Gpu, camera: &Camera, draws: &[Draw], style: &Style) -> u64 {
        let f = self.factor(gpu, camera, &style.passes);
        let (camera, _) = supersampled(camera, style, f);
        draws
            .iter()
            .map(|d| {
                let read = d.points.read_words(&camera, self.precision);
                d.count as u64 * d.points.read_bytes(read) as u64
            })
            .sum()
    }

    /// The supersampling factor a frame gets: what the passes ask for, less where the GPU's
    /// framebuffer would not fit one storage binding or texture.
    pub(crate) fn factor(&self, gpu: &Gpu, camera: &Camera, passes: &Passes) -> u32 {
        let mut f = passes.factor();
        if let Some((d, _)) = gpu.wgpu() {
            let limits = d.limits();
            let (w, h) = (camera.width.max(1) as u64, camera.height.max(1) as u64);
            // Bytes a pixel of the largest storage binding: the framebuffer, or the blend's.
            let bytes = if passes.blend { 16 } else { 8 };
            let fits = |f: u64| {
                w * h * f * f * bytes <= limits.max_storage_buffer_binding_size
                    && (w.max(h) * f) <= limits.max_texture_dimension_2d as u64
            };
            while f > 1 && !fits(f as u64) {
                f -= 1;
            }
        }
        f
    }
}
