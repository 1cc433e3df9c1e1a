//! The `myriad` command: argument parsing and wiring only. Library crates do the work; this file
//! turns their errors into one line on stderr and an exit code (0 success, 1 error, 2 usage).

mod annotate;
mod bench;
mod build_options;
mod cached;
mod classify;
mod dataset;
mod export;
mod ground;
mod info;
mod measure;
mod mesh;
mod partition;
mod photos;
mod progress;
mod raster;
mod render;
mod serve;
mod synth;
mod view;

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
    /// A header every request for an http(s):// dataset carries, NAME: VALUE (a private
    /// server's token: "Authorization: Bearer TOKEN", or MYRIAD_TOKEN in the environment); may
    /// be given again
    #[arg(long = "header", global = true, value_name = "NAME: VALUE")]
    headers: Vec<String>,
}

#[derive(Subcommand)]
enum Command {
    /// Build a level-of-detail dataset (.myr) from point clouds of any size
    Convert(dataset::ConvertArgs),
    /// Plan a build in parts (for Slurm, Ray, Kubernetes, AWS Batch): reads the inputs' headers only
    Plan(partition::PlanArgs),
    /// Merge the parts of a planned build into one dataset (pages copied, levels above built)
    Merge(partition::MergeArgs),
    /// Run a planned build on Slurm: an array job for the parts, then the merge
    Slurm(partition::SlurmArgs),
    /// Show what a point cloud file or dataset holds: format, count, bounds, attributes, CRS
    Info(info::InfoArgs),
    /// Write a dataset's points (in a box, at a level of detail) to LAS, LAZ or PLY
    Extract(dataset::ExtractArgs),
    /// Write a dataset as COPC or Potree 2.0 (for other viewers and tools), or LAS/LAZ
    Export(export::ExportArgs),
    /// Cut a cross-section along a line: its points to CSV, LAS/LAZ, DXF or a PNG of the profile
    Profile(measure::ProfileArgs),
    /// Measure the volume over a polygon above a base (the rim's plane, an elevation, an earlier survey)
    Volume(measure::VolumeArgs),
    /// Reclassify or remove points in a region, kept as edits beside the dataset (never written
    /// into it) and applied by every command; list, undo, redo, or write a dataset with them
    Classify(classify::ClassifyArgs),
    /// Find the ground (SMRF in tiles with overlap, out of core): a terrain kept beside the
    /// dataset and an edit that classifies its points against it
    Ground(ground::GroundArgs),
    /// Write a terrain model, surface model, canopy heights, intensity or density as a
    /// Cloud-Optimized GeoTIFF
    Raster(raster::RasterArgs),
    /// Write contour lines of the terrain (the ground points) as DXF or GeoJSON
    Contours(raster::ContoursArgs),
    /// Keep annotations and measurements with a dataset (as view and serve do), and export
    /// them to GeoJSON or DXF, or import them
    Annotate(annotate::AnnotateArgs),
    /// Keep photos and panoramas with a dataset: an E57 file's images, a Potree panorama list
    Photos(photos::PhotosArgs),
    /// Read every page of a dataset, check checksums and invariants, name damaged nodes
    Verify(dataset::VerifyArgs),
    /// Render a dataset to a PNG, headless (level of detail within a point budget)
    Render(render::RenderArgs),
    /// Write the surface a view's points make as a mesh: PLY or glTF
    Mesh(mesh::MeshArgs),
    /// Open datasets in a window: navigate, measure, clip (level of detail while you move)
    View(view::ViewArgs),
    /// Serve datasets and exported folders over HTTP (range requests) for browsers and viewers
    Serve(serve::ServeArgs),
    /// Write a simulated laser scan of a procedural scene (LAS or LAZ)
    Synth(synth::SynthArgs),
    /// Measure speed, memory and image quality, each next to a baseline or a peer tool
    ///
    /// One subcommand per benchmark: reading, synthesis, conversion, rendering and its passes,
    /// structures, culling, surfaces, stereo, export, opening, serving, prefetching, the web
    /// viewer and builds in parts. Each prints medians over several runs.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
}

