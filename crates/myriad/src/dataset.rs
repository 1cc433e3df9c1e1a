//! `myriad convert`, `extract` and `verify`.

use anyhow::{Result, bail};
use clap::Args;
use indicatif::ProgressBar;
use myriad_build::convert::{self, ConvertOptions};
use myriad_build::extract::{self, ExtractOptions};
use myriad_core::Aabb;
use myriad_format::Dataset;
use serde_json::json;
use std::path::{Path, PathBuf};

use crate::build_options::BuildArgs;
use crate::progress::{Bar, global_threads, print_memory_and_skipped};
use myriad_core::units::thousands;

#[derive(Args)]
pub struct ConvertArgs {
    /// Input point clouds (LAS, LAZ, E57, PLY, PCD, PTS/XYZ/CSV/TXT); several merge into one dataset
    #[arg(required_unless_present = "plan", conflicts_with = "plan")]
    inputs: Vec<PathBuf>,
    /// The dataset to write (.myr)
    #[arg(
        short,
        long,
        required_unless_present_any = ["append", "list_inputs", "list_ranges"],
        conflicts_with = "append"
    )]
    output: Option<PathBuf>,
    /// Add the inputs to this dataset (octree or layered) instead: the parts of the tree they
    /// fall in are rebuilt, the rest kept; verified whole, then it replaces the old one
    #[arg(long, value_name = "DATASET")]
    append: Option<PathBuf>,
    #[command(flatten)]
    build: BuildArgs,
    /// Build from a plan (`myriad plan`): its inputs and parameters; with --part, one part into
    /// the folder given by -o, else the whole plan on this machine
    #[arg(
        help_heading = "Building in parts",
        long,
        value_name = "PLAN",
        conflicts_with = "append"
    )]
    plan: Option<PathBuf>,
    /// The part of the plan to build: an index, or auto (SLURM_ARRAY_TASK_ID,
    /// JOB_COMPLETION_INDEX or AWS_BATCH_JOB_ARRAY_INDEX)
    #[arg(
        help_heading = "Building in parts",
        long,
        requires = "plan",
        value_name = "I|auto"
    )]
    part: Option<String>,
    /// Print the inputs the part reads (one path per line) and stop: what a driver copies to
    /// the machine that builds it
    #[arg(help_heading = "Building in parts", long, requires = "part")]
    list_inputs: bool,
    /// Print the byte ranges of its inputs the part reads (`PATH START END` per line, END
    /// excluded or `end`: to the file's end; `PATH 0 end`: read whole) and stop: for a LAZ input of which it
    /// reads some chunks, the header, those chunks and the chunk table, found in a copy that
    /// holds at least the header and the chunk table (a driver fetches those first)
    #[arg(
        help_heading = "Building in parts",
        long,
        requires = "part",
        conflicts_with = "list_inputs"
    )]
    list_ranges: bool,
    /// Run one of the plan's scatter tasks (an index, or auto as for --part) into the parts'
    /// folder given by -o: the chunks of the LAZ inputs that several parts read, each
    /// decompressed once, its records sorted into the parts' files there (`exchange/`), for
    /// parts built with --exchanged
    #[arg(
        help_heading = "Building in parts",
        long,
        requires = "plan",
        conflicts_with = "part",
        value_name = "I|auto"
    )]
    scatter: Option<String>,
    /// Build the part from what every scatter task of the plan wrote in its folder, instead of
    /// decompressing the chunks it shares with other parts (`myriad slurm` runs the scatter
    /// tasks first and builds its parts so)
    #[arg(help_heading = "Building in parts", long, requires = "part")]
    exchanged: bool,
    /// Replace an existing output
    #[arg(long)]
    force: bool,
    /// Print the summary as one JSON object
    #[arg(long)]
    json: bool,
}

pub fn convert(a: ConvertArgs) -> Result<()> {
    if let Some(d) = a.append.as_ref().filter(|d| myriad_format::s3::is_s3(d)) {
        bail!(
            "--append {}: a dataset on S3 is not changed in place (copy it here, append, copy it \
             back)",
            d.display()
        );
    }
    if let Some(d) = &a.append {
        return append(&a, d);
    }
    if let Some(plan) = &a.plan {
        let step = match (&a.part, &a.scatter) {
            (Some(i), _) => crate::partition::Step::Part(i, a.exchanged),
            (None, Some(t)) => crate::partition::Step::Scatter(t),
            (None, None) => crate::partition::Step::Whole,
        };
        return crate::partition::convert_planned(
            plan,
            step,
            crate::partition::List {
                inputs: a.list_inputs,
                ranges: a.list_ranges,
            },
            &a.output.clone().unwrap_or_default(),
            a.build.threads,
            a.json,
        );
    }
    let output = a.output.clone().expect("clap: --output or --append");
    let staged = myriad_build::staged::stage(&a.inputs, &output, a.force)?;
    let o = convert_options(&a, &staged)?;
    let bar = Bar::new();
    let s = convert::convert(&staged.inputs, &o, &bar)?;
    bar.clear();
    staged.finish()?;
    print_converted(&a, &output, &s);
    Ok(())
}

