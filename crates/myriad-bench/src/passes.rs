//! `myriad bench passes DATASET...`: what each post pass costs and what the chains buy.
//!
//! Cost: the median frame time of `--frames` converged frames of the overview at
//! `--frame-budget` points with no pass, each pass alone and the default chain (adaptive
//! squares), then without passes fixed 1-pixel squares, 5-pixel squares and 5-pixel paraboloids
//! (table 2 of Discher et al. 2018: adaptive sizes, multisampling, paraboloids against 5-pixel
//! squares), at each `--sizes` (1280x720 and 2160x2160, one eye of a current headset, by default);
//! a pass's cost is its median minus the median without passes, measured in the same run.
//! Quality: for each dataset and standard view, the PSNR of the image at each `--budgets` against
//! the image of every point drawn with the same passes, for no pass, fill, fill+blur, the
//! default chain, blending and the default chain blended; and the blended images against every
//! point drawn without blending (the data as they are: what blending buys at a budget, and
//! what it changes with every point).

use crate::render::{frame_times, psnr, quality};
use anyhow::Result;
use clap::Args;
use myriad_format::Dataset;
use myriad_io::image::write_png;
use myriad_lod::Camera;
use myriad_render::{ColorBy, DEFAULT_PASSES, Passes, PointSize, Rasterizer, Scene, Shape, Style};
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Args)]
pub struct PassesBenchArgs {
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    /// Image sizes of the timed frames: WxH,...
    #[arg(long, default_value = "1280x720,2160x2160")]
    sizes: String,
    /// Point budget of the timed frames
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "1M")]
    frame_budget: u64,
    /// Timed frames per configuration
    #[arg(long, default_value_t = 7)]
    frames: usize,
    /// Point budgets of the quality images, comma-separated
    #[arg(long, default_value = "250k,1M")]
    budgets: String,
    /// Size of the quality images
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Colour scheme of every image
    #[arg(long, value_parser = myriad_render::args::parse_color, default_value = "rgb")]
    color: ColorBy,
    /// Skip the timing (quality only)
    #[arg(long)]
    no_timing: bool,
    /// Skip the quality table (timing only)
    #[arg(long)]
    no_quality: bool,
    #[command(flatten)]
    device: crate::render::Device,
    /// Write the quality images into this folder (NAME-VIEW-BUDGET-CHAIN.png and -full)
    #[arg(long)]
    images: Option<PathBuf>,
}

fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| anyhow::anyhow!("--sizes: {s:?} is not WxH"))?;
    Ok((w.trim().parse()?, h.trim().parse()?))
}

