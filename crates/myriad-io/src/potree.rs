//! A Potree 2.0 writer (the format PotreeConverter 2 writes and the Potree viewer opens): a folder
//! with `metadata.json`, `hierarchy.bin` and `octree.bin`, DEFAULT encoding (uncompressed records).
//!
//! - `metadata.json`: version "2.0", point count, `boundingBox` (the root CUBE: node boxes are
//!   halved from it), `offset` and `scale` of the int32 positions, `spacing` (of the root), the
//!   hierarchy's `firstChunkSize`, `stepSize` and `depth`, and the attribute list (name, type,
//!   size, element count, min and max) in record order.
//! - `octree.bin`: each node's records, interleaved: position as 3 x int32
//!   ((x - offset) / scale), then every attribute in the listed order.
//! - `hierarchy.bin`: chunks of 22-byte records: u8 type (0 inner, 1 leaf, 2 proxy), u8 child mask
//!   (bit i: child i, i = 4x + 2y + z), u32 points, u64 byte offset, u64 byte size. A chunk lists
//!   its root and the nodes below it, breadth first, [`STEP`] levels deep; a node on the chunk's
//!   last level that has children is a proxy, whose offset and size are those of its own chunk in
//!   hierarchy.bin (which starts with the node again, as a real record). The root's chunk is at 0.

use crate::atomic::AtomicDir;
use myriad_core::{Aabb, Attribute, Error, ExtraType, NodeKey, PointBatch, Result, Schema};
use rayon::prelude::*;
use serde_json::{Value, json};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Levels per hierarchy chunk (as PotreeConverter).
pub const STEP: u32 = 4;
const RECORD: usize = 22;

/// What a Potree attribute is made of.
#[derive(Debug, Clone)]
enum Field {
    Position,
    Intensity,
    ReturnNumber,
    NumberOfReturns,
    ClassificationFlags,
    Classification,
    ScanAngleRank,
    ScanAngle,
    UserData,
    PointSourceId,
    GpsTime,
    Rgb,
    Nir,
    ScannerChannel,
    ScanFlags,
    Normal(usize),
    /// Offset of the dimension in the extra bytes, its type.
    Extra(usize, ExtraType),
}

#[derive(Debug, Clone)]
struct Attr {
    name: String,
    field: Field,
    /// Potree's type name of one element, its size, the element count.
    ty: &'static str,
    elem: usize,
    count: usize,
    description: String,
}

impl Attr {
    fn new(name: &str, field: Field, ty: &'static str, elem: usize, count: usize) -> Attr {
        Attr {
            name: name.into(),
            field,
            ty,
            elem,
            count,
            description: String::new(),
        }
    }
    fn size(&self) -> usize {
        self.elem * self.count
    }
}

