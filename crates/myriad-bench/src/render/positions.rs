//! `myriad bench render`'s comparison of how positions are held on the GPU: f32 (16 bytes a
//! point with colour, the layout before quantization) against positions quantized per node on
//! the dataset's grid, reading every word or, per batch, as few as leave points within half
//! of `precision` pixels (Schütz 2022): bytes on the GPU and read per drawn point, bytes
//! uploaded for a view from an empty GPU cache, the frame time at the frame budget, and the
//! PSNR of the standard views at the quality budget against the image of every point with f32
//! positions.

use super::{RenderBenchArgs, frame_times, psnr};
use anyhow::Result;
use myriad_format::Dataset;
use myriad_lod::{Camera, SelectOptions};
use myriad_render::{Gpu, PointSize, Rasterizer, Scene, Style};

/// (label, f32 positions, precision in pixels).
const ENCODINGS: [(&str, bool, f32); 6] = [
    ("f32", true, 0.0),
    ("quantized, all words", false, 0.0),
    ("quantized, 0.1 px", false, 0.1),
    ("quantized, 0.25 px", false, 0.25),
    ("quantized, 0.5 px", false, 0.5),
    ("quantized, 1 px", false, 1.0),
];

pub fn compare(
    scene: &mut Scene,
    ds: &Dataset,
    gpu: &Gpu,
    raster: &mut Rasterizer,
    a: &RenderBenchArgs,
) -> Result<()> {
    let style = Style {
        size: PointSize::Adaptive {
            scale: a.scale,
            max: 32.0,
        },
        ..Style::default()
    };
    let views: Vec<Camera> = Camera::standard_views(&scene.view_bounds, a.width, a.height)
        .into_iter()
        .map(|(_, mut c)| {
            c.fit_depth(&ds.meta.bounds);
            c
        })
        .collect();
    let (precision, was_f32) = (raster.precision, scene.f32_positions);
    // The references: every point, f32 positions.
    scene.f32_positions = true;
    raster.precision = 0.0;
    scene.buffers.clear();
    let every = SelectOptions {
        budget: u64::MAX,
        min_pixels: 0.0,
    };
    let occlusion = std::mem::replace(&mut scene.occlusion, myriad_lod::Occlusion::Off);
    let mut full = Vec::new();
    for cam in &views {
        scene.converge(cam, &every, None);
        full.push(scene.frame(gpu, raster, cam, &every, &style).0);
    }
    scene.occlusion = occlusion;
    println!(
        "positions on the GPU, adaptive size: bytes per point on the GPU and read per drawn point \
         and the upload from an empty GPU cache in the overview at {} points, its median frame; \
         PSNR of the three standard views at {} points against every point (f32)",
        myriad_core::units::thousands(a.frame_budget),
        myriad_core::units::thousands(a.budget)
    );
    println!(
        "{:<22} {:>7} {:>7} {:>10} {:>9} {:>26} {:>8}",
        "positions", "GPU B/p", "read B/p", "upload MB", "frame ms", "PSNR dB (3 views)", "vs f32"
    );
    let mut f32_psnr = None;
    for (label, f32_positions, px) in ENCODINGS {
        scene.f32_positions = f32_positions;
        raster.precision = px;
        scene.buffers.clear();
        let options = SelectOptions {
            budget: a.budget,
            min_pixels: 1.0,
        };
        let mut db = Vec::new();
        for (cam, reference) in views.iter().zip(&full) {
            scene.converge(cam, &options, None);
            db.push(psnr(
                &scene.frame(gpu, raster, cam, &options, &style).0,
                reference,
            ));
        }
        // The overview from an empty GPU cache: what its first frame uploads; then timed.
        scene.buffers.clear();
        let overview = SelectOptions {
            budget: a.frame_budget,
            min_pixels: 0.0,
        };
        scene.converge(&views[0], &overview, None);
        let (_, first) = scene.frame(gpu, raster, &views[0], &overview, &style);
        let (times, _) = frame_times(
            scene,
            gpu,
            raster,
            &views[0],
            &style,
            a.frame_budget,
            a.frames,
        );
        let mean = db.iter().sum::<f64>() / db.len() as f64;
        let base = *f32_psnr.get_or_insert(mean);
        println!(
            "{label:<22} {:>7.2} {:>7.2} {:>10.1} {:>9.1} {:>26} {:>+8.3}",
            first.gpu_bytes as f64 / first.gpu_points.max(1) as f64,
            first.read_bytes as f64 / first.points.max(1) as f64,
            first.upload_bytes as f64 / 1e6,
            times[times.len() / 2].0 * 1e3,
            db.iter()
                .map(|d| format!("{d:.2}"))
                .collect::<Vec<_>>()
                .join(" "),
            mean - base
        );
    }
    scene.f32_positions = was_f32;
    raster.precision = precision;
    scene.buffers.clear();
    Ok(())
}
