//! `myriad raster DATASET -o dtm.tif --what dtm|dsm|chm|intensity|density` (a Cloud-Optimized
//! GeoTIFF) and `myriad contours DATASET --interval 1 -o c.dxf|c.geojson`: terrain products of a
//! dataset's points, edits applied (`myriad_measure::raster`, `contours`).

use anyhow::{Result, bail};
use clap::Args;
use myriad_core::units::thousands;
use myriad_format::Dataset;
use myriad_measure::raster::{self, Layout, What};
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct RasterArgs {
    /// The dataset (a .myr, COPC, EPT or Potree 2.0 dataset; a scan is converted first)
    pub dataset: PathBuf,
    /// The GeoTIFF to write (.tif): tiled, compressed, directory first (a Cloud-Optimized GeoTIFF)
    #[arg(short, long)]
    pub output: PathBuf,
    /// What each cell holds: dtm (the terrain: mean of the ground points, gaps filled), dsm (the
    /// highest point), chm (dsm over dtm), intensity (mean), density (points per unit area)
    #[arg(long, value_parser = What::parse, default_value = "dtm")]
    pub what: What,
    /// The cell, in the dataset's units [default: the points' mean spacing in plan]
    #[arg(long)]
    pub cell: Option<f64>,
    /// How far (in metres) a terrain fills gaps from the ground around them
    #[arg(long, default_value_t = 64.0)]
    pub fill: f64,
    /// Replace an existing output
    #[arg(long)]
    pub force: bool,
}

#[derive(Args)]
pub struct ContoursArgs {
    /// The dataset (a .myr, COPC, EPT or Potree 2.0 dataset; a scan is converted first)
    pub dataset: PathBuf,
    /// The contours to write: .dxf (polylines at their elevations, every fifth on CONTOURS_INDEX)
    /// or .geojson (lines with their elevations, the CRS named)
    #[arg(short, long)]
    pub output: PathBuf,
    /// The height between contours, in the dataset's units
    #[arg(long, default_value_t = 1.0)]
    pub interval: f64,
    /// The terrain's cell, in the dataset's units [default: as `raster`]
    #[arg(long)]
    pub cell: Option<f64>,
    /// How far (in metres) the terrain fills gaps from the ground around them
    #[arg(long, default_value_t = 64.0)]
    pub fill: f64,
    /// Replace an existing output
    #[arg(long)]
    pub force: bool,
}

/// The cell and the filling in cells for a dataset.
fn grid(ds: &Dataset, cell: Option<f64>, fill: f64, fills: bool) -> Result<(f64, usize)> {
    if let Some(c) = cell
        && !(c.is_finite() && c > 0.0)
    {
        bail!("--cell {c}: a positive number");
    }
    if !(fill.is_finite() && fill >= 0.0) {
        bail!("--fill {fill}: a number 0 or more");
    }
    // A terrain model finer than the ground's grid: a cell of one mean spacing.
    let o = myriad_measure::ground::Options {
        cell,
        spacings: 1.0,
        fill,
        ..Default::default()
    };
    let (p, _) = o.resolve(ds.meta.points, &ds.meta.bounds, ds.meta.crs.as_deref());
    // The margin a tile is read with: a few tiles' worth at most.
    if fills && p.fill > 1024 {
        bail!(
            "--fill: at most 1,024 cells of {} (a larger --cell)",
            p.cell
        );
    }
    Ok((p.cell, if fill == 0.0 { 0 } else { p.fill }))
}

