//! `myriad bench profile DATASET...`: a cross-section of the dataset, cold (the dataset's pages
//! dropped from the page cache first) and warm: its time, points, and the nodes read of the
//! dataset's nodes; next to the baseline a user without the tool has, `extract` of the
//! corridor's plan box (every height) to LAS, cold, then cut in another program. The line
//! defaults to 1 km (or 90 % of the data's extent, when smaller) east-west through the data's
//! centre, 2 m wide.

use anyhow::{Result, anyhow};
use clap::Args;
use myriad_build::extract::{ExtractOptions, extract};
use myriad_core::Aabb;
use myriad_core::colour::ColorBy;
use myriad_format::Dataset;
use myriad_measure::files::xy_arg;
use myriad_measure::shape::Want;
use myriad_measure::{Bound, Corridor};
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::median;
use crate::open::drop_cache;

#[derive(Args)]
pub struct ProfileBenchArgs {
    /// Datasets (.myr)
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    /// The line: X1,Y1,X2,Y2[,...] or @FILE [default: 1 km east-west through the data's
    /// centre]
    #[arg(long, allow_hyphen_values = true)]
    line: Option<String>,
    /// Split the line's segments into this many vertices in all, each nudged off the line by
    /// a millionth of its segment (a GIS line's vertex count over the same ground)
    #[arg(long)]
    vertices: Option<usize>,
    /// The corridor's width
    #[arg(long, default_value_t = 2.0)]
    width: f64,
    /// Cold and warm runs of each
    #[arg(long, default_value_t = 5)]
    runs: usize,
}

/// A line of `length` (at most 90 % of the data's width) east-west through the centre.
pub(crate) fn default_line(b: &Aabb, length: f64) -> Vec<[f64; 2]> {
    let c = b.center();
    let half = (length.min(0.9 * (b.max[0] - b.min[0]))) / 2.0;
    vec![[c[0] - half, c[1]], [c[0] + half, c[1]]]
}

/// `pts` with its segments (and, `closed`, the last back to the first) split evenly into
/// about `n` vertices in all, the new ones nudged across by a millionth of their segment, so
/// that the shape covers the same ground with `n` real vertices.
pub(crate) fn subdivide(pts: &[[f64; 2]], closed: bool, n: usize) -> Vec<[f64; 2]> {
    let segs = if closed { pts.len() } else { pts.len() - 1 };
    let per = (n.saturating_sub(pts.len()) / segs.max(1)) + 1;
    let mut out = Vec::with_capacity(n + 1);
    for i in 0..segs {
        let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
        let d = [b[0] - a[0], b[1] - a[1]];
        for k in 0..per {
            let t = k as f64 / per as f64;
            let nudge = if k % 2 == 1 { 1e-6 } else { 0.0 };
            out.push([
                a[0] + t * d[0] - nudge * d[1],
                a[1] + t * d[1] + nudge * d[0],
            ]);
        }
    }
    if !closed {
        out.push(*pts.last().expect("a line"));
    }
    out
}

/// Seconds of `f`, after dropping `path`'s pages when `cold`.
pub(crate) fn timed<T>(path: &Path, cold: bool, f: impl FnOnce() -> Result<T>) -> Result<(f64, T)> {
    if cold {
        drop_cache(path)?;
    }
    let t = Instant::now();
    let v = f()?;
    Ok((t.elapsed().as_secs_f64(), v))
}

/// Medians of `runs` cold and warm runs of `tool` on a freshly opened `path`, the last run's
/// result, and the baseline: `extract` of the plan box `lo`..`hi` (every height) to LAS, cold,
/// its median and its points.
pub(crate) struct Timings<T> {
    pub cold: f64,
    pub warm: f64,
    pub last: T,
    pub baseline: f64,
    pub baseline_points: u64,
}

pub(crate) fn cold_warm_and_box<T>(
    path: &Path,
    runs: usize,
    (lo, hi): ([f64; 2], [f64; 2]),
    tool: impl Fn(&Dataset) -> Result<T>,
) -> Result<Timings<T>> {
    let tmp = std::env::temp_dir().join(format!("myriad-bench-box-{}", std::process::id()));
    std::fs::create_dir_all(&tmp)?;
    let (mut cold, mut warm, mut base) = (Vec::new(), Vec::new(), Vec::new());
    let (mut last, mut baseline_points) = (None, 0);
    for _ in 0..runs.max(1) {
        for is_cold in [true, false] {
            let (t, v) = timed(path, is_cold, || tool(&Dataset::open(path)?))?;
            last = Some(v);
            if is_cold { cold.push(t) } else { warm.push(t) }
        }
        let (t, s) = timed(path, true, || {
            let ds = Dataset::open(path)?;
            let b = ds.meta.bounds;
            let bbox = Aabb::new([lo[0], lo[1], b.min[2]], [hi[0], hi[1], b.max[2]]);
            let o = ExtractOptions {
                bbox: Some(bbox),
                force: true,
                ..Default::default()
            };
            Ok(extract(&ds, &tmp.join("box.las"), &o)?)
        })?;
        baseline_points = s.points;
        base.push(t);
    }
    let _ = std::fs::remove_dir_all(&tmp);
    Ok(Timings {
        cold: median(cold),
        warm: median(warm),
        last: last.expect("one run"),
        baseline: median(base),
        baseline_points,
    })
}

pub fn run(a: ProfileBenchArgs) -> Result<()> {
    for path in &a.datasets {
        let ds = Dataset::open(path)?;
        let mut line = match &a.line {
            Some(l) => {
                xy_arg(l, "--line", Want::Line)
                    .map_err(|e| anyhow!(e))?
                    .points
            }
            None => default_line(&ds.meta.bounds, 1000.0),
        };
        if let Some(n) = a.vertices {
            line = subdivide(&line, false, n);
        }
        let t = Instant::now();
        let corridor = Corridor::new(&line, a.width).map_err(|e| anyhow!(e))?;
        let index = t.elapsed().as_secs_f64();
        let t = cold_warm_and_box(path, a.runs, corridor.plan_bounds(), |ds| {
            myriad_measure::profile::profile(ds, &corridor, &Bound::all(), ColorBy::Rgb)
                .map_err(|e| anyhow!(e))
        })?;
        let u = myriad_measure::measurement::crs_units(ds.meta.crs.as_deref());
        println!(
            "{}: {} points, {} nodes",
            path.display(),
            ds.meta.points,
            ds.meta.nodes
        );
        println!(
            "  profile     {:.1} x {} {u}, {} vertices (indexed in {:.3} s): {} points from {} nodes; cold {:.3} s, warm {:.3} s (medians of {})",
            corridor.length(),
            a.width,
            corridor.line().len(),
            index,
            t.last.len(),
            t.last.nodes_read,
            t.cold,
            t.warm,
            a.runs.max(1)
        );
        println!(
            "  baseline    extract of its plan box to LAS, cold: {} points, {:.3} s",
            t.baseline_points, t.baseline
        );
    }
    Ok(())
}
