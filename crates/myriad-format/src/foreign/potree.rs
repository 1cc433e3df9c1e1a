//! Potree 2.0 read in place, as PotreeConverter 2 writes it: `metadata.json` (the root cube
//! `boundingBox`, `scale` and `offset`, `spacing`, `attributes`, `encoding`, `hierarchy`'s
//! `firstChunkSize`), `hierarchy.bin` and `octree.bin`.
//!
//! `hierarchy.bin` is chunks of 22-byte records, u8 type (0 inner, 1 leaf, 2 proxy), u8 child
//! mask, u32 points, u64 byte offset, u64 byte size, in breadth-first order from the chunk's
//! first node: a node's children (those its mask names, child index bit 2 = +x, bit 1 = +y, bit
//! 0 = +z) follow in the order of their indices. A proxy's offset and size are those of the chunk
//! that holds its subtree, whose first record is the node itself. The first chunk starts at 0.
//!
//! `octree.bin` holds each node's points. `DEFAULT`: a record per point, the attributes in
//! order, the position as i32 x3 (world = i * scale + offset). `BROTLI`: the node's bytes
//! Brotli-compressed, the attributes one after the other for all points, the position as a
//! 16-byte Morton code (two u64: bits 3k, 3k+1, 3k+2 of the second are bit k of x, y, z; of the
//! first, bit k + 16), and `rgb` as an 8-byte one (bit k + 16 of the channels in the first
//! u32 pair's high word: the same interleaving over one u64 read as two u32).

use super::{Foreign, Known, MAX_NODE, Place, SourcePage, Tree, damage};
use crate::{ByteSource, Damage, HierarchyPage, Metadata, NodeEntry, PageRef, Quantization};
use myriad_core::{Aabb, Attribute, Error, NodeKey, PointBatch, Result, Schema};
use serde_json::{Value, json};
use std::path::Path;
use std::sync::Arc;

const RECORD: usize = 22;

#[derive(Debug, Clone)]
struct Attr {
    name: String,
    size: usize,
    elements: usize,
    kind: String,
}

pub(crate) struct Potree {
    place: Place,
    hierarchy: Arc<dyn ByteSource>,
    octree: Arc<dyn ByteSource>,
    brotli: bool,
    attrs: Vec<Attr>,
    record_len: usize,
    scale: [f64; 3],
    offset: [f64; 3],
    schema: Schema,
    tree: Tree,
}

fn attribute_of(name: &str) -> Option<Attribute> {
    use Attribute::*;
    Some(match name {
        "intensity" => Intensity,
        "return number" => ReturnNumber,
        "number of returns" => NumberOfReturns,
        "classification" => Classification,
        "classification flags" => ClassificationFlags,
        "scan angle rank" | "scan angle" => ScanAngle,
        "user data" => UserData,
        "point source id" => PointSourceId,
        "gps-time" | "gps-time " | "gps time" => GpsTime,
        "rgb" | "rgba" => Rgb,
        "scanner channel" => ScannerChannel,
        _ => return None,
    })
}