/// The Potree attributes that hold `schema`, named as PotreeConverter names them, and the
/// attributes that Potree cannot hold.
fn attributes(schema: &Schema) -> (Vec<Attr>, Vec<String>) {
    let has = |a: Attribute| schema.has(&a);
    let extended = has(Attribute::ScannerChannel);
    let mut v = vec![Attr::new("position", Field::Position, "int32", 4, 3)];
    let mut lost = Vec::new();
    let simple = [
        (
            Attribute::Intensity,
            "intensity",
            Field::Intensity,
            "uint16",
            2,
        ),
        (
            Attribute::ReturnNumber,
            "return number",
            Field::ReturnNumber,
            "uint8",
            1,
        ),
        (
            Attribute::NumberOfReturns,
            "number of returns",
            Field::NumberOfReturns,
            "uint8",
            1,
        ),
        (
            Attribute::ClassificationFlags,
            "classification flags",
            Field::ClassificationFlags,
            "uint8",
            1,
        ),
        (
            Attribute::Classification,
            "classification",
            Field::Classification,
            "uint8",
            1,
        ),
    ];
    for (a, name, f, ty, size) in simple {
        if has(a) {
            v.push(Attr::new(name, f, ty, size, 1));
        }
    }
    if has(Attribute::ScanAngle) {
        v.push(if extended {
            Attr::new("scan angle", Field::ScanAngle, "int16", 2, 1)
        } else {
            Attr::new("scan angle rank", Field::ScanAngleRank, "int8", 1, 1)
        });
    }
    let more = [
        (
            Attribute::UserData,
            "user data",
            Field::UserData,
            "uint8",
            1,
        ),
        (
            Attribute::PointSourceId,
            "point source id",
            Field::PointSourceId,
            "uint16",
            2,
        ),
        (Attribute::GpsTime, "gps-time", Field::GpsTime, "double", 8),
    ];
    for (a, name, f, ty, size) in more {
        if has(a) {
            v.push(Attr::new(name, f, ty, size, 1));
        }
    }
    if has(Attribute::Rgb) {
        v.push(Attr::new("rgb", Field::Rgb, "uint16", 2, 3));
    }
    for (a, name, f, ty, size) in [
        (Attribute::Nir, "nir", Field::Nir, "uint16", 2),
        (
            Attribute::ScannerChannel,
            "scanner channel",
            Field::ScannerChannel,
            "uint8",
            1,
        ),
        (
            Attribute::ScanFlags,
            "scan flags",
            Field::ScanFlags,
            "uint8",
            1,
        ),
    ] {
        if has(a) {
            v.push(Attr::new(name, f, ty, size, 1));
        }
    }
    if has(Attribute::Normal) {
        // The names Potree's loader gathers into its NORMAL vector.
        for (i, name) in ["NormalX", "NormalY", "NormalZ"].iter().enumerate() {
            v.push(Attr::new(name, Field::Normal(i), "float", 4, 1));
        }
    }
    if has(Attribute::WavePacket) {
        lost.push("wave packets (Potree has no attribute for them)".into());
    }
    for a in &schema.attributes {
        if let Attribute::Extra(d) = a {
            let ty = match d.data_type {
                ExtraType::U8 => "uint8",
                ExtraType::I8 => "int8",
                ExtraType::U16 => "uint16",
                ExtraType::I16 => "int16",
                ExtraType::U32 => "uint32",
                ExtraType::I32 => "int32",
                ExtraType::U64 => "uint64",
                ExtraType::I64 => "int64",
                ExtraType::F32 => "float",
                ExtraType::F64 => "double",
                ExtraType::Undocumented(n) => {
                    lost.push(format!(
                        "extra bytes \"{}\" ({n} undocumented bytes: Potree needs a type)",
                        d.name
                    ));
                    continue;
                }
            };
            let mut at = Attr::new(
                &d.name,
                Field::Extra(d.offset, d.data_type),
                ty,
                d.data_type.size(),
                1,
            );
            at.description = d.description.clone();
            v.push(at);
        }
    }
    (v, lost)
}

/// The files a Potree folder holds (PotreeConverter adds log.txt): a folder with anything else
/// in it is not replaced, even with `force`.
const POTREE_FILES: [&str; 4] = ["metadata.json", "hierarchy.bin", "octree.bin", "log.txt"];

/// Whether `dir` holds a Potree dataset only.
fn is_potree(dir: &Path) -> bool {
    std::fs::read_dir(dir).is_ok_and(|entries| {
        entries
            .flatten()
            .all(|e| POTREE_FILES.contains(&e.file_name().to_string_lossy().as_ref()))
    })
}

#[derive(Debug, Clone, Copy, Default)]
struct Node {
    offset: u64,
    bytes: u64,
    points: u32,
}

/// What [`PotreeSink::finish`] wrote.
#[derive(Debug, Clone, Default)]
pub struct PotreeSummary {
    pub points: u64,
    pub nodes: u64,
    pub chunks: u64,
    pub bytes: u64,
}

/// Where the octree lies and how its positions are stored.
#[derive(Debug, Clone)]
pub struct Frame {
    /// The root node's cube.
    pub cube: Aabb,
    /// Step of the stored positions.
    pub scale: [f64; 3],
    /// A point of the grid the coordinates lie on (`offset + k * scale`).
    pub grid_offset: [f64; 3],
    /// Point spacing of the root.
    pub spacing: f64,
    /// OGC WKT or "EPSG:n".
    pub crs: Option<String>,
}

