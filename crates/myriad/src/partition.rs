//! `myriad plan`, `convert --plan [--part]`, `myriad merge` and `myriad slurm`: a build split
//! into parts that run anywhere (a Slurm array, a Kubernetes indexed job, AWS Batch, a Ray
//! task), then merged.

use anyhow::{Context, Result, bail};
use clap::Args;
use myriad_build::convert;
use myriad_build::partition::slurm::{self, Sbatch, SlurmBuild};
use myriad_build::partition::{self, BuildPlan, PlanOptions};
use serde_json::json;
use std::path::{Path, PathBuf};

use crate::progress::Bar;
use myriad_core::units::thousands;

#[derive(Args)]
pub struct PlanArgs {
    /// Input point clouds (as `convert` takes them)
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// The plan to write (JSON)
    #[arg(short, long)]
    output: PathBuf,
    /// Parts to split the build into (each part takes --memory and --threads; --structure
    /// octree or layered)
    #[arg(long)]
    parts: usize,
    // convert's options: --structure octree or layered only (kd and mwkd build on one machine
    // only); --memory and --threads are each part's.
    #[command(flatten)]
    build: crate::build_options::BuildArgs,
    /// Replace an existing plan
    #[arg(long)]
    force: bool,
    /// Points per chunk instead of what --memory gives (for tests)
    #[arg(help_heading = "Parts", long, hide = true)]
    chunk_points: Option<u64>,
    /// Let each part decompress whole every LAZ input that reaches its cells, instead of
    /// finding, once here, which of each input's chunks meet which part
    #[arg(help_heading = "Parts", long)]
    whole_inputs: bool,
}

/// `PLAN.chunks.json` beside `PLAN.json`: the LAZ inputs' chunk bounds, for the next plan.
fn chunk_cache_path(plan: &Path) -> PathBuf {
    let stem = plan.file_stem().unwrap_or_default().to_string_lossy();
    plan.with_file_name(format!("{stem}.chunks.json"))
}

pub fn plan(a: PlanArgs) -> Result<()> {
    if !a.force && a.output.exists() {
        bail!(
            "{}: output exists (use --force to replace it)",
            a.output.display()
        );
    }
    let structure = a.build.structure()?;
    if a.build.fanout.is_some() || a.build.grid.is_some() {
        bail!("--fanout and --grid are for convert (a plan builds an octree or layered)");
    }
    let defaults = convert::ConvertOptions::new(&a.output);
    let o = PlanOptions {
        parts: a.parts,
        structure,
        params: myriad_build::nested::NestedParams {
            capacity: a.build.capacity,
            ..defaults.params
        },
        memory: a.build.memory.unwrap_or(defaults.memory),
        threads: a.build.threads.unwrap_or(defaults.threads).max(1),
        precision: a.build.precision,
        open: a.build.open_options(),
        chunk_points: a.chunk_points,
        chunks: !a.whole_inputs,
        chunk_cache: Some(chunk_cache_path(&a.output)),
    };
    // Parts on other machines read the inputs by these paths: absolute, as a shared
    // filesystem mounts them.
    let inputs = a
        .inputs
        .iter()
        .map(|p| std::path::absolute(p).with_context(|| format!("{}", p.display())))
        .collect::<Result<Vec<_>>>()?;
    let p = partition::plan(&inputs, &o)?;
    let text = serde_json::to_string_pretty(&p.to_json())?;
    let file = myriad_io::atomic::AtomicFile::create(&a.output, a.force)?;
    std::fs::write(file.temp_path(), text + "\n")
        .with_context(|| file.temp_path().display().to_string())?;
    file.commit()?;
    let declared: u64 = p.inputs.iter().map(|i| i.points).sum();
    println!("{}", a.output.display());
    println!(
        "  inputs      {} ({} points)",
        p.inputs.len(),
        thousands(declared)
    );
    println!(
        "  parts       {} (cells of level {}; chunks at level {}, at most {} points)",
        p.parts.len(),
        p.partition_level,
        p.chunk_level,
        thousands(p.chunk_points)
    );
    if !p.chunked.is_empty() {
        let chunks: u64 = p.chunked.iter().map(|c| c.chunks as u64).sum();
        println!(
            "  chunked     {} LAZ inputs met by several parts ({} chunks): each part reads the chunks that meet its cells",
            p.chunked.len(),
            thousands(chunks)
        );
        let shared: usize = p.scatter_tasks().iter().flatten().map(|t| t.1.len()).sum();
        println!(
            "  scatter     {} tasks decompress the {} chunks parts read once each, before the parts (convert --plan {} --scatter T -o PARTS/, T = 0..{}; then --part I --exchanged)",
            p.parts.len(),
            thousands(shared as u64),
            a.output.display(),
            p.parts.len() - 1
        );
    }
    for (i, (cells, n)) in p.parts.iter().enumerate() {
        let chunks: usize = p.chunked.iter().map(|c| c.of(i).len()).sum();
        println!(
            "  part {i:<6} {} cells, about {} points, {} inputs{}",
            cells.len(),
            thousands(*n),
            p.inputs_of(Some(i)).len(),
            if p.chunked.is_empty() {
                String::new()
            } else {
                format!(" ({chunks} chunks of the chunked ones)")
            }
        );
    }
    println!(
        "  next        myriad convert --plan {} --part I -o PARTS/ (I = 0..{}), then myriad merge {} PARTS/ -o OUT.myr",
        a.output.display(),
        p.parts.len() - 1,
        a.output.display()
    );
    Ok(())
}

