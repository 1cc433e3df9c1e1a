//! `myriad bench volume DATASET...`: the volume over a polygon above the rim's plane, cold (the
//! dataset's pages dropped from the page cache first) and warm: its time, points, nodes read;
//! next to the baseline a user without the tool has, `extract` of the polygon's box to LAS,
//! cold, then a grid made in another program. The polygon defaults to a 1 ha square (100 m a
//! side, or 90 % of the data's smaller extent) at the data's centre.

use anyhow::{Result, anyhow};
use clap::Args;
use myriad_build::extract::{ExtractOptions, extract};
use myriad_core::Aabb;
use myriad_format::Dataset;
use myriad_measure::corridor::parse_xy_list;
use myriad_measure::volume::{Base, volume};
use myriad_measure::{Bound, Polygon};
use std::path::PathBuf;

use crate::median;
use crate::profile::timed;

#[derive(Args)]
pub struct VolumeBenchArgs {
    /// Datasets (.myr)
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    /// The polygon: X1,Y1,X2,Y2,X3,Y3[,...] [default: a 1 ha square at the data's centre]
    #[arg(long, allow_hyphen_values = true)]
    polygon: Option<String>,
    /// The grid's cell size [default: as `volume`'s]
    #[arg(long)]
    cell: Option<f64>,
    /// Cold and warm runs of each
    #[arg(long, default_value_t = 5)]
    runs: usize,
}

pub fn run(a: VolumeBenchArgs) -> Result<()> {
    let tmp = std::env::temp_dir().join(format!("myriad-bench-volume-{}", std::process::id()));
    std::fs::create_dir_all(&tmp)?;
    for path in &a.datasets {
        let ds = Dataset::open(path)?;
        let b = ds.meta.bounds;
        let pts = match &a.polygon {
            Some(p) => parse_xy_list(p, "--polygon", 3).map_err(|e| anyhow!(e))?,
            None => {
                let c = b.center();
                let h = 50f64.min(0.45 * (b.max[0] - b.min[0]).min(b.max[1] - b.min[1]));
                vec![
                    [c[0] - h, c[1] - h],
                    [c[0] + h, c[1] - h],
                    [c[0] + h, c[1] + h],
                    [c[0] - h, c[1] + h],
                ]
            }
        };
        let polygon = Polygon::new(&pts).map_err(|e| anyhow!(e))?;
        let (mut cold, mut warm, mut base) = (Vec::new(), Vec::new(), Vec::new());
        let mut last = None;
        let mut base_points = 0;
        for _ in 0..a.runs.max(1) {
            for is_cold in [true, false] {
                let (t, v) = timed(path, is_cold, || {
                    let ds = Dataset::open(path)?;
                    volume(&ds, &polygon, Base::Rim, a.cell, &Bound::all()).map_err(|e| anyhow!(e))
                })?;
                last = Some(v);
                if is_cold { cold.push(t) } else { warm.push(t) }
            }
            let (lo, hi) = polygon.plan_bounds();
            let bbox = Aabb::new([lo[0], lo[1], b.min[2]], [hi[0], hi[1], b.max[2]]);
            let out = tmp.join("box.las");
            let (t, s) = timed(path, true, || {
                let ds = Dataset::open(path)?;
                Ok(extract(
                    &ds,
                    &out,
                    &ExtractOptions {
                        bbox: Some(bbox),
                        force: true,
                        ..Default::default()
                    },
                )?)
            })?;
            base_points = s.points;
            base.push(t);
        }
        let v = last.expect("one run");
        let u = myriad_measure::measurement::unit_name(
            (ds.meta.crs.as_deref()).and_then(myriad_measure::measurement::metres_per_unit),
        );
        println!(
            "{}: {} points, {} nodes",
            path.display(),
            ds.meta.points,
            ds.meta.nodes
        );
        println!(
            "  volume      {:.0} {u}2, {} cells of {} {u}: fill {:.1} {u}3, cut {:.1} {u}3, {} points from {} nodes; cold {:.3} s, warm {:.3} s (medians of {})",
            v.area,
            v.cells,
            v.cell,
            v.fill,
            v.cut,
            v.points,
            v.nodes_read,
            median(cold),
            median(warm),
            a.runs.max(1)
        );
        println!(
            "  baseline    extract of its box to LAS, cold: {} points, {:.3} s",
            base_points,
            median(base)
        );
    }
    let _ = std::fs::remove_dir_all(&tmp);
    Ok(())
}
