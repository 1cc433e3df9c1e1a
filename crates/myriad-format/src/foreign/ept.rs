//! Entwine Point Tiles read in place (entwine.io/entwine-point-tile.html): `ept.json` (the cube
//! `bounds`, `points`, the `schema` of dimensions, `span`, `srs`, `dataType`), the hierarchy as
//! JSON files `ept-hierarchy/D-X-Y-Z.json` (key: point count; -1: the subtree's counts are in
//! the file of that key), and one file per node, `ept-data/D-X-Y-Z.laz` (`laszip`: a LAZ file),
//! `.bin` (`binary`: the schema's dimensions packed per point, little-endian) or `.zst`
//! (`zstandard`: the same, zstd-compressed). Keys are the octree's, as Myriad's.
//!
//! A node file that cannot be read (missing: 404; damaged) is a damaged node, named with its
//! file; the others show. Dimensions that are no LAS field (`OriginId`, a scanner's own) are
//! kept as extra dimensions in binary and zstandard datasets.

use super::{Foreign, Known, MAX_JSON, MAX_NODE, Place, SourcePage, Tree, damage};
use crate::{Damage, HierarchyPage, Metadata, NodeEntry, PageRef, Quantization};
use myriad_core::{
    Aabb, Attribute, Error, ExtraDim, ExtraType, NodeKey, PointBatch, Result, Schema,
};
use myriad_io::las_bytes::LasLayout;
use serde_json::{Value, json};
use std::path::Path;

#[derive(Debug, Clone, Copy, PartialEq)]
enum DataType {
    Laszip,
    Binary,
    Zstandard,
}

/// One dimension of the schema, where it lies in a binary record.
#[derive(Debug, Clone)]
struct Dim {
    name: String,
    /// `signed`, `unsigned`, `float`, with its size.
    kind: char,
    size: usize,
    at: usize,
    scale: f64,
    offset: f64,
    /// Where it lies in the extra bytes, for dimensions that are no LAS field.
    extra_at: Option<usize>,
}

impl Dim {
    /// The value in `r` (a record), scaled.
    fn value(&self, r: &[u8]) -> f64 {
        let b = &r[self.at..self.at + self.size];
        let raw = match (self.kind, self.size) {
            ('s', 1) => b[0] as i8 as f64,
            ('s', 2) => i16::from_le_bytes([b[0], b[1]]) as f64,
            ('s', 4) => i32::from_le_bytes(b.try_into().unwrap()) as f64,
            ('s', 8) => i64::from_le_bytes(b.try_into().unwrap()) as f64,
            ('u', 1) => b[0] as f64,
            ('u', 2) => u16::from_le_bytes([b[0], b[1]]) as f64,
            ('u', 4) => u32::from_le_bytes(b.try_into().unwrap()) as f64,
            ('u', 8) => u64::from_le_bytes(b.try_into().unwrap()) as f64,
            ('f', 4) => f32::from_le_bytes(b.try_into().unwrap()) as f64,
            ('f', 8) => f64::from_le_bytes(b.try_into().unwrap()),
            _ => 0.0,
        };
        raw * self.scale + self.offset
    }

    /// The LAS extra-bytes type of a dimension of this kind and size.
    fn extra_type(&self) -> Option<ExtraType> {
        let code = match (self.kind, self.size) {
            ('u', 1) => 1,
            ('s', 1) => 2,
            ('u', 2) => 3,
            ('s', 2) => 4,
            ('u', 4) => 5,
            ('s', 4) => 6,
            ('u', 8) => 7,
            ('s', 8) => 8,
            ('f', 4) => 9,
            ('f', 8) => 10,
            _ => return None,
        };
        ExtraType::from_las_code(code, 0)
    }
}

/// The LAS field a dimension fills (`None`: an extra dimension).
fn attribute_of(name: &str) -> Option<Attribute> {
    use Attribute::*;
    Some(match name {
        "Intensity" => Intensity,
        "ReturnNumber" => ReturnNumber,
        "NumberOfReturns" => NumberOfReturns,
        "ScanDirectionFlag" | "EdgeOfFlightLine" => ScanFlags,
        "Classification" => Classification,
        "ClassFlags" | "Synthetic" | "KeyPoint" | "Withheld" | "Overlap" => ClassificationFlags,
        "ScanAngleRank" | "ScanAngle" => ScanAngle,
        "UserData" => UserData,
        "PointSourceId" => PointSourceId,
        "GpsTime" => GpsTime,
        "Red" | "Green" | "Blue" => Rgb,
        "Infrared" => Nir,
        "ScanChannel" => ScannerChannel,
        _ => return None,
    })
}

