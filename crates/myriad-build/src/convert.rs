//! `convert`: the whole out-of-core build of a dataset, in any [`Structure`].
//!
//! 1. [`distribute`](crate::distribute): every input read once, points scattered to chunks on disk.
//! 2. Chunks built in parallel (one per thread, `chunks.rs`): each chunk's subtree
//!    ([`crate::nested::build_subtree_with`]; kd and mwkd first group the chunks by count
//!    ([`crate::kd::group_chunks`]) and build each group's subtree:
//!    [`crate::kd::build_subtree_with`], [`crate::mwkd::build_subtree_with`]); every node but
//!    the subtree's root is compressed and appended to the dataset as soon as it is built. The
//!    roots are spilled to disk, because the levels above may still take points from them.
//! 3. The levels above, bottom-up, families in parallel: a parent takes its representatives from
//!    its children ([`crate::nested::take_up`], [`crate::kd::take_up`]; mwkd: aggregates of them,
//!    [`crate::mwkd::take_up`]); the children are then final and written; the parent is spilled
//!    and becomes a child one level up (`above.rs`, shared with the merge of a partitioned
//!    build).
//! 4. The writer adds the hierarchy pages, metadata and header, and renames the file.
//!
//! Memory: the distribution's write buffers, then per thread one chunk or group (at most
//! `chunk_points` points, several copies while its subtree is built) or one family (at most nine
//! nodes of at most `capacity` points). [`plan`] sizes both from `--memory`.

use crate::above::Above;
use crate::distribute::{self, DistributeOptions, SPILL_PREFIX};
use crate::nested::{BuiltNode, NestedParams};
pub use crate::report::{Report, Silent};
pub use crate::structure::Structure;
use myriad_core::{Aabb, Error, Result};
use myriad_format::{DatasetWriter, Metadata, Quantization};
use myriad_io::OpenOptions;
use std::path::{Path, PathBuf};
use std::time::Instant;

mod chunks;
use chunks::Chunks;

pub const DEFAULT_CAPACITY: usize = 1 << 16;
pub const DEFAULT_INNER_DEPTH: u32 = 7;
pub const DEFAULT_MAX_LEVEL: u32 = 20;
/// Spill files of rows (points not on a LAS input's grid) are compressed when they would exceed
/// this (8 GB, about 150 M points).
pub const SPILL_COMPRESS_ABOVE: u64 = 8 << 30;

#[derive(Debug, Clone)]
pub struct ConvertOptions {
    pub structure: Structure,
    pub output: PathBuf,
    pub force: bool,
    /// Memory budget in bytes.
    pub memory: u64,
    /// Worker threads.
    pub threads: usize,
    /// Quantization step for inputs whose coordinates are floats (not LAS/LAZ), in their units.
    pub precision: f64,
    pub params: NestedParams,
    pub open: OpenOptions,
    /// Points per chunk, instead of what the memory budget gives (for tests: many chunks from
    /// a small input).
    pub chunk_points: Option<u64>,
    /// A build fixed by a plan (a part, or the whole plan on one machine): see
    /// [`crate::partition`].
    pub planned: Option<Planned>,
    /// Snapshots of the dataset as it is built, for a viewer or server to show meanwhile
    /// (octree and layered builds; [`crate::growing`]).
    pub growing: Option<std::sync::Arc<crate::growing::Growing>>,
    /// `mwkd`: the fan-out `N` (2..=8; `None`: the one that makes the tree's depth whole,
    /// [`crate::mwkd::fanout_for`]) and the clustering grid's `K` ([`crate::mwkd::MwkdParams`]).
    pub fanout: Option<usize>,
    pub grid: Option<usize>,
    /// Inputs recorded in the dataset's sources under another name than the path read (an
    /// `s3://` input copied to a local folder is recorded as its URL).
    pub recorded_as: std::collections::HashMap<PathBuf, String>,
}

/// What a plan fixes for a build: the grid (root cube, chunk level, schema, the cells a part
/// keeps), the quantization, the CRS and LAS header, and what the dataset's parameters record.
#[derive(Debug, Clone)]
pub struct Planned {
    pub grid: distribute::Grid,
    pub quantization: Quantization,
    pub crs: Option<String>,
    pub las_header: Option<Vec<u8>>,
    /// Keep a copy of the nodes of this level as they are before the levels above take their
    /// points ([`Summary::tops`]): what a merge builds the levels above a part from.
    pub tops_level: Option<u32>,
    /// Added to the dataset's parameters (which plan and part it was built from).
    pub parameters: serde_json::Value,
}

