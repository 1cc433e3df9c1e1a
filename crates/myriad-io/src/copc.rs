//! A COPC 1.0 writer (Cloud Optimized Point Cloud: a LAZ 1.4 file whose chunks are the nodes of
//! an octree, copc.io). The points of a node are one variable-size LAZ chunk; the octree's
//! hierarchy is stored in pages in an EVLR, so that a reader fetches only the parts it needs.
//!
//! File layout, as readers (laspy, copclib, copc.js, PDAL) insist on:
//!
//! | at | what |
//! |---|---|
//! | 0 | LAS 1.4 header, 375 bytes, point format 6, 7 or 8 (bit 7 set: compressed) |
//! | 375 | VLR `copc`/1: the info record, FIRST, 160 bytes (below) |
//! | | VLR `laszip encoded`/22204: variable-size chunks; then the input's other VLRs (WKT, extra bytes) |
//! | point data | i64 offset of the chunk table, then one LAZ chunk per node, then the chunk table |
//! | EVLRs | `copc`/1000: hierarchy pages |
//!
//! Info record: f64 centre x, y, z; f64 half size; f64 spacing (of the root); u64 root page offset
//! and size; f64 GPS time minimum and maximum; 11 reserved u64.
//!
//! Hierarchy page: 32-byte entries, i32 level, x, y, z; u64 offset; i32 byte size; i32 point count.
//! Point count -1: the entry points to the page of the subtree rooted at that key (whose first
//! entry is the node itself). A page here covers [`PAGE_LEVELS`] levels of its root's subtree;
//! pages are written children first, so every offset is known when its page is written.

use crate::atomic::AtomicFile;
use crate::las::LasWriteOptions;
use crate::las_records::{self, Layout, Quantization};
use laz::laszip::{ChunkTable, ChunkTableEntry};
use myriad_core::{
    Aabb, Attribute, Error, ExtraDim, ExtraType, NodeKey, PointBatch, Result, Schema,
};
use rayon::prelude::*;
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Cursor, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// Levels of the octree per hierarchy page.
pub const PAGE_LEVELS: u32 = 5;
/// Where the info record's data starts: after the 375-byte header and the 54-byte VLR header.
pub const INFO_AT: u64 = 375 + 54;
pub const INFO_LEN: usize = 160;
const ENTRY_LEN: usize = 32;

/// Where one node's chunk lies.
#[derive(Debug, Clone, Copy, Default)]
struct Chunk {
    offset: u64,
    bytes: u64,
    points: u64,
}

/// What [`CopcSink::finish`] wrote.
#[derive(Debug, Clone, Default)]
pub struct CopcSummary {
    pub points: u64,
    /// Hierarchy entries (nodes with points, and their ancestors).
    pub nodes: u64,
    pub pages: u64,
    pub bytes: u64,
}

/// One node encoded and compressed, ready to be appended.
struct Packed {
    key: NodeKey,
    chunk: Vec<u8>,
    points: u64,
    bounds: Aabb,
    by_return: [u64; 15],
    gps: (f64, f64),
}

/// Streams the nodes of an octree into a COPC file, atomically. Nodes arrive in any order, each
/// at most once; their points must lie in the node's cube under `cube` (the caller's duty).
pub struct CopcSink {
    file: AtomicFile,
    w: BufWriter<File>,
    path: PathBuf,
    header: las::Header,
    layout: Layout,
    record_len: usize,
    quant: Quantization,
    vlr: laz::LazVlr,
    data_start: u64,
    pos: u64,
    table: ChunkTable,
    chunks: BTreeMap<NodeKey, Chunk>,
    cube: Aabb,
    spacing: f64,
    page_levels: u32,
    by_return: [u64; 15],
    bounds: Aabb,
    gps: (f64, f64),
}

fn invalid(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Invalid(format!("{}: {e}", path.display()))
}

