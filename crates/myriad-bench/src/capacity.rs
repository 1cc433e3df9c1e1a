//! `myriad bench capacity SCAN`: table 3 of Kanzok et al. 2015, the points a node holds against
//! what a view costs. The scan is converted at each `--capacities` (Kanzok et al. tried 2^15, 2^16
//! and 2^17 points a node); each dataset is then opened cold (its pages dropped from the page
//! cache) and walked through three views in the paper's order: overview (from above at 45 degrees),
//! close (the standard close view) and detail (the eye inside the data, as `bench culling`'s inside
//! view), with occlusion culling (the default, `checked`) and without ("w/o z-test" in the paper).
//! Per view: nodes and points drawn (the 1-pixel threshold, no budget: as Kanzok et al. draw), the
//! median frame time of `--frames` frames, and the time to load the view completely from the one
//! before (the paper's arrows; the first view's from opening).

use crate::culling::inside_view;
use anyhow::{Result, bail};
use clap::Args;
use myriad_format::Dataset;
use myriad_lod::{Camera, Occlusion, SelectOptions};
use myriad_render::{Rasterizer, Scene, Style};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
pub struct CapacityBenchArgs {
    /// The scan (any input `convert` reads), converted at each capacity
    scan: PathBuf,
    /// Points a node holds, comma-separated
    #[arg(long, default_value = "32768,65536,131072")]
    capacities: String,
    /// Folder for the datasets (NAME-CAPACITY.myr, kept)
    #[arg(long)]
    scratch: PathBuf,
    /// Timed frames per view
    #[arg(long, default_value_t = 5)]
    frames: usize,
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    #[command(flatten)]
    device: crate::render::Device,
}

pub fn run(a: CapacityBenchArgs) -> Result<()> {
    let gpu = a.device.gpu()?;
    let raster = Rasterizer::new(&gpu);
    let capacities: Vec<u64> = (a.capacities.split(','))
        .map(|c| myriad_core::units::parse_count(c.trim()).map_err(anyhow::Error::msg))
        .collect::<Result<_>>()?;
    std::fs::create_dir_all(&a.scratch)?;
    let exe = std::env::current_exe()?;
    let stem = a
        .scan
        .file_stem()
        .map_or("scan".into(), |s| s.to_string_lossy().to_string());
    println!(
        "{}, {:?} path; {}x{}, no budget, 1-pixel threshold; frame ms median of {}",
        gpu.name, raster.path, a.width, a.height, a.frames
    );
    println!(
        "{:>9} {:<8} {:>9} {:>6} | {:>32} | {:>32} | {:>32}",
        "capacity",
        "culling",
        "convert s",
        "nodes",
        "open s, overview: nodes, pts, ms",
        "load s, close: nodes, pts, ms",
        "load s, detail: nodes, pts, ms"
    );
    let style = Style::default();
    let all = SelectOptions {
        budget: u64::MAX,
        min_pixels: 1.0,
    };
    for &c in &capacities {
        let out = a.scratch.join(format!("{stem}-{c}.myr"));
        let t = Instant::now();
        let r = std::process::Command::new(&exe)
            .arg("convert")
            .arg(&a.scan)
            .arg("-o")
            .arg(&out)
            .args(["--force", "--capacity", &c.to_string()])
            .output()?;
        let convert = t.elapsed().as_secs_f64();
        if !r.status.success() {
            bail!(
                "convert failed: {}",
                String::from_utf8_lossy(&r.stderr).trim()
            );
        }
        for (label, occlusion) in [("checked", Occlusion::Checked), ("off", Occlusion::Off)] {
            crate::open::drop_cache(&out)?;
            let t = Instant::now();
            let ds = Arc::new(Dataset::open(&out)?);
            let mut scene = Scene::open(ds.clone(), 4 << 30, 2 << 30);
            scene.occlusion = occlusion;
            let b = scene.view_bounds;
            let views = Camera::standard_views(&b, a.width, a.height);
            let mut detail = inside_view(&b, a.width, a.height);
            detail.fit_depth(&ds.meta.bounds);
            detail.near = detail.near.min(0.05);
            let cams = [views[0].1, views[2].1, detail];
            let mut cells = Vec::new();
            let mut since = t;
            for cam in cams {
                // Queries act from the frame after theirs: drawn until the selection settles.
                scene.settle(&gpu, &raster, &cam, &all, &style);
                let load = since.elapsed().as_secs_f64();
                let mut ms = Vec::new();
                let mut stats = myriad_render::FrameStats::default();
                for _ in 0..a.frames.max(1) {
                    let t = Instant::now();
                    (_, stats) = scene.frame(&gpu, &raster, &cam, &all, &style);
                    ms.push(t.elapsed().as_secs_f64() * 1e3);
                }
                ms.sort_by(f64::total_cmp);
                cells.push((
                    load,
                    stats.nodes,
                    myriad_core::units::thousands(stats.points),
                    ms[ms.len() / 2],
                ));
                since = Instant::now();
            }
            let [o, cl, d] = [&cells[0], &cells[1], &cells[2]];
            println!(
                "{c:>9} {label:<8} {convert:>9.2} {:>6} | {:>6.2} {:>5} {:>11} {:>7.1} | {:>6.2} {:>5} {:>11} {:>7.1} | {:>6.2} {:>5} {:>11} {:>7.1}",
                ds.meta.nodes, o.0, o.1, o.2, o.3, cl.0, cl.1, cl.2, cl.3, d.0, d.1, d.2, d.3
            );
        }
    }
    Ok(())
}