/// What `convert --plan` builds.
pub enum Step<'a> {
    /// The whole plan on this machine.
    Whole,
    /// `--part I [--exchanged]`.
    Part(&'a str, bool),
    /// `--scatter T`.
    Scatter(&'a str),
}

/// What `convert --plan --part` prints instead of building the part.
pub struct List {
    /// The inputs it reads.
    pub inputs: bool,
    /// Their byte ranges it reads.
    pub ranges: bool,
}

/// `convert --plan PLAN [--part I | --scatter T] -o OUT`: one part or scatter task into the
/// folder OUT, or the whole plan on this machine into the dataset OUT.
pub fn convert_planned(
    plan_path: &Path,
    step: Step,
    list: List,
    output: &Path,
    threads: Option<usize>,
    as_json: bool,
) -> Result<()> {
    let plan = BuildPlan::load(plan_path)?;
    // The threads the plan sized the chunks for, unless told otherwise.
    let threads = threads.unwrap_or(plan.threads);
    crate::progress::global_threads(threads);
    let bar = Bar::new();
    let (part, exchanged) = match step {
        Step::Part(i, exchanged) => (i, exchanged),
        Step::Scatter(t) => {
            return scatter(
                &plan,
                plan_path,
                partition::part_index(t, "--scatter")?,
                output,
                as_json,
            );
        }
        Step::Whole => {
            let o = plan.convert_options(None, output, threads);
            let s = convert::convert(&plan.inputs_of(None), &o, &bar)?;
            bar.clear();
            if as_json {
                crate::progress::print_json(
                    json!({"output": output.display().to_string(), "points": s.points,
                       "nodes": s.nodes, "seconds": s.seconds, "bytes": s.bytes,}),
                );
            } else {
                println!("{}", output.display());
                println!("  points      {}", thousands(s.points));
                println!("  nodes       {} (depth {})", thousands(s.nodes), s.depth);
                println!("  time        {:.2} s", s.seconds);
            }
            return Ok(());
        }
    };
    let index = partition::part_index(part, "--part")?;
    if list.inputs || list.ranges {
        return list_part(&plan, index, list.ranges);
    }
    let s = partition::build_part(&plan, index, output, threads, exchanged, &bar)?;
    bar.clear();
    print_part(&plan, plan_path, index, output, exchanged, &s, as_json);
    Ok(())
}

/// `--list-inputs` or `--list-ranges`: what part `index` reads, a line each.
fn list_part(plan: &BuildPlan, index: usize, ranges: bool) -> Result<()> {
    if index >= plan.parts.len() {
        bail!(
            "--part {index}: the plan has parts 0 to {}",
            plan.parts.len() - 1
        );
    }
    for p in plan.inputs_of(Some(index)) {
        if !ranges {
            println!("{}", p.display());
            continue;
        }
        for (a, b) in partition::ranges_read(plan, index, &p)? {
            match b {
                Some(b) => println!("{} {a} {b}", p.display()),
                None => println!("{} {a} end", p.display()),
            }
        }
    }
    Ok(())
}

/// What a part built: its dataset and tops, points, what it read, nodes, time.
fn print_part(
    plan: &BuildPlan,
    plan_path: &Path,
    index: usize,
    output: &Path,
    exchanged: bool,
    s: &partition::PartSummary,
    as_json: bool,
) {
    let (myr, tops) = partition::part_paths(output, index);
    let opened = s.inputs.iter().filter(|i| i.is_some()).count();
    let read: u64 = s.inputs.iter().flatten().map(|i| i.1).sum();
    if as_json {
        crate::progress::print_json(
            json!({"part": index, "dataset": (s.points > 0).then(|| myr.display().to_string()),
                   "tops": tops.display().to_string(), "points": s.points, "nodes": s.nodes,
                   "inputs_read": opened, "points_read": read, "seconds": s.seconds, "bytes": s.bytes,}),
        );
        return;
    }
    println!(
        "part {index} of {} ({})",
        plan.parts.len(),
        plan_path.display()
    );
    if s.points > 0 {
        println!("  dataset     {}", myr.display());
    } else {
        println!("  dataset     none: its cells hold no points");
    }
    println!("  tops        {}", tops.display());
    println!(
        "  points      {} from {} of {} inputs",
        thousands(s.points),
        opened,
        plan.inputs.len()
    );
    println!("  read        {} points", thousands(read));
    if exchanged {
        let from: u64 = (plan.chunked.iter())
            .filter_map(|c| s.inputs[c.input])
            .map(|i| i.1)
            .sum();
        println!(
            "  exchanged   {} points of them from the scatter tasks",
            thousands(from)
        );
    }
    println!("  nodes       {}", thousands(s.nodes));
    println!("  time        {:.2} s", s.seconds);
    crate::progress::print_memory_and_skipped(s.skipped_non_finite);
}

/// `convert --plan PLAN --scatter T -o DIR`.
fn scatter(
    plan: &BuildPlan,
    plan_path: &Path,
    task: usize,
    dir: &Path,
    as_json: bool,
) -> Result<()> {
    let bar = Bar::new();
    let s = partition::scatter(plan, task, dir, &bar)?;
    bar.clear();
    let written: u64 = s.routed.iter().sum();
    if as_json {
        crate::progress::print_json(
            json!({"scatter": task, "points_read": s.read, "points_written": written,
                   "outside": s.outside, "per_part": s.routed, "seconds": s.seconds,
                   "folder": partition::exchange_dir(dir).display().to_string(),}),
        );
        return Ok(());
    }
    println!(
        "scatter task {task} of {} ({})",
        plan.parts.len(),
        plan_path.display()
    );
    println!("  folder      {}", partition::exchange_dir(dir).display());
    println!("  read        {} points", thousands(s.read));
    println!(
        "  written     {} points for {} parts",
        thousands(written),
        s.routed.iter().filter(|&&n| n > 0).count()
    );
    if s.outside > 0 {
        println!(
            "  outside     {} points in no part's cells",
            thousands(s.outside)
        );
    }
    println!("  time        {:.2} s", s.seconds);
    crate::progress::print_memory_and_skipped(0);
    Ok(())
}

#[derive(Args)]
pub struct MergeArgs {
    /// The plan the parts were built from
    plan: PathBuf,
    /// The folder the parts were written to
    parts: PathBuf,
    /// The dataset to write (.myr)
    #[arg(short, long)]
    output: PathBuf,
    /// Replace an existing output
    #[arg(long)]
    force: bool,
    /// Copy the parts' pages into the output, one file that stands alone (by default it links
    /// the parts' files where they are: keep them there)
    #[arg(long)]
    single_file: bool,
    /// Worker threads [default: all cores]
    #[arg(long, value_parser = crate::build_options::parse_threads)]
    threads: Option<usize>,
    /// Print the summary as one JSON object
    #[arg(long)]
    json: bool,
}

pub fn merge(a: MergeArgs) -> Result<()> {
    let plan = BuildPlan::load(&a.plan)?;
    let threads = a
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let bar = Bar::new();
    let s = partition::merge(
        &plan,
        &a.parts,
        &a.output,
        a.force,
        a.single_file,
        threads,
        &bar,
    )?;
    bar.clear();
    if a.json {
        crate::progress::print_json(
            json!({"output": a.output.display().to_string(), "points": s.points,
                   "nodes": s.nodes, "pages_copied": if a.single_file { s.copied } else { 0 },
                   "pages_linked": if a.single_file { 0 } else { s.copied },
                   "files_linked": s.linked, "nodes_built": s.built,
                   "seconds": s.seconds, "bytes": s.bytes,}),
        );
        return Ok(());
    }
    println!("{}", a.output.display());
    println!(
        "  points      {} from {} parts",
        thousands(s.points),
        plan.parts.len()
    );
    println!(
        "  nodes       {} ({} pages {} the parts, {} built above level {})",
        thousands(s.nodes),
        thousands(s.copied),
        if a.single_file {
            "copied from"
        } else {
            "left in"
        },
        thousands(s.built),
        plan.partition_level
    );
    if !a.single_file {
        println!(
            "  files       {} (its own, {} bytes) and the {} part files it links: keep them where they are",
            a.output.display(),
            thousands(s.bytes),
            s.linked
        );
    }
    println!("  time        {:.2} s", s.seconds);
    crate::progress::print_memory_and_skipped(0);
    Ok(())
}

#[derive(Args)]
pub struct SlurmArgs {
    /// The plan (from `myriad plan`)
    plan: PathBuf,
    /// The dataset the merge writes (.myr), on a filesystem every node shares
    #[arg(short, long)]
    output: PathBuf,
    /// Where the parts go [default: OUTPUT with ".parts" added]
    #[arg(long)]
    parts_dir: Option<PathBuf>,
    /// Wait for the merge and exit 1 if a part or the merge failed
    #[arg(long)]
    wait: bool,
    /// Print the sbatch commands instead of running them
    #[arg(long)]
    dry_run: bool,
    /// The myriad program as the compute nodes see it [default: this one's path]
    #[arg(long)]
    myriad: Option<PathBuf>,
    /// Let each part decompress the LAZ chunks it shares with other parts itself, instead of a
    /// scatter job decompressing each once before the parts (`convert --plan ... --scatter`)
    #[arg(long)]
    no_exchange: bool,
    /// Options for every sbatch call, after `--` (e.g. -- --partition=cpu --mem=8G)
    #[arg(last = true)]
    sbatch: Vec<String>,
}

pub fn slurm(a: SlurmArgs) -> Result<()> {
    let plan = BuildPlan::load(&a.plan)?;
    let abs = |p: &Path| std::path::absolute(p).with_context(|| p.display().to_string());
    let output = abs(&a.output)?;
    let parts = match &a.parts_dir {
        Some(d) => abs(d)?,
        None => {
            let mut s = output.clone().into_os_string();
            s.push(".parts");
            PathBuf::from(s)
        }
    };
    if !a.dry_run {
        std::fs::create_dir_all(&parts).with_context(|| parts.display().to_string())?;
    }
    let build = SlurmBuild {
        plan: abs(&a.plan)?,
        output,
        parts,
        myriad: match a.myriad {
            Some(p) => p,
            None => std::env::current_exe().context("the path of this program")?,
        },
        exchange: !a.no_exchange,
        sbatch: a.sbatch,
    };
    let mut sbatch = Sbatch {
        dry_run: a.dry_run,
        lines: Vec::new(),
    };
    let submitted = slurm::submit(&plan, &build, &mut sbatch);
    for line in &sbatch.lines {
        println!("{line}");
    }
    let jobs = submitted?;
    if a.dry_run {
        return Ok(());
    }
    let (n, parts) = (jobs.tasks, build.parts.display());
    if let Some(job) = &jobs.scatter {
        println!(
            "scatter job {job} ({n} array tasks: the LAZ chunks parts share, decompressed once)"
        );
    }
    println!(
        "parts  job {} ({n} array tasks), logs in {parts}",
        jobs.parts
    );
    println!(
        "merge  job {} (after every part succeeds) -> {}",
        jobs.merge,
        build.output.display()
    );
    if a.wait {
        slurm::wait(&jobs, &build.parts, &build.output)?;
        println!("merged {}", build.output.display());
    }
    Ok(())
}