impl CopcSink {
    /// `options` must describe a LAS 1.4 point format 6, 7 or 8; `cube` is the root node's cube
    /// and `spacing` the root's point spacing.
    pub fn create(
        path: &Path,
        options: LasWriteOptions,
        cube: Aabb,
        spacing: f64,
        force: bool,
    ) -> Result<CopcSink> {
        let mut b = las::Builder::from(options.header);
        let format = b.point_format.to_u8().map_err(|e| invalid(path, e))?;
        if !(6..=8).contains(&format) {
            return Err(invalid(
                path,
                format!("COPC holds point formats 6, 7 and 8, not {format}"),
            ));
        }
        b.version = las::Version::new(1, 4);
        b.point_format.is_compressed = true;
        b.vlrs
            .retain(|v| !(v.user_id == "laszip encoded" || v.user_id == "copc"));
        b.evlrs.retain(|v| v.user_id != "copc");
        let vlr = laz::LazVlrBuilder::default()
            .with_point_format(format, b.point_format.extra_bytes)
            .map_err(|e| invalid(path, e))?
            .with_variable_chunk_size()
            .build();
        let mut laz_data = Vec::new();
        vlr.write_to(&mut laz_data)
            .map_err(|e| Error::io(path, e))?;
        b.vlrs.insert(
            0,
            las::Vlr {
                user_id: "copc".into(),
                record_id: 1,
                description: "copc info".into(),
                data: vec![0; INFO_LEN],
            },
        );
        b.vlrs.insert(
            1,
            las::Vlr {
                user_id: "laszip encoded".into(),
                record_id: 22204,
                description: "laz variable chunks".into(),
                data: laz_data,
            },
        );
        let header = b.into_header().map_err(|e| invalid(path, e))?;
        let fmt = *header.point_format();
        let layout = Layout::new(format).expect("formats 6-8 have a layout");
        let quant = Quantization::of(&header);
        let file = AtomicFile::create(path, force)?;
        let mut w = BufWriter::with_capacity(1 << 20, file.open_write()?);
        header
            .write_to(&mut w)
            .map_err(|e| invalid(path, format!("writing the header: {e}")))?;
        let data_start = w.stream_position().map_err(|e| Error::io(path, e))?;
        // The offset of the chunk table, known at the end.
        w.write_all(&(-1i64).to_le_bytes())
            .map_err(|e| Error::io(path, e))?;
        Ok(CopcSink {
            file,
            w,
            path: path.to_path_buf(),
            header,
            layout,
            record_len: fmt.len() as usize,
            quant,
            vlr,
            data_start,
            pos: data_start + 8,
            table: ChunkTable::default(),
            chunks: BTreeMap::new(),
            cube,
            spacing,
            page_levels: PAGE_LEVELS,
            by_return: [0; 15],
            bounds: Aabb::EMPTY,
            gps: (f64::INFINITY, f64::NEG_INFINITY),
        })
    }

    /// Levels per hierarchy page (tests use few, to make many pages).
    pub fn with_page_levels(mut self, levels: u32) -> CopcSink {
        self.page_levels = levels.max(1);
        self
    }