pub(crate) struct Ept {
    place: Place,
    data: DataType,
    dims: Vec<Dim>,
    record_len: usize,
    schema: Schema,
    tree: Tree,
}

impl Ept {
    /// Opens the EPT dataset whose `ept.json` is `path` (a file or URL; a folder holding one).
    pub(crate) fn open(path: &Path) -> Result<(Metadata, Ept)> {
        let (place, name, v) = super::open_json(path, "ept.json")?;
        let field = |m: &str| Error::Invalid(format!("{}: ept.json: {m}", name.display()));
        let b =
            super::numbers::<6>(&v, "bounds").ok_or_else(|| field("no \"bounds\" of 6 numbers"))?;
        let cube = Aabb::new([b[0], b[1], b[2]], [b[3], b[4], b[5]]);
        if (0..3).any(|a| cube.max[a] <= cube.min[a]) {
            return Err(field("\"bounds\" is empty"));
        }
        let conforming = super::numbers::<6>(&v, "boundsConforming")
            .map(|c| Aabb::new([c[0], c[1], c[2]], [c[3], c[4], c[5]]))
            .unwrap_or(cube);
        let points = v["points"]
            .as_u64()
            .ok_or_else(|| field("no \"points\" count"))?;
        let span = v["span"].as_f64().filter(|s| *s >= 1.0).unwrap_or(128.0);
        let data = match v["dataType"].as_str() {
            Some("laszip") => DataType::Laszip,
            Some("binary") => DataType::Binary,
            Some("zstandard") => DataType::Zstandard,
            other => {
                return Err(field(&format!(
                    "dataType {other:?}: laszip, binary or zstandard expected"
                )));
            }
        };
        if v["hierarchyType"].as_str().is_some_and(|h| h != "json") {
            return Err(field("hierarchyType: only \"json\" is defined"));
        }
        let mut dims = Vec::new();
        let mut at = 0;
        let mut extra = 0;
        let mut attributes: Vec<Attribute> = Vec::new();
        for d in v["schema"]
            .as_array()
            .ok_or_else(|| field("no \"schema\""))?
        {
            let dname = d["name"]
                .as_str()
                .ok_or_else(|| field("a dimension without a name"))?;
            let size = d["size"]
                .as_u64()
                .filter(|s| [1, 2, 4, 8].contains(s))
                .ok_or_else(|| field(&format!("dimension {dname}: size must be 1, 2, 4 or 8")))?
                as usize;
            let kind = match d["type"].as_str() {
                Some("signed") => 's',
                Some("unsigned") => 'u',
                Some("float") if size >= 4 => 'f',
                t => return Err(field(&format!("dimension {dname}: type {t:?}"))),
            };
            let mut dim = Dim {
                name: dname.to_string(),
                kind,
                size,
                at,
                scale: d["scale"]
                    .as_f64()
                    .filter(|s| s.is_finite() && *s != 0.0)
                    .unwrap_or(1.0),
                offset: d["offset"]
                    .as_f64()
                    .filter(|s| s.is_finite())
                    .unwrap_or(0.0),
                extra_at: None,
            };
            at += size;
            match (dname, attribute_of(dname)) {
                ("X" | "Y" | "Z", _) => {}
                (_, Some(a)) if !attributes.contains(&a) => attributes.push(a),
                (_, Some(_)) => {}
                (_, None) if data != DataType::Laszip => {
                    if let Some(t) = dim.extra_type() {
                        attributes.push(Attribute::Extra(ExtraDim {
                            name: dname.to_string(),
                            data_type: t,
                            offset: extra,
                            description: String::new(),
                            scale: d["scale"].as_f64(),
                            add_offset: d["offset"].as_f64(),
                        }));
                        dim.extra_at = Some(extra);
                        extra += size;
                    }
                }
                _ => {}
            }
            dims.push(dim);
        }
        let pos = |n: &str| dims.iter().find(|d| d.name == n).cloned();
        let (Some(x), Some(y), Some(z)) = (pos("X"), pos("Y"), pos("Z")) else {
            return Err(field("the schema lacks X, Y or Z"));
        };
        // Scaled integers keep their grid; floats get a millimetre one.
        let grid = |d: &Dim, a: usize| match d.kind {
            'f' => (0.001, (cube.min[a] + cube.max[a]) / 2.0),
            _ => (d.scale.abs(), d.offset),
        };
        let (gx, gy, gz) = (grid(&x, 0), grid(&y, 1), grid(&z, 2));
        let mut schema = Schema::new(attributes);
        schema.extra_bytes = extra;
        let crs = v["srs"]["wkt"]
            .as_str()
            .filter(|w| !w.trim().is_empty())
            .map(str::to_string)
            .or_else(|| {
                let code = v["srs"]["horizontal"].as_str()?;
                let auth = v["srs"]["authority"].as_str().unwrap_or("EPSG");
                Some(match v["srs"]["vertical"].as_str() {
                    Some(vert) => format!("{auth}:{code}+{vert}"),
                    None => format!("{auth}:{code}"),
                })
            });
        let meta = Metadata {
            structure: "ept".into(),
            parameters: json!({"format": "EPT", "dataType": v["dataType"], "span": span,
                "version": v["version"], "read_in_place": true}),
            points,
            nodes: 0,
            depth: 0,
            bounds: conforming,
            root: cube,
            quantization: Quantization {
                scale: [gx.0, gy.0, gz.0],
                offset: [gx.1, gy.1, gz.1],
            },
            crs,
            schema: schema.clone(),
            sources: vec![
                json!({"path": name.display().to_string(), "format": "EPT", "points": points}),
            ],
            las_header: None,
            software: "Entwine Point Tile".into(),
            levels: Vec::new(),
            files: Vec::new(),
        };
        let spacing = (cube.max[0] - cube.min[0]) / span;
        let ept = Ept {
            place,
            data,
            dims,
            record_len: at,
            schema,
            tree: Tree::new(PageRef::default(), spacing),
        };
        Ok((meta, ept))
    }

