//! Terrain products as rasters (`myriad raster`, `myriad contours`): a terrain model (the mean
//! height of the ground points of each cell, gaps filled from around them), a surface model (the
//! highest point), their difference (canopy heights), mean intensity and point density, over a
//! grid aligned to the cell, made block by block (a block is a GeoTIFF tile, with a margin for
//! filling gaps) from the pages each block's area meets: any size within a few blocks' memory.
//! The terrain is made of the points classified ground (2) and road (11), as the dataset's
//! edits leave them (`myriad ground` first where the dataset has no ground classes).

use crate::ground::smrf::{self, Grid};
use myriad_core::{Aabb, Attribute, Error, Result};
use myriad_format::Dataset;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// What a raster holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum What {
    Dtm,
    Dsm,
    Chm,
    Intensity,
    Density,
}

impl What {
    pub fn parse(s: &str) -> std::result::Result<What, String> {
        Ok(match s {
            "dtm" => What::Dtm,
            "dsm" => What::Dsm,
            "chm" => What::Chm,
            "intensity" => What::Intensity,
            "density" => What::Density,
            _ => return Err(format!("{s}: one of dtm, dsm, chm, intensity, density")),
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            What::Dtm => "dtm",
            What::Dsm => "dsm",
            What::Chm => "chm",
            What::Intensity => "intensity",
            What::Density => "density",
        }
    }

    fn needs_ground(self) -> bool {
        matches!(self, What::Dtm | What::Chm)
    }
}

/// A raster's grid: `nx` columns from `x0` east, `ny` rows from `y_top` south.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layout {
    pub x0: f64,
    pub y_top: f64,
    pub cell: f64,
    pub nx: usize,
    pub ny: usize,
}

impl Layout {
    /// The grid of `cell` over `b`, its corners on multiples of the cell.
    pub fn over(b: &Aabb, cell: f64) -> std::result::Result<Layout, String> {
        let mut x0 = (b.min[0] / cell).floor() * cell;
        let mut y_top = (b.max[1] / cell).floor() * cell + cell;
        // Rounding must not leave the lowest x or the highest y outside the grid.
        if ((b.min[0] - x0) / cell).floor() < 0.0 {
            x0 -= cell;
        }
        if ((y_top - b.max[1]) / cell).floor() < 0.0 {
            y_top += cell;
        }
        let nx = ((b.max[0] - x0) / cell).floor() + 1.0;
        let ny = ((y_top - b.min[1]) / cell).floor() + 1.0;
        if !(nx.is_finite() && ny.is_finite() && nx >= 1.0 && ny >= 1.0) {
            return Err("the dataset holds no points".into());
        }
        if nx * ny > 1e12 || nx > 4e9 || ny > 4e9 {
            return Err(format!(
                "{nx} x {ny} cells of {cell}: too many (a larger --cell)"
            ));
        }
        Ok(Layout {
            x0,
            y_top,
            cell,
            nx: nx as usize,
            ny: ny as usize,
        })
    }

    /// The cell of a point: column and row.
    pub fn cell_of(&self, x: f64, y: f64) -> (isize, isize) {
        (
            ((x - self.x0) / self.cell).floor() as isize,
            ((self.y_top - y) / self.cell).floor() as isize,
        )
    }
}

