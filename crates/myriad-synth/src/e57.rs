//! Synthetic terrestrial scans as E57 (`--scene indoor`): one scan per station, its points in
//! the scanner's own frame (Cartesian, 1 mm scaled integers, with the row and column of the
//! scan's grid: a stationary scanner's structured scan), the station's position as the scan's
//! pose, intensity and colour in 16 bits. Stations are generated one after another, so one
//! scan is held at a time (at most 2 M points).

use crate::{ORIGIN, SceneKind, SynthOptions, generate, scan::Indoor};
use ::e57::{
    ColorLimits, E57Writer, IntensityLimits, Quaternion, Record, RecordDataType, RecordName,
    RecordValue, Transform, Translation,
};
use myriad_core::{Error, PointBatch, Result};
use std::path::Path;

fn e57_error(path: &Path, e: ::e57::Error) -> Error {
    Error::Invalid(format!("{}: writing E57: {e}", path.display()))
}

/// Writes `options` (an indoor scene) to `path` as E57, atomically; `progress` is called with
/// the points written so far.
pub fn write(
    options: &SynthOptions,
    path: &Path,
    force: bool,
    mut progress: impl FnMut(u64) + Send,
) -> Result<u64> {
    if options.scene != SceneKind::Indoor {
        return Err(Error::Invalid(format!(
            "{}: synth writes E57 for --scene indoor (terrestrial scans from stations)",
            path.display()
        )));
    }
    let plan = Indoor::plan(options.points, options.seed);
    let file = myriad_io::atomic::AtomicFile::create(path, force)?;
    let tmp = file.temp_path().to_path_buf();
    let mut w = E57Writer::from_file(&tmp, "myriad-synth").map_err(|e| e57_error(path, e))?;
    let mut scan = PointBatch::with_schema(&crate::schema(), 0);
    let mut written = 0u64;
    let flush = |w: &mut E57Writer<std::fs::File>, scan: &mut PointBatch| -> Result<()> {
        let Some(&id) = scan.point_source_id.as_ref().and_then(|s| s.first()) else {
            return Ok(());
        };
        write_scan(w, &plan, id as u64 - 1, scan).map_err(|e| e57_error(path, e))?;
        *scan = PointBatch::with_schema(&crate::schema(), 0);
        Ok(())
    };
    generate(options, |b| {
        // A batch may end one station's scan and begin the next one's.
        let ids = b
            .point_source_id
            .as_ref()
            .expect("synthetic scans carry stations");
        let mut start = 0;
        while start < b.len() {
            let id = ids[start];
            let end = start + ids[start..].iter().take_while(|&&s| s == id).count();
            if scan.point_source_id.as_ref().and_then(|s| s.first()) != Some(&id) {
                flush(&mut w, &mut scan)?;
            }
            scan.append(&b.slice(start..end));
            written += (end - start) as u64;
            start = end;
        }
        progress(written);
        Ok(())
    })?;
    flush(&mut w, &mut scan)?;
    w.finalize().map_err(|e| e57_error(path, e))?;
    drop(w);
    file.commit()?;
    Ok(written)
}

/// Station `station`'s points as one scan, posed at the station.
fn write_scan(
    w: &mut E57Writer<std::fs::File>,
    plan: &Indoor,
    station: u64,
    b: &PointBatch,
) -> std::result::Result<(), ::e57::Error> {
    let o = plan.station(station);
    let o = [o[0] + ORIGIN[0], o[1] + ORIGIN[1], o[2] + ORIGIN[2]];
    let coord = |name| Record {
        name,
        data_type: RecordDataType::ScaledInteger {
            min: -10_000_000,
            max: 10_000_000,
            scale: 0.001,
            offset: 0.0,
        },
    };
    let int = |name, max| Record {
        name,
        data_type: RecordDataType::Integer { min: 0, max },
    };
    let grid = plan.pulses_per_station.div_ceil(plan.n_el) as i64;
    let proto = vec![
        coord(RecordName::CartesianX),
        coord(RecordName::CartesianY),
        coord(RecordName::CartesianZ),
        int(RecordName::RowIndex, plan.n_el as i64),
        int(RecordName::ColumnIndex, grid),
        int(RecordName::Intensity, 65535),
        int(RecordName::ColorRed, 65535),
        int(RecordName::ColorGreen, 65535),
        int(RecordName::ColorBlue, 65535),
    ];
    let mut pc = w.add_pointcloud(&format!("station-{}", station + 1), proto)?;
    pc.set_name(Some(format!("station {}", station + 1)));
    pc.set_transform(Some(Transform {
        rotation: Quaternion {
            w: 1.0,
            x: 0.0,
            y: 0.0,
            z: 0.0,
        },
        translation: Translation {
            x: o[0],
            y: o[1],
            z: o[2],
        },
    }));
    let limit = |v| Some(RecordValue::Integer(v));
    pc.set_intensity_limits(Some(IntensityLimits {
        intensity_min: limit(0),
        intensity_max: limit(65535),
    }));
    pc.set_color_limits(Some(ColorLimits {
        red_min: limit(0),
        red_max: limit(65535),
        green_min: limit(0),
        green_max: limit(65535),
        blue_min: limit(0),
        blue_max: limit(65535),
    }));
    let (intensity, rgb) = (
        b.intensity.as_ref().expect("intensity"),
        b.rgb.as_ref().expect("colour"),
    );
    for (j, p) in b.positions.iter().enumerate() {
        let mm = |a: usize| RecordValue::ScaledInteger(((p[a] - o[a]) * 1000.0).round() as i64);
        let c = rgb[j];
        pc.add_point(vec![
            mm(0),
            mm(1),
            mm(2),
            RecordValue::Integer(j as i64 % plan.n_el as i64),
            RecordValue::Integer(j as i64 / plan.n_el as i64),
            RecordValue::Integer(intensity[j] as i64),
            RecordValue::Integer(c[0] as i64),
            RecordValue::Integer(c[1] as i64),
            RecordValue::Integer(c[2] as i64),
        ])?;
    }
    pc.finalize()
}