    fn key_name(k: NodeKey) -> String {
        format!("{}-{}-{}-{}", k.level, k.cell[0], k.cell[1], k.cell[2])
    }

    /// Reads `ept-hierarchy/KEY.json`.
    fn read_page(&self, key: NodeKey) -> std::result::Result<SourcePage, Damage> {
        let rel = format!("ept-hierarchy/{}.json", Ept::key_name(key));
        let hurt = |m: String| damage(key, 0, format!("{}: {m}", self.place.name(&rel)), true);
        let text = self
            .place
            .read(&rel, MAX_JSON)
            .map_err(|m| damage(key, 0, m, true))?;
        let v: Value =
            serde_json::from_slice(&text).map_err(|e| hurt(format!("line {}: {e}", e.line())))?;
        let map = v
            .as_object()
            .ok_or_else(|| hurt("not a JSON object".into()))?;
        let mut page = SourcePage::default();
        for (k, count) in map {
            let parts: Vec<u32> = k.split('-').filter_map(|p| p.parse().ok()).collect();
            let [level, x, y, z] = parts[..] else {
                return Err(hurt(format!("\"{k}\" is not a key D-X-Y-Z")));
            };
            if level > 30 || [x, y, z].iter().any(|&c| c as u64 >= 1u64 << level) {
                return Err(hurt(format!("\"{k}\" is not a node of the octree")));
            }
            let nk = NodeKey {
                level,
                cell: [x, y, z],
            };
            match count.as_i64() {
                Some(-1) => page.below.push((nk, PageRef::default())),
                Some(c) if c >= 0 => page.nodes.push((
                    nk,
                    Known {
                        points: c as u64,
                        at: 0,
                        len: c as u64,
                    },
                )),
                _ => return Err(hurt(format!("\"{k}\": {count} is not a point count"))),
            }
        }
        Ok(page)
    }

