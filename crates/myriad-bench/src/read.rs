//! `myriad bench read FILE...`: points per second through Myriad's readers, next to the raw
//! decode of the las and laz crates for LAS/LAZ.

use crate::time_points;
use anyhow::Result;
use clap::Args;
use myriad_io::OpenOptions;
use std::path::PathBuf;

#[derive(Args)]
pub struct ReadArgs {
    #[arg(required = true)]
    files: Vec<PathBuf>,
    #[arg(long, default_value_t = 5)]
    runs: usize,
}

pub fn run(a: ReadArgs) -> Result<()> {
    println!(
        "{:<48} {:>12} {:>14} {:>16} {:>7}",
        "file", "points", "myriad pts/s", "las/laz raw pts/s", "ratio"
    );
    for path in &a.files {
        let format = myriad_io::detect(path)?;
        let (n, ours) = time_points(
            || {
                let mut src = myriad_io::open(path, &OpenOptions::default())?;
                let mut n = 0u64;
                let mut sum = 0.0;
                while let Some(b) = src.read_batch(myriad_io::MAX_BATCH)? {
                    n += b.len() as u64;
                    sum += b.positions.first().map_or(0.0, |p| p[0]); // keep the decode live
                }
                std::hint::black_box(sum);
                Ok(n)
            },
            a.runs,
        )?;
        let name = path.file_name().map_or_else(
            || path.display().to_string(),
            |f| f.to_string_lossy().into_owned(),
        );
        if matches!(format, myriad_io::Format::Las | myriad_io::Format::Laz) {
            let (_, raw) = time_points(|| Ok(myriad_io::las::read_raw_records(path)?), a.runs)?;
            println!(
                "{name:<48} {n:>12} {:>14.0} {:>16.0} {:>6.0}%",
                ours,
                raw,
                100.0 * ours / raw
            );
        } else {
            println!("{name:<48} {n:>12} {ours:>14.0} {:>16} {:>7}", "-", "-");
        }
    }
    println!(
        "medians of {} runs each; ratio = myriad / raw decode by the las and laz crates",
        a.runs
    );
    Ok(())
}