    fn pack(&self, key: NodeKey, batch: &PointBatch) -> Result<Packed> {
        let ordered = batch.gather(&chunk_order(batch));
        let batch = &ordered;
        let mut bytes = Vec::new();
        let mut bounds = Aabb::EMPTY;
        las_records::encode(
            batch,
            self.record_len,
            &self.layout,
            &self.quant,
            &mut bytes,
            &mut bounds,
        )
        .map_err(|e| {
            invalid(
                &self.path,
                format!("node {key:?}: point {}: {}", e.point, e.message),
            )
        })?;
        let mut c = laz::LasZipCompressor::new(Cursor::new(Vec::new()), self.vlr.clone())
            .map_err(|e| invalid(&self.path, e))?;
        c.compress_many(&bytes)
            .and_then(|_| c.finish_current_chunk())
            .map_err(|e| Error::io(&self.path, e))?;
        let mut chunk = c.into_inner().into_inner();
        // The compressor reserved the chunk table's offset first: the chunk is what follows.
        chunk.drain(..8);
        let mut by_return = [0u64; 15];
        for &n in batch.return_number.iter().flatten() {
            if (1..=15).contains(&n) {
                by_return[n as usize - 1] += 1;
            }
        }
        let gps = batch
            .gps_time
            .iter()
            .flatten()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| {
                (lo.min(t), hi.max(t))
            });
        Ok(Packed {
            key,
            chunk,
            points: batch.len() as u64,
            bounds,
            by_return,
            gps,
        })
    }

    /// Encodes and compresses `nodes` on all cores and appends them, one chunk each. A node
    /// without points takes no chunk (it is listed in the hierarchy only when a descendant has
    /// points).
    pub fn write_nodes(&mut self, nodes: &[(NodeKey, PointBatch)]) -> Result<()> {
        for (key, batch) in nodes {
            if !batch.is_consistent() {
                return Err(invalid(
                    &self.path,
                    format!("node {key:?}: a column's length differs from the point count"),
                ));
            }
            if self.chunks.contains_key(key) {
                return Err(invalid(&self.path, format!("node {key:?} written twice")));
            }
        }
        let packed: Vec<Result<Packed>> = nodes
            .par_iter()
            .filter(|(_, b)| !b.is_empty())
            .map(|(k, b)| self.pack(*k, b))
            .collect();
        for p in packed {
            let p = p?;
            self.w
                .write_all(&p.chunk)
                .map_err(|e| Error::io(&self.path, e))?;
            let bytes = p.chunk.len() as u64;
            self.table.push(ChunkTableEntry {
                point_count: p.points,
                byte_count: bytes,
            });
            self.chunks.insert(
                p.key,
                Chunk {
                    offset: self.pos,
                    bytes,
                    points: p.points,
                },
            );
            self.pos += bytes;
            self.bounds = self.bounds.union(&p.bounds);
            for i in 0..15 {
                self.by_return[i] += p.by_return[i];
            }
            self.gps = (self.gps.0.min(p.gps.0), self.gps.1.max(p.gps.1));
        }
        Ok(())
    }

    /// Points written so far.
    pub fn points(&self) -> u64 {
        self.chunks.values().map(|c| c.points).sum()
    }

    /// Writes the chunk table, the hierarchy, the info record and the final header, then moves
    /// the file to its name.
    pub fn finish(mut self) -> Result<CopcSummary> {
        let path = self.path.clone();
        let io = |e| Error::io(&path, e);
        let table_at = self.pos;
        self.table.write_to(&mut self.w, &self.vlr).map_err(io)?;
        let evlr_at = self.w.stream_position().map_err(io)?;
        let (pages, root, entries) = self.hierarchy(evlr_at + 60);
        let mut evlr = Vec::with_capacity(60);
        evlr.extend_from_slice(&0u16.to_le_bytes());
        evlr.extend_from_slice(&fixed::<16>("copc"));
        evlr.extend_from_slice(&1000u16.to_le_bytes());
        evlr.extend_from_slice(&(pages.len() as u64).to_le_bytes());
        evlr.extend_from_slice(&fixed::<32>("EPT hierarchy"));
        self.w.write_all(&evlr).map_err(io)?;
        self.w.write_all(&pages).map_err(io)?;
        let end = self.w.stream_position().map_err(io)?;

        let points: u64 = self.chunks.values().map(|c| c.points).sum();
        let mut raw = self
            .header
            .clone()
            .into_raw()
            .map_err(|e| invalid(&path, e))?;
        raw.number_of_point_records = 0;
        raw.number_of_points_by_return = [0; 5];
        raw.large_file = Some(las::raw::header::LargeFile {
            number_of_point_records: points,
            number_of_points_by_return: self.by_return,
        });
        raw.evlr = Some(las::raw::header::Evlr {
            start_of_first_evlr: evlr_at,
            number_of_evlrs: 1,
        });
        let b = if points > 0 {
            self.bounds
        } else {
            Aabb::new([0.0; 3], [0.0; 3])
        };
        (raw.min_x, raw.min_y, raw.min_z) = (b.min[0], b.min[1], b.min[2]);
        (raw.max_x, raw.max_y, raw.max_z) = (b.max[0], b.max[1], b.max[2]);
        if raw.offset_to_point_data as u64 != self.data_start {
            return Err(invalid(&path, "the header's size changed while writing"));
        }

        let mut info = Vec::with_capacity(INFO_LEN);
        let c = self.cube.center();
        let half = self.cube.size()[0] / 2.0;
        let (gmin, gmax) = if self.gps.0 <= self.gps.1 {
            self.gps
        } else {
            (0.0, 0.0)
        };
        for v in [c[0], c[1], c[2], half, self.spacing] {
            info.extend_from_slice(&v.to_le_bytes());
        }
        info.extend_from_slice(&root.0.to_le_bytes());
        info.extend_from_slice(&root.1.to_le_bytes());
        info.extend_from_slice(&gmin.to_le_bytes());
        info.extend_from_slice(&gmax.to_le_bytes());
        info.resize(INFO_LEN, 0);

        self.w.seek(SeekFrom::Start(0)).map_err(io)?;
        raw.write_to(&mut self.w).map_err(|e| invalid(&path, e))?;
        self.w.seek(SeekFrom::Start(INFO_AT)).map_err(io)?;
        self.w.write_all(&info).map_err(io)?;
        self.w.seek(SeekFrom::Start(self.data_start)).map_err(io)?;
        self.w
            .write_all(&(table_at as i64).to_le_bytes())
            .map_err(io)?;
        self.w.flush().map_err(io)?;
        let file = self.w.into_inner().map_err(|e| io(e.into_error()))?;
        file.sync_all().map_err(io)?;
        drop(file);
        self.file.commit()?;
        Ok(CopcSummary {
            points,
            nodes: entries,
            pages: (pages.len() / ENTRY_LEN) as u64 - entries + 1,
            bytes: end,
        })
    }

    /// The hierarchy pages as they will lie from `base` on: (bytes, (root page offset, size),
    /// node entries). Every ancestor of a node with points is listed (with 0 points when it has
    /// none), so that a reader walking down from the root reaches every node.
    fn hierarchy(&self, base: u64) -> (Vec<u8>, (u64, u64), u64) {
        let nodes = crate::with_ancestors(&self.chunks);
        let mut children: HashMap<NodeKey, Vec<NodeKey>> = HashMap::new();
        for k in nodes.keys().filter(|k| k.level > 0) {
            children.entry(k.parent()).or_default().push(*k);
        }
        let mut out = Vec::new();
        let root = self.page(NodeKey::ROOT, &nodes, &children, base, &mut out);
        (out, root, nodes.len() as u64)
    }

    /// Writes the page rooted at `top` (its child pages first) to `out`; returns its offset and
    /// size.
    fn page(
        &self,
        top: NodeKey,
        nodes: &BTreeMap<NodeKey, Chunk>,
        children: &HashMap<NodeKey, Vec<NodeKey>>,
        base: u64,
        out: &mut Vec<u8>,
    ) -> (u64, u64) {
        let mut entries: Vec<(NodeKey, u64, i32, i32)> = Vec::new();
        let mut stack = vec![top];
        while let Some(k) = stack.pop() {
            if k != top && k.level == top.level + self.page_levels {
                let (offset, size) = self.page(k, nodes, children, base, out);
                entries.push((k, offset, size as i32, -1));
                continue;
            }
            let c = nodes[&k];
            entries.push((k, c.offset, c.bytes as i32, c.points as i32));
            stack.extend(children.get(&k).into_iter().flatten());
        }
        let offset = base + out.len() as u64;
        for (k, at, size, count) in &entries {
            for v in [k.level, k.cell[0], k.cell[1], k.cell[2]] {
                out.extend_from_slice(&(v as i32).to_le_bytes());
            }
            out.extend_from_slice(&at.to_le_bytes());
            out.extend_from_slice(&size.to_le_bytes());
            out.extend_from_slice(&count.to_le_bytes());
        }
        (offset, (entries.len() * ENTRY_LEN) as u64)
    }
}