/// Streams the nodes of an octree into a Potree 2.0 folder.
pub struct PotreeSink {
    dir: AtomicDir,
    octree: BufWriter<File>,
    attrs: Vec<Attr>,
    record: usize,
    cube: Aabb,
    offset: [f64; 3],
    scale: [f64; 3],
    spacing: f64,
    name: String,
    /// The CRS as a proj4 string, or empty.
    projection: String,
    nodes: BTreeMap<NodeKey, Node>,
    pos: u64,
    /// Per attribute, per element: min and max.
    ranges: Vec<Vec<(f64, f64)>>,
    path: PathBuf,
}

impl PotreeSink {
    /// Positions are stored as int32 steps of the frame's scale from the point of its grid next
    /// to the cube's minimum (so that coordinates on that grid stay exact). Returns the sink and what it cannot keep of `schema`.
    pub fn create(
        dir: &Path,
        schema: &Schema,
        frame: Frame,
        force: bool,
    ) -> Result<(PotreeSink, Vec<String>)> {
        let Frame {
            cube,
            scale,
            grid_offset,
            spacing,
            crs,
        } = frame;
        let offset: [f64; 3] = std::array::from_fn(|a| {
            grid_offset[a] + ((cube.min[a] - grid_offset[a]) / scale[a]).floor() * scale[a]
        });
        for a in 0..3 {
            let steps = (cube.max[a] - offset[a]) / scale[a];
            if !(steps.is_finite() && steps < i32::MAX as f64) {
                return Err(Error::unsupported(
                    dir,
                    "the dataset's extent at its precision does not fit Potree's 32-bit positions",
                ));
            }
        }
        let (attrs, mut lost) = attributes(schema);
        // Potree's map reads a proj4 string (a WKT stops its viewer): PROJ makes it from the CRS.
        let projection = match &crs {
            None => String::new(),
            Some(c) => match crate::proj::Crs::new(c).and_then(|c| c.proj4()) {
                Ok(p) => p,
                Err(e) => {
                    let c: String = c.chars().take(40).collect();
                    lost.push(format!(
                        "the CRS \"{c}...\" (Potree's metadata takes a proj4 string: {e})"
                    ));
                    String::new()
                }
            },
        };
        let ad = AtomicDir::create(dir, force, is_potree, "a Potree folder")?;
        let path = ad.temp().join("octree.bin");
        let octree = BufWriter::with_capacity(
            1 << 20,
            File::create(&path).map_err(|e| Error::io(&path, e))?,
        );
        let record = attrs.iter().map(Attr::size).sum();
        let ranges = attrs
            .iter()
            .map(|a| vec![(f64::INFINITY, f64::NEG_INFINITY); a.count])
            .collect();
        let name = dir
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        Ok((
            PotreeSink {
                dir: ad,
                octree,
                attrs,
                record,
                cube,
                offset,
                scale,
                spacing,
                name,
                projection,
                nodes: BTreeMap::new(),
                pos: 0,
                ranges,
                path: dir.to_path_buf(),
            },
            lost,
        ))
    }

    /// Bytes per point record.
    pub fn record_len(&self) -> usize {
        self.record
    }

