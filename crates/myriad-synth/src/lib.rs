//! `myriad synth`: simulated laser scans of procedural scenes, of any size, streamed to LAS/LAZ.
//!
//! The scan is a numbered sequence of pulses; blocks of pulses are generated in parallel (rayon)
//! and written in order by one writer thread, so output is identical for any thread count and
//! memory is bounded by a few blocks in flight, whatever `points` is. See [`scene`] for the world
//! and [`scan`] for the scanners.

mod e57;
mod rng;
pub mod scan;
pub mod scene;
pub mod stockpiles;

use myriad_core::{Error, PointBatch, Result, Schema};
use myriad_io::las::{LasSink, LasWriteOptions};
use rayon::prelude::*;
use std::path::Path;
use std::sync::mpsc::sync_channel;

/// The built-in scenes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneKind {
    /// Airborne survey of a city: streets, buildings of varied heights, trees, gentle terrain.
    City,
    /// Airborne survey of hilly, forested land with a winding road.
    Terrain,
    /// Terrestrial scans of furnished rooms, two stations per room.
    Indoor,
    /// Cones and ridges of material of known volume on sloping ground ([`stockpiles`]); epoch
    /// 2 is a later survey with the first pile gone.
    Stockpiles { epoch: u32 },
}

#[derive(Debug, Clone)]
pub struct SynthOptions {
    pub points: u64,
    pub scene: SceneKind,
    pub seed: u64,
}

/// Where a scene sits in the world: easting and northing in [`CRS_WKT`], so coordinates look real.
pub const ORIGIN: [f64; 3] = [500_000.0, 4_400_000.0, 0.0];

/// The coordinate reference system of every synthetic scan: WGS 84 / UTM zone 33N (EPSG:32633).
pub const CRS_WKT: &str = concat!(
    r#"PROJCS["WGS 84 / UTM zone 33N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,"#,
    r#"AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],"#,
    r#"UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AUTHORITY["EPSG","4326"]],"#,
    r#"PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",0],PARAMETER["central_meridian",15],"#,
    r#"PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",500000],PARAMETER["false_northing",0],"#,
    r#"UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AXIS["Northing",NORTH],AUTHORITY["EPSG","32633"]]"#
);
const BLOCK_PULSES: u64 = 1 << 15;

/// The attributes every synthetic scan carries: those of LAS point format 3.
pub fn schema() -> Schema {
    Schema::for_las_format(3)
}

enum Scanner<'a> {
    Air(scan::Airborne<'a>),
    Indoor(scan::Indoor),
    Piles(stockpiles::Site),
}

impl Scanner<'_> {
    fn block(&self, b: u64) -> PointBatch {
        let mut out = PointBatch::with_schema(&schema(), (BLOCK_PULSES as usize * 5) / 4);
        let mut cache = scan::Cache::default();
        for k in b * BLOCK_PULSES..(b + 1) * BLOCK_PULSES {
            match self {
                Scanner::Air(a) => a.pulse(k, &mut cache, &mut out),
                Scanner::Indoor(s) => s.pulse(k, &mut cache, &mut out),
                Scanner::Piles(s) => s.pulse(k, &mut out),
            }
        }
        for p in &mut out.positions {
            for a in 0..3 {
                p[a] += ORIGIN[a];
            }
        }
        out
    }
}