pub fn run(a: PassesBenchArgs) -> Result<()> {
    let gpu = a.device.gpu()?;
    let raster = Rasterizer::new(&gpu);
    let sizes = a
        .sizes
        .split(',')
        .map(parse_size)
        .collect::<Result<Vec<_>>>()?;
    let budgets = a
        .budgets
        .split(',')
        .map(|b| myriad_core::units::parse_count(b.trim()).map_err(anyhow::Error::msg))
        .collect::<Result<Vec<_>>>()?;
    println!("{}, {:?} path", gpu.name, raster.path);
    if let Some(dir) = &a.images {
        std::fs::create_dir_all(dir)?;
    }
    // Each pass alone over adaptive squares; then the rows of Discher et al. 2018's table 2 that
    // are no pass: fixed 1-pixel points against adaptive ones, and 5-pixel squares against 5-pixel
    // paraboloids.
    let adaptive = (PointSize::adaptive(), Shape::Square);
    let default_blend = format!("{DEFAULT_PASSES},blend");
    let timed: [(&str, &str, _); 14] = [
        ("none", "none", adaptive),
        ("fill", "fill", adaptive),
        ("shade", "shade", adaptive),
        ("ssao", "ssao", adaptive),
        ("edl", "edl", adaptive),
        ("blur", "blur", adaptive),
        ("aa", "aa", adaptive),
        ("default", DEFAULT_PASSES, adaptive),
        ("blend", "blend", adaptive),
        ("def+blend", &default_blend, adaptive),
        ("all", "fill,shade,ssao,edl,blur,aa", adaptive),
        ("1px", "none", (PointSize::Fixed(1.0), Shape::Square)),
        ("5px-sq", "none", (PointSize::Fixed(5.0), Shape::Square)),
        (
            "5px-par",
            "none",
            (PointSize::Fixed(5.0), Shape::Paraboloid),
        ),
    ];
    // Each blended chain after the chain it blends.
    let chains: [(&str, &str); 6] = [
        ("none", "none"),
        ("fill", "fill"),
        ("fill+blur", "fill,blur"),
        ("default", DEFAULT_PASSES),
        ("blend", "blend"),
        ("def+blend", &default_blend),
    ];
    let unblended = |label: &str| match label {
        "blend" => Some(0),
        "def+blend" => Some(3),
        _ => None,
    };
    for path in &a.datasets {
        let ds = Arc::new(Dataset::open(path)?);
        let name = path
            .file_stem()
            .map_or("dataset".into(), |s| s.to_string_lossy().to_string());
        let mut scene = Scene::open(ds.clone(), usize::MAX, usize::MAX);
        scene.set_colour(a.color);
        println!(
            "\n{name}: {} points",
            myriad_core::units::thousands(ds.meta.points)
        );
        if !a.no_timing {
            println!(
                "frame time, overview, budget {}, median of {} frames; cost = median - median of none",
                myriad_core::units::thousands(a.frame_budget),
                a.frames
            );
            for &(w, h) in &sizes {
                let mut cam = Camera::standard_views(&scene.view_bounds, w, h)[0].1;
                cam.fit_depth(&ds.meta.bounds);
                let mut base = 0.0;
                for (label, chain, (size, shape)) in &timed {
                    let style = Style {
                        passes: Passes::parse(chain).map_err(anyhow::Error::msg)?,
                        size: *size,
                        shape: *shape,
                        ..Style::default()
                    };
                    let (times, points) = frame_times(
                        &mut scene,
                        &gpu,
                        &raster,
                        &cam,
                        &style,
                        a.frame_budget,
                        a.frames,
                    );
                    let median = times[times.len() / 2].0 * 1e3;
                    if *label == "none" {
                        base = median;
                    }
                    println!(
                        "{w}x{h} {label:<8} {:>9} points  median {median:>8.1} ms  cost {:>+8.1} ms  (min {:.1}, max {:.1})",
                        myriad_core::units::thousands(points),
                        median - base,
                        times[0].0 * 1e3,
                        times[times.len() - 1].0 * 1e3,
                    );
                }
            }
        }
        if a.no_quality {
            continue;
        }
        println!(
            "PSNR (dB) against every point drawn with the same passes, {}x{}",
            a.width, a.height
        );
        print!("{:<10} {:>9}", "view", "budget");
        for (label, _) in &chains {
            print!(" {label:>10}");
        }
        println!("  fill gain  blend/none  def+blend/def  (blended against every point unblended)");
        let views = Camera::standard_views(&scene.view_bounds, a.width, a.height);
        for (view, mut cam) in views {
            cam.fit_depth(&ds.meta.bounds);
            for &budget in &budgets {
                print!("{view:<10} {:>9}", myriad_core::units::thousands(budget));
                let mut values = Vec::new();
                let mut fulls: Vec<Vec<u8>> = Vec::new();
                let mut against_plain = Vec::new();
                for (label, chain) in &chains {
                    let style = Style {
                        passes: Passes::parse(chain).map_err(anyhow::Error::msg)?,
                        ..Style::default()
                    };
                    let q = quality(&mut scene, &gpu, &raster, &cam, &style, budget)
                        .map_err(|e| anyhow::anyhow!("{name}: {view}: {e}"))?;
                    print!(" {:>10.2}", q.psnr);
                    values.push(q.psnr);
                    if let Some(k) = unblended(label) {
                        against_plain.push(psnr(&q.lod, &fulls[k]));
                    }
                    if let Some(dir) = &a.images {
                        let chain = label.replace('+', "-");
                        let b = myriad_core::units::thousands(budget).replace(',', "");
                        let file = dir.join(format!("{name}-{view}-{b}-{chain}.png"));
                        write_png(&file, a.width, a.height, &q.lod)?;
                        let file = dir.join(format!("{name}-{view}-full-{chain}.png"));
                        write_png(&file, a.width, a.height, &q.full)?;
                    }
                    fulls.push(q.full);
                }
                println!(
                    "  {:>+8.2}  {:>10.2}  {:>13.2}",
                    values[1] - values[0],
                    against_plain[0],
                    against_plain[1]
                );
            }
        }
    }
    Ok(())
}
