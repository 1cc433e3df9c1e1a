//! Ground found out of core (`myriad ground`): the terrain under a dataset of any size, made by
//! [`smrf`] in tiles with overlap (each tile's core exactly as the whole grid would give it, so
//! no seam), written as a [`surface`] beside the dataset; an edit (`myriad_measure::edits`)
//! then gives class 2 to the points near it, class 7 to those far below it, and class 1 to
//! points labelled ground that are not.
//!
//! Memory: the tiles in flight (one a thread), each a grid of its core and margin with a few
//! values a cell; the points are read node by node from the pages each tile's area meets.

pub mod smrf;
pub mod surface;

#[cfg(not(target_arch = "wasm32"))]
pub use build::*;

/// How a point is classified against the terrain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rule {
    /// A point within this height of the terrain is ground...
    pub threshold: f64,
    /// ...plus this much per unit of the terrain's slope there (rise over run).
    pub scalar: f64,
    /// A point more than this further below the terrain than a ground point may be is low
    /// noise (class 7).
    pub low: f64,
}

impl Default for Rule {
    fn default() -> Rule {
        Rule {
            threshold: 0.5,
            scalar: 1.25,
            low: 1.0,
        }
    }
}

impl Rule {
    /// The class of a point of class `class` at height `h` above a terrain of slope `slope`:
    /// `None` to leave it. Points of the surfaces on the ground (water 9, rail 10, road 11)
    /// keep their classes there.
    pub fn class(&self, class: u8, h: f64, slope: f64) -> Option<u8> {
        let tol = self.threshold + self.scalar * slope;
        if h.abs() <= tol {
            (!matches!(class, 2 | 9 | 10 | 11)).then_some(2)
        } else if h < -(tol + self.low) {
            Some(7)
        } else if class == 2 {
            Some(1)
        } else {
            None
        }
    }
}

/// What a user sets, in metres where they are lengths (converted to the dataset's units
/// through its CRS; a dataset without one is taken to be in metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// The grid's cell; `None`: [`Options::spacings`] times the points' mean spacing in plan.
    pub cell: Option<f64>,
    /// With no cell given: how many mean spacings a cell is.
    pub spacings: f64,
    pub slope: f64,
    pub window: f64,
    pub fill: f64,
    pub threshold: f64,
    pub scalar: f64,
    pub low: f64,
    /// A point with fewer than this many others in the 3 x 3 x 3 cubes of a cell around it is
    /// isolated noise (class 7); 0: none looked for.
    pub isolated: usize,
}

impl Default for Options {
    fn default() -> Options {
        Options {
            cell: None,
            spacings: 2.5,
            slope: 0.15,
            window: 30.0,
            fill: 64.0,
            threshold: 0.5,
            scalar: 1.25,
            low: 1.0,
            isolated: 2,
        }
    }
}

impl Options {
    /// The filter's parameters and the rule for a dataset of `points` points within `bounds`
    /// in `crs`.
    pub fn resolve(
        &self,
        points: u64,
        bounds: &myriad_core::Aabb,
        crs: Option<&str>,
    ) -> (smrf::Params, Rule) {
        let unit = crs.and_then(crate::crs::metres_per_unit).unwrap_or(1.0);
        let m = |v: f64| v / unit;
        let area = (bounds.max[0] - bounds.min[0]) * (bounds.max[1] - bounds.min[1]);
        let spacing = (area / points.max(1) as f64).sqrt();
        let cell = self.cell.unwrap_or_else(|| {
            // Two significant digits, at least a centimetre.
            let c = (self.spacings * spacing).max(m(0.01));
            let e = 10f64.powf(c.log10().floor() - 1.0);
            (c / e).round() * e
        });
        let cells = |v: f64| (m(v) / cell).ceil().max(1.0) as usize;
        (
            smrf::Params {
                cell,
                slope: self.slope,
                window: cells(self.window),
                fill: cells(self.fill),
                low: m(self.low),
            },
            Rule {
                threshold: m(self.threshold),
                scalar: self.scalar,
                low: m(self.low),
            },
        )
    }
}

/// Classes the terrain is never made from and never changed: noise, low and high.
pub fn is_noise(class: u8) -> bool {
    class == 7 || class == 18
}

/// A filter keeping every point but noise ([`is_noise`]), for a dataset's columns (all points
/// where it has no classes).
pub fn not_noise(schema: &myriad_core::Schema) -> Result<crate::Bound, String> {
    if !schema.has(&myriad_core::Attribute::Classification) {
        return Ok(crate::Bound::all());
    }
    crate::Filter::parse(Some("0-6,8-17,19-255"), &[])?.bind(schema)
}

#[cfg(not(target_arch = "wasm32"))]
mod build {
    use super::smrf::{self, Grid, Params};
    use super::surface::{Isolated, MAX_ISOLATED, Placement, SurfaceWriter, voxel_key};
    use myriad_core::{Aabb, Error, Result};
    use myriad_format::Dataset;
    use rayon::prelude::*;
    use std::path::Path;
    use std::sync::atomic::{AtomicU64, Ordering};