impl Potree {
    /// Opens the Potree 2.0 dataset whose `metadata.json` is `path` (a file or URL; a folder).
    pub(crate) fn open(path: &Path) -> Result<(Metadata, Potree)> {
        let (place, name, v) = super::open_json(path, "metadata.json")?;
        let field = |m: &str| Error::Invalid(format!("{}: metadata.json: {m}", name.display()));
        if !v["version"].as_str().is_some_and(|s| s.starts_with("2.")) {
            return Err(field(&format!(
                "version {}: Potree 2.x expected",
                v["version"]
            )));
        }
        let bb = &v["boundingBox"];
        let (Some(min), Some(max)) = (
            super::numbers::<3>(bb, "min"),
            super::numbers::<3>(bb, "max"),
        ) else {
            return Err(field("no boundingBox min and max"));
        };
        let cube = Aabb::new(min, max);
        if (0..3).any(|a| max[a] <= min[a]) {
            return Err(field("boundingBox is empty"));
        }
        let scale = super::numbers::<3>(&v, "scale")
            .filter(|s| s.iter().all(|x| *x > 0.0))
            .ok_or_else(|| field("no positive scale"))?;
        let offset = super::numbers::<3>(&v, "offset").ok_or_else(|| field("no offset"))?;
        let spacing = v["spacing"]
            .as_f64()
            .filter(|s| *s > 0.0 && s.is_finite())
            .ok_or_else(|| field("no spacing"))?;
        let points = v["points"]
            .as_u64()
            .ok_or_else(|| field("no points count"))?;
        let brotli = match v["encoding"].as_str().unwrap_or("DEFAULT") {
            "DEFAULT" => false,
            "BROTLI" => true,
            e => return Err(field(&format!("encoding {e}: DEFAULT or BROTLI expected"))),
        };
        let first = v["hierarchy"]["firstChunkSize"]
            .as_u64()
            .filter(|s| *s > 0 && s.is_multiple_of(RECORD as u64))
            .ok_or_else(|| field("hierarchy.firstChunkSize is not a multiple of 22"))?;
        let mut attrs = Vec::new();
        let mut attributes = Vec::new();
        let mut record_len = 0;
        for a in v["attributes"]
            .as_array()
            .ok_or_else(|| field("no attributes"))?
        {
            let an = a["name"].as_str().unwrap_or_default().to_string();
            let size = a["size"]
                .as_u64()
                .filter(|s| *s > 0 && *s <= 64)
                .ok_or_else(|| field(&format!("attribute {an}: no size")))?
                as usize;
            let elements = a["numElements"].as_u64().unwrap_or(1).max(1) as usize;
            record_len += size;
            if let Some(at) = attribute_of(&an)
                && !attributes.contains(&at)
            {
                attributes.push(at);
            }
            attrs.push(Attr {
                name: an,
                size,
                elements,
                kind: a["type"].as_str().unwrap_or_default().to_string(),
            });
        }
        if !attrs.first().is_some_and(|a| {
            matches!(a.name.as_str(), "position" | "POSITION_CARTESIAN") && a.size == 12
        }) {
            return Err(field("the first attribute is not an int32 x3 position"));
        }
        let schema = Schema::new(attributes);
        let hierarchy = place.open("hierarchy.bin", 1 << 20)?;
        let octree = place.open("octree.bin", 64)?;
        let crs = v["projection"]
            .as_str()
            .filter(|p| !p.trim().is_empty())
            .map(str::to_string);
        let meta = Metadata {
            structure: "potree-2.0".into(),
            parameters: json!({"format": "Potree 2.0", "encoding": v["encoding"], "read_in_place": true}),
            points,
            nodes: 0,
            depth: 0,
            bounds: attrs_minmax(&v).unwrap_or(cube),
            root: cube,
            quantization: Quantization { scale, offset },
            crs,
            schema: schema.clone(),
            sources: vec![
                json!({"path": name.display().to_string(), "format": "Potree 2.0", "points": points}),
            ],
            las_header: None,
            software: "PotreeConverter 2".into(),
            levels: Vec::new(),
            files: Vec::new(),
        };
        let root = PageRef {
            offset: 0,
            length: first as u32,
            crc: 0,
        };
        let p = Potree {
            place,
            hierarchy,
            octree,
            brotli,
            attrs,
            record_len,
            scale,
            offset,
            schema,
            tree: Tree::new(root, spacing),
        };
        Ok((meta, p))
    }

    /// Reads the hierarchy chunk at `r`, whose first node is `key`.
    fn read_chunk(&self, key: NodeKey, r: PageRef) -> std::result::Result<SourcePage, Damage> {
        let hurt = |at: u64, m: String| {
            damage(
                key,
                at,
                format!("{}: {m}", self.place.name("hierarchy.bin")),
                true,
            )
        };
        let len = self.hierarchy.len();
        if r.offset.saturating_add(r.length as u64) > len
            || !(r.length as usize).is_multiple_of(RECORD)
            || r.length == 0
        {
            return Err(hurt(
                r.offset,
                format!("a {}-byte chunk does not fit the file", r.length),
            ));
        }
        let b = self
            .hierarchy
            .read_at(r.offset, r.length as usize)
            .map_err(|e| hurt(r.offset, e.to_string()))?;
        let mut page = SourcePage::default();
        let mut keys = vec![key];
        let octree_len = self.octree.len();
        for (i, rec) in b.chunks_exact(RECORD).enumerate() {
            let at = r.offset + (i * RECORD) as u64;
            let Some(&k) = keys.get(i) else {
                break; // records past the nodes the masks name
            };
            let (kind, mask) = (rec[0], rec[1]);
            let points = u32::from_le_bytes(rec[2..6].try_into().unwrap()) as u64;
            let offset = u64::from_le_bytes(rec[6..14].try_into().unwrap());
            let size = u64::from_le_bytes(rec[14..22].try_into().unwrap());
            if kind == 2 {
                if i == 0
                    || size == 0
                    || !size.is_multiple_of(RECORD as u64)
                    || offset.saturating_add(size) > len
                    || size > u32::MAX as u64
                {
                    return Err(hurt(
                        at,
                        format!("node {k}: proxy of {size} bytes at {offset}"),
                    ));
                }
                page.below.push((
                    k,
                    PageRef {
                        offset,
                        length: size as u32,
                        crc: 0,
                    },
                ));
                continue;
            }
            if offset.saturating_add(size) > octree_len {
                return Err(hurt(
                    at,
                    format!("node {k}: {size} bytes at {offset} lie past octree.bin's end"),
                ));
            }
            page.nodes.push((
                k,
                Known {
                    points: if size == 0 { 0 } else { points },
                    at: offset,
                    len: size,
                },
            ));
            for c in 0..8 {
                if mask & (1 << c) != 0 {
                    // Potree's child index: bit 2 +x, bit 1 +y, bit 0 +z; Myriad's octant: bit 0 +x.
                    let octant = ((c >> 2) & 1) | (c & 2) | ((c & 1) << 2);
                    if k.level >= 30 {
                        return Err(hurt(at, format!("node {k}: deeper than 30 levels")));
                    }
                    keys.push(k.child(octant));
                }
            }
        }
        Ok(page)
    }