/// The order a node's points are compressed in (a COPC node is read whole, so any order is
/// its contents): by GPS time where the points have it (the order they were scanned in, each
/// field then changing little from a point to the next: KY's COPC 22 % smaller than in the
/// dataset's level order), else along a Morton curve over the node's box (neighbours in space
/// next to each other: 11-12 % smaller). Ties keep their order.
pub fn chunk_order(batch: &PointBatch) -> Vec<u32> {
    let mut ids: Vec<u32> = (0..batch.len() as u32).collect();
    if let Some(t) = &batch.gps_time {
        ids.sort_by(|&a, &b| t[a as usize].total_cmp(&t[b as usize]));
        return ids;
    }
    let mut b = Aabb::EMPTY;
    batch.positions.iter().for_each(|&p| b.extend(p));
    let s = b.size();
    let side = s[0].max(s[1]).max(s[2]);
    let cells = ((1u64 << 21) - 1) as f64;
    let codes: Vec<u64> = batch
        .positions
        .iter()
        .map(|p| {
            let q: [u32; 3] = std::array::from_fn(|a| {
                let f = if side > 0.0 {
                    (p[a] - b.min[a]) / side
                } else {
                    0.0
                };
                (f * cells).clamp(0.0, cells) as u32
            });
            myriad_core::geometry::morton(q[0], q[1], q[2])
        })
        .collect();
    ids.sort_by_key(|&i| codes[i as usize]);
    ids
}