    /// Decodes binary records into the dataset's columns.
    fn decode_binary(
        &self,
        key: NodeKey,
        rel: &str,
        b: &[u8],
        points: u64,
    ) -> std::result::Result<PointBatch, Damage> {
        if b.len() as u64 != points * self.record_len as u64 {
            return Err(damage(
                key,
                0,
                format!(
                    "{}: {} bytes, {points} points of {} bytes expected",
                    self.place.name(rel),
                    b.len(),
                    self.record_len
                ),
                false,
            ));
        }
        let n = points as usize;
        let mut out = PointBatch::with_schema(&self.schema, n);
        let get = |name: &str| self.dims.iter().find(|d| d.name == name);
        let (x, y, z) = (get("X").unwrap(), get("Y").unwrap(), get("Z").unwrap());
        let records = || b.chunks_exact(self.record_len);
        out.positions
            .extend(records().map(|r| [x.value(r), y.value(r), z.value(r)]));
        macro_rules! col {
            ($f:ident, $name:expr, $t:ty) => {
                if let (Some(c), Some(d)) = (out.$f.as_mut(), get($name)) {
                    c.extend(records().map(|r| d.value(r) as $t));
                }
            };
        }
        col!(intensity, "Intensity", u16);
        col!(return_number, "ReturnNumber", u8);
        col!(number_of_returns, "NumberOfReturns", u8);
        col!(classification, "Classification", u8);
        col!(user_data, "UserData", u8);
        col!(point_source_id, "PointSourceId", u16);
        col!(gps_time, "GpsTime", f64);
        col!(nir, "Infrared", u16);
        col!(scanner_channel, "ScanChannel", u8);
        if let Some(c) = out.scan_angle.as_mut() {
            let d = get("ScanAngleRank").or(get("ScanAngle")).unwrap();
            c.extend(records().map(|r| d.value(r) as f32));
        }
        let bits = |names: &[&str], r: &[u8]| {
            names.iter().enumerate().fold(0u8, |acc, (i, n)| {
                acc | (get(n).is_some_and(|d| d.value(r) != 0.0) as u8) << i
            })
        };
        if let Some(c) = out.scan_flags.as_mut() {
            c.extend(records().map(|r| bits(&["ScanDirectionFlag", "EdgeOfFlightLine"], r)));
        }
        if let Some(c) = out.classification_flags.as_mut() {
            match get("ClassFlags") {
                Some(d) => c.extend(records().map(|r| d.value(r) as u8)),
                None => c.extend(
                    records().map(|r| bits(&["Synthetic", "KeyPoint", "Withheld", "Overlap"], r)),
                ),
            }
        }
        if let Some(c) = out.rgb.as_mut() {
            let ch = |n| get(n);
            let (r_, g_, b_) = (ch("Red"), ch("Green"), ch("Blue"));
            let v = |d: Option<&Dim>, r: &[u8]| d.map_or(0, |d| d.value(r) as u16);
            c.extend(records().map(|r| [v(r_, r), v(g_, r), v(b_, r)]));
        }
        if let Some(e) = out.extra_bytes.as_mut() {
            for r in records() {
                for d in self.dims.iter().filter(|d| d.extra_at.is_some()) {
                    e.extend_from_slice(&r[d.at..d.at + d.size]);
                }
            }
        }
        Ok(out)
    }
}

impl Foreign for Ept {
    fn hierarchy_page(&self, key: NodeKey) -> std::result::Result<HierarchyPage, Damage> {
        self.tree.page(key, &|k, _| self.read_page(k))
    }

    fn read_node(&self, e: &NodeEntry) -> std::result::Result<PointBatch, Damage> {
        if e.points == 0 {
            return Ok(PointBatch::with_schema(&self.schema, 0));
        }
        let ext = match self.data {
            DataType::Laszip => "laz",
            DataType::Binary => "bin",
            DataType::Zstandard => "zst",
        };
        let rel = format!("ept-data/{}.{ext}", Ept::key_name(e.key));
        let file = self.place.name(&rel);
        let b = self
            .place
            .read(&rel, MAX_NODE)
            .map_err(|m| damage(e.key, 0, m, false))?;
        let mut batch = match self.data {
            DataType::Laszip => {
                let (_, b) = LasLayout::decode_file(Path::new(&file), &b).map_err(|err| {
                    let d = super::as_damage(e.key, err, 0);
                    damage(e.key, d.offset, format!("{file}: {}", d.message), false)
                })?;
                b
            }
            DataType::Binary => self.decode_binary(e.key, &rel, &b, e.points as u64)?,
            DataType::Zstandard => {
                let raw = crate::codec::decompress(
                    &b,
                    (e.points as usize).saturating_mul(self.record_len),
                )
                .map_err(|err| damage(e.key, 0, format!("{file}: zstandard: {err}"), false))?;
                self.decode_binary(e.key, &rel, &raw, e.points as u64)?
            }
        };
        if batch.len() != e.points as usize {
            return Err(damage(
                e.key,
                0,
                format!(
                    "{file}: {} points, the hierarchy says {}",
                    batch.len(),
                    e.points
                ),
                false,
            ));
        }
        batch.conform(&self.schema);
        Ok(batch)
    }

    fn fetched(&self) -> Option<(u64, u64)> {
        self.place.fetched()
    }

    fn changed(&self) -> Option<String> {
        self.place.changed()
    }
}