impl ConvertOptions {
    pub fn new(output: &Path) -> ConvertOptions {
        ConvertOptions {
            structure: Structure::Octree,
            output: output.to_path_buf(),
            force: false,
            memory: default_memory(),
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            precision: 1e-4,
            params: NestedParams {
                capacity: DEFAULT_CAPACITY,
                inner_depth: DEFAULT_INNER_DEPTH,
                max_level: DEFAULT_MAX_LEVEL,
                ntree: false,
            },
            open: OpenOptions {
                sidecar_placements: true,
                ..Default::default()
            },
            chunk_points: None,
            planned: None,
            growing: None,
            fanout: None,
            grid: None,
            recorded_as: Default::default(),
        }
    }
}

/// The default budget of a build: [`DEFAULT_MEMORY`], or a quarter of the machine's memory
/// where that is less (at least [`MIN_MEMORY`]).
pub fn default_memory() -> u64 {
    machine_memory().clamp(MIN_MEMORY, DEFAULT_MEMORY)
}

/// A build's default budget, 1 GB: what PotreeConverter 2 takes for about 40 M points (352 MB
/// to 1.3 GB on the corpus of docs/guide/benchmarks-build.md). Scans whose points fit in half of
/// it are built from memory; larger ones keep what the write buffers hold and spill the rest
/// ([`crate::distribute`]): the build peaks near 500 MB whatever the scan (a 50 M point city in
/// 544-578 MB, 6 % slower than from memory in 2.8 GB). `--memory` gives more.
pub const DEFAULT_MEMORY: u64 = 1 << 30;

/// A quarter of the machine's memory, at most 8 GB (1 GB when it cannot be read): the default
/// of `convert --append`, which refuses to go over its budget.
pub fn machine_memory() -> u64 {
    let total = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|m| {
            m.lines()
                .find(|l| l.starts_with("MemTotal:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
        })
        .map(|kb| kb * 1024);
    total.map_or(1 << 30, |t| (t / 4).min(8 << 30))
}

/// Parses a memory size: "512MB", "2GB", "1.5G", "300k", or plain bytes.
pub fn parse_size(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let v: f64 = num
        .parse()
        .map_err(|_| format!("\"{s}\" is not a size (e.g. 512MB, 2GB, or bytes)"))?;
    let mult = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1u64,
        "k" | "kb" | "kib" => 1 << 10,
        "m" | "mb" | "mib" => 1 << 20,
        "g" | "gb" | "gib" => 1 << 30,
        "t" | "tb" | "tib" => 1 << 40,
        u => {
            return Err(format!(
                "\"{s}\": unknown unit \"{u}\" (use B, KB, MB, GB, TB)"
            ));
        }
    };
    Ok((v * mult as f64) as u64)
}

/// Bytes a point takes in memory while its chunk is built (its columns, a copy passed down, the
/// MOSPT's codes and orders), for the widest common schema.
pub(crate) const BUILD_BYTES_PER_POINT: u64 = 4 * 72 + 48;
const MIN_CHUNK_POINTS: u64 = 50_000;
/// The smallest budget the build accepts.
pub const MIN_MEMORY: u64 = 512 << 20;

/// How a memory budget is spent: write buffers for distribution, and points per chunk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plan {
    pub buffer_bytes: usize,
    /// What the buffers may hold when every point is expected to stay in memory until its
    /// chunk is built: the budget less the chunks being built, or half of it if more.
    pub resident_bytes: usize,
    pub chunk_points: u64,
    /// Threads that fit the budget (at most those asked for).
    pub threads: usize,
}