/// Mesa's Vulkan drivers print "error: XDG_RUNTIME_DIR is invalid or not set" when probed in a
/// session without one (a server, a container, CI), which reads like an error of ours. Give them
/// a private one under the temporary folder, as a login session would have.
fn quiet_mesa() {
    #[cfg(target_os = "linux")]
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        use std::os::unix::fs::{DirBuilderExt, MetadataExt};
        // SAFETY: getuid has no preconditions.
        let uid = unsafe { libc::getuid() };
        let dir = std::env::temp_dir().join(format!("myriad-runtime-{uid}"));
        let _ = std::fs::DirBuilder::new().mode(0o700).create(&dir);
        let ours = std::fs::metadata(&dir).is_ok_and(|m| m.is_dir() && m.uid() == uid);
        if ours {
            // SAFETY: called first thing in main, before any thread exists.
            unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
        }
    }
}

fn main() -> ExitCode {
    // Output piped into `head` and closed early ends the program quietly, as for other Unix
    // tools, instead of a panic in `println!`.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    quiet_mesa();
    // Every dataset opened from disk carries the edits kept beside it.
    myriad_measure::edits::install();
    let cli = Cli::parse();
    if !cli.headers.is_empty() {
        match (cli.headers.iter())
            .map(|h| myriad_format::remote::parse_header(h))
            .collect::<Result<Vec<_>, _>>()
        {
            Ok(h) => myriad_format::remote::set_headers(h),
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(1);
            }
        }
    }
    let result = match cli.command {
        Command::Convert(a) => dataset::convert(a),
        Command::Plan(a) => partition::plan(a),
        Command::Merge(a) => partition::merge(a),
        Command::Slurm(a) => partition::slurm(a),
        Command::Info(a) => info::run(a),
        Command::Extract(a) => dataset::extract(a),
        Command::Export(a) => export::run(a),
        Command::Profile(a) => measure::profile(a),
        Command::Volume(a) => measure::volume(a),
        Command::Classify(a) => classify::run(a),
        Command::Ground(a) => ground::run(a),
        Command::Raster(a) => raster::run(a),
        Command::Contours(a) => raster::contours(a),
        Command::Annotate(a) => annotate::run(a),
        Command::Photos(a) => photos::run(a),
        Command::Verify(a) => dataset::verify(a),
        Command::Render(a) => render::run(a),
        Command::Mesh(a) => mesh::run(a),
        Command::View(a) => view::run(a),
        Command::Serve(a) => serve::run(a),
        Command::Synth(a) => synth::run(a),
        Command::Bench(b) => bench::run(b),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // The chain, leaving out causes the message before them already says (an I/O
            // error's text is part of the file error that wraps it).
            let mut msg = e.to_string();
            for cause in e.chain().skip(1) {
                let c = cause.to_string();
                if !msg.contains(&c) {
                    msg = format!("{msg}: {c}");
                }
            }
            let msg = msg.replace('\n', " ");
            eprintln!("error: {msg}");
            ExitCode::from(1)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parses(args: &[&str]) -> bool {
        Cli::try_parse_from(std::iter::once("myriad").chain(args.iter().copied())).is_ok()
    }

    /// Local scanner coordinates are often negative: every option that takes numbers accepts a
    /// leading minus (as the first of its numbers, too).
    #[test]
    fn numbers_take_a_minus_sign() {
        let render = ["render", "ky.myr", "-o", "x.png"];
        let with = |extra: &[&str]| parses(&[&render[..], extra].concat());
        assert!(with(&["--camera", "-4,-1,6,30,30,0"]));
        assert!(with(&["--camera=-4,-1,6,30,30,0"]));
        assert!(with(&["--up", "-1,0,0"]));
        assert!(with(&["--clip", "-5,-5,-5,-1,-1,-1"]));
        assert!(parses(&["view", "a.myr", "--camera", "-1,-2,-3,0,0,0"]));
        assert!(parses(&[
            "extract",
            "a.myr",
            "-o",
            "b.las",
            "--box",
            "-10,-10,-1,0,0,0"
        ]));
        // The value is still checked: a flag where numbers belong is a usage error.
        assert!(!with(&["--camera", "--full"]));
    }

    #[test]
    fn the_lod_threshold_is_a_positive_pixel_count() {
        let render = ["render", "ky.myr", "-o", "x.png", "--lod-threshold"];
        assert!(parses(&[&render[..], &["2"]].concat()));
        for bad in ["0", "-1", "65", "x"] {
            assert!(!parses(&[&render[..], &[bad]].concat()), "{bad}");
        }
        assert!(!parses(&["view", "a.myr", "--lod-threshold", "0"]));
    }
}