    /// The records of `batch` and each attribute's range.
    fn encode(&self, batch: &PointBatch) -> (Vec<u8>, Vec<Vec<(f64, f64)>>) {
        let n = batch.len();
        let mut out = vec![0u8; n * self.record];
        let mut ranges: Vec<Vec<(f64, f64)>> = self
            .attrs
            .iter()
            .map(|a| vec![(f64::INFINITY, f64::NEG_INFINITY); a.count])
            .collect();
        let mut at = 0;
        for (ai, a) in self.attrs.iter().enumerate() {
            let r = &mut ranges[ai];
            let mut put = |i: usize, e: usize, bytes: &[u8], v: f64| {
                let o = i * self.record + at + e * a.elem;
                out[o..o + bytes.len()].copy_from_slice(bytes);
                r[e] = (r[e].0.min(v), r[e].1.max(v));
            };
            macro_rules! col {
                ($c:ident, $conv:expr) => {
                    if let Some(c) = &batch.$c {
                        for (i, &x) in c.iter().enumerate() {
                            let (b, v) = $conv(x);
                            put(i, 0, &b, v);
                        }
                    }
                };
            }
            match &a.field {
                Field::Position => {
                    for (i, p) in batch.positions.iter().enumerate() {
                        for (e, &x) in p.iter().enumerate() {
                            let q = ((x - self.offset[e]) / self.scale[e]).round() as i32;
                            put(i, e, &q.to_le_bytes(), x);
                        }
                    }
                }
                Field::Intensity => col!(intensity, |x: u16| (x.to_le_bytes(), x as f64)),
                Field::ReturnNumber => col!(return_number, |x: u8| ([x], x as f64)),
                Field::NumberOfReturns => col!(number_of_returns, |x: u8| ([x], x as f64)),
                Field::ClassificationFlags => {
                    col!(classification_flags, |x: u8| ([x], x as f64))
                }
                Field::Classification => col!(classification, |x: u8| ([x], x as f64)),
                Field::ScanAngleRank => col!(scan_angle, |x: f32| {
                    let v = x.round().clamp(-128.0, 127.0) as i8;
                    (v.to_le_bytes(), v as f64)
                }),
                Field::ScanAngle => col!(scan_angle, |x: f32| {
                    let v = (x as f64 / 0.006).round().clamp(-32768.0, 32767.0) as i16;
                    (v.to_le_bytes(), v as f64)
                }),
                Field::UserData => col!(user_data, |x: u8| ([x], x as f64)),
                Field::PointSourceId => col!(point_source_id, |x: u16| (x.to_le_bytes(), x as f64)),
                Field::GpsTime => col!(gps_time, |x: f64| (x.to_le_bytes(), x)),
                Field::Rgb => {
                    if let Some(c) = &batch.rgb {
                        for (i, rgb) in c.iter().enumerate() {
                            for (e, &v) in rgb.iter().enumerate() {
                                put(i, e, &v.to_le_bytes(), v as f64);
                            }
                        }
                    }
                }
                Field::Nir => col!(nir, |x: u16| (x.to_le_bytes(), x as f64)),
                Field::ScannerChannel => col!(scanner_channel, |x: u8| ([x], x as f64)),
                Field::ScanFlags => col!(scan_flags, |x: u8| ([x], x as f64)),
                Field::Normal(axis) => {
                    if let Some(c) = &batch.normal {
                        for (i, nv) in c.iter().enumerate() {
                            put(i, 0, &nv[*axis].to_le_bytes(), nv[*axis] as f64);
                        }
                    }
                }
                Field::Extra(off, ty) => {
                    if let Some(bytes) = &batch.extra_bytes {
                        let s = batch.extra_stride;
                        let size = ty.size();
                        for i in 0..n {
                            let Some(b) = bytes.get(i * s + off..i * s + off + size) else {
                                break;
                            };
                            put(i, 0, b, extra_value(*ty, b));
                        }
                    }
                }
            }
            at += a.size();
        }
        (out, ranges)
    }

    /// Encodes `nodes` on all cores and appends their records to octree.bin.
    pub fn write_nodes(&mut self, nodes: &[(NodeKey, PointBatch)]) -> Result<()> {
        for (key, batch) in nodes {
            if !batch.is_consistent() {
                return Err(Error::Invalid(format!(
                    "{}: node {key:?}: a column's length differs from the point count",
                    self.path.display()
                )));
            }
            if self.nodes.contains_key(key) || batch.len() > u32::MAX as usize {
                return Err(Error::Invalid(format!(
                    "{}: node {key:?} written twice or too large",
                    self.path.display()
                )));
            }
        }
        let encoded: Vec<_> = nodes
            .par_iter()
            .filter(|(_, b)| !b.is_empty())
            .map(|(k, b)| (*k, b.len(), self.encode(b)))
            .collect();
        for (key, n, (bytes, ranges)) in encoded {
            self.octree
                .write_all(&bytes)
                .map_err(|e| Error::io(&self.path, e))?;
            self.nodes.insert(
                key,
                Node {
                    offset: self.pos,
                    bytes: bytes.len() as u64,
                    points: n as u32,
                },
            );
            self.pos += bytes.len() as u64;
            for (mine, theirs) in self.ranges.iter_mut().zip(ranges) {
                for (m, t) in mine.iter_mut().zip(theirs) {
                    *m = (m.0.min(t.0), m.1.max(t.1));
                }
            }
        }
        Ok(())
    }

