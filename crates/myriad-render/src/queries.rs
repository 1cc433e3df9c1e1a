//! Occlusion queries (Scheiblauer 2006): after a frame, the boxes of nodes are tested against
//! its depth; a box of which no pixel passes the depth test is hidden, and the next selection
//! culls its node (`myriad_lod::Occlusion::Queries`). On the GPU paths, hardware occlusion
//! queries (`queries.wgsl`: the frame's depth first written into a depth texture as
//! near / w, then each box's twelve triangles drawn without colour or depth writes, one query
//! each); on the CPU path, the same test on the CPU: each triangle's pixel centres, near / w
//! interpolated as the GPU does (it is affine in the image), against the frame's depth. A box
//! reaching the near plane is visible without a test (clipped triangles could miss the eye's
//! surroundings).

use crate::device::{Gpu, lock};
use crate::pipelines::{module, target};
use crate::targets::{Path, Targets};
use myriad_lod::Camera;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use wgpu::util::DeviceExt;

/// The queries' shader: the frame's depth into a depth texture, and the boxes.
pub const QUERIES_WGSL: &str = include_str!("queries.wgsl");

/// The triangles of a box by corner (as `FACES` in queries.wgsl).
const FACES: [usize; 36] = [
    0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3,
    5, 3, 7, 5,
];

/// What a frame leaves for the queries after it: its camera (supersampled as drawn), the origin
/// its positions were relative to, and on the CPU path its linear depth (0: empty).
pub(crate) struct Last {
    pub camera: Camera,
    pub origin: [f64; 3],
    pub depth: Option<Vec<f32>>,
}

/// A rasterizer's occlusion queries: their pipelines, made when first asked for, and what the
/// last frame left for them.
#[derive(Default)]
pub(crate) struct Queries {
    pipelines: OnceLock<Pipelines>,
    last: Mutex<Option<Last>>,
}

/// The query pipelines.
struct Pipelines {
    boxes: wgpu::RenderPipeline,
    /// The path's depth into the query depth texture.
    depth: wgpu::RenderPipeline,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Uniforms {
    view_proj: [[f32; 4]; 4],
    far: f32,
    near: f32,
    width: u32,
    pad: u32,
}

fn depth_state(compare: wgpu::CompareFunction, write: bool) -> wgpu::DepthStencilState {
    wgpu::DepthStencilState {
        format: wgpu::TextureFormat::Depth32Float,
        depth_write_enabled: Some(write),
        depth_compare: Some(compare),
        stencil: Default::default(),
        bias: Default::default(),
    }
}

impl Pipelines {
    fn new(gpu: &Gpu, path: Path) -> Pipelines {
        let module = module(gpu, "queries", QUERIES_WGSL);
        let pipeline = |label, vertex, fragment: Option<&str>, depth| {
            gpu.wgpu().expect("a GPU path").0.create_render_pipeline(
                &wgpu::RenderPipelineDescriptor {
                    label: Some(label),
                    layout: None,
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some(vertex),
                        compilation_options: Default::default(),
                        buffers: &[],
                    },
                    primitive: wgpu::PrimitiveState::default(),
                    depth_stencil: Some(depth),
                    multisample: Default::default(),
                    fragment: fragment.map(|f| wgpu::FragmentState {
                        module: &module,
                        entry_point: Some(f),
                        compilation_options: Default::default(),
                        targets: &[],
                    }),
                    multiview_mask: None,
                    cache: None,
                },
            )
        };
        Pipelines {
            boxes: pipeline(
                "query boxes",
                "box_vertex",
                None,
                depth_state(wgpu::CompareFunction::GreaterEqual, false),
            ),
            depth: pipeline(
                "query depth",
                "full_vertex",
                Some(if path == Path::Compute {
                    "compute_depth"
                } else {
                    "quad_depth_fragment"
                }),
                depth_state(wgpu::CompareFunction::Always, true),
            ),
        }
    }
}