pub fn plan(memory: u64, threads: usize, params: &NestedParams) -> Plan {
    // Fixed costs: readers' blocks (LAZ decompresses one block ahead on all cores), the
    // writer's buffer, code and allocator slack.
    let fixed = 160u64 << 20;
    let free = memory.saturating_sub(fixed);
    let buffer_bytes = (free / 4).clamp(8 << 20, 512 << 20);
    let family = 9 * params.capacity as u64 * BUILD_BYTES_PER_POINT / 2;
    // Fewer threads than asked when the budget cannot give each a useful chunk.
    let least = MIN_CHUNK_POINTS * BUILD_BYTES_PER_POINT + family;
    let threads = threads.clamp(1, ((free * 3 / 4) / least).max(1) as usize);
    let per_thread = (free * 3 / 4 / threads as u64).saturating_sub(family);
    let chunk_points = (per_thread / BUILD_BYTES_PER_POINT).clamp(MIN_CHUNK_POINTS, 2_000_000);
    let building = threads as u64 * (chunk_points * BUILD_BYTES_PER_POINT + family);
    Plan {
        buffer_bytes: buffer_bytes as usize,
        // Points kept from reading leave memory as their chunks are built (a chunk's rows go
        // to its build), so half the budget may hold them where `building` leaves less: it
        // counts four copies of the widest schema's rows for every point of a chunk, and a
        // build from memory of KY (7.2 M points, 374 MB of rows) with 1 GB peaks at 491 MB.
        resident_bytes: free
            .saturating_sub(building)
            .max(free / 2)
            .max(buffer_bytes) as usize,
        chunk_points,
        threads,
    }
}

/// One phase of a build: how long it took, and the CPU time of all threads in it (the share of
/// the cores it kept busy; `None` where the system does not say).
#[derive(Debug, Clone, PartialEq)]
pub struct Phase {
    pub name: &'static str,
    pub seconds: f64,
    pub cpu_seconds: Option<f64>,
}

/// Times the phases of a build one after the other.
struct Phases {
    done: Vec<Phase>,
    wall: Instant,
    cpu: Option<f64>,
}

impl Phases {
    fn start() -> Phases {
        Phases {
            done: Vec::new(),
            wall: Instant::now(),
            cpu: myriad_io::process::cpu_seconds(),
        }
    }

    /// Ends the phase `name`, and starts the next.
    fn end(&mut self, name: &'static str) {
        let cpu = myriad_io::process::cpu_seconds();
        self.done.push(Phase {
            name,
            seconds: self.wall.elapsed().as_secs_f64(),
            cpu_seconds: cpu.zip(self.cpu).map(|(now, then)| now - then),
        });
        self.wall = Instant::now();
        self.cpu = cpu;
    }
}

#[derive(Debug, Clone)]
pub struct Summary {
    pub points: u64,
    pub nodes: u64,
    pub depth: u32,
    pub bytes: u64,
    pub chunks: usize,
    pub seconds: f64,
    /// Each phase, in order.
    pub phases: Vec<Phase>,
    pub skipped_non_finite: u64,
    pub trimmed: u64,
    /// Points that did not move into the target CRS (`--to-crs`), dropped.
    pub not_transformed: u64,
    pub clamped: u64,
    /// Bounds of the points taken, and each input's points taken and read (more where a part
    /// keeps some cells only).
    pub bounds: Aabb,
    pub sources: Vec<(PathBuf, u64, u64)>,
    /// The nodes of [`Planned::tops_level`] before the levels above took points from them.
    pub tops: Vec<BuiltNode>,
}

