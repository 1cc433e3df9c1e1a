//! `myriad bench open DATASET...`: how soon a dataset of any size shows something. Each run
//! opens the dataset afresh (header, metadata, root hierarchy page), frames the `render`
//! default view and draws frames as a viewer does until one shows points (the first image) and
//! then until every selected node is drawn (converged). Cold runs first drop the file's pages
//! from the page cache (`posix_fadvise(DONTNEED)`, which needs no privileges; the whole
//! cache with `/proc/sys/vm/drop_caches` where that is writable); cold and warm runs alternate.
//! Next to it, the baseline: reading every hierarchy page (what opening did before pages were
//! loaded on demand), cold, and the memory the whole hierarchy takes.
//!
//! `--fixture PATH` adds a dataset of `--fixture-points` points (10 billion by default) made
//! for measuring opening alone: a quadtree of 30,000-point nodes over a 100 km square whose
//! levels 0 to 3 have real node pages and whose deeper nodes' pages are not in the file
//! (readers report them as damaged and draw around them).

use anyhow::{Result, bail};
use clap::Args;
use myriad_core::{Aabb, NodeKey, PointBatch, Schema};
use myriad_format::{
    Dataset, DatasetWriter, Metadata, NodeEntry, NodeShape, PageRef, Quantization,
};
use myriad_lod::{Hierarchy, SelectOptions};
use myriad_render::{Rasterizer, Scene, Style};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(Args)]
pub struct OpenBenchArgs {
    /// Datasets (.myr)
    datasets: Vec<PathBuf>,
    /// Also this fixture, written first when it is not there
    #[arg(long)]
    fixture: Option<PathBuf>,
    /// Points of the fixture (k, M, G suffixes)
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "10G")]
    fixture_points: u64,
    /// Cold and warm runs of each
    #[arg(long, default_value_t = 5)]
    runs: usize,
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Point budget (as `render`'s default)
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "5M")]
    budget: u64,
    /// A standard view (overview, top, close) instead of `render`'s default view
    #[arg(long, value_parser = ["overview", "top", "close"])]
    view: Option<String>,
    #[command(flatten)]
    device: crate::render::Device,
}

/// Drops the file's pages from the page cache (and the whole cache where allowed). Whether
/// the whole cache was dropped.
pub(crate) fn drop_cache(path: &Path) -> Result<bool> {
    use std::os::fd::AsRawFd;
    let f = std::fs::File::open(path)?;
    // SAFETY: a valid descriptor of an open file; the call only advises the kernel.
    let r = unsafe { libc::posix_fadvise(f.as_raw_fd(), 0, 0, libc::POSIX_FADV_DONTNEED) };
    if r != 0 {
        bail!("{}: posix_fadvise: error {r}", path.display());
    }
    Ok(std::fs::write("/proc/sys/vm/drop_caches", "1").is_ok())
}

struct Run {
    first: Duration,
    converged: Duration,
    /// Hierarchy pages read (the root page included) and what they take in memory.
    pages: usize,
    bytes: usize,
    frames: usize,
    failed: usize,
    /// Time the frames spent uploading (in all, and the most in one frame), and the nodes
    /// uploaded with the words the loader threads made, and encoded at their upload.
    upload: Duration,
    upload_max: Duration,
    prepared: usize,
    encoded: usize,
}