/// The LAS 1.4 header of a COPC file for points of `s`: point format 6, 7 or 8 from the
/// attributes (normals as three f32 extra dimensions after the others), `quant` (scale, offset),
/// the VLRs of the input's stored header `las_header` (but its CRS and extra-bytes records, made
/// anew), the CRS as WKT. Also returns what the file cannot hold, one line each.
pub fn header_for(
    s: &Schema,
    quant: ([f64; 3], [f64; 3]),
    las_header: Option<&[u8]>,
    crs: Option<&str>,
) -> Result<(LasWriteOptions, Vec<String>)> {
    let mut not_kept = Vec::new();
    let format = if s.has(&Attribute::Nir) {
        8
    } else if s.has(&Attribute::Rgb) {
        7
    } else {
        6
    };
    if s.has(&Attribute::ScanAngle) && !s.has(&Attribute::ScannerChannel) {
        not_kept.push(
            "scan angle ranks as whole degrees (formats 6 to 8 store 0.006-degree steps: within 0.003 degrees)"
                .into(),
        );
    }
    if s.has(&Attribute::WavePacket) {
        not_kept.push("wave packets (COPC holds point formats 6 to 8, without waveforms)".into());
    }
    let mut dims: Vec<ExtraDim> = s
        .attributes
        .iter()
        .filter_map(|a| match a {
            Attribute::Extra(d) => Some(d.clone()),
            _ => None,
        })
        .collect();
    if s.has(&Attribute::Normal) {
        for (i, name) in ["NormalX", "NormalY", "NormalZ"].iter().enumerate() {
            dims.push(ExtraDim {
                name: name.to_string(),
                data_type: ExtraType::F32,
                offset: s.extra_bytes + 4 * i,
                description: "normal".into(),
                scale: None,
                add_offset: None,
            });
        }
    }
    let extra: usize = s.extra_bytes + if s.has(&Attribute::Normal) { 12 } else { 0 };
    let mut b = las::Builder::from((1, 4));
    b.point_format = las::point::Format::new(format).map_err(|e| Error::Invalid(e.to_string()))?;
    b.point_format.extra_bytes = extra as u16;
    b.generating_software = "myriad export".into();
    if let Some(bytes) = las_header {
        let h = crate::las::header_from_bytes(bytes)?;
        b.gps_time_type = h.gps_time_type();
        b.file_source_id = h.file_source_id();
        b.system_identifier = h.system_identifier().to_string();
        let ours = |v: &las::Vlr| {
            v.user_id == "LASF_Projection"
                || (v.user_id == "LASF_Spec" && v.record_id == 4)
                || v.user_id == "laszip encoded"
                || v.user_id == "copc"
        };
        b.vlrs.extend(h.vlrs().iter().filter(|v| !ours(v)).cloned());
        for v in h.evlrs().iter().filter(|v| !ours(v)) {
            if v.data.len() <= u16::MAX as usize {
                b.vlrs.push(v.clone());
            } else {
                not_kept.push(format!(
                    "the EVLR {}/{} ({} bytes: too large for a VLR)",
                    v.user_id,
                    v.record_id,
                    v.data.len()
                ));
            }
        }
    }
    if !dims.is_empty() {
        b.vlrs.push(crate::las::extra_bytes_vlr(&dims));
    }
    match crs {
        Some(c) if c.starts_with("EPSG:") => not_kept.push(format!(
            "the CRS {c} (COPC stores WKT; the input gave only GeoTIFF keys)"
        )),
        Some(wkt) => b.vlrs.push(las::Vlr {
            user_id: "LASF_Projection".into(),
            record_id: 2112,
            description: "OGC WKT".into(),
            data: wkt.as_bytes().to_vec(),
        }),
        None => {}
    }
    let header = b.into_header().map_err(|e| Error::Invalid(e.to_string()))?;
    let options = LasWriteOptions::like(&header).with_transforms(quant.0, quant.1)?;
    Ok((options, not_kept))
}

