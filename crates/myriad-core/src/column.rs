//! Columns as numbers: what a filter tests, a colour ramp maps and a CSV row holds, for any
//! attribute of a schema, extra-bytes dimensions included.

use crate::{Attribute, ExtraDim, ExtraType, PointBatch, Schema};

/// One number per point: a position axis or a column (a colour's component, an extra-bytes
/// dimension), as filters test it, colour ramps map it and CSV files write it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Column {
    Axis(usize),
    Intensity,
    ReturnNumber,
    NumberOfReturns,
    Classification,
    ScannerChannel,
    ScanAngle,
    UserData,
    PointSourceId,
    GpsTime,
    Rgb(usize),
    Nir,
    Extra(Extra),
    /// Elevation above the terrain registered as this ([`crate::ground`]).
    AboveGround(u32),
}

/// Where an extra-bytes dimension lies in a point's extra bytes, and how its value reads.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extra {
    pub offset: usize,
    pub data_type: ExtraType,
    pub scale: f64,
    pub add_offset: f64,
}

impl Extra {
    pub fn of(d: &ExtraDim) -> Extra {
        Extra {
            offset: d.offset,
            data_type: d.data_type,
            scale: d.scale.unwrap_or(1.0),
            add_offset: d.add_offset.unwrap_or(0.0),
        }
    }
}

impl Column {
    /// The columns of `schema` as numbers, with the names a CSV header gives them (colours
    /// and normals one column per component; undocumented extra bytes left out).
    pub fn columns(schema: &Schema) -> Vec<(String, Column)> {
        let mut out = Vec::new();
        for a in &schema.attributes {
            let one = |n: &str, f: Column| vec![(n.to_string(), f)];
            out.extend(match a {
                Attribute::Intensity => one("intensity", Column::Intensity),
                Attribute::ReturnNumber => one("return_number", Column::ReturnNumber),
                Attribute::NumberOfReturns => one("number_of_returns", Column::NumberOfReturns),
                Attribute::Classification => one("classification", Column::Classification),
                Attribute::ScannerChannel => one("scanner_channel", Column::ScannerChannel),
                Attribute::ScanAngle => one("scan_angle", Column::ScanAngle),
                Attribute::UserData => one("user_data", Column::UserData),
                Attribute::PointSourceId => one("point_source_id", Column::PointSourceId),
                Attribute::GpsTime => one("gps_time", Column::GpsTime),
                Attribute::Rgb => vec![
                    ("red".into(), Column::Rgb(0)),
                    ("green".into(), Column::Rgb(1)),
                    ("blue".into(), Column::Rgb(2)),
                ],
                Attribute::Nir => one("nir", Column::Nir),
                Attribute::Extra(d) if !matches!(d.data_type, ExtraType::Undocumented(_)) => {
                    one(&d.name, Column::Extra(Extra::of(d)))
                }
                _ => vec![],
            });
        }
        out
    }

    /// The column `name` names in `schema` (`x`, `y`, `z`, attribute names as `myriad info`
    /// lists them, `red`/`green`/`blue`, extra-bytes dimensions by name).
    pub fn find(name: &str, schema: &Schema) -> Option<Column> {
        let n = name.trim().to_ascii_lowercase();
        let n = n.strip_prefix("extra:").unwrap_or(&n).replace(' ', "_");
        let has = |a: Attribute| schema.has(&a);
        let f = match n.as_str() {
            "x" => Column::Axis(0),
            "y" => Column::Axis(1),
            "z" | "elevation" => Column::Axis(2),
            "intensity" if has(Attribute::Intensity) => Column::Intensity,
            "return_number" | "return" if has(Attribute::ReturnNumber) => Column::ReturnNumber,
            "number_of_returns" | "returns" if has(Attribute::NumberOfReturns) => {
                Column::NumberOfReturns
            }
            "classification" | "class" if has(Attribute::Classification) => Column::Classification,
            "scanner_channel" if has(Attribute::ScannerChannel) => Column::ScannerChannel,
            "scan_angle" if has(Attribute::ScanAngle) => Column::ScanAngle,
            "user_data" if has(Attribute::UserData) => Column::UserData,
            "point_source_id" | "point_source" | "source" if has(Attribute::PointSourceId) => {
                Column::PointSourceId
            }
            "gps_time" | "time" if has(Attribute::GpsTime) => Column::GpsTime,
            "red" if has(Attribute::Rgb) => Column::Rgb(0),
            "green" if has(Attribute::Rgb) => Column::Rgb(1),
            "blue" if has(Attribute::Rgb) => Column::Rgb(2),
            "nir" if has(Attribute::Nir) => Column::Nir,
            _ => schema.attributes.iter().find_map(|a| match a {
                Attribute::Extra(d) if d.name.to_ascii_lowercase().replace(' ', "_") == n => {
                    Some(Column::Extra(Extra::of(d)))
                }
                _ => None,
            })?,
        };
        Some(f)
    }

