//! COPC 1.0 read in place (copc.io): a LAZ 1.4 file whose variable-size chunks are the nodes of
//! an octree, its hierarchy in pages of an EVLR. Opening reads the header and VLRs in one
//! range (over HTTP, the opening request asks for [`HEAD`] bytes); the first hierarchy page
//! read is the root page the info VLR points to; each node is one range and is decoded alone.
//!
//! Info VLR (`copc`/1, 160 bytes): f64 centre x, y, z; f64 half size; f64 spacing (of the root);
//! u64 root page offset and size; f64 GPS time minimum and maximum; reserved. A hierarchy page
//! is 32-byte entries: i32 level, x, y, z; u64 offset; i32 byte size; i32 point count (-1: the
//! entry points to the page of the subtree rooted at that key, which holds the node itself).

use super::{Foreign, Known, SourcePage, Tree, damage};
use crate::{ByteSource, Damage, HierarchyPage, Metadata, NodeEntry, PageRef, Quantization};
use myriad_core::{Aabb, Error, NodeKey, PointBatch, Result};
use myriad_io::las_bytes::LasLayout;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Bytes asked for when opening over HTTP: the 375-byte header, the info VLR, the laszip VLR,
/// and room for a WKT or extra-bytes VLR (a longer header takes a second request).
pub const HEAD: usize = 64 << 10;
const INFO_LEN: usize = 160;
const ENTRY_LEN: usize = 32;
/// The most bytes a hierarchy page may have (2 M entries).
const MAX_PAGE: u64 = 64 << 20;

/// Whether the file at `path` is COPC: LAS 1.4 whose first VLR is `copc`/1.
pub fn has_info(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 375 + 54];
    let Ok(mut f) = std::fs::File::open(path) else {
        return false;
    };
    if f.read_exact(&mut head).is_err() {
        return false;
    }
    is_copc_head(&head)
}

/// Whether a file's first 429 bytes are a COPC file's.
fn is_copc_head(head: &[u8]) -> bool {
    head.len() >= 429
        && &head[..4] == b"LASF"
        && head[24] == 1
        && head[25] == 4
        && &head[375 + 2..375 + 6] == b"copc"
        && u16::from_le_bytes([head[375 + 18], head[375 + 19]]) == 1
}

pub(crate) struct Copc {
    bytes: Arc<dyn ByteSource>,
    name: PathBuf,
    las: LasLayout,
    tree: Tree,
}

impl Copc {
    /// Opens the COPC file in `bytes`, named `name`: its metadata and its reader.
    pub(crate) fn open(bytes: Arc<dyn ByteSource>, name: &Path) -> Result<(Metadata, Copc)> {
        let len = bytes.len();
        let io = |e: std::io::Error| Error::io(name, e);
        let mut head = bytes
            .read_at(0, (HEAD as u64).min(len) as usize)
            .map_err(io)?;
        if !is_copc_head(&head) {
            return Err(Error::at_byte(
                name,
                0,
                "not a COPC file (LAS 1.4 whose first VLR is \"copc\" record 1)",
            ));
        }
        let data_at = myriad_io::las_bytes::data_offset(name, &head)?;
        if data_at > head.len() as u64 {
            if data_at > 16 << 20 || data_at > len {
                return Err(Error::at_byte(
                    name,
                    96,
                    format!("VLRs up to byte {data_at}: too long"),
                ));
            }
            head = bytes.read_at(0, data_at as usize).map_err(io)?;
        }
        let las = LasLayout::parse(name, &head, len)?;
        let info = &head[375 + 54..375 + 54 + INFO_LEN];
        let f = |i: usize| f64::from_le_bytes(info[i * 8..i * 8 + 8].try_into().unwrap());
        let u = |i: usize| u64::from_le_bytes(info[i * 8..i * 8 + 8].try_into().unwrap());
        let (center, half, spacing) = ([f(0), f(1), f(2)], f(3), f(4));
        let at = 375 + 54;
        if !(center.iter().all(|c| c.is_finite()) && half.is_finite() && half > 0.0) {
            return Err(Error::at_byte(
                name,
                at,
                format!("COPC info: centre {center:?}, half size {half}"),
            ));
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(Error::at_byte(
                name,
                at + 32,
                format!("COPC info: root spacing {spacing}"),
            ));
        }
        let (root_at, root_len) = (u(5), u(6));
        if root_at.saturating_add(root_len) > len
            || root_len > MAX_PAGE
            || !root_len.is_multiple_of(ENTRY_LEN as u64)
        {
            return Err(Error::at_byte(
                name,
                at + 40,
                format!(
                    "COPC info: root hierarchy page of {root_len} bytes at {root_at} does not fit the file"
                ),
            ));
        }
        let cube = Aabb::new(center.map(|c| c - half), center.map(|c| c + half));
        let (scale, offset) = las.scale_offset();
        let meta = Metadata {
            structure: "copc".into(),
            parameters: json!({"format": "COPC 1.0", "read_in_place": true}),
            points: las.points,
            nodes: 0,
            depth: 0,
            bounds: las.bounds.unwrap_or(cube),
            root: cube,
            quantization: Quantization { scale, offset },
            crs: las.crs.clone(),
            schema: las.schema.clone(),
            sources: vec![
                json!({"path": name.display().to_string(), "format": "COPC", "points": las.points}),
            ],
            las_header: las.header_bytes().ok(),
            software: String::from_utf8_lossy(&head[26 + 32..26 + 64])
                .trim_end_matches('\0')
                .trim()
                .to_string(),
            levels: Vec::new(),
            files: Vec::new(),
        };
        let root = PageRef {
            offset: root_at,
            length: root_len as u32,
            crc: 0,
        };
        let copc = Copc {
            bytes,
            name: name.to_path_buf(),
            las,
            tree: Tree::new(root, spacing),
        };
        Ok((meta, copc))
    }