/// The queries' depth, near / w; 0 where nothing was drawn.
fn reversed(w: f64, camera: &Camera) -> f64 {
    if w <= 0.0 {
        return 0.0;
    }
    (camera.near / w.max(camera.near)).clamp(0.0, 1.0)
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Whether a box reaches the near plane (then it is visible without a test).
fn at_the_eye(camera: &Camera, corners: &[[f64; 3]; 8]) -> bool {
    corners.iter().any(|&c| camera.to_eye(c)[2] <= camera.near)
}

/// The CPU path's occlusion query: whether any pixel centre of the box's triangles is as near as
/// or nearer than `depth` (linear, 0 where empty).
fn cpu_visible(camera: &Camera, depth: &[f32], corners: &[[f64; 3]; 8]) -> bool {
    let (w, h) = (camera.width.max(1) as usize, camera.height.max(1) as usize);
    let focal = camera.focal();
    // Pixel coordinates and depth-test value of each corner.
    let screen: Vec<[f64; 3]> = corners
        .iter()
        .map(|&c| {
            let e = camera.to_eye(c);
            [
                w as f64 / 2.0 + e[0] * focal / e[2],
                h as f64 / 2.0 - e[1] * focal / e[2],
                reversed(e[2], camera),
            ]
        })
        .collect();
    // A box is convex: where a face turned away from the eye covers a pixel, one turned
    // towards it covers it too, nearer. The faces turned away are not scanned.
    let centre = corners
        .iter()
        .fold([0.0; 3], |s, c| [s[0] + c[0], s[1] + c[1], s[2] + c[2]])
        .map(|v| v / 8.0);
    let eye = camera.position;
    let turned_away = |t: &[usize]| {
        let [a, b, c] = [corners[t[0]], corners[t[1]], corners[t[2]]];
        let (u, v) = (sub(b, a), sub(c, a));
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let outward = if dot(n, sub(a, centre)) >= 0.0 {
            1.0
        } else {
            -1.0
        };
        outward * dot(n, sub(eye, a)) < 0.0
    };
    for t in FACES.chunks_exact(3) {
        if turned_away(t) {
            continue;
        }
        let [a, b, c] = [screen[t[0]], screen[t[1]], screen[t[2]]];
        let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        if area == 0.0 {
            continue;
        }
        let lo = |k: usize| a[k].min(b[k]).min(c[k]).floor().max(0.0) as usize;
        let hi = |k: usize, n: usize| (a[k].max(b[k]).max(c[k]).ceil().max(0.0) as usize).min(n);
        for y in lo(1)..hi(1, h) {
            for x in lo(0)..hi(0, w) {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                // Barycentric weights; near / w is affine in the image.
                let wa = ((b[0] - px) * (c[1] - py) - (b[1] - py) * (c[0] - px)) / area;
                let wb = ((c[0] - px) * (a[1] - py) - (c[1] - py) * (a[0] - px)) / area;
                let wc = 1.0 - wa - wb;
                if wa < 0.0 || wb < 0.0 || wc < 0.0 {
                    continue;
                }
                let z = wa * a[2] + wb * b[2] + wc * c[2];
                let stored = depth[y * w + x];
                if z >= reversed(stored as f64, camera) {
                    return true;
                }
            }
        }
    }
    false
}

/// Pixels per side of a [`Tiles`] tile.
const TILE: usize = 16;

/// The CPU queries' first test: per tile of the frame, its farthest depth (infinite where a
/// pixel is empty). A box whose nearest corner lies beyond the farthest depth of every tile its
/// screen rectangle meets is hidden at every pixel, without scanning its triangles: the boxes of
/// hidden nodes, the costly ones to scan, mostly end here.
struct Tiles {
    across: usize,
    down: usize,
    far: Vec<f32>,
}

impl Tiles {
    fn new(camera: &Camera, depth: &[f32]) -> Tiles {
        let (w, h) = (camera.width.max(1) as usize, camera.height.max(1) as usize);
        let (across, down) = (w.div_ceil(TILE), h.div_ceil(TILE));
        let mut far = vec![0f32; across * down];
        for y in 0..h.min(depth.len() / w) {
            let row = &depth[y * w..(y + 1) * w];
            let tiles = &mut far[(y / TILE) * across..(y / TILE + 1) * across];
            for (x, &d) in row.iter().enumerate() {
                let t = &mut tiles[x / TILE];
                *t = t.max(if d > 0.0 { d } else { f32::INFINITY });
            }
        }
        Tiles { across, down, far }
    }

    /// Whether every pixel the box can cover holds something nearer than the box's nearest
    /// corner (`false`: not known; the box is scanned).
    fn hide(&self, camera: &Camera, corners: &[[f64; 3]; 8]) -> bool {
        let Some((nearest, [x0, y0, x1, y1])) = camera.box_on_screen(corners) else {
            return false;
        };
        let tile = |v: f64, n: usize| ((v.max(0.0) as usize) / TILE).min(n - 1);
        let (tx0, tx1) = (
            tile(x0.floor() - 1.0, self.across),
            tile(x1.ceil() + 1.0, self.across),
        );
        let (ty0, ty1) = (
            tile(y0.floor() - 1.0, self.down),
            tile(y1.ceil() + 1.0, self.down),
        );
        let nearest = nearest as f32;
        (ty0..=ty1).all(|ty| {
            self.far[ty * self.across + tx0..=ty * self.across + tx1]
                .iter()
                .all(|&f| f < nearest)
        })
    }
}

/// Occlusion queries submitted and not read yet ([`crate::Rasterizer::query_submit`]).
pub struct QueryTicket {
    /// Per box: known (`Ok`: visible or not), or the index of its GPU query.
    boxes: Vec<Result<bool, usize>>,
    /// The GPU's sample counts, mapped once the flag is set.
    gpu: Option<(wgpu::Buffer, Arc<AtomicBool>)>,
}

impl QueryTicket {
    /// Whether any pixel of each box passed, waiting for the GPU's results.
    pub fn wait(mut self, gpu: &Gpu) -> Vec<bool> {
        if let Some((_, ready)) = &self.gpu {
            let (d, _) = gpu.wgpu().expect("queries made on a GPU");
            while !ready.load(Ordering::Acquire) {
                d.poll(wgpu::PollType::wait_indefinitely())
                    .expect("wait for the queries");
            }
        }
        self.poll(gpu).expect("the results are in")
    }

    /// Whether any pixel of each box passed, once the results are in; never waits.
    pub fn poll(&mut self, gpu: &Gpu) -> Option<Vec<bool>> {
        let counts = match &self.gpu {
            None => Vec::new(),
            Some((readback, ready)) => {
                let (d, _) = gpu.wgpu().expect("queries made on a GPU");
                let _ = d.poll(wgpu::PollType::Poll);
                if !ready.load(Ordering::Acquire) {
                    return None;
                }
                let counts = bytemuck::cast_slice::<u8, u64>(
                    &readback.slice(..).get_mapped_range().expect("mapped"),
                )
                .to_vec();
                readback.unmap();
                counts
            }
        };
        Some(
            (self.boxes.iter())
                .map(|b| match *b {
                    Ok(v) => v,
                    Err(k) => counts[k] > 0,
                })
                .collect(),
        )
    }
}

impl Queries {
    /// What the frame just drawn leaves for the queries after it.
    pub fn set_last(&self, last: Last) {
        *lock(&self.last) = Some(last);
    }

    /// Submits the queries of `boxes` against the last frame drawn by `path` into `targets`
    /// (see [`crate::Rasterizer::query_submit`]).
    pub fn submit(
        &self,
        gpu: &Gpu,
        path: Path,
        targets: &Mutex<Option<Targets>>,
        boxes: &[[[f64; 3]; 8]],
    ) -> QueryTicket {
        let mut ticket = QueryTicket {
            boxes: vec![Ok(true); boxes.len()],
            gpu: None,
        };
        let last = lock(&self.last);
        let Some(last) = last.as_ref() else {
            return ticket;
        };
        let cam = &last.camera;
        let tested: Vec<usize> = (0..boxes.len())
            .filter(|&i| !at_the_eye(cam, &boxes[i]))
            .collect();
        if tested.is_empty() {
            return ticket;
        }
        match &last.depth {
            // The CPU path before it was asked to keep its depth: nothing known.
            None if path == Path::Cpu => {}
            Some(depth) => {
                let tiles = Tiles::new(cam, depth);
                for &i in &tested {
                    let hidden = tiles.hide(cam, &boxes[i]);
                    ticket.boxes[i] = Ok(!hidden && cpu_visible(cam, depth, &boxes[i]));
                }
            }
            None => {
                for (k, &i) in tested.iter().enumerate() {
                    ticket.boxes[i] = Err(k);
                }
                ticket.gpu = Some(self.gpu_queries(
                    gpu,
                    path,
                    targets,
                    last,
                    tested.iter().map(|&i| &boxes[i]),
                ));
            }
        }
        ticket
    }

    /// Submits hardware occlusion queries, one per box; their sample counts come into the
    /// returned buffer, mapped when the flag is set.
    fn gpu_queries<'a>(
        &self,
        gpu: &Gpu,
        path: Path,
        targets: &Mutex<Option<Targets>>,
        last: &Last,
        boxes: impl Iterator<Item = &'a [[f64; 3]; 8]>,
    ) -> (wgpu::Buffer, Arc<AtomicBool>) {
        let (d, queue) = gpu.wgpu().expect("a GPU path");
        let p = self.pipelines.get_or_init(|| Pipelines::new(gpu, path));
        let cam = &last.camera;
        let o = last.origin;
        let corners: Vec<[f32; 4]> = boxes
            .flat_map(|b| {
                b.map(|c| {
                    [
                        (c[0] - o[0]) as f32,
                        (c[1] - o[1]) as f32,
                        (c[2] - o[2]) as f32,
                        1.0,
                    ]
                })
            })
            .collect();
        let n = corners.len() / 8;
        let uniforms = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("query uniforms"),
            contents: bytemuck::bytes_of(&Uniforms {
                view_proj: cam.view_proj(o),
                far: cam.far as f32,
                near: cam.near as f32,
                width: cam.width.max(1),
                pad: 0,
            }),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let corner_buffer = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("query boxes"),
            contents: bytemuck::cast_slice(&corners),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let mut guard = lock(targets);
        let t = guard.as_mut().expect("a frame was drawn");
        let mut enc = d.create_command_encoder(&Default::default());
        let entry = |binding, resource| wgpu::BindGroupEntry { binding, resource };
        {
            let (w, h, _) = t.size;
            let view = t.query_depth.get_or_insert_with(|| {
                target(
                    gpu,
                    "query depth",
                    (w, h),
                    wgpu::TextureFormat::Depth32Float,
                    wgpu::TextureUsages::RENDER_ATTACHMENT,
                )
            });
            let source = match (&t.framebuffer, &t.depth) {
                (Some(fb), _) => entry(2, fb.as_entire_binding()),
                (None, depth) => entry(
                    3,
                    wgpu::BindingResource::TextureView(depth.as_ref().expect("quad targets")),
                ),
            };
            let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("query depth"),
                layout: &p.depth.get_bind_group_layout(0),
                entries: &[entry(0, uniforms.as_entire_binding()), source],
            });
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("query depth"),
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(0.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            pass.set_pipeline(&p.depth);
            pass.set_bind_group(0, &bind, &[]);
            pass.draw(0..3, 0..1);
        }
        let depth_view = t.query_depth.as_ref().expect("made above");
        let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("query boxes"),
            layout: &p.boxes.get_bind_group_layout(0),
            entries: &[
                entry(0, uniforms.as_entire_binding()),
                entry(1, corner_buffer.as_entire_binding()),
            ],
        });
        let per_set = wgpu::QUERY_SET_MAX_QUERIES as usize;
        let resolved = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("query results"),
            size: (n.div_ceil(per_set) * per_set * 8) as u64,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("query readback"),
            size: (n * 8) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        for first in (0..n).step_by(per_set) {
            let count = (n - first).min(per_set);
            let set = d.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("occlusion"),
                ty: wgpu::QueryType::Occlusion,
                count: count as u32,
            });
            {
                let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("query boxes"),
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: depth_view,
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Load,
                            store: wgpu::StoreOp::Store,
                        }),
                        stencil_ops: None,
                    }),
                    occlusion_query_set: Some(&set),
                    ..Default::default()
                });
                pass.set_pipeline(&p.boxes);
                pass.set_bind_group(0, &bind, &[]);
                for k in 0..count {
                    let b = (first + k) as u32;
                    pass.begin_occlusion_query(k as u32);
                    pass.draw(b * 36..(b + 1) * 36, 0..1);
                    pass.end_occlusion_query();
                }
            }
            enc.resolve_query_set(&set, 0..count as u32, &resolved, (first * 8) as u64);
        }
        enc.copy_buffer_to_buffer(&resolved, 0, &readback, 0, (n * 8) as u64);
        queue.submit([enc.finish()]);
        drop(guard);
        let ready = Arc::new(AtomicBool::new(false));
        let flag = ready.clone();
        // (An error: the ticket was dropped first; nothing waits for it then.)
        readback.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            if r.is_ok() {
                flag.store(true, Ordering::Release);
            }
        });
        (readback, ready)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_core::Aabb;

    /// Looking along +x from x = -20 at a wall at x = 2 (y and z 0 to 10), 200 x 200 pixels;
    /// its depth as the frame would leave it, the wall's pixels at its linear depth.
    fn wall() -> (Camera, Vec<f32>) {
        let cam = Camera {
            position: [-20.0, 5.0, 5.0],
            target: [0.0, 5.0, 5.0],
            up: [0.0, 0.0, 1.0],
            fov_y: 60.0,
            width: 200,
            height: 200,
            near: 0.1,
            far: 100.0,
        };
        let focal = cam.focal();
        let mut depth = vec![0.0f32; 200 * 200];
        for y in 0..200 {
            for x in 0..200 {
                // The pixel's ray meets the plane x = 2 at depth 22.
                let (ey, ez) = (
                    (x as f64 + 0.5 - 100.0) * 22.0 / focal,
                    (100.0 - y as f64 - 0.5) * 22.0 / focal,
                );
                if (0.0..=10.0).contains(&(5.0 - ey)) && (0.0..=10.0).contains(&(5.0 + ez)) {
                    depth[y * 200 + x] = 22.0;
                }
            }
        }
        (cam, depth)
    }

    #[test]
    fn the_cpu_query_finds_what_the_wall_hides() {
        let (cam, depth) = wall();
        let test =
            |b: Aabb| !at_the_eye(&cam, &b.corners()) && cpu_visible(&cam, &depth, &b.corners());
        assert!(!test(Aabb::new([6.0, 4.0, 4.0], [8.0, 6.0, 6.0])), "behind");
        assert!(
            test(Aabb::new([6.0, 11.0, 4.0], [8.0, 13.0, 6.0])),
            "beside"
        );
        assert!(
            test(Aabb::new([0.0, 4.0, 4.0], [1.0, 6.0, 6.0])),
            "in front"
        );
        assert!(
            test(Aabb::new([6.0, 9.0, 4.0], [8.0, 11.0, 6.0])),
            "across the edge"
        );
        // The eye inside: visible, untested.
        assert!(at_the_eye(
            &cam,
            &Aabb::new([-21.0, 4.0, 4.0], [8.0, 6.0, 6.0]).corners()
        ));
    }
}