    /// The value of point `i`; NaN where the batch lacks the column.
    pub fn value(&self, b: &PointBatch, i: usize) -> f64 {
        let get = |c: &Option<Vec<_>>| -> Option<f64> { c.as_ref().map(|c: &Vec<u8>| c[i] as f64) };
        let v = match self {
            Column::Axis(a) => Some(b.positions[i][*a]),
            Column::Intensity => b.intensity.as_ref().map(|c| c[i] as f64),
            Column::ReturnNumber => get(&b.return_number),
            Column::NumberOfReturns => get(&b.number_of_returns),
            Column::Classification => get(&b.classification),
            Column::ScannerChannel => get(&b.scanner_channel),
            Column::ScanAngle => b.scan_angle.as_ref().map(|c| c[i] as f64),
            Column::UserData => get(&b.user_data),
            Column::PointSourceId => b.point_source_id.as_ref().map(|c| c[i] as f64),
            Column::GpsTime => b.gps_time.as_ref().map(|c| c[i]),
            Column::Rgb(k) => b.rgb.as_ref().map(|c| c[i][*k] as f64),
            Column::Nir => b.nir.as_ref().map(|c| c[i] as f64),
            Column::AboveGround(id) => {
                let [x, y, z] = b.positions[i];
                crate::ground::get(*id)
                    .and_then(|g| g.height(x, y))
                    .map(|h| z - h)
            }
            Column::Extra(d) => b.extra_bytes.as_ref().and_then(|e| {
                let at = i * b.extra_stride + d.offset;
                extra_value(e.get(at..at + d.data_type.size())?, d)
            }),
        };
        v.unwrap_or(f64::NAN)
    }
}

/// An extra-bytes value as a number, with its scale and offset; `None` for undocumented bytes.
pub fn extra_value(bytes: &[u8], d: &Extra) -> Option<f64> {
    let arr = |n: usize| -> [u8; 8] {
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(&bytes[..n]);
        a
    };
    let raw = match d.data_type {
        ExtraType::Undocumented(_) => return None,
        ExtraType::U8 => bytes[0] as f64,
        ExtraType::I8 => bytes[0] as i8 as f64,
        ExtraType::U16 => u16::from_le_bytes([bytes[0], bytes[1]]) as f64,
        ExtraType::I16 => i16::from_le_bytes([bytes[0], bytes[1]]) as f64,
        ExtraType::U32 => u32::from_le_bytes(bytes[..4].try_into().ok()?) as f64,
        ExtraType::I32 => i32::from_le_bytes(bytes[..4].try_into().ok()?) as f64,
        ExtraType::U64 => u64::from_le_bytes(arr(8)) as f64,
        ExtraType::I64 => i64::from_le_bytes(arr(8)) as f64,
        ExtraType::F32 => f32::from_le_bytes(bytes[..4].try_into().ok()?) as f64,
        ExtraType::F64 => f64::from_le_bytes(arr(8)),
    };
    Some(raw * d.scale + d.add_offset)
}
