//! `myriad convert`, `extract`, `verify`, and `info` on a dataset.

use anyhow::{Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use myriad_build::convert::{self, ConvertOptions};
use myriad_build::extract::{self, ExtractOptions};
use myriad_core::Aabb;
use myriad_format::Dataset;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::info::{print_bounds, print_crs, thousands};

#[derive(Args)]
pub struct ConvertArgs {
    /// Input point clouds (LAS, LAZ, E57, PLY, PCD, PTS/XYZ/CSV/TXT); several merge into one dataset
    #[arg(required_unless_present = "plan", conflicts_with = "plan")]
    inputs: Vec<PathBuf>,
    /// The dataset to write (.myr)
    #[arg(
        short,
        long,
        required_unless_present_any = ["append", "list_inputs"],
        conflicts_with = "append"
    )]
    output: Option<PathBuf>,
    /// Add the inputs to this dataset (octree or layered) instead: the parts of the tree they
    /// fall in are rebuilt, the rest kept; replaced only when complete, then verified
    #[arg(long, value_name = "DATASET")]
    append: Option<PathBuf>,
    /// Build from a plan (`myriad plan`): its inputs and parameters; with --part, one part into
    /// the folder given by -o, else the whole plan on this machine
    #[arg(long, value_name = "PLAN", conflicts_with = "append")]
    plan: Option<PathBuf>,
    /// The part of the plan to build: an index, or auto (SLURM_ARRAY_TASK_ID,
    /// JOB_COMPLETION_INDEX or AWS_BATCH_JOB_ARRAY_INDEX)
    #[arg(long, requires = "plan", value_name = "I|auto")]
    part: Option<String>,
    /// Print the inputs the part reads (one path per line) and stop: what a driver copies to
    /// the machine that builds it
    #[arg(long, requires = "part")]
    list_inputs: bool,
    #[command(flatten)]
    build: BuildArgs,
    /// Replace an existing output
    #[arg(long)]
    force: bool,
    /// Print the summary as one JSON object
    #[arg(long)]
    json: bool,
}

/// The options a build takes, in `convert` and `plan`.
#[derive(Args)]
pub struct BuildArgs {
    /// Hierarchy to build: octree (nested octree of MOSPTs, 003), layered (octree with adaptive
    /// n-tree representatives and contours, 000), kd (balanced kd-tree, 002), mwkd (multi-way
    /// kd-tree of aggregates drawn as splats, 004)
    #[arg(long, default_value = "octree")]
    pub(crate) structure: String,
    /// Memory budget: 512MB, 2GB, or bytes [default: a quarter of RAM, at most 8GB]
    #[arg(long, value_parser = convert::parse_size)]
    pub(crate) memory: Option<u64>,
    /// Worker threads [default: all cores]
    #[arg(long)]
    pub(crate) threads: Option<usize>,
    /// Quantization step of float inputs (PLY, PCD, E57, text), in their units; LAS/LAZ keep their scale
    #[arg(long, default_value_t = 0.0001)]
    pub(crate) precision: f64,
    /// Most points per node
    #[arg(long, default_value_t = convert::DEFAULT_CAPACITY)]
    pub(crate) capacity: usize,
    /// Column layout of text inputs, e.g. x,y,z,intensity,r,g,b
    #[arg(long)]
    pub(crate) columns: Option<String>,
    /// Ignore SCAN.placement files next to inputs (see README)
    #[arg(long)]
    pub(crate) no_placement: bool,
}

impl BuildArgs {
    /// The structure named, and the capacity checked.
    pub(crate) fn structure(&self) -> Result<convert::Structure> {
        if self.capacity < 64 {
            bail!("--capacity {} is too small (at least 64)", self.capacity);
        }
        Ok(match self.structure.as_str() {
            "nested-octree" => convert::Structure::Octree,
            s => convert::Structure::parse(s).map_err(|e| anyhow::anyhow!("--structure: {e}"))?,
        })
    }

    /// How the inputs are opened.
    pub(crate) fn open_options(&self) -> myriad_io::OpenOptions {
        myriad_io::OpenOptions {
            columns: self.columns.clone(),
            sidecar_placements: !self.no_placement,
            ..Default::default()
        }
    }
}

/// A progress bar per phase on a terminal (indicatif draws nothing when stderr is not one).
pub(crate) struct Bar {
    bar: Mutex<Option<ProgressBar>>,
}

