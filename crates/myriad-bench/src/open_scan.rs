//! `myriad bench open-scan SCAN...`: how soon a raw scan (a LAS/LAZ file, or a folder of tiles)
//! shows, before any dataset of it exists. Per scan: the first image, cold (the files' pages
//! dropped from the page cache first, as `bench open` does): the preview `render --no-wait`
//! draws (headers, LAZ chunk tables, the first point of each chunk; LAS records at a stride),
//! and the bytes it reads; then `convert` alone, a separate `myriad convert` process as a user
//! runs it, and the image of the finished dataset from the same camera; and the PSNR against that
//! final image of what a viewer opened at the start shows 1, 2, 5, 10 and 30 s in: the build a
//! viewer runs (`myriad_build::growing`: a snapshot a second, the chunks built so far with the
//! preview where they are not), its newest snapshot drawn at each of those times while the
//! build runs (on the same cores, as a viewer would), and that build's time against `convert`
//! alone. Medians of `--runs`; every image on the CPU path, the passes `render`'s default.

use crate::median;
use crate::render::psnr;
use anyhow::{Result, bail};
use clap::Args;
use myriad_build::convert::{ConvertOptions, Silent};
use myriad_build::growing::{DEFAULT_EVERY, Growing};
use myriad_format::Dataset;
use myriad_lod::{Camera, SelectOptions};
use myriad_render::preview::Sample;
use myriad_render::{ColorBy, Gpu, Passes, Rasterizer, Scene, Style};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
pub struct OpenScanBenchArgs {
    /// LAS/LAZ files, or folders of them (each folder one scan)
    #[arg(required = true)]
    scans: Vec<PathBuf>,
    /// Cold runs of the first image, and `convert` runs (medians)
    #[arg(long, default_value_t = 3)]
    runs: usize,
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Colour of both images (as `render --color`; a scan whose RGB is all zero compares
    /// black with black in rgb)
    #[arg(long, value_parser = myriad_render::args::parse_color, default_value = "rgb")]
    color: ColorBy,
    /// Seconds the first image's preview may take, decoding whole chunks of large LAZ scans
    /// after their chunks' first points (0: the chunk starts alone) [default: render
    /// --no-wait's]
    #[arg(long)]
    preview_budget: Option<f64>,
    /// Where each scan's dataset is built (removed at the end)
    #[arg(short, long, default_value = "myriad-bench-open-scan.myr")]
    output: PathBuf,
}

/// The times the PSNR is given at, in seconds from the start.
const AT: [f64; 5] = [1.0, 2.0, 5.0, 10.0, 30.0];

pub fn run(a: OpenScanBenchArgs) -> Result<()> {
    let runs = a.runs.max(1);
    let budget = match a.preview_budget {
        Some(s) if s.is_finite() && s >= 0.0 => std::time::Duration::from_secs_f64(s.min(60.0)),
        Some(s) => bail!("--preview-budget {s}: seconds, 0 or more"),
        None => myriad_io::las_preview::PREVIEW_BUDGET,
    };
    let gpu = Gpu::cpu();
    let raster = Rasterizer::new(&gpu);
    let style = Style {
        passes: Passes::default_chain(),
        ..Style::default()
    };
    let exe = std::env::current_exe()?;
    println!(
        "{}x{} on the {}, medians of {runs} runs; first image cold; PSNR (dB) against the finished dataset's image",
        a.width, a.height, gpu.name
    );
    println!(
        "{:<40} {:>13} {:>8} {:>10} {:>9} {:>8} {:>9} {:>9} {:>7} {:>9}  PSNR at {}",
        "scan",
        "points",
        "sampled",
        "bytes read",
        "first s",
        "first dB",
        "convert s",
        "drawn s",
        "ratio",
        "final s",
        AT.map(|t| format!("{t} s")).join(" / ")
    );
    let mut whole_cache = true;
    for scan in &a.scans {
        let files = myriad_build::cached::inputs_of(scan)?;
        // The first image, cold.
        let mut firsts = Vec::new();
        let mut first = None;
        for _ in 0..runs {
            for f in &files {
                whole_cache &= crate::open::drop_cache(f)?;
            }
            let t = Instant::now();
            let tiles = myriad_io::las_preview::preview_files(&files, 1 << 20, budget)?;
            let sample = Sample::layered(&tiles.samples, &tiles.even, tiles.detail_share, a.color);
            let Some(cam) = Camera::view(None, &sample.view, &sample.all, a.width, a.height) else {
                bail!("{}: no view", scan.display());
            };
            let img = sample.draw(&gpu, &raster, &cam, &style);
            firsts.push(t.elapsed().as_secs_f64());
            first = Some((img, cam, sample.positions.len(), tiles));
        }
        let (preview, cam, sampled, tiles) = first.expect("one run at least");
        // `convert` alone, as a user runs it.
        let mut converts = Vec::new();
        for _ in 0..runs {
            for f in &files {
                crate::open::drop_cache(f)?;
            }
            let t = Instant::now();
            let out = std::process::Command::new(&exe)
                .arg("convert")
                .args(&files)
                .arg("-o")
                .arg(&a.output)
                .arg("--force")
                .output()?;
            if !out.status.success() {
                bail!(
                    "{}: convert failed: {}",
                    scan.display(),
                    String::from_utf8_lossy(&out.stderr).trim()
                );
            }
            converts.push(t.elapsed().as_secs_f64());
        }
        // The finished dataset's image from the same camera, as `render` draws it.
        let options = SelectOptions {
            budget: 5_000_000,
            min_pixels: 1.0,
        };
        let draw = |ds: Arc<Dataset>| {
            let mut scene = Scene::open(ds, 2 << 30, 1 << 30);
            scene.set_colour(a.color);
            scene.last = scene.converge(&cam, &options, None);
            scene.frame(&gpu, &raster, &cam, &options, &style).0
        };
        let t = Instant::now();
        let done = draw(Arc::new(Dataset::open(&a.output)?));
        let final_draw = t.elapsed().as_secs_f64();
        let convert = median(converts);
        // The build a viewer runs, its newest snapshot drawn at each of AT while it goes.
        for f in &files {
            crate::open::drop_cache(f)?;
        }
        let t = Instant::now();
        let growing = Growing::new(DEFAULT_EVERY);
        growing.set_fill(myriad_build::cached::preview_batch(scan)?);
        let mut o = ConvertOptions::new(&a.output);
        o.force = true;
        o.growing = Some(growing.clone());
        let inputs = files.clone();
        let build = std::thread::spawn(move || {
            let r = myriad_build::convert::convert(&inputs, &o, &Silent);
            (r, t.elapsed().as_secs_f64())
        });
        let mut shown = Vec::new();
        for at in AT {
            while !build.is_finished() && t.elapsed().as_secs_f64() < at {
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
            if build.is_finished() {
                break;
            }
            let p = match growing.latest() {
                Some(s) => psnr(&draw(s.dataset), &done),
                None => psnr(&preview, &done),
            };
            shown.push(p);
        }
        let (built, drawn) = build.join().expect("the build thread");
        built?;
        // The finished dataset drawn once the viewer's build ends.
        let at_end = drawn + final_draw;
        let name = scan.file_name().map_or_else(
            || scan.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        println!(
            "{:<40} {:>13} {:>8} {:>10} {:>9.3} {:>8.1} {:>9.2} {:>9.2} {:>7.2} {:>9.2}  {}",
            name,
            myriad_core::units::thousands(tiles.total),
            myriad_core::units::thousands(sampled as u64),
            myriad_core::units::thousands(tiles.bytes_read),
            median(firsts),
            psnr(&preview, &done),
            convert,
            drawn,
            drawn / convert,
            at_end,
            (0..AT.len())
                .map(|i| shown.get(i).map_or("final".into(), |p| format!("{p:.1}")))
                .collect::<Vec<_>>()
                .join(" / ")
        );
    }
    std::fs::remove_file(&a.output).ok();
    if !whole_cache {
        println!(
            "(the files' pages were dropped from the page cache; the whole cache could not be)"
        );
    }
    Ok(())
}