    /// The most cells a grid may have (a side of 2^24 cells).
    const MAX_SIDE: f64 = (1u64 << 24) as f64;
    /// Most tiles of a surface (its index stays a few megabytes).
    const MAX_TILES: usize = 100_000;
    /// Bytes of memory a cell of a tile in flight takes (the filter's grids)...
    pub const BYTES_PER_CELL: u64 = 40;
    /// ...and, where isolated points are looked for, the cubes' keys of its points (8 bytes
    /// each, some 8 points a cell at the default cell of 2.5 spacings).
    pub const BYTES_PER_CELL_ISOLATED: u64 = 104;

    /// The voxels of a tile's core (`cx`, `cy`, `w`, `h`, in cells) whose points have fewer than
    /// `least` others in the 27 voxels around them; `keys`: a voxel key a point of the tile and
    /// its margin.
    fn lonely_voxels(
        mut keys: Vec<u64>,
        least: usize,
        (cx, cy, w, h): (usize, usize, usize, usize),
    ) -> Vec<u64> {
        keys.sort_unstable();
        let mut runs: Vec<(u64, u32)> = Vec::new();
        for k in keys {
            match runs.last_mut() {
                Some((last, n)) if *last == k => *n += 1,
                _ => runs.push((k, 1)),
            }
        }
        let count = |k: u64| {
            runs.binary_search_by_key(&k, |r| r.0)
                .map_or(0, |i| runs[i].1)
        };
        let split = |k: u64| {
            (
                (k >> 40) as i64,
                (k >> 16 & 0xff_ffff) as i64,
                (k & 0xffff) as i64,
            )
        };
        let mut out = Vec::new();
        for &(k, n) in &runs {
            let (i, j, z) = split(k);
            let core = (i as usize) >= cx && (i as usize) < cx + w;
            if !core || (j as usize) < cy || (j as usize) >= cy + h || n as usize > least {
                continue;
            }
            let mut others = n as usize - 1;
            'around: for di in -1..=1 {
                for dj in -1..=1 {
                    for dz in -1..=1 {
                        let (a, b, c) = (i + di, j + dj, z + dz);
                        let side = 0..1 << 24;
                        if (di, dj, dz) == (0, 0, 0)
                            || !side.contains(&a)
                            || !side.contains(&b)
                            || !(0..=0xffff).contains(&c)
                        {
                            continue;
                        }
                        others += count(voxel_key(a as u64, b as u64, c as u64)) as usize;
                        if others >= least {
                            break 'around;
                        }
                    }
                }
            }
            if others < least {
                out.push(k);
            }
        }
        out
    }

    /// What [`build`] made.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct Made {
        pub placement: Placement,
        pub tiles: usize,
        /// Points read (a point in the overlap of tiles is read once for each).
        pub points_read: u64,
        pub bytes: u64,
    }

    /// The side of a tile's core for a memory budget and a number of threads (`isolated`: the
    /// isolated points looked for too). An error where even a tile of 64 cells and its margin
    /// do not fit in `memory`.
    pub fn tile_for(memory: u64, threads: usize, p: &Params, isolated: bool) -> Result<usize> {
        let per_cell = if isolated {
            BYTES_PER_CELL_ISOLATED
        } else {
            BYTES_PER_CELL
        };
        let cells = memory / per_cell / threads.max(1) as u64;
        let side = (cells as f64).sqrt() as usize;
        let m = 2 * smrf::margin(p);
        if side < 64 + m {
            let least = ((64 + m) as u64).pow(2) * per_cell * threads.max(1) as u64;
            return Err(Error::Invalid(format!(
                "--memory {memory}: a tile of 64 cells and its margin of {} need {least} bytes on \
                 each of {threads} threads together (more --memory, a larger --cell, or a smaller \
                 --window or --fill)",
                m / 2
            )));
        }
        Ok((side - m).min(2048))
    }

    /// Makes the terrain under `ds` with `p` in tiles of `tile` cells (a side) and writes it to
    /// `out` (which must not exist), with the voxels (cubes of a cell) whose points have fewer
    /// than `isolated` others in the 27 around them (none where 0). `progress` is told each tile
    /// done.
    pub fn build(
        ds: &Dataset,
        p: &Params,
        isolated: usize,
        tile: usize,
        out: &Path,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Made> {
        let b = ds.meta.bounds;
        let name = ds.path().display();
        let (nx, ny) = (
            ((b.max[0] - b.min[0]) / p.cell).floor() + 1.0,
            ((b.max[1] - b.min[1]) / p.cell).floor() + 1.0,
        );
        if !(nx.is_finite() && ny.is_finite()) || b.is_empty() {
            return Err(Error::Invalid(format!(
                "{name}: the dataset holds no points"
            )));
        }
        if nx > MAX_SIDE || ny > MAX_SIDE {
            return Err(Error::Invalid(format!(
                "{name}: a grid of {nx} x {ny} cells of {}: larger than 2^24 a side (a larger --cell)",
                p.cell
            )));
        }
        let placement = Placement {
            x0: b.min[0],
            y0: b.min[1],
            cell: p.cell,
            nx: nx as usize,
            ny: ny as usize,
            tile,
        };
        // The terrain is made from every point but noise.
        let bound = super::not_noise(&ds.meta.schema).map_err(Error::Invalid)?;
        if tile == 0 || tile > super::surface::MAX_TILE {
            return Err(Error::Invalid(format!(
                "a tile of {tile} cells: from 1 to {}",
                super::surface::MAX_TILE
            )));
        }
        if placement.tiles().0 * placement.tiles().1 > MAX_TILES {
            return Err(Error::Invalid(format!(
                "{name}: {} x {} tiles of {tile} cells: more than {MAX_TILES} (a larger tile or cell)",
                placement.tiles().0,
                placement.tiles().1
            )));
        }
        let writer = SurfaceWriter::create(out, placement)?;
        let (tx, ty) = placement.tiles();
        let m = smrf::margin(p);
        let done = AtomicU64::new(0);
        let read = AtomicU64::new(0);
        let lonely = std::sync::Mutex::new(Vec::new());
        let voxel = |q: &[f64; 3]| {
            let (i, j) = (
                (q[0] - placement.x0) / p.cell,
                (q[1] - placement.y0) / p.cell,
            );
            let k = ((q[2] - b.min[2]) / p.cell).clamp(0.0, 65535.0);
            voxel_key(i as u64, j as u64, k as u64)
        };
        (0..tx * ty)
            .into_par_iter()
            .try_for_each(|t| -> Result<()> {
                let (cx, cy, w, h) = placement.core(t % tx, t / tx);
                // The tile's grid: its core and the margin around it within the whole grid (the
                // whole grid is one tile with no margin: the same cells, the same values), cell
                // (0, 0) at (ex, ey).
                let (ex, ey) = (cx.saturating_sub(m), cy.saturating_sub(m));
                let (gw, gh) = (
                    (cx + w + m).min(placement.nx) - ex,
                    (cy + h + m).min(placement.ny) - ey,
                );
                let (ex, ey) = (ex as isize, ey as isize);
                let area = Aabb::new(
                    [
                        placement.x0 + ex as f64 * p.cell,
                        placement.y0 + ey as f64 * p.cell,
                        b.min[2],
                    ],
                    [
                        placement.x0 + (ex + gw as isize) as f64 * p.cell,
                        placement.y0 + (ey + gh as isize) as f64 * p.cell,
                        b.max[2],
                    ],
                );
                let mut zmin = Grid::empty(gw, gh);
                let mut keys = Vec::new();
                let got = crate::read_region(ds, &area, &bound, |batch| {
                    for q in &batch.positions {
                        let gx = ((q[0] - placement.x0) / p.cell).floor() as isize - ex;
                        let gy = ((q[1] - placement.y0) / p.cell).floor() as isize - ey;
                        if gx >= 0 && gy >= 0 && (gx as usize) < gw && (gy as usize) < gh {
                            if isolated > 0 {
                                keys.push(voxel(q));
                            }
                            let c = &mut zmin.z[gy as usize * gw + gx as usize];
                            let z = q[2] as f32;
                            if c.is_nan() || z < *c {
                                *c = z;
                            }
                        }
                    }
                })
                .map_err(Error::Invalid)?;
                read.fetch_add(got.points, Ordering::Relaxed);
                if isolated > 0 {
                    let found = lonely_voxels(keys, isolated, (cx, cy, w, h));
                    let mut all = lonely.lock().expect("isolated voxels");
                    all.extend(found);
                    if all.len() > MAX_ISOLATED {
                        return Err(Error::Invalid(format!(
                            "{name}: more than {MAX_ISOLATED} isolated cubes of {}: \
                             --isolated {isolated} finds too many (a smaller one, or 0)",
                            p.cell
                        )));
                    }
                }
                let (terrain, _) = smrf::terrain(&zmin, p);
                writer.write_tile(t % tx, t / tx, |x, y| {
                    let (gx, gy) = ((x - ex) as usize, (y - ey) as usize);
                    terrain.z[gy * gw + gx]
                })?;
                progress(done.fetch_add(1, Ordering::Relaxed) as usize + 1, tx * ty);
                Ok(())
            })?;
        if isolated > 0 {
            let mut keys = lonely.into_inner().expect("isolated voxels");
            keys.sort_unstable();
            writer.set_isolated(Isolated { z0: b.min[2], keys });
        }
        let bytes = writer.finish()?;
        Ok(Made {
            placement,
            tiles: tx * ty,
            points_read: read.into_inner(),
            bytes,
        })
    }
}
