//! `--to-crs`: a source whose points move into another coordinate system as they are read,
//! through PROJ ([`crate::proj`]), on all cores, with the dataset's grid chosen anew for the
//! target's units. [`crate::open`] applies it after the placement, so every build (convert,
//! append, plan, parts) moves its points the same way.

use crate::proj::{Kind, Pool};
use crate::{PointSource, SourceInfo};
use myriad_core::{Aabb, Error, PointBatch, Result};

/// `--to-crs` (and `--from-crs`): what [`crate::open`] moves every point into.
#[derive(Debug, Clone, PartialEq)]
pub struct Reproject {
    /// The target CRS, as the user gave it.
    pub to: String,
    /// The CRS of inputs whose file names none.
    pub from: Option<String>,
}

/// A grid step in the target's units as fine as `step` source units, a tenth finer (rounded
/// down to a power of ten): a moved point stays within a twentieth of the input's own step.
fn target_step(step: f64, from: (f64, bool), to: (f64, bool)) -> f64 {
    // Angles through the length of a radian on the equator: a degree is 111 km.
    const RADIUS: f64 = 6_378_137.0;
    let metres = step * from.0 * if from.1 { RADIUS } else { 1.0 };
    let t = metres / (to.0 * if to.1 { RADIUS } else { 1.0 });
    10f64.powf(t.log10().floor()) / 10.0
}

/// A source whose points are moved into another CRS as they are read. Points that do not
/// transform (outside the projection's domain, a grid missing there) are dropped and counted
/// ([`PointSource::not_transformed`]), never moved to 0,0.
pub struct Reprojected {
    inner: Box<dyn PointSource>,
    workers: Pool,
    info: SourceInfo,
    header: Option<::las::Header>,
    failed: u64,
}

impl Reprojected {
    pub fn new(inner: Box<dyn PointSource>, r: &Reproject) -> Result<Reprojected> {
        let path = inner.info().path.clone();
        let from = match (&inner.info().crs, &r.from) {
            (Some(c), _) => c.clone(),
            (None, Some(f)) => f.clone(),
            (None, None) => {
                return Err(Error::unsupported(
                    &path,
                    "names no coordinate system to move its points from: give --from-crs",
                ));
            }
        };
        let fail = |m: String| Error::unsupported(&path, m);
        let workers = Pool::new(&from, &r.to).map_err(fail)?;
        let mut transform = workers.get();
        let mut info = inner.info().clone();
        info.crs = Some(transform.target().wkt().map_err(fail)?);
        // The grid anew, per axis, for the target's units (a foot is not a metre, a metre
        // not a degree); inputs of float coordinates keep --precision, in the target's units.
        let (su, tu) = (
            transform.source().axis_units().map_err(fail)?,
            transform.target().axis_units().map_err(fail)?,
        );
        // Heights: PROJ moves them only between CRSs with a vertical axis (a 2D CRS's z is
        // taken as metres above the ellipsoid where the other has heights, else left as it is).
        let metres = (1.0, false);
        let unit = |u: &[(f64, bool)], a: usize| u.get(a).copied().unwrap_or(metres);
        info.scale = inner.info().scale.map(|s| {
            std::array::from_fn(|a| {
                if a == 2 && su.len() < 3 && tu.len() < 3 {
                    s[2].abs()
                } else {
                    target_step(s[a].abs(), unit(&su, a), unit(&tu, a))
                }
            })
        });
        info.offset = None;
        // Earth-centred axes each mix heights and ground: the finest step for all three.
        if transform.target().horizontal_kind() == Kind::Geocentric
            && let Some(st) = &mut info.scale
        {
            *st = [st.iter().copied().fold(f64::INFINITY, f64::min); 3];
        }
        let fine = info.scale;
        // The header's bounds moved: the box of its faces' points, moved, with a margin (a
        // point outside it still finds its place: the build scatters again when one does).
        info.bounds = inner.info().bounds.and_then(|b| {
            let mut faces = Vec::new();
            let n = 8;
            for axis in 0..3 {
                for side in [b.min[axis], b.max[axis]] {
                    for i in 0..=n {
                        for j in 0..=n {
                            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                            let mut p = [0.0; 3];
                            p[axis] = side;
                            p[u] = b.min[u] + (b.max[u] - b.min[u]) * i as f64 / n as f64;
                            p[v] = b.min[v] + (b.max[v] - b.min[v]) * j as f64 / n as f64;
                            faces.push(p);
                        }
                    }
                }
            }
            if transform.apply(&mut faces) > 0 {
                return None;
            }
            let mut moved = Aabb::EMPTY;
            for p in &faces {
                moved.extend(*p);
            }
            let pad = moved.size().map(|s| s * 1e-3);
            Some(Aabb {
                min: std::array::from_fn(|a| moved.min[a] - pad[a]),
                max: std::array::from_fn(|a| moved.max[a] + pad[a]),
            })
        });
        // A grid that fine must still number the data's extent in LAS's 32-bit integers from
        // an offset on a whole unit (what `extract` writes): coarser by tens where it does not.
        if let (Some(mut step), Some(b)) = (fine, info.bounds) {
            for a in 0..3 {
                let reach = b.max[a] - b.min[a].floor();
                while reach / step[a] >= i32::MAX as f64 / 2.0 {
                    step[a] *= 10.0;
                }
            }
            info.scale = Some(step);
        }
        // Scanner positions move with the points.
        info.origins.retain_mut(|o| match transform.point(*o) {
            Some(q) => {
                *o = q;
                true
            }
            None => false,
        });
        // The LAS header's own CRS records describe the coordinates before: dropped.
        let header = inner.las_header().map(|h| {
            let mut h = h.clone();
            h.remove_crs_vlrs();
            h
        });
        drop(transform);
        Ok(Reprojected {
            inner,
            workers,
            info,
            header,
            failed: 0,
        })
    }
}

impl PointSource for Reprojected {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>> {
        while let Some(mut b) = self.inner.read_batch(max)? {
            // A normal turns as the map's local frame does: moved as a short step from its
            // point, the step's direction after.
            let mut tips: Option<Vec<[f64; 3]>> = b.normal.as_ref().map(|normals| {
                b.positions
                    .iter()
                    .zip(normals)
                    .map(|(p, n)| std::array::from_fn(|a| p[a] + 0.01 * n[a] as f64))
                    .collect()
            });
            let failed = self.workers.apply(&mut b.positions);
            if let (Some(normals), Some(tips)) = (&mut b.normal, &mut tips) {
                self.workers.apply(tips);
                for ((n, q), t) in normals.iter_mut().zip(&b.positions).zip(tips.iter()) {
                    let d: [f64; 3] = std::array::from_fn(|a| t[a] - q[a]);
                    let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    if l > 0.0 && l.is_finite() {
                        *n = d.map(|c| (c / l) as f32);
                    }
                }
            }
            if failed > 0 {
                let keep: Vec<bool> = b.positions.iter().map(|p| p[0].is_finite()).collect();
                b.retain_mask(&keep);
                self.failed += failed as u64;
            }
            if !b.is_empty() {
                return Ok(Some(b));
            }
        }
        Ok(None)
    }

    fn skipped_non_finite(&self) -> u64 {
        self.inner.skipped_non_finite()
    }

    fn not_transformed(&self) -> u64 {
        self.failed
    }

    fn trimmed(&self) -> u64 {
        self.inner.trimmed()
    }

    fn placement_path(&self) -> Option<&std::path::Path> {
        self.inner.placement_path()
    }

    fn las_header(&self) -> Option<&::las::Header> {
        self.header.as_ref()
    }
}