/// Generates `options.points` points in pulse order and hands them to `sink` in batches.
/// `sink` runs on its own thread while the next blocks are generated.
pub fn generate<F>(options: &SynthOptions, mut sink: F) -> Result<()>
where
    F: FnMut(&PointBatch) -> Result<()> + Send,
{
    let city;
    let terrain;
    let scanner = match options.scene {
        SceneKind::City => {
            city = scene::Scene::new(scene::Kind::City, options.seed);
            Scanner::Air(scan::Airborne::new(
                &city,
                scan::Flight::plan(options.points, 0.97),
            ))
        }
        SceneKind::Terrain => {
            terrain = scene::Scene::new(scene::Kind::Terrain, options.seed);
            Scanner::Air(scan::Airborne::new(
                &terrain,
                scan::Flight::plan(options.points, 1.1),
            ))
        }
        SceneKind::Indoor => Scanner::Indoor(scan::Indoor::plan(options.points, options.seed)),
        SceneKind::Stockpiles { epoch } => {
            Scanner::Piles(stockpiles::Site::plan(options.points, options.seed, epoch))
        }
    };
    // Several blocks per thread per wave, so that uneven blocks still keep every core busy.
    let wave = (rayon::current_num_threads() * 6).max(2) as u64;
    let (tx, rx) = sync_channel::<Vec<PointBatch>>(1);
    std::thread::scope(|s| {
        let writer = s.spawn(move || -> Result<()> {
            let mut left = options.points;
            for batches in rx {
                for mut b in batches {
                    if left == 0 {
                        return Ok(());
                    }
                    if b.len() as u64 > left {
                        b.truncate(left as usize);
                    }
                    left -= b.len() as u64;
                    sink(&b)?;
                }
                if left == 0 {
                    return Ok(());
                }
            }
            Ok(())
        });
        let mut generated = 0u64;
        let mut next = 0u64;
        while generated < options.points {
            let batches: Vec<PointBatch> = (next..next + wave)
                .into_par_iter()
                .map(|b| scanner.block(b))
                .collect();
            next += wave;
            generated += batches.iter().map(|b| b.len() as u64).sum::<u64>();
            if tx.send(batches).is_err() {
                break; // the writer stopped (error or done)
            }
        }
        drop(tx);
        writer.join().expect("synth writer thread panicked")
    })
}

/// Writes a synthetic scan to `path` (LAS, or LAZ when it ends in .laz; E57, one scan per
/// station, for the indoor scene), atomically. `progress` is called with the points written so
/// far.
pub fn write(
    options: &SynthOptions,
    path: &Path,
    force: bool,
    progress: impl FnMut(u64) + Send,
) -> Result<u64> {
    write_as(options, path, force, DEFAULT_POINT_FORMAT, progress)
}

/// The LAS point format of a synthetic scan unless asked otherwise.
pub const DEFAULT_POINT_FORMAT: u8 = 3;

/// The LAS point formats [`write_as`] writes: 0-3 and 6-8 (those without waveforms).
pub const POINT_FORMATS: [u8; 7] = [0, 1, 2, 3, 6, 7, 8];