/// The block of cells `[c0, c0 + w) x [r0, r0 + h)` of `what`, with gaps of a terrain filled
/// from as far as `fill` cells (read with that margin, so that blocks agree with the whole).
/// Also the ground points read.
pub fn block(
    ds: &Dataset,
    l: &Layout,
    what: What,
    fill: usize,
    (c0, r0, w, h): (usize, usize, usize, usize),
) -> Result<(Vec<f32>, u64)> {
    let m = if what.needs_ground() { fill } else { 0 };
    let (e0, f0) = (c0.saturating_sub(m), r0.saturating_sub(m));
    let (gw, gh) = ((c0 + w + m).min(l.nx) - e0, (r0 + h + m).min(l.ny) - f0);
    let b = &ds.meta.bounds;
    // Read a cell wider on every side: which cell a point is in is decided by `cell_of` alone
    // (the area's edges, computed otherwise, may round the other way).
    let area = Aabb::new(
        [
            l.x0 + (e0 as f64 - 1.0) * l.cell,
            l.y_top - (f0 + gh + 1) as f64 * l.cell,
            b.min[2],
        ],
        [
            l.x0 + (e0 + gw + 1) as f64 * l.cell,
            l.y_top - (f0 as f64 - 1.0) * l.cell,
            b.max[2],
        ],
    );
    let not_noise = crate::ground::not_noise(&ds.meta.schema).map_err(Error::Invalid)?;
    let n = gw * gh;
    let (mut top, mut sum, mut count) = (vec![f32::NAN; n], vec![0f64; n], vec![0u64; n]);
    let mut ground_sum = vec![0f64; n];
    let mut ground_n = vec![0u64; n];
    let in_core = |c: usize, r: usize| {
        (c0 - e0..c0 - e0 + w).contains(&c) && (r0 - f0..r0 - f0 + h).contains(&r)
    };
    let mut ground = 0u64;
    crate::read_region(ds, &area, &not_noise, |batch| {
        for i in 0..batch.len() {
            let [x, y, z] = batch.positions[i];
            let (c, r) = l.cell_of(x, y);
            let (c, r) = (c - e0 as isize, r - f0 as isize);
            // A point on the area's far edges belongs to the next block.
            if c < 0 || r < 0 || c as usize >= gw || r as usize >= gh {
                continue;
            }
            let k = r as usize * gw + c as usize;
            if top[k].is_nan() || z as f32 > top[k] {
                top[k] = z as f32;
            }
            count[k] += 1;
            if let Some(v) = &batch.intensity {
                sum[k] += v[i] as f64;
            }
            if let Some(cl) = &batch.classification
                && matches!(cl[i], 2 | 11)
            {
                ground_sum[k] += z;
                ground_n[k] += 1;
                ground += in_core(c as usize, r as usize) as u64;
            }
        }
    })
    .map_err(Error::Invalid)?;
    let terrain = || {
        let mut g = Grid {
            nx: gw,
            ny: gh,
            z: means(&ground_sum, &ground_n),
        };
        smrf::fill(&mut g, fill);
        g.z
    };
    let values: Vec<f32> = match what {
        What::Dsm => top,
        What::Dtm => terrain(),
        What::Chm => (top.iter().zip(terrain()))
            .map(|(&t, g)| {
                if t.is_nan() || g.is_nan() {
                    f32::NAN
                } else {
                    (t - g).max(0.0)
                }
            })
            .collect(),
        What::Intensity => means(&sum, &count),
        What::Density => count
            .iter()
            .map(|&n| (n as f64 / (l.cell * l.cell)) as f32)
            .collect(),
    };
    // The core.
    let mut core = Vec::with_capacity(w * h);
    for r in r0 - f0..r0 - f0 + h {
        core.extend_from_slice(&values[r * gw + (c0 - e0)..r * gw + (c0 - e0) + w]);
    }
    Ok((core, ground))
}

/// The EPSG code a GeoTIFF names a CRS by, and whether it is geographic: a projected or
/// geographic CRS only (a compound one's code is not its horizontal part's; a geocentric one has
/// no place in a raster's keys). A bare code without PROJ to say what it is: geographic in EPSG's
/// 4000s.
pub fn geokeys(crs: &str) -> Option<(u32, bool)> {
    let d = crate::crs::describe(crs);
    let code = d.epsg?;
    let bare = crs.trim_start().starts_with("EPSG:");
    if d.vertical.is_some() && !bare {
        return None;
    }
    match d.kind {
        "projected" => Some((code, false)),
        "geographic" => Some((code, true)),
        "unknown" if bare => Some((code, (4000..5000).contains(&code))),
        _ => None,
    }
}