/// Removes what a killed build left next to `output`: spill folders and partial outputs whose
/// process is gone ([`myriad_io::claim`]: their lock is free and they are older than this
/// process), never those of a build still running, on this machine or another.
pub fn remove_stale(output: &Path) {
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let Some(name) = output.file_name().and_then(|n| n.to_str()) else {
        return;
    };
    myriad_io::claim::remove_stale_folders(dir, SPILL_PREFIX);
    let partial = format!(".{name}.");
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let file = e.file_name();
        let Some(f) = file.to_str() else { continue };
        if f.starts_with(&partial)
            && f.ends_with(".partial")
            && e.path().is_file()
            && myriad_io::claim::is_stale_file(&e.path())
        {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// The integer grid of the dataset: the finest input scale per axis (LAS/LAZ inputs keep their
/// coordinates exactly), `precision` for inputs of float coordinates; the first LAS input's
/// offset, else the root cube's corner on a whole unit.
///
/// Node pages store positions as integers on this grid: the grid must number the whole root cube
/// within 2^53 steps per axis (where f64 still counts every step), or positions would be clamped.
/// A scale that fine for the extent is refused, naming the input it came from.
pub(crate) fn quantization(
    sources: &[&myriad_io::SourceInfo],
    root: &Aabb,
    precision: f64,
) -> Result<Quantization> {
    let mut scale = [f64::INFINITY; 3];
    let mut finest: [Option<&Path>; 3] = [None; 3];
    for info in sources {
        // A negative LAS scale mirrors the records, not the coordinates: the grid step is its size.
        let s = info.scale.map_or([precision; 3], |s| s.map(f64::abs));
        for a in 0..3 {
            if s[a] < scale[a] {
                scale[a] = s[a];
                finest[a] = info.scale.map(|_| info.path.as_path());
            }
        }
    }
    let offset = sources
        .iter()
        .find_map(|i| i.offset)
        .unwrap_or(root.min.map(f64::floor));
    for a in 0..3 {
        let reach = (root.max[a] - offset[a])
            .abs()
            .max((root.min[a] - offset[a]).abs());
        if !(reach / scale[a] < 2f64.powi(53)) {
            let axis = ["X", "Y", "Z"][a];
            let what = format!(
                "a grid step of {:e} cannot number coordinates {reach:e} from the offset {} on {axis} (more than 2^53 steps)",
                scale[a], offset[a]
            );
            return Err(match finest[a] {
                Some(p) => Error::unsupported(
                    p,
                    format!("{what}: its {axis} scale is too fine for the data's extent"),
                ),
                None => Error::Invalid(format!("{what}: use a coarser --precision")),
            });
        }
    }
    Ok(Quantization { scale, offset })
}

/// Extensions of the formats Myriad reads or writes other than datasets: a dataset written
/// under one of them would be taken for a scan.
const NOT_A_DATASET: &[&str] = &[
    "las", "laz", "ply", "pcd", "xyz", "txt", "csv", "pts", "e57", "png", "json", "glb", "gltf",
];

/// The output of a build: a dataset name in a folder that exists, not one of the inputs
/// (`--force` included), and no input given twice.
pub fn check_output(out: &Path, inputs: &[PathBuf]) -> Result<()> {
    if let Some(e) = out.extension().and_then(|e| e.to_str())
        && NOT_A_DATASET.contains(&e.to_ascii_lowercase().as_str())
    {
        return Err(Error::Invalid(format!(
            "{}: convert writes a dataset (.myr), not .{e} (`myriad export` and `extract` \
             write LAS, LAZ, COPC and PLY)",
            out.display()
        )));
    }
    myriad_io::atomic::require_folder(out)?;
    myriad_io::atomic::refuse_input_as_output(out, inputs)?;
    myriad_io::atomic::refuse_repeated_inputs(inputs)
}

/// Converts `inputs` into a dataset at `options.output`.
pub fn convert(
    inputs: &[PathBuf],
    options: &ConvertOptions,
    report: &dyn Report,
) -> Result<Summary> {
    let start = Instant::now();
    let out = &options.output;
    check_request(inputs, options)?;
    remove_stale(out);
    let structure = options.structure;
    let params = NestedParams {
        ntree: structure == Structure::Layered,
        ..options.params
    };
    let plan = plan(options.memory, options.threads.max(1), &params);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(plan.threads)
        .build()
        .map_err(|e| Error::Invalid(format!("thread pool: {e}")))?;
    let mut phases = Phases::start();

    // 1. Distribution. A build drawn while it runs: octree and layered only.
    let growing = (options.growing.as_ref())
        .filter(|_| !matches!(structure, Structure::Kd | Structure::Mwkd));
    let dist = read_inputs(inputs, options, &plan, growing, report)?;
    phases.end("reading");

    let quant = dataset_quantization(options, &dist)?;
    let writer = DatasetWriter::create(out, options.force, quant)?;
    let root = dist.root;
    let schema = dist.schema.clone();
    let spill_dir = dist.spill_dir().to_path_buf();

    // 2. Chunks (kd, mwkd: groups of chunks), in parallel, largest first (they take longest).
    report.phase("building", dist.points);
    let orientation = orientation(&dist);
    let mw = crate::mwkd::MwkdParams {
        fanout: (options.fanout)
            .unwrap_or_else(|| crate::mwkd::fanout_for(dist.points, params.capacity)),
        capacity: params.capacity,
        grid: options.grid,
        orientation,
    };
    let meta = metadata(options, &params, &mw, &dist, quant);
    let chunks = Chunks {
        dist: &dist,
        params: &params,
        writer: &writer,
        pool: &pool,
        spill_dir: &spill_dir,
        report,
    };
    let pending = if matches!(structure, Structure::Kd | Structure::Mwkd) {
        let chunk_points = options.chunk_points.unwrap_or(plan.chunk_points);
        chunks.build_groups(structure, &mw, chunk_points)?
    } else {
        chunks.build_nested(growing, &meta)?
    };
    phases.end("building");

    // 3. The levels above the chunks.
    let tops_level = options.planned.as_ref().and_then(|p| p.tops_level);
    let tops = Above {
        structure,
        params: &params,
        mw: &mw,
        root: &root,
        schema: &schema,
        writer: &writer,
        pool: &pool,
        spill_dir: &spill_dir,
    }
    .build(pending, tops_level, report)?;
    phases.end("merging");

    // 4. Hierarchy, metadata, header.
    let (nodes, depth, bytes) = write_dataset(writer, meta, dist.points, out, report)?;
    phases.end("writing");
    let seconds = start.elapsed().as_secs_f64();
    Ok(summary(
        &dist,
        (nodes, depth, bytes),
        seconds,
        phases.done,
        tops,
    ))
}

/// The dataset's integer grid: the plan's, else the one the inputs give ([`quantization`]).
fn dataset_quantization(
    options: &ConvertOptions,
    dist: &distribute::Distribution,
) -> Result<Quantization> {
    Ok(match &options.planned {
        Some(p) => p.quantization,
        None => {
            let infos: Vec<_> = dist.sources.iter().map(|(i, _)| i).collect();
            quantization(&infos, &dist.root, options.precision)?
        }
    })
}

/// Refuses a build that cannot be made as asked: an output that exists (without `--force`), or
/// that is no dataset name ([`check_output`]), a budget below the least, a precision that is
/// no length.
fn check_request(inputs: &[PathBuf], options: &ConvertOptions) -> Result<()> {
    let out = &options.output;
    if !options.force && out.exists() {
        return Err(Error::Invalid(format!(
            "{}: output exists (use --force to replace it)",
            out.display()
        )));
    }
    check_output(out, inputs)?;
    check_memory(options.memory)?;
    check_precision(options.precision)
}

/// `--precision`: a positive length (`plan` checks it as `convert` does: a NaN saved in a plan
/// failed every part after).
pub(crate) fn check_precision(precision: f64) -> Result<()> {
    if !(precision.is_finite() && precision > 0.0) {
        return Err(Error::Invalid(
            "--precision must be a positive length".into(),
        ));
    }
    Ok(())
}

/// Step 1: every input read once and its points scattered to chunks next to the output
/// ([`distribute::distribute_with`]), the reading reported and sampled for a build drawn while
/// it runs; refused where the inputs hold no points (but for a planned part).
fn read_inputs(
    inputs: &[PathBuf],
    options: &ConvertOptions,
    plan: &Plan,
    growing: Option<&std::sync::Arc<crate::growing::Growing>>,
    report: &dyn Report,
) -> Result<distribute::Distribution> {
    let temp_dir = match options.output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let dist = distribute::distribute_with(
        inputs,
        &options.open,
        &DistributeOptions {
            chunk_points: options.chunk_points.unwrap_or(plan.chunk_points),
            buffer_bytes: plan.buffer_bytes,
            resident_bytes: plan.resident_bytes,
            compress_above: SPILL_COMPRESS_ABOVE,
            min_chunks: 8 * plan.threads as u64,
            temp_dir,
            grid: options.planned.as_ref().map(|p| p.grid.clone()),
        },
        &mut |p| match p {
            distribute::Progress::Declared(n) => {
                report.phase("reading", n);
                if let Some(g) = growing {
                    g.expect(n);
                }
            }
            distribute::Progress::Read(n) => report.advance(n),
            // Drawn while the build reads: a sample of what is decoded.
            distribute::Progress::Points(b) => {
                if let Some(g) = growing {
                    g.sample(b);
                    g.offer_decoded();
                }
            }
        },
    )?;
    if dist.points == 0 && options.planned.is_none() {
        return Err(Error::Invalid(format!(
            "{}: the inputs hold no points",
            inputs[0].display()
        )));
    }
    Ok(dist)
}

/// How the normals get their sign: the input's where it has them; else estimated, and turned
/// towards the scanners where every input says where its scans were taken from (E57 scans from
/// one place), or towards each flight line's side where scan angles say it (airborne LAS).
fn orientation(dist: &distribute::Distribution) -> crate::mwkd::Orientation {
    if dist.schema.has(&myriad_core::Attribute::Normal) {
        crate::mwkd::Orientation::Input
    } else {
        let infos: Vec<_> = dist.sources.iter().map(|(i, _)| i).collect();
        match crate::distribute::scan_origins(&infos) {
            Some((table, _)) => crate::mwkd::Orientation::Scanners(std::sync::Arc::new(table)),
            // Airborne: towards the side of each flight line its scan angles say.
            None => match dist.sides.directions() {
                Some(d) => crate::mwkd::Orientation::Flights(std::sync::Arc::new(d)),
                None => crate::mwkd::Orientation::Up,
            },
        }
    }
}

/// The dataset's metadata (its counts are set when it is written): its structure and
/// parameters, the distribution's bounds, root, schema and sources, the plan's CRS and LAS
/// header where a plan fixes them.
fn metadata(
    options: &ConvertOptions,
    params: &NestedParams,
    mw: &crate::mwkd::MwkdParams,
    dist: &distribute::Distribution,
    quant: Quantization,
) -> Metadata {
    let structure = options.structure;
    Metadata {
        structure: structure.stored_name().into(),
        parameters: parameters(
            structure,
            params,
            (structure == Structure::Mwkd).then_some(mw),
            options.planned.as_ref(),
        ),
        points: dist.points,
        nodes: 0,
        depth: 0,
        bounds: dist.bounds,
        root: dist.root,
        quantization: quant,
        crs: match &options.planned {
            Some(p) => p.crs.clone(),
            None => dist.sources.iter().find_map(|(i, _)| i.crs.clone()),
        },
        schema: dist.schema.clone(),
        sources: (dist.sources.iter())
            .map(|(i, n)| {
                let mut v = source(i, *n);
                if let Some(name) = options.recorded_as.get(&i.path) {
                    v["path"] = name.as_str().into();
                }
                v
            })
            .collect(),
        las_header: match &options.planned {
            Some(p) => p.las_header.clone(),
            None => dist.las_header.clone(),
        },
        levels: Vec::new(),
        files: Vec::new(),
        software: format!("myriad {}", env!("CARGO_PKG_VERSION")),
    }
}

/// Step 4: the hierarchy pages, metadata and header written and the file renamed, once the
/// nodes hold every point read (`points`). The nodes, depth and bytes of the dataset; a part
/// whose cells hold no points writes none (0 bytes).
fn write_dataset(
    writer: DatasetWriter,
    meta: Metadata,
    points: u64,
    out: &Path,
    report: &dyn Report,
) -> Result<(u64, u32, u64)> {
    report.phase("writing", 1);
    let (written, nodes, depth) = writer.totals();
    if written != points {
        // Only a builder bug could lose points; the partial file is removed, nothing appears.
        return Err(Error::Invalid(format!(
            "{}: internal error: {} points read, {written} in the nodes",
            out.display(),
            points
        )));
    }
    // A part whose cells hold no points (the plan's estimate was off) writes no dataset.
    let bytes = if written == 0 {
        0
    } else {
        writer.finish(meta)?
    };
    report.advance(1);
    Ok((nodes, depth, bytes))
}

/// What the build did: the distribution's counts, the dataset's nodes, depth and bytes
/// (`written`), the time it took in all and by phase, and the tops kept for a merge.
fn summary(
    dist: &distribute::Distribution,
    written: (u64, u32, u64),
    seconds: f64,
    phases: Vec<Phase>,
    tops: Vec<BuiltNode>,
) -> Summary {
    let (nodes, depth, bytes) = written;
    Summary {
        points: dist.points,
        nodes,
        depth,
        bytes,
        chunks: dist.chunks.len(),
        seconds,
        phases,
        skipped_non_finite: dist.skipped_non_finite,
        trimmed: dist.trimmed,
        not_transformed: dist.not_transformed,
        clamped: dist.clamped,
        bounds: dist.bounds,
        sources: dist
            .sources
            .iter()
            .zip(&dist.read)
            .map(|((i, n), r)| (i.path.clone(), *n, *r))
            .collect(),
        tops,
    }
}

/// An input as the dataset's metadata lists it, with the points taken from it.
pub(crate) fn source(info: &myriad_io::SourceInfo, points: u64) -> serde_json::Value {
    serde_json::json!({
        "path": info.path.display().to_string(),
        "format": info.format.name(),
        "version": info.version,
        "points": points,
    })
}

/// Refuses a memory budget the build cannot work in.
pub(crate) fn check_memory(memory: u64) -> Result<()> {
    if memory < MIN_MEMORY {
        return Err(Error::Invalid(format!(
            "--memory {} MB is below the {} MB the build needs",
            memory >> 20,
            MIN_MEMORY >> 20
        )));
    }
    // Sums of a few times the budget stay within u64 (a value beyond it was taken as u64's
    // largest and overflowed the plan: found by an audit).
    if memory > MAX_MEMORY {
        return Err(Error::Invalid(format!(
            "--memory {} TB is more than the {} TB a build plans for",
            memory >> 40,
            MAX_MEMORY >> 40
        )));
    }
    Ok(())
}

/// The largest `--memory` taken: 1 PiB.
pub const MAX_MEMORY: u64 = 1 << 50;

/// The parameters a dataset records: its structure's, and which plan and part it was built
/// from.
pub(crate) fn parameters(
    structure: Structure,
    params: &NestedParams,
    mw: Option<&crate::mwkd::MwkdParams>,
    planned: Option<&Planned>,
) -> serde_json::Value {
    use crate::mwkd::Orientation;
    let mut v = serde_json::json!({
        "fanout": mw.map(|m| m.fanout),
        "grid": mw.and_then(|m| m.grid),
        // Normals from the input, and estimated ones turned towards their scanners, have a
        // sign (a node's normal cone may face away); other estimated ones were turned up.
        "normals": match (structure, mw.map(|m| &m.orientation)) {
            (Structure::Mwkd, Some(Orientation::Input)) => Some("input"),
            (Structure::Mwkd, Some(Orientation::Scanners(_) | Orientation::Flights(_))) => {
                Some("oriented")
            }
            (Structure::Mwkd, _) => Some("estimated"),
            _ => None,
        },
        "capacity": params.capacity,
        "inner_depth": params.inner_depth,
        "max_level": params.max_level,
    });
    if let Some(serde_json::Value::Object(extra)) = planned.map(|p| &p.parameters) {
        for (k, x) in extra {
            v[k] = x.clone();
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes() {
        assert_eq!(parse_size("512MB"), Ok(512 << 20));
        assert_eq!(parse_size("2GB"), Ok(2 << 30));
        assert_eq!(parse_size("1.5g"), Ok(3 << 29));
        assert_eq!(parse_size("300k"), Ok(300 << 10));
        assert_eq!(parse_size("123456"), Ok(123456));
        assert!(parse_size("lots").is_err());
        assert!(parse_size("2 parsecs").is_err());
        assert!(parse_size("").is_err());
    }

    #[test]
    fn plans_fit_the_budget() {
        let params = NestedParams {
            capacity: DEFAULT_CAPACITY,
            inner_depth: DEFAULT_INNER_DEPTH,
            max_level: DEFAULT_MAX_LEVEL,
            ntree: false,
        };
        for memory in [MIN_MEMORY, 512 << 20, 2 << 30, 8 << 30] {
            for threads in [1, 2, 8, 64] {
                let p = plan(memory, threads, &params);
                // Buffers (which may hold twice their length in capacity) during distribution;
                // chunks and families per thread while building.
                let build = p.threads as u64
                    * (p.chunk_points * BUILD_BYTES_PER_POINT
                        + 9 * params.capacity as u64 * BUILD_BYTES_PER_POINT / 2);
                assert!(2 * p.buffer_bytes as u64 + (160 << 20) <= memory);
                assert!(build + (160 << 20) <= memory, "{memory} {threads}: {p:?}");
                // Points kept from reading to building, beside the chunks being built: within
                // the budget, or half of it (they leave as their chunks are built), or no more
                // than the buffers hold anyway.
                assert!(
                    p.resident_bytes as u64 + build + (160 << 20) <= memory
                        || p.resident_bytes as u64 <= (memory - (160 << 20)) / 2
                        || p.resident_bytes == p.buffer_bytes,
                    "{memory} {threads}: {p:?}"
                );
                assert!(p.resident_bytes as u64 + (160 << 20) <= memory);
                assert!(p.threads >= 1 && p.threads <= threads);
            }
        }
    }
}
