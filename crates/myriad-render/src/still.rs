//! A still image of a dataset, as `render` draws one headless: the first frame as soon as the
//! root node is in, the selection settled ([`Scene::settle`]), then the frame a viewer would
//! draw now, timed; where asked, the surface that frame's points make, drawn in their place
//! (cluster, move and reduce on the GPU where the frame was drawn on one).

use crate::surface::{Built, Drawer, Surface};
use crate::{FrameStats, Gpu, Rasterizer, Scene, Style};
use myriad_lod::{Camera, SelectOptions};
use std::time::{Duration, Instant};

/// A still image and how it was made.
pub struct Still {
    /// RGBA8, rows top to bottom.
    pub image: Vec<u8>,
    /// The last frame's.
    pub stats: FrameStats,
    /// Points of the settled selection.
    pub selected_points: u64,
    /// From the start the caller gave to the first frame, and to the settled selection.
    pub first_image: Duration,
    pub converged: Duration,
    /// The last frame's time: selection, cache lookups, drawing, readback.
    pub frame: Duration,
    /// The surface drawn instead of the points, where asked.
    pub surface: Option<SurfaceDrawn>,
}

/// A surface made from a frame's points, and drawn.
pub struct SurfaceDrawn {
    pub built: Built,
    /// Why it was made on the CPU though the frame was drawn on a GPU.
    pub on_cpu: Option<String>,
    /// Making it (cluster, move, reduce, reconstruct), and drawing it.
    pub made: Duration,
    pub drawn: Duration,
}

/// The still image of `scene` seen by `camera` within `options`, times counted from `t0`; the
/// surface of its points instead where `surface` is given.
#[allow(clippy::too_many_arguments)]
pub fn draw(
    scene: &mut Scene,
    gpu: &Gpu,
    raster: &Rasterizer,
    camera: &Camera,
    options: &SelectOptions,
    style: &Style,
    surface: Option<&Surface>,
    t0: Instant,
) -> Still {
    first_frame(scene, gpu, raster, camera, options, style);
    let first_image = t0.elapsed();
    let selection = scene.settle(gpu, raster, camera, options, style);
    let converged = t0.elapsed();
    let t = Instant::now();
    let (mut image, stats) = scene.frame(gpu, raster, camera, options, style);
    let frame = t.elapsed();
    let surface = surface.map(|s| {
        let (made, img) = surface_of(scene, gpu, camera, style, s);
        image = img;
        made
    });
    Still {
        image,
        stats,
        selected_points: selection.points,
        first_image,
        converged,
        frame,
        surface,
    }
}

/// The first frame there is: drawn as soon as the first selected node (the root) is in.
fn first_frame(
    scene: &mut Scene,
    gpu: &Gpu,
    raster: &Rasterizer,
    camera: &Camera,
    options: &SelectOptions,
    style: &Style,
) {
    let first = scene.update(camera, options);
    if let Some(root) = first.nodes.first() {
        let l = &mut scene.loader;
        while !l.is_resident(&root.key) && !l.failed().contains_key(&root.key) {
            if l.poll() == 0 {
                std::thread::sleep(Duration::from_millis(1));
            }
        }
    }
    scene.frame(gpu, raster, camera, options, style);
}

/// The surface of the points the last frame of `scene` drew, made and drawn; its image.
fn surface_of(
    scene: &Scene,
    gpu: &Gpu,
    camera: &Camera,
    style: &Style,
    s: &Surface,
) -> (SurfaceDrawn, Vec<u8>) {
    let t = Instant::now();
    let (points, colours) = crate::surface::drawn_points(scene, style.clip);
    let mut on_cpu = None;
    let built = Built::on(gpu, camera, &points, &colours, s).unwrap_or_else(|why| {
        on_cpu = Some(why);
        Built::new(camera, &points, &colours, s)
    });
    let made = t.elapsed();
    let t = Instant::now();
    let image = if gpu.is_cpu() {
        crate::surface::draw(camera, &built.mesh, style)
    } else {
        Drawer::new(gpu).draw_built(gpu, camera, &built, style)
    };
    let drawn = t.elapsed();
    let made = SurfaceDrawn {
        built,
        on_cpu,
        made,
        drawn,
    };
    (made, image)
}