/// Each cell's sum over its count (NaN where it has none).
fn means(sum: &[f64], count: &[u64]) -> Vec<f32> {
    (sum.iter().zip(count))
        .map(|(&s, &n)| {
            if n > 0 {
                (s / n as f64) as f32
            } else {
                f32::NAN
            }
        })
        .collect()
}

/// What [`write`] made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Made {
    pub layout: Layout,
    pub bytes: u64,
    pub ground: u64,
}

/// Writes `what` of `ds` on a grid of `cell` as a Cloud-Optimized GeoTIFF at `out`.
pub fn write(
    ds: &Dataset,
    what: What,
    cell: f64,
    fill: usize,
    out: &std::path::Path,
    force: bool,
) -> Result<Made> {
    let name = ds.path().display();
    if !(cell.is_finite() && cell > 0.0) {
        return Err(Error::Invalid(format!("--cell {cell}: a positive number")));
    }
    if what.needs_ground() && !ds.meta.schema.has(&Attribute::Classification) {
        return Err(Error::Invalid(format!(
            "{name}: no classes, so no ground points for a terrain model"
        )));
    }
    if what == What::Intensity && !ds.meta.schema.has(&Attribute::Intensity) {
        return Err(Error::Invalid(format!("{name}: no intensity")));
    }
    let l =
        Layout::over(&ds.meta.bounds, cell).map_err(|m| Error::Invalid(format!("{name}: {m}")))?;
    // Refused before writing where even its uncompressed pixels could not fit on the disk.
    let most = l.nx as u64 * l.ny as u64 * 4;
    let dir = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(std::path::Path::new("."));
    if let Some(free) = myriad_io::process::free_bytes(dir)
        && most > free
    {
        return Err(Error::Invalid(format!(
            "{}: a raster of {} x {} cells (up to {most} bytes) does not fit in the {free} bytes free there (a larger --cell)",
            out.display(),
            l.nx,
            l.ny
        )));
    }
    if most + (1 << 24) > u32::MAX as u64 {
        return Err(Error::Invalid(format!(
            "{}: a raster of {} x {} cells could pass the 4 GB a classic TIFF holds (BigTIFF is not \
             written yet): a larger --cell",
            out.display(),
            l.nx,
            l.ny
        )));
    }
    let epsg = ds.meta.crs.as_deref().and_then(geokeys);
    let writer = myriad_io::geotiff::GeoTiffWriter::create(
        out,
        force,
        l.nx,
        l.ny,
        myriad_io::geotiff::Georef {
            x0: l.x0,
            y_top: l.y_top,
            cell,
            epsg,
        },
    )?;
    let tile = myriad_io::geotiff::TILE;
    let (across, down) = writer.tiles();
    let ground = AtomicU64::new(0);
    (0..across * down)
        .into_par_iter()
        .try_for_each(|t| -> Result<()> {
            let (tx, ty) = (t % across, t / across);
            let (c0, r0) = (tx * tile, ty * tile);
            let (w, h) = (tile.min(l.nx - c0), tile.min(l.ny - r0));
            let (core, g) = block(ds, &l, what, fill, (c0, r0, w, h))?;
            ground.fetch_add(g, Ordering::Relaxed);
            // A whole tile: the image's edge padded with no data.
            let mut full = vec![f32::NAN; tile * tile];
            for r in 0..h {
                full[r * tile..r * tile + w].copy_from_slice(&core[r * w..(r + 1) * w]);
            }
            writer.write_tile(tx, ty, &full)
        })?;
    let ground = ground.into_inner();
    if what.needs_ground() && ground == 0 {
        return Err(Error::Invalid(format!(
            "{name}: no ground points (class 2 or 11) for a terrain model: `myriad ground {name}` \
             first; nothing written"
        )));
    }
    let bytes = writer.finish()?;
    Ok(Made {
        layout: l,
        bytes,
        ground,
    })
}