    /// Decodes `n` points of a node from their bytes as stored (uncompressed already).
    fn decode(&self, key: NodeKey, b: &[u8], n: usize) -> std::result::Result<PointBatch, Damage> {
        let per_point: usize = match self.brotli {
            false => self.record_len,
            true => self.attrs.iter().map(brotli_size).sum(),
        };
        if b.len() != n * per_point {
            return Err(damage(
                key,
                0,
                format!("{} bytes for {n} points of {per_point} bytes", b.len()),
                false,
            ));
        }
        let mut out = PointBatch::with_schema(&self.schema, n);
        // Where each attribute's value of point `i` lies.
        let mut start = 0;
        for a in &self.attrs {
            let (stride, base) = match self.brotli {
                false => (self.record_len, start),
                true => (brotli_size(a), start * n),
            };
            let at = |i: usize| base + i * stride;
            let name = a.name.as_str();
            if matches!(name, "position" | "POSITION_CARTESIAN") {
                out.positions.extend((0..n).map(|i| {
                    let p = &b[at(i)..at(i) + stride];
                    let xyz: [i64; 3] = match self.brotli {
                        false => std::array::from_fn(|k| {
                            i32::from_le_bytes(p[k * 4..k * 4 + 4].try_into().unwrap()) as i64
                        }),
                        true => {
                            let hi = u64::from_le_bytes(p[0..8].try_into().unwrap());
                            let lo = u64::from_le_bytes(p[8..16].try_into().unwrap());
                            std::array::from_fn(|k| {
                                (unmorton(lo, k) | unmorton(hi, k) << 16) as i32 as i64
                            })
                        }
                    };
                    std::array::from_fn(|k| xyz[k] as f64 * self.scale[k] + self.offset[k])
                }));
            } else if let Some(attr) = attribute_of(name) {
                let val = |i: usize, e: usize| -> f64 {
                    let es = a.size / a.elements;
                    let o = at(i) + e * es;
                    scalar(&a.kind, &b[o..o + es])
                };
                match attr {
                    Attribute::Rgb => {
                        if let Some(c) = out.rgb.as_mut() {
                            c.extend((0..n).map(|i| match self.brotli {
                                false => [val(i, 0) as u16, val(i, 1) as u16, val(i, 2) as u16],
                                true => {
                                    let m =
                                        u64::from_le_bytes(b[at(i)..at(i) + 8].try_into().unwrap());
                                    [
                                        unmorton(m, 0) as u16,
                                        unmorton(m, 1) as u16,
                                        unmorton(m, 2) as u16,
                                    ]
                                }
                            }));
                        }
                    }
                    // A LAS 1.0-1.3 angle rank is signed whatever the type says; a LAS 1.4
                    // angle is in 0.006 degree units.
                    Attribute::ScanAngle if name == "scan angle rank" => {
                        fill(&mut out, attr, (0..n).map(|i| b[at(i)] as i8 as f64))
                    }
                    Attribute::ScanAngle => fill(&mut out, attr, (0..n).map(|i| val(i, 0) * 0.006)),
                    _ => fill(&mut out, attr, (0..n).map(|i| val(i, 0))),
                }
            }
            start += match self.brotli {
                false => a.size,
                true => brotli_size(a),
            };
        }
        Ok(out)
    }
}

/// Bytes per point of an attribute in a BROTLI node (Morton-coded positions and colours).
fn brotli_size(a: &Attr) -> usize {
    match a.name.as_str() {
        "position" | "POSITION_CARTESIAN" => 16,
        "rgb" | "rgba" => 8,
        _ => a.size,
    }
}

/// Bits `3k + axis` of `m`, for k below 16 (of a 48-bit interleaving), as a number.
fn unmorton(m: u64, axis: usize) -> u32 {
    (0..16).fold(0u32, |v, k| v | (((m >> (3 * k + axis)) & 1) as u32) << k)
}