impl Bar {
    pub(crate) fn new() -> Bar {
        Bar {
            bar: Mutex::new(None),
        }
    }

    pub(crate) fn clear(&self) {
        if let Some(b) = self.bar.lock().unwrap().take() {
            b.finish_and_clear();
        }
    }
}

impl convert::Report for Bar {
    fn phase(&self, name: &'static str, total: u64) {
        let b = ProgressBar::new(total);
        let unit = match name {
            "merging" => "nodes",
            "writing" => "steps",
            _ => "points",
        };
        b.set_style(
            ProgressStyle::with_template(&format!(
                "{{prefix:>9}} [{{bar:40}}] {{human_pos}}/{{human_len}} {unit} {{per_sec:0}} ETA {{eta}}"
            ))
            .expect("valid template")
            .progress_chars("=> "),
        );
        b.set_prefix(name);
        if let Some(old) = self.bar.lock().unwrap().replace(b) {
            old.finish_and_clear();
        }
    }
    fn advance(&self, n: u64) {
        if let Some(b) = &*self.bar.lock().unwrap() {
            b.inc(n);
        }
    }
}

pub fn convert(a: ConvertArgs) -> Result<()> {
    if let Some(d) = &a.append {
        return append(&a, d);
    }
    if let Some(plan) = &a.plan {
        return crate::partition::convert_planned(
            plan,
            a.part.as_deref(),
            a.list_inputs,
            &a.output.clone().unwrap_or_default(),
            a.build.threads,
            a.json,
        );
    }
    let output = a.output.clone().expect("clap: --output or --append");
    let structure = a.build.structure()?;
    let mut o = ConvertOptions::new(&output);
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
    o.open.columns = a.build.columns.clone();
    o.open.sidecar_placements = !a.build.no_placement;
    let bar = Bar::new();
    let s = convert::convert(&a.inputs, &o, &bar)?;
    if let Some(b) = bar.bar.lock().unwrap().take() {
        b.finish_and_clear();
    }
    let rate = s.points as f64 / s.seconds;
    let bpp = s.bytes as f64 / s.points as f64;
    if a.json {
        println!(
            "{}",
            json!({
                "output": output.display().to_string(),
                "points": s.points, "nodes": s.nodes, "depth": s.depth, "chunks": s.chunks,
                "seconds": s.seconds, "points_per_second": rate, "bytes": s.bytes,
                "bytes_per_point": bpp, "skipped_non_finite": s.skipped_non_finite,
                "trimmed": s.trimmed,
                "peak_rss_bytes": crate::bench::peak_rss_bytes(),
                "phases": s.phases.iter().map(|(n, t)| json!({"phase": n, "seconds": t})).collect::<Vec<_>>(),
            })
        );
        return Ok(());
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
            .map(|(n, t)| format!("{n} {t:.2} s"))
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
    Ok(())
}

/// `convert NEW... --append DATASET`: the scans added in place, then the dataset verified.
fn append(a: &ConvertArgs, dataset: &Path) -> Result<()> {
    let open = a.build.open_options();
    if let Some(t) = a.build.threads {
        global_threads(t);
    }
    let bar = Bar::new();
    let memory = a.build.memory.unwrap_or_else(convert::default_memory);
    let s = myriad_build::append::append(dataset, &a.inputs, &open, memory, &bar)?;
    bar.clear();
    // Read back whole: every page's checksum, the counts, the invariants.
    let ds = Dataset::open(dataset)?;
    let r = extract::verify(&ds, |_| {});
    if let Some(d) = r.damage.first() {
        bail!(
            "{} (after appending: please report this)",
            ds.damage_error(d)
        );
    }
    if a.json {
        println!(
            "{}",
            json!({
                "dataset": dataset.display().to_string(), "added": s.added, "points": s.points,
                "nodes_rebuilt": s.rebuilt, "nodes_copied": s.copied,
                "cut_level": s.cut, "cells_rebuilt": s.cells_rebuilt, "cells": s.cells,
                "levels_grown": s.grown,
                "seconds": s.seconds, "bytes": s.bytes,
                "skipped_non_finite": s.skipped_non_finite,
                "peak_rss_bytes": crate::bench::peak_rss_bytes(),
            })
        );
        return Ok(());
    }
    println!("{}", dataset.display());
    println!(
        "  added       {} points, now {} (verified: {} nodes)",
        thousands(s.added),
        thousands(s.points),
        thousands(r.nodes)
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

/// LAZ decompression runs on rayon's global pool: it gets the build's number of threads.
pub(crate) fn global_threads(t: usize) {
    rayon::ThreadPoolBuilder::new()
        .num_threads(t.max(1))
        .build_global()
        .ok();
}

/// A build summary's last lines: peak memory, and the points skipped for NaN or infinite
/// coordinates (when there were any).
pub(crate) fn print_memory_and_skipped(skipped: u64) {
    if let Some(p) = crate::bench::peak_rss_bytes() {
        println!("  memory      {:.0} MB peak resident", p as f64 / 1e6);
    }
    if skipped > 0 {
        println!(
            "  skipped     {} with NaN/infinite coordinates",
            thousands(skipped)
        );
    }
}

/// Is `path` a dataset (by its magic)?
pub fn is_dataset(path: &Path) -> bool {
    use std::io::Read;
    // Over HTTP only datasets are read.
    if myriad_format::remote::is_url(path) {
        return true;
    }
    let mut head = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && &head == myriad_format::MAGIC
}

pub fn info(path: &Path, as_json: bool) -> Result<()> {
    let ds = Dataset::open(path)?;
    let m = &ds.meta;
    // Per level: nodes, points, and the finest spacing; from the metadata (one read however
    // large the dataset), or by walking every hierarchy page where a dataset written before
    // the table was kept there lacks it.
    let (levels, damage) = if m.levels.is_empty() {
        let (nodes, damage) = ds.nodes();
        for d in &damage {
            eprintln!("warning: {}", ds.damage_error(d));
        }
        (myriad_format::Level::table(&nodes), Some(damage.len()))
    } else {
        (m.levels.clone(), None)
    };
    let bpp = ds.file_length as f64 / m.points.max(1) as f64;
    if as_json {
        println!(
            "{}",
            json!({
                "path": path.display().to_string(),
                "format": "myriad",
                "version": myriad_format::FORMAT_VERSION,
                "points": m.points,
                "nodes": m.nodes,
                "depth": m.depth,
                "structure": m.structure,
                "parameters": m.parameters,
                "bounds": json!({"min": m.bounds.min, "max": m.bounds.max}),
                "root": json!({"min": m.root.min, "max": m.root.max}),
                "scale": m.quantization.scale,
                "offset": m.quantization.offset,
                "crs": m.crs,
                "attributes": m.schema.names(),
                "file_size": ds.file_length,
                "bytes_per_point": bpp,
                "sources": m.sources,
                "levels": levels.iter().map(|l| json!({"level": l.level, "nodes": l.nodes, "points": l.points, "node_size": l.spacing.is_finite().then_some(l.spacing)})).collect::<Vec<_>>(),
                "damaged_hierarchy_pages": damage,
            })
        );
        return Ok(());
    }
    let b = m.bounds;
    println!("{}", path.display());
    println!(
        "  format      Myriad dataset {}",
        myriad_format::FORMAT_VERSION
    );
    println!("  structure   {} {}", m.structure, m.parameters);
    println!("  points      {}", thousands(m.points));
    println!("  nodes       {} (depth {})", thousands(m.nodes), m.depth);
    print_bounds(&b);
    println!("  attributes  {}", m.schema);
    let q = m.quantization;
    println!("  scale       {} {} {}", q.scale[0], q.scale[1], q.scale[2]);
    print_crs(m.crs.as_deref());
    println!(
        "  file size   {} bytes, {:.2} bytes per point",
        thousands(ds.file_length),
        bpp
    );
    println!("  level      nodes         points   node size");
    for l in &levels {
        println!(
            "  {:>5} {:>10} {:>14} {:>11.3}",
            l.level,
            thousands(l.nodes),
            thousands(l.points),
            l.spacing
        );
    }
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
            force: a.force,
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
        let ds = Dataset::open(path)?;
        let bar = ProgressBar::new(ds.meta.points);
        let r = extract::verify(&ds, |n| bar.inc(n));
        bar.finish_and_clear();
        // Pages of two versions are no verdict on either.
        ds.check_unchanged()?;
        for d in &r.damage {
            println!("damaged: {}", ds.damage_error(d));
        }
        if r.damage.is_empty() {
            println!(
                "{}: ok, {} nodes, {} points, every checksum and invariant holds",
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