/// `s` in a zero-padded field of `N` bytes.
fn fixed<const N: usize>(s: &str) -> [u8; N] {
    let mut b = [0u8; N];
    let n = s.len().min(N);
    b[..n].copy_from_slice(&s.as_bytes()[..n]);
    b
}

/// The hierarchy of a COPC file as a reader walks it (for tests and `info`): every entry with
/// its point count, from the root page down through child pages.
pub fn read_hierarchy(bytes: &[u8]) -> std::result::Result<Vec<(NodeKey, u64, u32, u32)>, String> {
    let u64_at = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().unwrap());
    if bytes.len() < INFO_AT as usize + INFO_LEN || &bytes[377..381] != b"copc" {
        return Err("the copc info record is not the first VLR".into());
    }
    let root = (u64_at(INFO_AT as usize + 40), u64_at(INFO_AT as usize + 48));
    let mut out = Vec::new();
    let mut pages = vec![root];
    while let Some((at, size)) = pages.pop() {
        let (at, size) = (at as usize, size as usize);
        if at + size > bytes.len() || size % ENTRY_LEN != 0 {
            return Err(format!(
                "page at {at} of {size} bytes lies outside the file"
            ));
        }
        for e in bytes[at..at + size].chunks_exact(ENTRY_LEN) {
            let i = |o: usize| i32::from_le_bytes(e[o..o + 4].try_into().unwrap());
            let key = NodeKey {
                level: i(0) as u32,
                cell: [i(4) as u32, i(8) as u32, i(12) as u32],
            };
            let offset = u64::from_le_bytes(e[16..24].try_into().unwrap());
            let (size, count) = (i(24), i(28));
            if count == -1 {
                pages.push((offset, size as u64));
            } else {
                out.push((key, offset, size as u32, count as u32));
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod order_tests {
    use super::chunk_order;
    use myriad_core::PointBatch;

    fn batch(positions: Vec<[f64; 3]>) -> PointBatch {
        PointBatch {
            positions,
            ..Default::default()
        }
    }

    #[test]
    fn a_chunk_is_compressed_in_scan_order_or_along_a_morton_curve() {
        // By GPS time where there is one, ties in their order.
        let mut b = batch(vec![[0.0; 3]; 4]);
        b.gps_time = Some(vec![3.0, 1.0, 2.0, 1.0]);
        assert_eq!(chunk_order(&b), [1, 3, 2, 0]);
        // Else octant by octant of the points' box: (0, 0, 0) first, then +x, +y, +z, and
        // within an octant its own octants.
        let b = batch(vec![
            [9.0, 9.0, 9.0],
            [0.0, 0.0, 9.0],
            [0.0, 9.0, 0.0],
            [9.0, 0.0, 0.0],
            [1.0, 1.0, 1.0],
            [0.0, 0.0, 0.0],
        ]);
        assert_eq!(chunk_order(&b), [5, 4, 3, 2, 1, 0]);
    }
}
