//! `myriad bench stereo DATASET...`: table 1 of Discher et al. 2018, for stereo frames. For each
//! dataset, the overview (or `--view`) at `--size` x `--size` per eye (2160: one eye of a current
//! headset), the budget `--budget`: the median frame (selection, loads, uploads, drawing, post
//! passes) of the mono view, of both eyes in two passes and in a single pass, each with and without
//! the hidden-area mask (single pass: one pass over the points on the CPU, one dispatch on the
//! compute path, one instanced draw on the quad path). On the quad path each is timed with the
//! nodes drawn front to back (the reverse painter's order of Discher et al. 2018) and in the
//! selection's order.

use crate::median;
use anyhow::Result;
use clap::Args;
use myriad_format::Dataset;
use myriad_lod::SelectOptions;
use myriad_render::stereo::Stereo;
use myriad_render::{Gpu, Path, Rasterizer, Scene, Style};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
pub struct StereoBenchArgs {
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    /// Pixels on each side of each eye's image
    #[arg(long, default_value_t = 2160)]
    size: u32,
    /// Point budget of both eyes together
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "5M")]
    budget: u64,
    /// Distance between the eyes, in the datasets' units
    #[arg(long, default_value_t = 0.064)]
    ipd: f64,
    /// Timed frames per configuration (medians)
    #[arg(long, default_value_t = 5)]
    frames: usize,
    #[command(flatten)]
    device: crate::render::Device,
    /// Rasterizer: compute, quads or cpu [default: the device's]; on the quad path every frame
    /// is also timed with the nodes in the selection's order, not front to back
    #[arg(long = "raster", value_parser = myriad_render::args::parse_path)]
    path: Option<Path>,
    /// Post passes over each eye's image, comma-separated (as `render --passes`; the hidden
    /// area skips them too) [default: none]
    #[arg(long, value_parser = myriad_render::args::parse_passes)]
    passes: Option<myriad_render::Passes>,
    /// The standard view the eyes look from: overview, top or close (the data reach the
    /// corners, where the hidden area is)
    #[arg(long, default_value = "overview", value_parser = ["overview", "top", "close"])]
    view: String,
}

pub fn run(a: StereoBenchArgs) -> Result<()> {
    let gpu = match a.path {
        Some(Path::Cpu) => Gpu::cpu(),
        Some(_) => Gpu::headless().map_err(anyhow::Error::msg)?,
        None => a.device.gpu()?,
    };
    if a.path == Some(Path::Compute) && !gpu.atomics {
        anyhow::bail!("{}: no 64-bit atomics, so no compute path", gpu.name);
    }
    let mut raster = a
        .path
        .map_or_else(|| Rasterizer::new(&gpu), |p| Rasterizer::with_path(&gpu, p));
    println!(
        "{}, {:?} path; {}x{} per eye, budget {}, eyes {} apart; medians of {} frames",
        gpu.name, raster.path, a.size, a.size, a.budget, a.ipd, a.frames
    );
    let style = Style {
        passes: a.passes.unwrap_or_default(),
        ..Style::default()
    };
    let options = SelectOptions {
        budget: a.budget,
        min_pixels: 1.0,
    };
    for path in &a.datasets {
        let ds = Arc::new(Dataset::open(&myriad_build::cached::dataset_for(
            path,
            &myriad_build::convert::Silent,
        )?)?);
        let mut scene = Scene::open(ds.clone(), 2 << 30, 1 << 30);
        let cam = crate::view_camera(
            Some(&a.view),
            &scene.view_bounds,
            &ds.meta.bounds,
            a.size,
            a.size,
        )?;
        let eyes = cam.eyes(a.ipd);
        let name = path.display();
        println!("\n{name}\n| frame | points | ms |\n|---|---|---|");
        scene.converge(&cam, &options, None);
        // Node order matters only where there is a depth test (the quad path); the CPU and
        // compute paths keep the nearest point by atomics in any order.
        let orders: &[bool] = if raster.path == Path::Quads {
            &[true, false]
        } else {
            &[true]
        };
        let as_selected = |front_to_back: bool| {
            if front_to_back {
                ""
            } else {
                ", nodes as selected"
            }
        };
        for &front_to_back in orders {
            raster.front_to_back = front_to_back;
            row(
                &format!("mono{}", as_selected(front_to_back)),
                a.frames,
                || scene.frame(&gpu, &raster, &cam, &options, &style).1.points,
            );
        }
        scene.converge_with(&|s: &Scene| s.select_eyes(&eyes, &options, None));
        for &front_to_back in orders {
            raster.front_to_back = front_to_back;
            for (label, single_pass, hidden_area) in [
                ("two passes", false, false),
                ("two passes, hidden-area mask", false, true),
                ("single pass", true, false),
                ("single pass, hidden-area mask", true, true),
            ] {
                let stereo = Stereo {
                    ipd: a.ipd,
                    single_pass,
                    hidden_area,
                };
                let label = format!("{label}{}", as_selected(front_to_back));
                row(&label, a.frames, || {
                    scene
                        .frame_stereo(&gpu, &raster, &eyes, &options, &style, &stereo, None)
                        .1
                        .points
                });
            }
        }
    }
    Ok(())
}

/// Times `frame` (which returns the points it drew) `frames` times and prints its row of the
/// table: the points, the median milliseconds.
fn row(label: &str, frames: usize, mut frame: impl FnMut() -> u64) {
    let mut ms = Vec::new();
    let mut points = 0;
    for _ in 0..frames.max(1) {
        let t = Instant::now();
        points = frame();
        ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    println!(
        "| {label} | {} | {:.1} |",
        myriad_core::units::thousands(points),
        median(ms)
    );
}
