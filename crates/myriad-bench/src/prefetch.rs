//! `myriad bench prefetch DATASET...`: what prefetching (Goswami et al. 2010: the nodes just
//! outside the view loaded ahead) saves a viewer that orbits. Each run opens the dataset afresh,
//! converges on `render`'s default view, then orbits the target by `--degrees` in `--frames` frames
//! drawn as a viewer draws them (never waiting) and keeps drawing at the last view until it has
//! converged. Reported per mode (prefetching off and on, `mwkd`'s ancestors standing in for
//! nodes that come into view off and on; runs alternate):
//! frames drawn with selected nodes missing, frames with a hole (a node missing that nothing
//! drawn stands in for), the nodes missing per frame, the PSNR of the frames with nodes missing
//! against the same view converged, and the time to converge once the orbit stops.
//! `--cold` drops the file from the page cache before each run (loads then wait for the disk).

use anyhow::{Result, bail};
use clap::Args;
use myriad_format::Dataset;
use myriad_lod::SelectOptions;
use myriad_render::{Rasterizer, Scene, Style};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(Args)]
pub struct PrefetchBenchArgs {
    /// Datasets (.myr)
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    #[arg(long, default_value_t = 40.0)]
    degrees: f64,
    #[arg(long, default_value_t = 40)]
    frames: usize,
    #[arg(long, default_value_t = 3)]
    runs: usize,
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "5M")]
    budget: u64,
    /// Drop the file from the page cache before each run
    #[arg(long)]
    cold: bool,
    /// Start from a standard view (overview, top, close) instead of `render`'s default
    #[arg(long, value_parser = ["overview", "top", "close"])]
    view: Option<String>,
    /// `mwkd`: ancestors on the GPU standing in for nodes that come into view: both (rows for
    /// each), on or off
    #[arg(long, default_value = "both", value_parser = ["both", "on", "off"])]
    stand_ins: String,
    /// `mwkd`: how far behind their place stand-ins are drawn, as shares of their distance
    /// (a row for each; 0: in place)
    #[arg(long, value_delimiter = ',', default_values_t = [myriad_render::scene::STAND_INS_BEHIND])]
    behind: Vec<f32>,
    /// Prefetching: both (rows for each), on or off
    #[arg(long, default_value = "both", value_parser = ["both", "on", "off"])]
    prefetch: String,
    #[command(flatten)]
    device: crate::render::Device,
}

struct Run {
    incomplete: usize,
    holes: usize,
    missing: f64,
    /// Median PSNR of the incomplete frames against their views converged (infinite: none).
    psnr: f64,
    settle: f64,
}

fn orbit(
    path: &Path,
    widen: f64,
    stand_ins: Option<f32>,
    a: &PrefetchBenchArgs,
    gpu: &myriad_render::Gpu,
) -> Result<Run> {
    if a.cold {
        crate::open::drop_cache(path)?;
    }
    let raster = Rasterizer::new(gpu);
    let style = Style::default();
    let options = SelectOptions {
        budget: a.budget,
        min_pixels: 1.0,
    };
    let ds = Arc::new(Dataset::open(path)?);
    let mut scene = Scene::open(ds.clone(), 2 << 30, 1 << 30);
    scene.prefetch = widen;
    scene.ancestor_stand_ins = stand_ins.is_some();
    scene.stand_ins_behind = stand_ins.unwrap_or(0.0);
    let start = crate::view_camera(
        a.view.as_deref(),
        &scene.view_bounds,
        &ds.meta.bounds,
        a.width,
        a.height,
    )?;
    scene.converge(&start, &options, None);
    let mut cam = start;
    let (mut incomplete, mut holes, mut missing) = (0, 0, 0usize);
    // The frames with nodes missing, to compare with their views converged.
    let mut shown = Vec::new();
    let turn = |step: usize| {
        let angle = (a.degrees * step as f64 / a.frames.max(1) as f64).to_radians();
        let v: [f64; 3] = std::array::from_fn(|i| start.position[i] - start.target[i]);
        let (s, c) = angle.sin_cos();
        let mut cam = start;
        cam.position = [
            start.target[0] + v[0] * c - v[1] * s,
            start.target[1] + v[0] * s + v[1] * c,
            start.position[2],
        ];
        cam
    };
    for step in 1..=a.frames {
        cam = turn(step);
        let (image, stats) = scene.frame(gpu, &raster, &cam, &options, &style);
        if !stats.complete {
            incomplete += 1;
            shown.push((cam, image));
        }
        holes += (stats.holes > 0) as usize;
        missing += stats.selected_nodes.saturating_sub(stats.nodes);
    }
    let t = Instant::now();
    loop {
        let (_, stats) = scene.frame(gpu, &raster, &cam, &options, &style);
        if stats.complete && stats.in_flight == 0 {
            break;
        }
        if t.elapsed() > Duration::from_secs(300) {
            bail!("{}: not converged after the orbit", path.display());
        }
    }
    let settle = t.elapsed().as_secs_f64();
    let mut psnr = Vec::new();
    for (cam, image) in &shown {
        scene.converge(cam, &options, None);
        let (full, _) = scene.frame(gpu, &raster, cam, &options, &style);
        psnr.push(crate::render::psnr(image, &full));
    }
    psnr.sort_by(f64::total_cmp);
    Ok(Run {
        incomplete,
        holes,
        missing: missing as f64 / a.frames.max(1) as f64,
        psnr: psnr.get(psnr.len() / 2).copied().unwrap_or(f64::INFINITY),
        settle,
    })
}

