//! `myriad bench culling DATASET...`: what occlusion culling saves and costs.
//!
//! Two views per dataset: inside (the eye at the middle of the data, a third of the way up,
//! looking level along its longer horizontal axis: in a building, a room with walls between it
//! and the rest) and outside (the standard overview from above at 45 degrees). For each view,
//! each method (`off`, `software`, `queries`: occlusion queries after each frame, hardware ones
//! on a GPU, acting from the next frame; `checked`: the software test with its culls queried;
//! the last two drawn until the selection settles) and each `--budgets`
//! (then the 1-pixel threshold alone, no budget), once converged: nodes and points selected,
//! nodes culled, the median selection, query and frame time of `--frames` frames, and the PSNR
//! against the image of every point with culling off.

use crate::render::psnr;
use anyhow::Result;
use clap::Args;
use myriad_format::Dataset;
use myriad_io::image::write_png;
use myriad_lod::{Camera, Occlusion, SelectOptions};
use myriad_render::{ColorBy, Rasterizer, Scene, Style};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
pub struct CullingBenchArgs {
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    /// Point budgets, comma-separated (then the threshold alone, without a budget)
    #[arg(long, default_value = "500k,1M,2M")]
    budgets: String,
    /// Timed frames per configuration
    #[arg(long, default_value_t = 5)]
    frames: usize,
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Colour scheme of every image (elevation: scans without colours still show)
    #[arg(long, value_parser = myriad_render::args::parse_color, default_value = "elevation")]
    color: ColorBy,
    #[command(flatten)]
    device: crate::render::Device,
    /// Write the images into this folder (NAME-VIEW-METHOD-BUDGET.png and -full)
    #[arg(long)]
    images: Option<PathBuf>,
}

/// The eye in the middle of `b`, a third of the way up, looking level along the longer
/// horizontal axis.
pub fn inside_view(b: &myriad_core::Aabb, width: u32, height: u32) -> Camera {
    let c = b.center();
    let s = b.size();
    let eye = [c[0], c[1], b.min[2] + s[2] / 3.0];
    let axis = if s[0] >= s[1] { 0 } else { 1 };
    let mut target = eye;
    target[axis] += s[axis].max(1e-6);
    Camera {
        position: eye,
        target,
        up: [0.0, 0.0, 1.0],
        fov_y: 60.0,
        width,
        height,
        near: 0.05,
        far: 1.0,
    }
}

pub fn run(a: CullingBenchArgs) -> Result<()> {
    let gpu = a.device.gpu()?;
    let raster = Rasterizer::new(&gpu);
    let mut budgets: Vec<u64> = a
        .budgets
        .split(',')
        .map(|b| myriad_core::units::parse_count(b.trim()).map_err(anyhow::Error::msg))
        .collect::<Result<_>>()?;
    budgets.push(u64::MAX);
    println!("{}, {:?} path", gpu.name, raster.path);
    if let Some(dir) = &a.images {
        std::fs::create_dir_all(dir)?;
    }
    let style = Style::default();
    for path in &a.datasets {
        let ds = Arc::new(Dataset::open(path)?);
        let name = path
            .file_stem()
            .map_or("dataset".into(), |s| s.to_string_lossy().to_string());
        let mut scene = Scene::open(ds.clone(), 4 << 30, 2 << 30);
        scene.set_colour(a.color);
        println!(
            "\n{name}: {} points, {} nodes; {}x{}, frame times median of {}",
            myriad_core::units::thousands(ds.meta.points),
            ds.meta.nodes,
            a.width,
            a.height,
            a.frames
        );
        println!(
            "{:<8} {:<9} {:>9} {:>7} {:>11} {:>7} {:>10} {:>9} {:>9} {:>7}",
            "view",
            "method",
            "budget",
            "nodes",
            "points",
            "culled",
            "select ms",
            "query ms",
            "frame ms",
            "PSNR"
        );
        let mut inside = inside_view(&scene.view_bounds, a.width, a.height);
        inside.fit_depth(&ds.meta.bounds);
        inside.near = inside.near.min(0.05);
        let mut outside = Camera::standard_views(&scene.view_bounds, a.width, a.height)[0].1;
        outside.fit_depth(&ds.meta.bounds);
        for (view, cam) in [("inside", inside), ("outside", outside)] {
            // The reference: every point, nothing culled.
            scene.occlusion = Occlusion::Off;
            let all = SelectOptions {
                budget: u64::MAX,
                min_pixels: 0.0,
            };
            scene.converge(&cam, &all, None);
            let (full, _) = scene.frame(&gpu, &raster, &cam, &all, &style);
            let save = |label: &str, img: &[u8]| -> Result<()> {
                if let Some(dir) = &a.images {
                    let file = dir.join(format!("{name}-{view}-{label}.png"));
                    write_png(&file, a.width, a.height, img)?;
                }
                Ok(())
            };
            save("full", &full)?;
            for &budget in &budgets {
                for (method, occlusion) in [
                    ("off", Occlusion::Off),
                    ("software", Occlusion::Software),
                    ("queries", Occlusion::Queries),
                    ("checked", Occlusion::Checked),
                ] {
                    scene.occlusion = occlusion;
                    let o = SelectOptions {
                        budget,
                        min_pixels: 1.0,
                    };
                    // Queries act from the frame after theirs: drawn until the selection
                    // settles.
                    scene.settle(&gpu, &raster, &cam, &o, &style);
                    let mut frames = Vec::new();
                    let mut image = Vec::new();
                    let mut stats = myriad_render::FrameStats::default();
                    for _ in 0..a.frames.max(1) {
                        let t = Instant::now();
                        (image, stats) = scene.frame(&gpu, &raster, &cam, &o, &style);
                        frames.push((
                            t.elapsed().as_secs_f64(),
                            stats.select.as_secs_f64(),
                            stats.query.as_secs_f64(),
                        ));
                    }
                    let median = |k: usize| {
                        let mut v: Vec<f64> = frames.iter().map(|f| [f.0, f.1, f.2][k]).collect();
                        v.sort_by(f64::total_cmp);
                        v[v.len() / 2] * 1e3
                    };
                    let b = if budget == u64::MAX {
                        "none".to_string()
                    } else {
                        myriad_core::units::thousands(budget)
                    };
                    println!(
                        "{view:<8} {method:<9} {b:>9} {:>7} {:>11} {:>7} {:>10.2} {:>9.2} {:>9.1} {:>7.2}",
                        stats.nodes,
                        myriad_core::units::thousands(stats.points),
                        stats.culled,
                        median(1),
                        median(2),
                        median(0),
                        psnr(&image, &full),
                    );
                    save(&format!("{method}-{}", b.replace(',', "")), &image)?;
                }
            }
        }
    }
    Ok(())
}
