//! `myriad synth -o FILE --points N`

use anyhow::{Result, bail};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use myriad_synth::{SceneKind, SynthOptions};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Clone, Copy, ValueEnum)]
enum Scene {
    City,
    Terrain,
    Indoor,
    /// Cones and ridges of known volume on sloping ground, for `myriad volume`
    Stockpiles,
}

#[derive(Args)]
pub struct SynthArgs {
    /// Output file: .las, .laz, or .e57 (--scene indoor: one scan per station, posed)
    #[arg(short, long)]
    output: PathBuf,
    /// Number of points: 1000000, 1e6, 250k, 100M, 2G
    #[arg(long, value_parser = myriad_core::units::parse_count)]
    points: u64,
    #[arg(long, value_enum, default_value = "city")]
    scene: Scene,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// --scene stockpiles: the survey (2: the same site later, its first pile taken away)
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=2))]
    epoch: u32,
    /// Replace the output if it exists
    #[arg(long)]
    force: bool,
    /// LAS point format: 0, 1, 2, 3, 6, 7 or 8 (the scan's attributes the format holds; zero
    /// for the scanner channel, the red channel as near infrared)
    #[arg(long, default_value_t = myriad_synth::DEFAULT_POINT_FORMAT)]
    point_format: u8,
}

pub fn run(a: SynthArgs) -> Result<()> {
    if a.points == 0 {
        bail!("--points must be at least 1");
    }
    // The site's piles are planned before a point is written (one per 25,600 points).
    if matches!(a.scene, Scene::Stockpiles) && a.points > 10_000_000_000 {
        bail!("--points: a stockpile site has at most 10G points");
    }
    let options = SynthOptions {
        points: a.points,
        scene: match a.scene {
            Scene::City => SceneKind::City,
            Scene::Terrain => SceneKind::Terrain,
            Scene::Indoor => SceneKind::Indoor,
            Scene::Stockpiles => SceneKind::Stockpiles { epoch: a.epoch },
        },
        seed: a.seed,
    };
    let bar = if std::io::stderr().is_terminal() {
        let b = ProgressBar::new(a.points);
        b.set_style(
            ProgressStyle::with_template(
                "synth {bar:40} {human_pos}/{human_len} points, {per_sec:0}, ETA {eta}",
            )
            .expect("valid template"),
        );
        b
    } else {
        ProgressBar::hidden()
    };
    let start = Instant::now();
    let n = myriad_synth::write_as(&options, &a.output, a.force, a.point_format, |done| {
        bar.set_position(done)
    })?;
    bar.finish_and_clear();
    let secs = start.elapsed().as_secs_f64();
    let bytes = std::fs::metadata(&a.output).map(|m| m.len()).unwrap_or(0);
    eprintln!(
        "wrote {n} points to {} in {secs:.2} s ({:.2} M points/s), {bytes} bytes",
        a.output.display(),
        n as f64 / secs / 1e6
    );
    if let SceneKind::Stockpiles { epoch } = options.scene {
        print_piles(a.points, a.seed, epoch);
    }
    Ok(())
}

/// Each pile of the stockpile site with its volume and a polygon around it for `myriad volume`.
fn print_piles(points: u64, seed: u64, epoch: u32) {
    use myriad_synth::stockpiles::{Shape, Site};
    let site = Site::plan(points, seed, epoch);
    let standing = site.piles().len();
    let all = site.all_piles();
    for (i, p) in all.iter().enumerate() {
        let gone = epoch >= 2 && i == 0;
        let what = match p.shape {
            Shape::Cone { radius } => format!("cone r {radius:.2} m"),
            Shape::Prism { length, width, .. } => format!("ridge {length:.2} x {width:.2} m"),
        };
        println!(
            "pile {}: {what}, {:.2} m high, {:.3} m3{}  --polygon {}",
            i + 1,
            p.height,
            p.volume(),
            if gone {
                " (taken away in this epoch)"
            } else {
                ""
            },
            p.polygon(3.0, myriad_synth::ORIGIN)
        );
    }
    if all.is_empty() {
        println!(
            "no pile: the site is smaller than one {} m plot; more --points",
            myriad_synth::stockpiles::PLOT
        );
    } else {
        println!("{standing} piles standing");
    }
}