/// `convert`'s options: the build's (checked), the staged output and inputs' names.
fn convert_options(
    a: &ConvertArgs,
    staged: &myriad_build::staged::Staged,
) -> Result<ConvertOptions> {
    let structure = a.build.structure()?;
    let mut o = ConvertOptions::new(&staged.output);
    o.force = a.force;
    o.structure = structure;
    if let Some(m) = a.build.memory {
        o.memory = m;
    }
    if let Some(t) = a.build.threads {
        if t == 0 {
            bail!("--threads must be at least 1");
        }
        o.threads = t;
        global_threads(t);
    }
    o.precision = a.build.precision;
    o.params.capacity = a.build.capacity;
    o.fanout = a.build.fanout.map(|n| n as usize);
    o.grid = a.build.grid.map(|k| k as usize);
    o.open = a.build.open_options();
    o.recorded_as = staged.copied.clone();
    Ok(o)
}

/// What a build did: its summary lines, or one JSON object with `--json`.
fn print_converted(a: &ConvertArgs, output: &Path, s: &convert::Summary) {
    let rate = s.points as f64 / s.seconds;
    let bpp = s.bytes as f64 / s.points as f64;
    if a.json {
        crate::progress::print_json(json!({
            "output": output.display().to_string(),
            "points": s.points, "nodes": s.nodes, "depth": s.depth, "chunks": s.chunks,
            "seconds": s.seconds, "points_per_second": rate, "bytes": s.bytes,
            "bytes_per_point": bpp, "skipped_non_finite": s.skipped_non_finite,
            "trimmed": s.trimmed, "not_transformed": s.not_transformed,
            "phases": s.phases.iter().map(|p| json!({
                "phase": p.name, "seconds": p.seconds, "cpu_seconds": p.cpu_seconds,
            })).collect::<Vec<_>>(),
        }));
        return;
    }
    println!("{}", output.display());
    println!("  points      {}", thousands(s.points));
    println!("  nodes       {} (depth {})", thousands(s.nodes), s.depth);
    println!(
        "  time        {:.2} s, {:.2} M points/s ({})",
        s.seconds,
        rate / 1e6,
        s.phases
            .iter()
            .map(|p| format!("{} {:.2} s", p.name, p.seconds))
            .collect::<Vec<_>>()
            .join(", ")
    );
    println!(
        "  size        {} bytes, {:.2} bytes per point",
        thousands(s.bytes),
        bpp
    );
    print_memory_and_skipped(s.skipped_non_finite);
    if s.trimmed > 0 {
        println!(
            "  trimmed     {} outside placement boxes",
            thousands(s.trimmed)
        );
    }
    if s.not_transformed > 0 {
        println!(
            "  dropped     {} that do not transform into {} (outside its domain, or a grid \
             PROJ lacks there)",
            thousands(s.not_transformed),
            a.build.to_crs.as_deref().unwrap_or("the target CRS")
        );
    }
}

/// `convert NEW... --append DATASET`: the scans added in place (the dataset verified before it
/// replaces the old one).
fn append(a: &ConvertArgs, dataset: &Path) -> Result<()> {
    let open = a.build.open_options();
    // Scans added to a dataset move into its CRS: --to-crs may only name that one.
    if let Some(to) = &a.build.to_crs {
        let want = myriad_io::proj::Crs::new(to)
            .and_then(|c| c.wkt())
            .map_err(|e| anyhow::anyhow!("--to-crs {e}"))?;
        let has = Dataset::open_stored(dataset)?.meta.crs.clone();
        if has.as_deref() != Some(want.as_str()) {
            bail!(
                "--to-crs {to}: {} is in another coordinate system ({}); scans added to it are \
                 moved into its own: give that one",
                dataset.display(),
                has.map_or("none".into(), |c| myriad_measure::crs::describe(&c).line())
            );
        }
    }
    if let Some(t) = a.build.threads {
        global_threads(t);
    }
    let bar = Bar::new();
    let memory = a.build.memory.unwrap_or_else(convert::machine_memory);
    let s = myriad_build::append::append(dataset, &a.inputs, &open, memory, &bar)?;
    bar.clear();
    if a.json {
        crate::progress::print_json(json!({
            "dataset": dataset.display().to_string(), "added": s.added, "points": s.points,
            "nodes_rebuilt": s.rebuilt, "nodes_copied": s.copied,
            "cut_level": s.cut, "cells_rebuilt": s.cells_rebuilt, "cells": s.cells,
            "levels_grown": s.grown,
            "seconds": s.seconds, "bytes": s.bytes,
            "skipped_non_finite": s.skipped_non_finite,
        }));
        return Ok(());
    }
    println!("{}", dataset.display());
    println!(
        "  added       {} points, now {} (verified: {} nodes)",
        thousands(s.added),
        thousands(s.points),
        thousands(s.nodes)
    );
    println!(
        "  nodes       {} rebuilt, {} copied as they were (cut at level {}: {} of {} cells rebuilt{})",
        thousands(s.rebuilt),
        thousands(s.copied),
        s.cut,
        s.cells_rebuilt,
        s.cells,
        if s.grown > 0 {
            format!(
                "; the root grew by {} level{}",
                s.grown,
                if s.grown == 1 { "" } else { "s" }
            )
        } else {
            String::new()
        }
    );
    println!("  time        {:.2} s", s.seconds);
    print_memory_and_skipped(s.skipped_non_finite);
    Ok(())
}