    /// Writes hierarchy.bin and metadata.json, then moves the folder to its name.
    pub fn finish(mut self) -> Result<PotreeSummary> {
        let io = |p: &Path, e| Error::io(p, e);
        self.octree.flush().map_err(|e| io(&self.path, e))?;
        let octree_bytes = self.pos;
        let (hierarchy, first, depth, entries, chunks) = self.hierarchy();
        let hpath = self.dir.temp().join("hierarchy.bin");
        std::fs::write(&hpath, &hierarchy).map_err(|e| io(&hpath, e))?;
        let points: u64 = self.nodes.values().map(|n| n.points as u64).sum();
        let attributes: Vec<Value> = self
            .attrs
            .iter()
            .zip(&self.ranges)
            .map(|(a, r)| {
                let (min, max): (Vec<f64>, Vec<f64>) = r
                    .iter()
                    .map(|&(lo, hi)| if lo <= hi { (lo, hi) } else { (0.0, 0.0) })
                    .unzip();
                json!({
                    "name": a.name, "description": a.description, "size": a.size(),
                    "numElements": a.count, "elementSize": a.elem, "type": a.ty,
                    "min": min, "max": max,
                    "scale": vec![1.0; a.count], "offset": vec![0.0; a.count],
                })
            })
            .collect();
        let meta = json!({
            "version": "2.0",
            "name": self.name,
            "description": "",
            "points": points,
            "projection": self.projection,
            "hierarchy": {"firstChunkSize": first, "stepSize": STEP, "depth": depth},
            "offset": self.offset,
            "scale": self.scale,
            "spacing": self.spacing,
            "boundingBox": {"min": self.cube.min, "max": self.cube.max},
            "encoding": "DEFAULT",
            "attributes": attributes,
        });
        let mpath = self.dir.temp().join("metadata.json");
        let text = serde_json::to_string_pretty(&meta).expect("JSON of numbers and strings");
        std::fs::write(&mpath, text).map_err(|e| io(&mpath, e))?;
        let file = self
            .octree
            .into_inner()
            .map_err(|e| Error::io(&self.path, e.into_error()))?;
        file.sync_all().map_err(|e| io(&self.path, e))?;
        drop(file);
        self.dir.commit()?;
        Ok(PotreeSummary {
            points,
            nodes: entries,
            chunks,
            bytes: octree_bytes + hierarchy.len() as u64,
        })
    }

    /// hierarchy.bin: (bytes, size of the root's chunk, depth, records of real nodes, chunks).
    fn hierarchy(&self) -> (Vec<u8>, u64, u32, u64, u64) {
        let nodes = crate::with_ancestors(&self.nodes);
        let mut children: HashMap<NodeKey, Vec<(usize, NodeKey)>> = HashMap::new();
        for k in nodes.keys().filter(|k| k.level > 0) {
            let c = (0..3).fold(0, |m, a| m | ((k.cell[a] & 1) as usize) << (2 - a));
            children.entry(k.parent()).or_default().push((c, *k));
        }
        for v in children.values_mut() {
            v.sort();
        }
        let mask = |k: &NodeKey| {
            children
                .get(k)
                .map_or(0u8, |v| v.iter().fold(0u8, |m, (c, _)| m | 1 << c))
        };
        // Chunks in the order they are laid out: the root's first, then breadth first.
        let mut chunk_roots = vec![NodeKey::ROOT];
        // Per chunk: its records (key, is proxy).
        let mut chunk_records: Vec<Vec<(NodeKey, bool)>> = Vec::new();
        let mut i = 0;
        while i < chunk_roots.len() {
            let top = chunk_roots[i];
            let mut records = Vec::new();
            let mut queue = std::collections::VecDeque::from([top]);
            while let Some(k) = queue.pop_front() {
                let proxy = k != top && k.level == top.level + STEP && mask(&k) != 0;
                records.push((k, proxy));
                if proxy {
                    chunk_roots.push(k);
                } else {
                    queue.extend(children.get(&k).into_iter().flatten().map(|(_, c)| *c));
                }
            }
            chunk_records.push(records);
            i += 1;
        }
        let mut chunk_at: HashMap<NodeKey, (u64, u64)> = HashMap::new();
        let mut at = 0u64;
        for (top, records) in chunk_roots.iter().zip(&chunk_records) {
            let size = (records.len() * RECORD) as u64;
            chunk_at.insert(*top, (at, size));
            at += size;
        }
        let mut out = Vec::with_capacity(at as usize);
        for records in &chunk_records {
            for (k, proxy) in records {
                let n = nodes[k];
                let m = mask(k);
                let (ty, offset, size) = if *proxy {
                    let (o, s) = chunk_at[k];
                    (2u8, o, s)
                } else {
                    (if m == 0 { 1u8 } else { 0u8 }, n.offset, n.bytes)
                };
                out.push(ty);
                out.push(m);
                out.extend_from_slice(&n.points.to_le_bytes());
                out.extend_from_slice(&offset.to_le_bytes());
                out.extend_from_slice(&size.to_le_bytes());
            }
        }
        let depth = nodes.keys().map(|k| k.level).max().unwrap_or(0);
        let first = chunk_at[&NodeKey::ROOT].1;
        (
            out,
            first,
            depth,
            nodes.len() as u64,
            chunk_roots.len() as u64,
        )
    }
}

