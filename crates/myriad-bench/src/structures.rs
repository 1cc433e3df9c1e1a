//! `myriad bench structures FILE`: the same file converted with every structure, one table.
//!
//! Per structure: build speed, peak memory (of the `myriad convert` process) and bytes per point
//! from convert's own summary; nodes and depth from the dataset; the PSNR of the image at
//! `--budget` against the image of every point, in the three standard views, with adaptive and
//! with 1-pixel points (the views are the octree's, so every structure is seen from the same
//! cameras; with 1-pixel points the full images are the same for all, since all hold the same
//! points); and the median frame time of the whole pipeline at `--frame-budget` in the overview.

use crate::render::{frame_times, quality};
use anyhow::{Result, bail};
use clap::Args;
use myriad_build::convert::Structure;
use myriad_format::Dataset;
use myriad_lod::Camera;
use myriad_render::{Gpu, PointSize, Rasterizer, Scene, Style};
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Args)]
pub struct StructuresBenchArgs {
    /// The point cloud to convert
    file: PathBuf,
    /// Point budget of the images compared with the full one
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "1M")]
    budget: u64,
    /// Point budget of the timed frames
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "5M")]
    frame_budget: u64,
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Timed frames per structure
    #[arg(long, default_value_t = 9)]
    frames: usize,
    /// Structures to compare, e.g. octree,kd [default: all]
    #[arg(long, value_delimiter = ',')]
    structures: Vec<String>,
    /// Draw on the CPU even where there is a hardware GPU
    #[arg(long)]
    cpu: bool,
    /// Where the datasets are written; kept when given, else a temporary folder removed at the end
    #[arg(long)]
    keep: Option<PathBuf>,
    /// Most points per node, for every structure (Goswami et al. 2010's "VBO size") [default:
    /// convert's]
    #[arg(long)]
    capacity: Option<usize>,
    /// mwkd's fan-out N and clustering grid K (Goswami et al. 2010, tables II and IV) [default:
    /// convert's]
    #[arg(long)]
    fanout: Option<u32>,
    #[arg(long)]
    grid: Option<u32>,
}

struct Row {
    name: &'static str,
    rate: f64,
    peak: f64,
    bpp: f64,
    nodes: u64,
    depth: u32,
    adaptive: Vec<f64>,
    fixed: Vec<f64>,
    frame_ms: f64,
}