/// [`write`] in LAS point format `format` ([`POINT_FORMATS`]; LAS and LAZ only): the scan's
/// attributes that the format holds, and zero for those it holds that a scan does not make (the
/// scanner channel), the near infrared taken from the red channel (format 8).
pub fn write_as(
    options: &SynthOptions,
    path: &Path,
    force: bool,
    format: u8,
    mut progress: impl FnMut(u64) + Send,
) -> Result<u64> {
    if !POINT_FORMATS.contains(&format) {
        return Err(Error::Invalid(format!(
            "point format {format}: synth writes formats 0-3 and 6-8"
        )));
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if ext.as_deref() == Some("e57") {
        if format != DEFAULT_POINT_FORMAT {
            return Err(Error::Invalid(format!(
                "{}: a point format is for LAS and LAZ files",
                path.display()
            )));
        }
        return e57::write(options, path, force, progress);
    }
    if !matches!(ext.as_deref(), Some("las" | "laz")) {
        return Err(Error::Invalid(format!(
            "{}: synth writes .las, .laz or (--scene indoor) .e57 files",
            path.display()
        )));
    }
    let target = Schema::for_las_format(format);
    let opts = LasWriteOptions::for_schema(&target, [0.001; 3], ORIGIN)?.with_wkt_crs(CRS_WKT)?;
    let mut sink = LasSink::create(path, opts, force)?;
    let mut written = 0u64;
    generate(options, |b| {
        if format == DEFAULT_POINT_FORMAT {
            sink.write(b)?;
        } else {
            sink.write(&conform(b, &target))?;
        }
        written += b.len() as u64;
        progress(written);
        Ok(())
    })?;
    sink.finish()
}

/// `b` with the columns of `schema`: those it has, zeros for the others (the near infrared:
/// the red channel).
fn conform(b: &PointBatch, schema: &Schema) -> PointBatch {
    let mut out = PointBatch {
        positions: b.positions.clone(),
        ..Default::default()
    };
    for k in 0..PointBatch::COLUMNS {
        let Some(a) = PointBatch::column_attribute(k) else {
            continue;
        };
        if !schema.has(&a) {
            continue;
        }
        match b.column_le(k) {
            Some((_, bytes)) => out.set_column_le(k, &bytes),
            None => out.set_column_le(k, &vec![0; b.len() * PointBatch::column_size(k)]),
        }
    }
    if let (Some(nir), Some(rgb)) = (&mut out.nir, &b.rgb) {
        for (n, c) in nir.iter_mut().zip(rgb) {
            *n = c[0];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn collect(scene: SceneKind, points: u64, seed: u64) -> PointBatch {
        let mut all = PointBatch::with_schema(&schema(), points as usize);
        generate(
            &SynthOptions {
                points,
                scene,
                seed,
            },
            |b| {
                all.append(b);
                Ok(())
            },
        )
        .unwrap();
        all
    }

    #[test]
    fn every_point_format_keeps_what_it_holds() {
        let all = collect(SceneKind::City, 5_000, 3);
        for format in POINT_FORMATS {
            let schema = Schema::for_las_format(format);
            let b = conform(&all, &schema);
            let got = b.schema();
            assert_eq!(
                got.attributes.len(),
                schema.attributes.len(),
                "format {format}"
            );
            assert!(
                schema.attributes.iter().all(|a| got.has(a)),
                "format {format}"
            );
            assert_eq!(b.positions, all.positions);
            assert!(b.is_consistent());
            assert_eq!(b.intensity, all.intensity);
            if schema.has(&myriad_core::Attribute::GpsTime) {
                assert_eq!(b.gps_time, all.gps_time, "format {format}");
            }
            if format == 8 {
                let red: Vec<u16> = all.rgb.as_ref().unwrap().iter().map(|c| c[0]).collect();
                assert_eq!(b.nir.as_ref(), Some(&red));
            }
        }
    }

    #[test]
    fn exact_count_and_deterministic() {
        for scene in [
            SceneKind::City,
            SceneKind::Terrain,
            SceneKind::Indoor,
            SceneKind::Stockpiles { epoch: 1 },
        ] {
            let a = collect(scene, 100_003, 7);
            assert_eq!(a.len(), 100_003, "{scene:?}");
            assert!(a.is_consistent());
            let b = collect(scene, 100_003, 7);
            assert_eq!(a, b, "{scene:?} not deterministic");
            let c = collect(scene, 1000, 8);
            assert_ne!(a.positions[..1000], c.positions[..], "seed has no effect");
        }
    }

    #[test]
    fn city_has_ground_buildings_trees_roads_and_multiple_returns() {
        let a = collect(SceneKind::City, 400_000, 1);
        let class = a.classification.as_ref().unwrap();
        for c in [
            scene::GROUND,
            scene::BUILDING,
            scene::HIGH_VEGETATION,
            scene::ROAD,
        ] {
            let n = class.iter().filter(|&&x| x == c).count();
            assert!(n > 1000, "class {c}: only {n} points");
        }
        let nret = a.number_of_returns.as_ref().unwrap();
        assert!(nret.iter().any(|&n| n >= 2), "no multiple returns");
        let rn = a.return_number.as_ref().unwrap();
        assert!(rn.iter().zip(nret).all(|(r, n)| *r >= 1 && r <= n));
        let gps = a.gps_time.as_ref().unwrap();
        assert!(
            gps.windows(2).all(|w| w[0] <= w[1]),
            "gps time must not go backwards"
        );
    }

    #[test]
    fn indoor_density_falls_with_range() {
        let a = collect(SceneKind::Indoor, 200_000, 3);
        // Station 1 scans from near the room's centre: count points near vs far from it.
        let src = a.point_source_id.as_ref().unwrap();
        let pts: Vec<[f64; 3]> = a
            .positions
            .iter()
            .zip(src)
            .filter(|(_, s)| **s == 1)
            .map(|(p, _)| *p)
            .collect();
        let c = pts
            .iter()
            .fold([0.0; 3], |m, p| [m[0] + p[0], m[1] + p[1], m[2] + p[2]]);
        let c = [c[0] / pts.len() as f64, c[1] / pts.len() as f64];
        // Floor points (z < 0.01) within 2 m vs between 4 and 6 m: density per m² falls.
        let floor = |r0: f64, r1: f64| {
            let n = pts
                .iter()
                .filter(|p| {
                    p[2] < ORIGIN[2] + 0.01 && {
                        let r = ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2)).sqrt();
                        r >= r0 && r < r1
                    }
                })
                .count();
            n as f64 / (std::f64::consts::PI * (r1 * r1 - r0 * r0))
        };
        assert!(
            floor(0.5, 2.0) > 2.0 * floor(3.0, 4.0),
            "near {} far {}",
            floor(0.5, 2.0),
            floor(3.0, 4.0)
        );
    }
}