/// The value of an extra dimension's raw bytes (for its range).
fn extra_value(ty: ExtraType, b: &[u8]) -> f64 {
    let a = |n: usize| -> [u8; 8] {
        let mut x = [0u8; 8];
        x[..n].copy_from_slice(&b[..n]);
        x
    };
    match ty {
        ExtraType::U8 => b[0] as f64,
        ExtraType::I8 => b[0] as i8 as f64,
        ExtraType::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
        ExtraType::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
        ExtraType::U32 => u32::from_le_bytes(a(4)[..4].try_into().unwrap()) as f64,
        ExtraType::I32 => i32::from_le_bytes(a(4)[..4].try_into().unwrap()) as f64,
        ExtraType::U64 => u64::from_le_bytes(a(8)) as f64,
        ExtraType::I64 => i64::from_le_bytes(a(8)) as f64,
        ExtraType::F32 => f32::from_le_bytes(a(4)[..4].try_into().unwrap()) as f64,
        ExtraType::F64 => f64::from_le_bytes(a(8)),
        ExtraType::Undocumented(_) => 0.0,
    }
}

/// A node as Potree's loader reads it: name, type, points, byte offset and size in octree.bin.
pub type NodeRecord = (String, u8, u32, u64, u64);

/// The nodes of a Potree folder's hierarchy.bin as Potree's loader walks it, from the root's
/// chunk through every proxy. For tests.
pub fn read_hierarchy(
    bytes: &[u8],
    first_chunk: u64,
) -> std::result::Result<Vec<NodeRecord>, String> {
    let mut out = Vec::new();
    // (name, offset, size) of chunks to read.
    let mut pending = vec![("r".to_string(), 0u64, first_chunk)];
    while let Some((name, at, size)) = pending.pop() {
        let (at, size) = (at as usize, size as usize);
        if at + size > bytes.len() || size % RECORD != 0 || size == 0 {
            return Err(format!(
                "chunk of {name} at {at}, {size} bytes, is not in the file"
            ));
        }
        let recs = &bytes[at..at + size];
        let mut names = std::collections::VecDeque::from([name]);
        for r in recs.chunks_exact(RECORD) {
            let Some(name) = names.pop_front() else {
                return Err("a chunk has more records than its child masks name".into());
            };
            let (ty, mask) = (r[0], r[1]);
            let points = u32::from_le_bytes(r[2..6].try_into().unwrap());
            let offset = u64::from_le_bytes(r[6..14].try_into().unwrap());
            let size = u64::from_le_bytes(r[14..22].try_into().unwrap());
            if ty == 2 {
                pending.push((name, offset, size));
                continue;
            }
            for c in 0..8 {
                if mask & (1 << c) != 0 {
                    names.push_back(format!("{name}{c}"));
                }
            }
            out.push((name, ty, points, offset, size));
        }
        if !names.is_empty() {
            return Err("a chunk's child masks name more nodes than it holds".into());
        }
    }
    Ok(out)
}