    /// Reads and parses the hierarchy page at `r`, the page of `key`'s subtree.
    fn read_page(&self, key: NodeKey, r: PageRef) -> std::result::Result<SourcePage, Damage> {
        let len = self.bytes.len();
        let hurt = |at: u64, m: String| damage(key, at, m, true);
        if r.offset.saturating_add(r.length as u64) > len
            || !(r.length as usize).is_multiple_of(ENTRY_LEN)
        {
            return Err(hurt(
                r.offset,
                format!("a {}-byte hierarchy page does not fit the file", r.length),
            ));
        }
        let b = self
            .bytes
            .read_at(r.offset, r.length as usize)
            .map_err(|e| hurt(r.offset, e.to_string()))?;
        let mut page = SourcePage::default();
        for (i, e) in b.chunks_exact(ENTRY_LEN).enumerate() {
            let at = r.offset + (i * ENTRY_LEN) as u64;
            let i32_at = |o: usize| i32::from_le_bytes(e[o..o + 4].try_into().unwrap());
            let (level, x, y, z) = (i32_at(0), i32_at(4), i32_at(8), i32_at(12));
            let offset = u64::from_le_bytes(e[16..24].try_into().unwrap());
            let (size, count) = (i32_at(24), i32_at(28));
            let side = 1i64 << level.clamp(0, 31);
            if !(0..=30).contains(&level) || [x, y, z].iter().any(|&c| c < 0 || c as i64 >= side) {
                return Err(hurt(
                    at,
                    format!("entry {i}: key {level}-{x}-{y}-{z} is not a node of the octree"),
                ));
            }
            let k = NodeKey {
                level: level as u32,
                cell: [x as u32, y as u32, z as u32],
            };
            if size < 0 || offset.saturating_add(size as u64) > len {
                return Err(hurt(
                    at + 16,
                    format!("entry {k}: {size} bytes at {offset} do not fit the file"),
                ));
            }
            match count {
                -1 => page.below.push((
                    k,
                    PageRef {
                        offset,
                        length: size as u32,
                        crc: 0,
                    },
                )),
                c if c >= 0 => page.nodes.push((
                    k,
                    Known {
                        points: c as u64,
                        at: offset,
                        len: if c == 0 { 0 } else { size as u64 },
                    },
                )),
                c => return Err(hurt(at + 28, format!("entry {k}: point count {c}"))),
            }
        }
        Ok(page)
    }
}

impl Foreign for Copc {
    fn hierarchy_page(&self, key: NodeKey) -> std::result::Result<HierarchyPage, Damage> {
        self.tree.page(key, &|k, r| self.read_page(k, r))
    }

    fn read_node(&self, e: &NodeEntry) -> std::result::Result<PointBatch, Damage> {
        let hurt = |at: u64, m: String| damage(e.key, at, m, false);
        if e.points == 0 {
            let mut b = PointBatch::with_schema(&self.las.schema, 0);
            b.extra_stride = self.las.schema.extra_bytes;
            return Ok(b);
        }
        // Points in no bytes: the hierarchy is wrong (found by fuzzing: read as none, a
        // command over the node said 0 points and succeeded).
        if e.page.length == 0 {
            return Err(hurt(
                e.page.offset,
                format!("the hierarchy gives {} points in 0 bytes", e.points),
            ));
        }
        let chunk = self
            .bytes
            .read_at(e.page.offset, e.page.length as usize)
            .map_err(|m| hurt(e.page.offset, m.to_string()))?;
        let b = self
            .las
            .decode_chunk(&self.name, e.page.offset, &chunk, e.points as u64)
            .map_err(|err| super::as_damage(e.key, err, e.page.offset))?;
        Ok(b)
    }

    fn fetched(&self) -> Option<(u64, u64)> {
        self.bytes.fetched()
    }

    fn changed(&self) -> Option<String> {
        self.bytes.changed()
    }
}
