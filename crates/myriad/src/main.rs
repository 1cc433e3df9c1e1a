//! The `myriad` command: argument parsing and wiring only. Library crates do the work; this file
//! turns their errors into one line on stderr and an exit code (0 success, 1 error, 2 usage).

mod bench;
mod info;
mod synth;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "myriad",
    version,
    about = "Out-of-core level-of-detail point clouds: convert, inspect, view"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Show what a point cloud file holds: format, count, bounds, attributes, CRS
    Info(info::InfoArgs),
    /// Write a simulated laser scan of a procedural scene (LAS or LAZ)
    Synth(synth::SynthArgs),
    /// Measure reading and synthesis speed (medians over several runs, with baselines)
    #[command(subcommand)]
    Bench(bench::BenchCommand),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Info(a) => info::run(a),
        Command::Synth(a) => synth::run(a),
        Command::Bench(b) => bench::run(b),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let msg = format!("{e:#}").replace('\n', " ");
            eprintln!("error: {msg}");
            ExitCode::from(1)
        }
    }
}