/// A little-endian value of a Potree type.
fn scalar(kind: &str, b: &[u8]) -> f64 {
    match (kind, b.len()) {
        ("int8", 1) => b[0] as i8 as f64,
        ("uint8", 1) => b[0] as f64,
        ("int16", 2) => i16::from_le_bytes([b[0], b[1]]) as f64,
        ("uint16", 2) => u16::from_le_bytes([b[0], b[1]]) as f64,
        ("int32", 4) => i32::from_le_bytes(b.try_into().unwrap()) as f64,
        ("uint32", 4) => u32::from_le_bytes(b.try_into().unwrap()) as f64,
        ("int64", 8) => i64::from_le_bytes(b.try_into().unwrap()) as f64,
        ("uint64", 8) => u64::from_le_bytes(b.try_into().unwrap()) as f64,
        ("float", 4) => f32::from_le_bytes(b.try_into().unwrap()) as f64,
        ("double", 8) => f64::from_le_bytes(b.try_into().unwrap()),
        (_, 1) => b[0] as f64,
        _ => 0.0,
    }
}

/// Fills the column of `attr` with `values`.
fn fill(out: &mut PointBatch, attr: Attribute, values: impl Iterator<Item = f64>) {
    match attr {
        Attribute::Intensity => out
            .intensity
            .as_mut()
            .map(|c| c.extend(values.map(|v| v as u16))),
        Attribute::ReturnNumber => out
            .return_number
            .as_mut()
            .map(|c| c.extend(values.map(|v| v as u8))),
        Attribute::NumberOfReturns => out
            .number_of_returns
            .as_mut()
            .map(|c| c.extend(values.map(|v| v as u8))),
        Attribute::Classification => out
            .classification
            .as_mut()
            .map(|c| c.extend(values.map(|v| v as u8))),
        Attribute::ClassificationFlags => out
            .classification_flags
            .as_mut()
            .map(|c| c.extend(values.map(|v| v as u8))),
        Attribute::ScanAngle => out
            .scan_angle
            .as_mut()
            .map(|c| c.extend(values.map(|v| v as f32))),
        Attribute::UserData => out
            .user_data
            .as_mut()
            .map(|c| c.extend(values.map(|v| v as u8))),
        Attribute::PointSourceId => out
            .point_source_id
            .as_mut()
            .map(|c| c.extend(values.map(|v| v as u16))),
        Attribute::GpsTime => out.gps_time.as_mut().map(|c| c.extend(values)),
        Attribute::ScannerChannel => out
            .scanner_channel
            .as_mut()
            .map(|c| c.extend(values.map(|v| v as u8))),
        _ => None,
    };
}

/// The points' bounds: the position attribute's `min` and `max`, where given.
fn attrs_minmax(v: &Value) -> Option<Aabb> {
    let a = v["attributes"].as_array()?.first()?;
    Some(Aabb::new(
        super::numbers::<3>(a, "min")?,
        super::numbers::<3>(a, "max")?,
    ))
}

impl Foreign for Potree {
    fn hierarchy_page(&self, key: NodeKey) -> std::result::Result<HierarchyPage, Damage> {
        self.tree.page(key, &|k, r| self.read_chunk(k, r))
    }

    fn read_node(&self, e: &NodeEntry) -> std::result::Result<PointBatch, Damage> {
        let n = e.points as usize;
        if n == 0 {
            return Ok(PointBatch::with_schema(&self.schema, 0));
        }
        let file = self.place.name("octree.bin");
        let hurt = |m: String| damage(e.key, e.page.offset, format!("{file}: {m}"), false);
        if e.page.length == 0 {
            return Err(hurt(format!("the hierarchy gives {n} points in 0 bytes")));
        }
        if e.page.length as u64 > MAX_NODE {
            return Err(hurt(format!("{} bytes", e.page.length)));
        }
        let raw = self
            .octree
            .read_at(e.page.offset, e.page.length as usize)
            .map_err(|m| hurt(m.to_string()))?;
        let b = match self.brotli {
            false => raw,
            true => {
                let most = n.saturating_mul(self.attrs.iter().map(brotli_size).sum::<usize>());
                let mut out = Vec::with_capacity(most);
                let mut r = brotli_decompressor::Decompressor::new(&raw[..], 1 << 16);
                use std::io::Read;
                (&mut r)
                    .take(most as u64 + 1)
                    .read_to_end(&mut out)
                    .map_err(|err| hurt(format!("Brotli: {err}")))?;
                out
            }
        };
        self.decode(e.key, &b, n).map_err(|d| hurt(d.message))
    }

    fn fetched(&self) -> Option<(u64, u64)> {
        let mut t = self.place.fetched()?;
        for s in [&self.hierarchy, &self.octree] {
            let (r, b) = s.fetched().unwrap_or_default();
            t = (t.0 + r, t.1 + b);
        }
        Some(t)
    }

    fn changed(&self) -> Option<String> {
        self.place
            .changed()
            .or_else(|| self.hierarchy.changed())
            .or_else(|| self.octree.changed())
    }
}