pub(crate) fn parse_box(s: &str) -> Result<Aabb, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("\"{s}\": expected minx,miny,minz,maxx,maxy,maxz"))?;
    if v.len() != 6 {
        return Err(format!("\"{s}\": expected 6 numbers, got {}", v.len()));
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Err(format!("\"{s}\": expected 6 finite numbers"));
    }
    if (0..3).any(|a| v[a] > v[a + 3]) {
        return Err(format!("\"{s}\": a minimum is above its maximum"));
    }
    Ok(Aabb::new([v[0], v[1], v[2]], [v[3], v[4], v[5]]))
}

#[derive(Args)]
pub struct ExtractArgs {
    /// The dataset (.myr)
    dataset: PathBuf,
    /// Output: .las, .laz (the input's point format when it was LAS/LAZ) or .ply
    #[arg(short, long)]
    output: PathBuf,
    /// Only points in this box: minx,miny,minz,maxx,maxy,maxz
    #[arg(long = "box", value_parser = parse_box, allow_hyphen_values = true)]
    bbox: Option<Aabb>,
    /// Level of detail: points at about this spacing [default: every original point]
    #[arg(long)]
    spacing: Option<f64>,
    #[command(flatten)]
    filter: crate::measure::FilterArgs,
    /// Replace an existing output
    #[arg(long)]
    force: bool,
}

pub fn extract(a: ExtractArgs) -> Result<()> {
    if let Some(s) = a.spacing
        && !(s.is_finite() && s > 0.0)
    {
        bail!("--spacing must be a positive length");
    }
    myriad_io::atomic::refuse_input_as_output(&a.output, &[&a.dataset])?;
    let ds = Dataset::open(&a.dataset)?;
    let s = extract::extract(
        &ds,
        &a.output,
        &ExtractOptions {
            bbox: a.bbox,
            spacing: a.spacing,
            filter: a.filter.filter()?,
            force: a.force,
            ..Default::default()
        },
    )?;
    for d in &s.damage {
        eprintln!("warning: {}", ds.damage_error(d));
    }
    println!(
        "{}: {} points from {} nodes",
        a.output.display(),
        thousands(s.points),
        thousands(s.nodes_read)
    );
    if let Some(d) = s.damage.first() {
        bail!(
            "{} ({} damaged page{} skipped; {} lacks their points)",
            ds.damage_error(d),
            s.damage.len(),
            if s.damage.len() == 1 { "" } else { "s" },
            a.output.display()
        );
    }
    Ok(())
}

#[derive(Args)]
pub struct VerifyArgs {
    /// Datasets (.myr)
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
}

pub fn verify(a: VerifyArgs) -> Result<()> {
    let mut bad = 0;
    let mut first = None;
    for path in &a.datasets {
        // The pages as stored, whatever edits are kept beside them.
        let ds = Dataset::open_stored(path)?;
        // A file of its missing or replaced is one line, not a line per page in it.
        ds.check_files()?;
        let bar = ProgressBar::new(ds.meta.points);
        let r = extract::verify(&ds, |n| bar.inc(n));
        bar.finish_and_clear();
        // Pages of two versions are no verdict on either.
        ds.check_unchanged()?;
        for d in &r.damage {
            println!("damaged: {}", ds.damage_error(d));
        }
        if r.damage.is_empty() {
            let files = match ds.files().len() {
                0 => String::new(),
                n => format!(" (in {} files: its own and {n} it links)", n + 1),
            };
            println!(
                "{}: ok, {} nodes, {} points{files}, every checksum and invariant holds",
                path.display(),
                thousands(r.nodes),
                thousands(r.points)
            );
        } else {
            println!("{}: {} damaged", path.display(), r.damage.len());
            bad += 1;
            first.get_or_insert((ds.damage_error(&r.damage[0]), r.damage.len()));
        }
    }
    // The error line names the first damaged page; stdout lists them all.
    if let Some((e, n)) = first {
        bail!(
            "{e} ({n} damaged in this dataset; {bad} of {} datasets damaged)",
            a.datasets.len()
        );
    }
    Ok(())
}