pub fn run(a: RasterArgs) -> Result<()> {
    let ext = extension(&a.output);
    if ext != "tif" && ext != "tiff" {
        bail!(
            "{}: a raster is written as GeoTIFF (.tif)",
            a.output.display()
        );
    }
    let ds = Dataset::open(&crate::cached::dataset_for(&a.dataset)?)?;
    let fills = matches!(a.what, What::Dtm | What::Chm);
    let (cell, fill) = grid(&ds, a.cell, a.fill, fills)?;
    let t = std::time::Instant::now();
    let made = raster::write(&ds, a.what, cell, fill, &a.output, a.force)?;
    let l = made.layout;
    println!(
        "{}: {} of {} x {} cells of {cell} from ({}, {}), {} bytes, {:.2} s",
        a.output.display(),
        a.what.name(),
        thousands(l.nx as u64),
        thousands(l.ny as u64),
        l.x0,
        l.y_top,
        thousands(made.bytes),
        t.elapsed().as_secs_f64()
    );
    if ds.meta.crs.as_deref().and_then(raster::geokeys).is_none() {
        println!(
            "the dataset has no projected or geographic CRS with an EPSG code: the GeoTIFF is placed without one"
        );
    }
    Ok(())
}

/// Most cells of a terrain contoured (held whole: some 40 bytes a cell).
const MAX_CONTOUR_CELLS: u64 = 25_000_000;

pub fn contours(a: ContoursArgs) -> Result<()> {
    let ext = extension(&a.output);
    if ext != "dxf" && ext != "geojson" && ext != "json" {
        bail!(
            "{}: contours are written as .dxf or .geojson",
            a.output.display()
        );
    }
    if !(a.interval.is_finite() && a.interval > 0.0) {
        bail!("--interval {}: a positive number", a.interval);
    }
    let ds = Dataset::open(&crate::cached::dataset_for(&a.dataset)?)?;
    let (cell, fill) = grid(&ds, a.cell, a.fill, true)?;
    let l = Layout::over(&ds.meta.bounds, cell).map_err(anyhow::Error::msg)?;
    if l.nx as u64 * l.ny as u64 > MAX_CONTOUR_CELLS {
        bail!(
            "{}: a terrain of {} x {} cells of {cell}: more than {} (a larger --cell)",
            a.dataset.display(),
            l.nx,
            l.ny,
            thousands(MAX_CONTOUR_CELLS)
        );
    }
    let t = std::time::Instant::now();
    let (z, ground) = raster::block(&ds, &l, What::Dtm, fill, (0, 0, l.nx, l.ny))?;
    if ground == 0 {
        bail!(
            "{}: no ground points (class 2 or 11) for a terrain: `myriad ground` first",
            a.dataset.display()
        );
    }
    let (lo, hi) = z
        .iter()
        .filter(|v| !v.is_nan())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if ((hi - lo) as f64 / a.interval) > 10_000.0 {
        bail!(
            "--interval {}: more than 10,000 levels between {lo} and {hi}",
            a.interval
        );
    }
    let lines = myriad_measure::contours::contours(&z, l.nx, l.ny, a.interval, |c, r| {
        [l.x0 + (c + 0.5) * cell, l.y_top - (r + 0.5) * cell]
    });
    let vertices: usize = lines.iter().map(|c| c.points.len()).sum();
    if ext == "dxf" {
        myriad_measure::files::save_drawing(
            &myriad_measure::files::contours_drawing(&lines, a.interval),
            &a.output,
            a.force,
        )?;
    } else {
        let features = lines
            .iter()
            .map(|c| {
                let mut pts: Vec<[f64; 2]> = c.points.clone();
                if c.closed {
                    pts.push(pts[0]);
                }
                serde_json::json!({
                    "type": "Feature",
                    "properties": { "elevation": c.elevation },
                    "geometry": { "type": "LineString", "coordinates": pts },
                })
            })
            .collect();
        let doc = myriad_measure::geojson::collection(features, ds.meta.crs.as_deref());
        myriad_measure::files::write_atomic(&a.output, a.force, |w| {
            serde_json::to_writer(&mut *w, &doc).map_err(std::io::Error::other)
        })?;
    }
    println!(
        "{}: {} contours every {} ({} vertices) from a terrain of {} x {} cells of {cell}, {:.2} s",
        a.output.display(),
        thousands(lines.len() as u64),
        a.interval,
        thousands(vertices as u64),
        thousands(l.nx as u64),
        thousands(l.ny as u64),
        t.elapsed().as_secs_f64()
    );
    Ok(())
}

fn extension(p: &Path) -> String {
    p.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}
