//! `myriad bench synth`: the speed and peak memory of `myriad synth`.

use crate::time_points;
use anyhow::Result;
use clap::Args;
use myriad_io::process::peak_rss_bytes;
use std::path::PathBuf;

#[derive(Args)]
pub struct SynthBenchArgs {
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "100M")]
    points: u64,
    #[arg(long, default_value_t = 3)]
    runs: usize,
    /// Output file (replaced on every run, removed at the end); .las or .laz
    #[arg(short, long, default_value = "myriad-bench-synth.las")]
    output: PathBuf,
}

pub fn run(a: SynthBenchArgs) -> Result<()> {
    let options = myriad_synth::SynthOptions {
        points: a.points,
        scene: myriad_synth::SceneKind::City,
        seed: 1,
    };
    let (n, rate) = time_points(
        || Ok(myriad_synth::write(&options, &a.output, true, |_| {})?),
        a.runs,
    )?;
    let bytes = std::fs::metadata(&a.output).map(|m| m.len()).unwrap_or(0);
    std::fs::remove_file(&a.output).ok();
    println!(
        "synth {n} points to {}: median {:.2} M points/s over {} runs, {bytes} bytes",
        a.output.display(),
        rate / 1e6,
        a.runs
    );
    match peak_rss_bytes() {
        Some(p) => println!("peak resident memory: {:.1} MB", p as f64 / 1e6),
        None => println!("peak resident memory: unknown on this platform"),
    }
    Ok(())
}
