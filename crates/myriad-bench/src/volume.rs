//! `myriad bench volume DATASET...`: the volume over a polygon above the rim's plane, cold (the
//! dataset's pages dropped from the page cache first) and warm: its time, points, nodes read;
//! next to the baseline a user without the tool has, `extract` of the polygon's box to LAS,
//! cold, then a grid made in another program. The polygon defaults to a 1 ha square (100 m a
//! side, or 90 % of the data's smaller extent) at the data's centre.

use anyhow::{Result, anyhow};
use clap::Args;
use myriad_format::Dataset;
use myriad_measure::files::xy_arg;
use myriad_measure::shape::Want;
use myriad_measure::volume::{Base, volume};
use myriad_measure::{Bound, Polygon};
use std::path::PathBuf;

use crate::profile::{cold_warm_and_box, subdivide};

#[derive(Args)]
pub struct VolumeBenchArgs {
    /// Datasets (.myr)
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    /// The polygon: X1,Y1,X2,Y2,X3,Y3[,...] or @FILE [default: a 1 ha square at the data's
    /// centre]
    #[arg(long, allow_hyphen_values = true)]
    polygon: Option<String>,
    /// Split the polygon's edges into this many vertices in all, each nudged off its edge by a
    /// millionth of it (a GIS parcel's vertex count over the same ground)
    #[arg(long)]
    vertices: Option<usize>,
    /// The grid's cell size [default: as `volume`'s]
    #[arg(long)]
    cell: Option<f64>,
    /// Cold and warm runs of each
    #[arg(long, default_value_t = 5)]
    runs: usize,
}

pub fn run(a: VolumeBenchArgs) -> Result<()> {
    for path in &a.datasets {
        let ds = Dataset::open(path)?;
        let b = ds.meta.bounds;
        let mut pts = match &a.polygon {
            Some(p) => {
                xy_arg(p, "--polygon", Want::Polygon)
                    .map_err(|e| anyhow!(e))?
                    .points
            }
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
        if let Some(n) = a.vertices {
            pts = subdivide(&pts, true, n);
        }
        let start = std::time::Instant::now();
        let polygon = Polygon::new(&pts).map_err(|e| anyhow!(e))?;
        let index = start.elapsed().as_secs_f64();
        let t = cold_warm_and_box(path, a.runs, polygon.plan_bounds(), |ds| {
            volume(ds, &polygon, Base::Rim, a.cell, &Bound::all()).map_err(|e| anyhow!(e))
        })?;
        let v = &t.last;
        let u = myriad_measure::measurement::crs_units(ds.meta.crs.as_deref());
        println!(
            "{}: {} points, {} nodes",
            path.display(),
            ds.meta.points,
            ds.meta.nodes
        );
        println!(
            "  volume      {:.0} {u}2, {} vertices (checked and indexed in {:.3} s), {} cells of {} {u}: fill {:.1} {u}3, cut {:.1} {u}3, {} points from {} nodes; cold {:.3} s, warm {:.3} s (medians of {})",
            v.area,
            polygon.vertices().len(),
            index,
            v.cells,
            v.cell,
            v.fill,
            v.cut,
            v.points,
            v.nodes_read,
            t.cold,
            t.warm,
            a.runs.max(1)
        );
        println!(
            "  baseline    extract of its box to LAS, cold: {} points, {:.3} s",
            t.baseline_points, t.baseline
        );
    }
    Ok(())
}