pub fn run(a: StructuresBenchArgs) -> Result<()> {
    let structures: Vec<Structure> = if a.structures.is_empty() {
        Structure::ALL.to_vec()
    } else {
        a.structures
            .iter()
            .map(|s| Structure::parse(s).map_err(anyhow::Error::msg))
            .collect::<Result<_>>()?
    };
    let (gpu, why) = if a.cpu {
        (Gpu::cpu(), None)
    } else {
        Gpu::best()
    };
    if let Some(why) = why {
        eprintln!("warning: {why}: drawing on the CPU");
    }
    let raster = Rasterizer::new(&gpu);
    let dir = match &a.keep {
        Some(d) => d.clone(),
        None => {
            std::env::temp_dir().join(format!("myriad-bench-structures-{}", std::process::id()))
        }
    };
    std::fs::create_dir_all(&dir)?;
    let exe = std::env::current_exe()?;
    let mut views: Option<Vec<(&'static str, Camera)>> = None;
    let mut rows = Vec::new();
    for s in &structures {
        let out = dir.join(format!("{}.myr", s.name()));
        eprintln!("converting with --structure {}", s.name());
        let mut cmd = std::process::Command::new(&exe);
        cmd.arg("convert").arg(&a.file).arg("-o").arg(&out).args([
            "--structure",
            s.name(),
            "--force",
            "--json",
        ]);
        if let Some(c) = a.capacity {
            cmd.args(["--capacity", &c.to_string()]);
        }
        if *s == Structure::Mwkd {
            if let Some(n) = a.fanout {
                cmd.args(["--fanout", &n.to_string()]);
            }
            if let Some(k) = a.grid {
                cmd.args(["--grid", &k.to_string()]);
            }
        }
        let o = cmd.output()?;
        if !o.status.success() {
            bail!(
                "convert --structure {} failed: {}",
                s.name(),
                String::from_utf8_lossy(&o.stderr).trim()
            );
        }
        let summary: serde_json::Value = serde_json::from_slice(&o.stdout)?;
        let ds = Arc::new(Dataset::open(&out)?);
        let mut scene = Scene::open(ds.clone(), usize::MAX, usize::MAX);
        let cams = views
            .get_or_insert_with(|| {
                Camera::standard_views(&scene.view_bounds, a.width, a.height)
                    .into_iter()
                    .map(|(v, mut c)| {
                        c.fit_depth(&ds.meta.bounds);
                        (v, c)
                    })
                    .collect()
            })
            .clone();
        let mut row = Row {
            name: s.name(),
            rate: summary["points_per_second"].as_f64().unwrap_or(f64::NAN),
            peak: summary["peak_rss_bytes"].as_f64().unwrap_or(f64::NAN),
            bpp: summary["bytes_per_point"].as_f64().unwrap_or(f64::NAN),
            nodes: ds.meta.nodes,
            depth: ds.meta.depth,
            adaptive: vec![],
            fixed: vec![],
            frame_ms: f64::NAN,
        };
        for (view, cam) in &cams {
            for (size, into) in [
                (PointSize::adaptive(), &mut row.adaptive),
                (PointSize::Fixed(1.0), &mut row.fixed),
            ] {
                let style = Style {
                    size,
                    ..Style::default()
                };
                let q = quality(&mut scene, &gpu, &raster, cam, &style, a.budget)
                    .map_err(|e| anyhow::anyhow!("{}: {view}: {e}", s.name()))?;
                into.push(q.psnr);
            }
        }
        let style = Style::default();
        let (times, _) = frame_times(
            &mut scene,
            &gpu,
            &raster,
            &cams[0].1,
            &style,
            a.frame_budget,
            a.frames,
        );
        row.frame_ms = times[times.len() / 2].0 * 1e3;
        if a.keep.is_none() {
            drop(scene);
            drop(ds);
            std::fs::remove_file(&out).ok();
        }
        rows.push(row);
    }
    if a.keep.is_none() {
        std::fs::remove_dir(&dir).ok();
    }
    let names: Vec<&str> = views
        .as_ref()
        .map(|v| v.iter().map(|(n, _)| *n).collect())
        .unwrap_or_default();
    println!(
        "{}: {} ({:?} path), {}x{}; PSNR in dB at a budget of {} against every point, \
         adaptive / 1-pixel points; frame: median of {} at {} points, overview, adaptive",
        a.file.display(),
        gpu.name,
        raster.path,
        a.width,
        a.height,
        myriad_core::units::thousands(a.budget),
        a.frames,
        myriad_core::units::thousands(a.frame_budget),
    );
    let views = names.join("/");
    println!(
        "{:<10} {:>9} {:>8} {:>6} {:>7} {:>5}  {:>23}  {:>23} {:>9}",
        "structure",
        "M pts/s",
        "peak MB",
        "B/pt",
        "nodes",
        "depth",
        format!("adaptive {views}"),
        format!("1-pixel {views}"),
        "frame ms"
    );
    let fmt = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:.2}"))
            .collect::<Vec<_>>()
            .join("/")
    };
    for r in &rows {
        println!(
            "{:<10} {:>9.2} {:>8.0} {:>6.2} {:>7} {:>5}  {:>23}  {:>23} {:>9.1}",
            r.name,
            r.rate / 1e6,
            r.peak / 1e6,
            r.bpp,
            r.nodes,
            r.depth,
            fmt(&r.adaptive),
            fmt(&r.fixed),
            r.frame_ms
        );
    }
    Ok(())
}