fn open_and_draw(path: &Path, a: &OpenBenchArgs, gpu: &myriad_render::Gpu) -> Result<Run> {
    let raster = Rasterizer::new(gpu);
    let options = SelectOptions {
        budget: a.budget,
        min_pixels: 1.0,
    };
    let style = Style::default();
    let t0 = Instant::now();
    let ds = Arc::new(Dataset::open(path)?);
    let mut scene = Scene::open(ds.clone(), 2 << 30, 1 << 30);
    let cam = crate::view_camera(
        a.view.as_deref(),
        &scene.view_bounds,
        &ds.meta.bounds,
        a.width,
        a.height,
    )?;
    let mut first = None;
    let mut frames = 0;
    let (mut upload, mut upload_max) = (Duration::ZERO, Duration::ZERO);
    loop {
        let (_, stats) = scene.frame(gpu, &raster, &cam, &options, &style);
        frames += 1;
        upload += stats.upload;
        upload_max = upload_max.max(stats.upload);
        if std::env::var_os("MYRIAD_BENCH_TRACE").is_some() {
            eprintln!(
                "{:.3} s: {} points, select {:?} upload {:?} draw {:?}",
                t0.elapsed().as_secs_f64(),
                stats.points,
                stats.select,
                stats.upload,
                stats.draw
            );
        }
        if first.is_none() && stats.points > 0 {
            first = Some(t0.elapsed());
        }
        if stats.complete && stats.in_flight == 0 {
            return Ok(Run {
                first: first.unwrap_or(t0.elapsed()),
                converged: t0.elapsed(),
                pages: scene.loader.pages_read + 1,
                bytes: stats.hierarchy_bytes,
                frames,
                failed: scene.loader.failed().len(),
                upload,
                upload_max,
                prepared: scene.uploads_prepared,
                encoded: scene.uploads_encoded,
            });
        }
        if t0.elapsed() > Duration::from_secs(600) {
            bail!("{}: not converged after 10 minutes", path.display());
        }
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

pub fn run(a: OpenBenchArgs) -> Result<()> {
    let gpu = a.device.gpu()?;
    let mut paths = a.datasets.clone();
    if let Some(f) = &a.fixture {
        if !f.exists() {
            let t = Instant::now();
            write_fixture(f, a.fixture_points)?;
            println!(
                "wrote the fixture {} in {:.1} s",
                f.display(),
                t.elapsed().as_secs_f64()
            );
        }
        paths.push(f.clone());
    }
    if paths.is_empty() {
        bail!("no dataset: give one or more, or --fixture");
    }
    println!(
        "{}, {}x{}, {} view, budget {}; medians of {} cold and {} warm runs (cold: the file's pages \
         dropped from the page cache)",
        gpu.name,
        a.width,
        a.height,
        a.view.as_deref().unwrap_or("render's default"),
        myriad_core::units::thousands(a.budget),
        a.runs,
        a.runs
    );
    for path in &paths {
        let ds = Dataset::open(path)?;
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        // The baseline: every hierarchy page, cold.
        let whole_cache = drop_cache(path)?;
        let t = Instant::now();
        let ds2 = Dataset::open(path)?;
        let (nodes, _) = ds2.nodes();
        let walk = t.elapsed();
        let all_pages = count_pages(&ds2);
        let whole = Hierarchy::new(ds.meta.root, nodes).bytes();
        let mut cold = Vec::new();
        let mut warm = Vec::new();
        for _ in 0..a.runs.max(1) {
            drop_cache(path)?;
            cold.push(open_and_draw(path, &a, &gpu)?);
            warm.push(open_and_draw(path, &a, &gpu)?);
        }
        let m = |v: &[Run], f: &dyn Fn(&Run) -> f64| median(v.iter().map(f).collect());
        let secs = |d: Duration| d.as_secs_f64();
        println!(
            "\n{name}: {} points, {} nodes, {} hierarchy pages{}",
            myriad_core::units::thousands(ds.meta.points),
            myriad_core::units::thousands(ds.meta.nodes),
            myriad_core::units::thousands(all_pages as u64),
            if whole_cache {
                " (whole page cache dropped too)"
            } else {
                ""
            }
        );
        println!(
            "  before (every hierarchy page read on opening): {:.3} s cold, {:.1} MB",
            secs(walk),
            whole as f64 / 1e6
        );
        for (label, runs) in [("cold", &cold), ("warm", &warm)] {
            println!(
                "  {label}: first image {:.3} s, converged {:.2} s ({:.0} frames), {:.0} pages read, \
                 {:.2} MB of hierarchy{}",
                m(runs, &|r| secs(r.first)),
                m(runs, &|r| secs(r.converged)),
                m(runs, &|r| r.frames as f64),
                m(runs, &|r| r.pages as f64),
                m(runs, &|r| r.bytes as f64) / 1e6,
                match m(runs, &|r| r.failed as f64) {
                    0.0 => String::new(),
                    n => format!(", {n:.0} nodes without pages"),
                }
            );
            println!(
                "    uploads on the frame thread: {:.1} ms in all, at most {:.1} ms in a frame; \
                 {:.0} nodes uploaded as the loader threads made them, {:.0} encoded at upload",
                m(runs, &|r| secs(r.upload)) * 1e3,
                m(runs, &|r| secs(r.upload_max)) * 1e3,
                m(runs, &|r| r.prepared as f64),
                m(runs, &|r| r.encoded as f64),
            );
        }
    }
    Ok(())
}

fn count_pages(ds: &Dataset) -> usize {
    let mut n = 0;
    let mut todo = vec![ds.root_page()];
    while let Some(p) = todo.pop() {
        if let Ok(page) = ds.hierarchy_page(&p) {
            n += 1;
            todo.extend(page.children);
        }
    }
    n
}

/// Points per fixture node, and the deepest level whose nodes have real pages.
const FIXTURE_NODE: u32 = 30_000;
const FIXTURE_REAL: u32 = 3;

/// The fixture: a full quadtree of [`FIXTURE_NODE`]-point nodes over a 100 km square, deep
/// enough for `points`; points spread by a Halton sequence (every prefix spread evenly) on a
/// rolling terrain.
fn write_fixture(path: &Path, points: u64) -> Result<()> {
    let mut depth = 0;
    while (0..=depth).map(|l| 4u64.pow(l)).sum::<u64>() * (FIXTURE_NODE as u64) < points {
        depth += 1;
    }
    let side = 100_000.0;
    let min = [500_000.0, 4_000_000.0, 0.0];
    let root = Aabb::new(min, [min[0] + side, min[1] + side, side]);
    let quant = Quantization {
        scale: [0.01; 3],
        offset: min,
    };
    let w = DatasetWriter::create(path, false, quant)?;
    let schema = Schema::new(vec![]);
    let terrain = |x: f64, y: f64| {
        60.0 + 40.0 * (x / 3000.0).sin() * (y / 2100.0).cos() + 8.0 * (x / 170.0 + y / 230.0).sin()
    };
    let halton = |mut i: u64, b: u64| {
        let (mut f, mut r) = (1.0, 0.0);
        while i > 0 {
            f /= b as f64;
            r += f * (i % b) as f64;
            i /= b;
        }
        r
    };
    let n = FIXTURE_NODE as u64;
    let prefix = [n / 16, n / 4, n];
    for level in 0..=depth {
        let cells = 1u32 << level;
        let s = side / cells as f64;
        let spacing: Vec<f64> = prefix.iter().map(|&p| s / (p as f64).sqrt()).collect();
        for y in 0..cells {
            for x in 0..cells {
                let key = NodeKey {
                    level,
                    cell: [x, y, 0],
                };
                if level > FIXTURE_REAL {
                    w.write_entry(NodeEntry::new(
                        key,
                        PageRef {
                            offset: u64::MAX / 4,
                            length: 1,
                            crc: 0,
                        },
                        FIXTURE_NODE,
                        prefix.iter().map(|&p| p as u32).collect(),
                        spacing.clone(),
                    ));
                    continue;
                }
                let mut b = PointBatch::with_schema(&schema, n as usize);
                for i in 1..=n {
                    let px = min[0] + (x as f64 + halton(i, 2)) * s;
                    let py = min[1] + (y as f64 + halton(i, 3)) * s;
                    b.positions.push([px, py, terrain(px, py)]);
                }
                w.write_node(key, &b, &prefix, &spacing, NodeShape::default())?;
            }
        }
    }
    w.finish(Metadata {
        structure: "nested-octree".into(),
        parameters: serde_json::json!({"fixture": "node pages below level 3 absent"}),
        points: 0,
        nodes: 0,
        depth: 0,
        bounds: Aabb::new(min, [min[0] + side, min[1] + side, 120.0]),
        root,
        quantization: quant,
        crs: None,
        schema,
        sources: vec![],
        las_header: None,
        software: format!("myriad {} bench open --fixture", env!("CARGO_PKG_VERSION")),
        levels: vec![],
        files: vec![],
    })?;
    Ok(())
}