pub fn run(a: PrefetchBenchArgs) -> Result<()> {
    if let Some(b) = a.behind.iter().find(|b| !(b.is_finite() && **b >= 0.0)) {
        bail!("--behind {b}: a share of the distance, 0 or more");
    }
    let gpu = a.device.gpu()?;
    println!(
        "{}, {}x{}, {} view, budget {}, an orbit of {} degrees in {} frames, {} page cache; medians of {} runs",
        gpu.name,
        a.width,
        a.height,
        a.view.as_deref().unwrap_or("render's default"),
        myriad_core::units::thousands(a.budget),
        a.degrees,
        a.frames,
        if a.cold { "cold" } else { "warm" },
        a.runs
    );
    println!(
        "{:<16} {:<9} {:<10} {:>6} {:>18} {:>12} {:>16} {:>12} {:>9}",
        "dataset",
        "prefetch",
        "stand-ins",
        "behind",
        "incomplete frames",
        "hole frames",
        "missing / frame",
        "psnr dB",
        "settle s"
    );
    let on: Vec<Option<f32>> = a.behind.iter().map(|&b| Some(b)).collect();
    let stand_ins: Vec<Option<f32>> = match a.stand_ins.as_str() {
        "on" => on,
        "off" => vec![None],
        _ => [None].into_iter().chain(on).collect(),
    };
    let widths: &[f64] = match a.prefetch.as_str() {
        "on" => &[myriad_render::scene::DEFAULT_PREFETCH],
        "off" => &[1.0],
        _ => &[1.0, myriad_render::scene::DEFAULT_PREFETCH],
    };
    let modes: Vec<(f64, Option<f32>)> = (widths.iter())
        .flat_map(|&w| stand_ins.iter().map(move |&s| (w, s)))
        .collect();
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    for path in &a.datasets {
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        let mut by_mode: Vec<Vec<Run>> = modes.iter().map(|_| Vec::new()).collect();
        for _ in 0..a.runs.max(1) {
            for (m, &(widen, stand_in)) in modes.iter().enumerate() {
                by_mode[m].push(orbit(path, widen, stand_in, &a, &gpu)?);
            }
        }
        let on_off = |b: bool| if b { "on" } else { "off" };
        for (runs, &(widen, stand_in)) in by_mode.iter().zip(&modes) {
            println!(
                "{name:<16} {:<9} {:<10} {:>6} {:>18.0} {:>12.0} {:>16.1} {:>12.2} {:>9.2}",
                on_off(widen > 1.0),
                on_off(stand_in.is_some()),
                stand_in.map_or("-".to_string(), |b| format!("{b}")),
                median(runs.iter().map(|r| r.incomplete as f64).collect()),
                median(runs.iter().map(|r| r.holes as f64).collect()),
                median(runs.iter().map(|r| r.missing).collect()),
                median(runs.iter().map(|r| r.psnr).collect()),
                median(runs.iter().map(|r| r.settle).collect()),
            );
        }
    }
    Ok(())
}
