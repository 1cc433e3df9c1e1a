//! The Myriad dataset file, `.myr`: a 64-byte header, node pages, metadata (JSON) and a hierarchy
//! stored in pages (like COPC), every page with a CRC-32. Writers append node pages from any
//! thread as nodes are built and write the hierarchy, metadata and header last; readers work on
//! byte ranges ([`ByteSource`]: a file now, HTTP range requests later) and are shared between
//! threads. Opening a dataset of any size reads the header, the metadata and the root hierarchy
//! page. The byte layout is in docs/format.md.
//!
//! This crate decides nothing about levels of detail: it stores what a builder gives it.

pub mod hierarchy;
pub mod page;
pub mod splat;

pub mod metadata;
pub mod remote;

pub use hierarchy::{ChildPage, HierarchyPage, NodeEntry, PageRef};
pub use metadata::{Level, Metadata};
pub use page::Quantization;

use myriad_core::{Aabb, Error, NodeKey, Obb, PointBatch, Result, Schema};
use myriad_io::atomic::AtomicFile;
use serde_json::Value;
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

pub const MAGIC: &[u8; 8] = b"MYRIAD\x00\x1a";
/// 2: hierarchy entries carry optional node bounds, contours and splat pages (the kd, layered and
/// mwkd structures).
pub const FORMAT_VERSION: u32 = 2;
pub const HEADER_LEN: usize = 64;

/// The 64-byte file header.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Header {
    metadata: PageRef,
    hierarchy: PageRef,
    file_length: u64,
    points: u64,
}

impl Header {
    fn encode(&self) -> [u8; HEADER_LEN] {
        let mut b = [0u8; HEADER_LEN];
        b[..8].copy_from_slice(MAGIC);
        b[8..12].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
        let put = |b: &mut [u8; HEADER_LEN], at: usize, r: PageRef| {
            b[at..at + 8].copy_from_slice(&r.offset.to_le_bytes());
            b[at + 8..at + 12].copy_from_slice(&r.length.to_le_bytes());
            b[at + 12..at + 16].copy_from_slice(&r.crc.to_le_bytes());
        };
        put(&mut b, 16, self.metadata);
        put(&mut b, 32, self.hierarchy);
        b[48..56].copy_from_slice(&self.file_length.to_le_bytes());
        b[56..64].copy_from_slice(&self.points.to_le_bytes());
        let crc = crc32fast::hash(&b);
        b[12..16].copy_from_slice(&crc.to_le_bytes());
        b
    }

    fn decode(b: &[u8; HEADER_LEN]) -> std::result::Result<Header, (u64, String)> {
        if &b[..8] != MAGIC {
            return Err((0, "not a Myriad dataset (wrong magic)".into()));
        }
        let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap());
        let u64_at = |o: usize| u64::from_le_bytes(b[o..o + 8].try_into().unwrap());
        let version = u32_at(8);
        let mut zeroed = *b;
        zeroed[12..16].fill(0);
        if crc32fast::hash(&zeroed) != u32_at(12) {
            return Err((12, "header checksum mismatch".into()));
        }
        if version != FORMAT_VERSION {
            return Err((
                8,
                format!(
                    "format version {version}; this build reads {FORMAT_VERSION} (convert the input again)"
                ),
            ));
        }
        let r = |at: usize| PageRef {
            offset: u64_at(at),
            length: u32_at(at + 8),
            crc: u32_at(at + 12),
        };
        Ok(Header {
            metadata: r(16),
            hierarchy: r(32),
            file_length: u64_at(48),
            points: u64_at(56),
        })
    }
}

/// Bytes addressed by offset: a file, later an HTTP resource. Shared between threads.
pub trait ByteSource: Send + Sync {
    fn len(&self) -> u64;
    fn read_at(&self, offset: u64, len: usize) -> std::io::Result<Vec<u8>>;
    /// Requests made and bytes fetched, for sources over a network.
    fn fetched(&self) -> Option<(u64, u64)> {
        None
    }
}

/// A local file, read with positioned reads (no shared cursor).
pub struct FileBytes {
    file: File,
    len: u64,
}

impl FileBytes {
    pub fn open(path: &Path) -> Result<FileBytes> {
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        Ok(FileBytes { file, len })
    }
}

impl ByteSource for FileBytes {
    fn len(&self) -> u64 {
        self.len
    }
    fn read_at(&self, offset: u64, len: usize) -> std::io::Result<Vec<u8>> {
        use std::os::unix::fs::FileExt;
        let mut b = vec![0u8; len];
        self.file.read_exact_at(&mut b, offset)?;
        Ok(b)
    }
}

/// A node's stored outline: bounds for nodes that are not their key's octree cell, a contour
/// where the structure has one.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NodeShape {
    pub bounds: Option<Aabb>,
    pub contour: Option<Obb>,
}

/// Writes a dataset: node pages appended by any thread as they are built, then
/// [`DatasetWriter::finish`] writes the hierarchy pages, the metadata and the header, and moves
/// the file to its name. Until then the file has a zeroed header, under a temporary name.
pub struct DatasetWriter {
    out: Mutex<Out>,
    file: AtomicFile,
    path: PathBuf,
    quant: Quantization,
    entries: Mutex<Vec<NodeEntry>>,
    splats: Mutex<HashMap<NodeKey, splat::SplatInfo>>,
}

struct Out {
    w: BufWriter<File>,
    pos: u64,
}

impl DatasetWriter {
    pub fn create(path: &Path, force: bool, quant: Quantization) -> Result<DatasetWriter> {
        let file = AtomicFile::create(path, force)?;
        let mut w = BufWriter::with_capacity(1 << 20, file.open_write()?);
        w.write_all(&[0u8; HEADER_LEN])
            .map_err(|e| Error::io(path, e))?;
        Ok(DatasetWriter {
            out: Mutex::new(Out {
                w,
                pos: HEADER_LEN as u64,
            }),
            file,
            path: path.to_path_buf(),
            quant,
            entries: Mutex::new(Vec::new()),
            splats: Mutex::new(HashMap::new()),
        })
    }

    pub fn quantization(&self) -> &Quantization {
        &self.quant
    }

    /// Compresses and appends one node (on the calling thread; only the append is serialized).
    /// `prefix` and `spacing` are the node's levels of detail. Returns the page's bytes.
    pub fn write_node(
        &self,
        key: NodeKey,
        batch: &PointBatch,
        prefix: &[u64],
        spacing: &[f64],
        shape: NodeShape,
    ) -> Result<u64> {
        if batch.len() > u32::MAX as usize {
            return Err(Error::Invalid(format!(
                "node {key} holds {} points; a node holds at most 2^32 - 1",
                batch.len()
            )));
        }
        let bytes = if batch.is_empty() {
            Vec::new()
        } else {
            page::encode(batch, &self.quant)
        };
        let (offset, crc) = self.append(&bytes)?;
        let mut entry = NodeEntry::new(
            key,
            PageRef {
                offset: if bytes.is_empty() { 0 } else { offset },
                length: bytes.len() as u32,
                crc,
            },
            batch.len() as u32,
            prefix.iter().map(|&p| p as u32).collect(),
            spacing.to_vec(),
        );
        entry.bounds = shape.bounds;
        entry.contour = shape.contour;
        self.entries.lock().expect("entries lock").push(entry);
        Ok(bytes.len() as u64)
    }

    /// Adds an entry as given, its page written elsewhere or nowhere: for fixtures that
    /// measure a hierarchy alone (`myriad bench open --fixture`); a reader reports a node whose
    /// page is not in the file as damaged.
    pub fn write_entry(&self, entry: NodeEntry) {
        self.entries.lock().expect("entries lock").push(entry);
    }

    /// Appends a page (only the append is serialized); its offset and CRC-32.
    fn append(&self, bytes: &[u8]) -> Result<(u64, u32)> {
        let crc = crc32fast::hash(bytes);
        let mut out = self.out.lock().expect("writer lock");
        let at = out.pos;
        out.w
            .write_all(bytes)
            .map_err(|e| Error::io(&self.path, e))?;
        out.pos += bytes.len() as u64;
        Ok((at, crc))
    }

    /// Appends the splat page of node `key` (normals and radii of its points, `mwkd`), to be
    /// joined to its entry. `aggregate`: its points are aggregates, not original points.
    pub fn write_splats(
        &self,
        key: NodeKey,
        s: &splat::Splats,
        cone: [f32; 4],
        aggregate: bool,
    ) -> Result<u64> {
        let (bytes, radius) = splat::encode(s);
        let (offset, crc) = self.append(&bytes)?;
        let info = splat::SplatInfo {
            page: PageRef {
                offset,
                length: bytes.len() as u32,
                crc,
            },
            radius,
            cone,
            aggregate,
        };
        self.splats.lock().expect("splats lock").insert(key, info);
        Ok(bytes.len() as u64)
    }

    /// Original points (aggregates not counted), nodes and deepest level written so far.
    pub fn totals(&self) -> (u64, u64, u32) {
        let e = self.entries.lock().expect("entries lock");
        let sp = self.splats.lock().expect("splats lock");
        (
            e.iter()
                .filter(|n| !sp.get(&n.key).is_some_and(|s| s.aggregate))
                .map(|n| n.points as u64)
                .sum(),
            e.len() as u64,
            e.iter().map(|n| n.key.level).max().unwrap_or(0),
        )
    }

    /// Bytes written so far.
    pub fn position(&self) -> u64 {
        self.out.lock().expect("writer lock").pos
    }

    /// Writes the hierarchy pages (children before parents), the metadata and the header, syncs,
    /// and renames the file to its name. `meta.nodes` and `meta.depth` are set here. Returns the
    /// file's size.
    pub fn finish(self, mut meta: Metadata) -> Result<u64> {
        let path = self.path.clone();
        let io = |e| Error::io(&path, e);
        let mut entries = self.entries.into_inner().expect("entries lock");
        let mut splats = self.splats.into_inner().expect("splats lock");
        for e in &mut entries {
            e.splats = splats.remove(&e.key);
        }
        let mut out = self.out.into_inner().expect("writer lock");
        meta.nodes = entries.len() as u64;
        meta.depth = entries.iter().map(|e| e.key.level).max().unwrap_or(0);
        meta.points = entries
            .iter()
            .filter(|e| !e.aggregate())
            .map(|e| e.points as u64)
            .sum();
        meta.levels = Level::table(&entries);
        // Group entries by page; pages by their parent page.
        let mut pages: BTreeMap<NodeKey, Vec<NodeEntry>> = BTreeMap::new();
        for e in entries {
            pages
                .entry(hierarchy::page_root(e.key))
                .or_default()
                .push(e);
        }
        let mut below: HashMap<NodeKey, Vec<NodeKey>> = HashMap::new();
        for &k in pages.keys() {
            if k.level > 0 {
                below
                    .entry(hierarchy::page_root(k.parent()))
                    .or_default()
                    .push(k);
            }
        }
        fn write_page(
            key: NodeKey,
            pages: &mut BTreeMap<NodeKey, Vec<NodeEntry>>,
            below: &HashMap<NodeKey, Vec<NodeKey>>,
            out: &mut Out,
        ) -> std::io::Result<PageRef> {
            let mut children = Vec::new();
            for &c in below.get(&key).map(|v| v.as_slice()).unwrap_or(&[]) {
                children.push(ChildPage {
                    key: c,
                    page: write_page(c, pages, below, out)?,
                });
            }
            let mut nodes = pages.remove(&key).unwrap_or_default();
            nodes.sort_by_key(|n| n.key);
            let bytes = HierarchyPage { nodes, children }.encode();
            let r = PageRef {
                offset: out.pos,
                length: bytes.len() as u32,
                crc: crc32fast::hash(&bytes),
            };
            out.w.write_all(&bytes)?;
            out.pos += bytes.len() as u64;
            Ok(r)
        }
        let hierarchy = write_page(NodeKey::ROOT, &mut pages, &below, &mut out).map_err(io)?;
        meta.check_finite().map_err(|m| {
            Error::Invalid(format!(
                "{}: metadata: {m}; no dataset written",
                path.display()
            ))
        })?;
        let json = serde_json::to_vec_pretty(&meta.to_json()).expect("JSON of plain values");
        let metadata = PageRef {
            offset: out.pos,
            length: json.len() as u32,
            crc: crc32fast::hash(&json),
        };
        out.w.write_all(&json).map_err(io)?;
        out.pos += json.len() as u64;
        let header = Header {
            metadata,
            hierarchy,
            file_length: out.pos,
            points: meta.points,
        };
        // Everything else is on disk before the header that makes the file a dataset.
        out.w.flush().map_err(io)?;
        let mut f = out.w.into_inner().map_err(|e| io(e.into_error()))?;
        f.sync_data().map_err(io)?;
        f.seek(SeekFrom::Start(0)).map_err(io)?;
        f.write_all(&header.encode()).map_err(io)?;
        f.sync_all().map_err(io)?;
        drop(f);
        // What is renamed into place opens, with this metadata and every hierarchy page intact.
        let reopened = Dataset::open(self.file.temp_path()).and_then(|ds| {
            if ds.meta != meta {
                return Err(Error::Invalid(
                    "its metadata differs from what was written".into(),
                ));
            }
            match ds.nodes() {
                (nodes, damage) if damage.is_empty() && nodes.len() as u64 == meta.nodes => Ok(()),
                (_, damage) => Err(match damage.first() {
                    Some(d) => ds.damage_error(d),
                    None => Error::Invalid("its hierarchy lacks nodes".into()),
                }),
            }
        });
        if let Err(e) = reopened {
            return Err(Error::Invalid(format!(
                "{}: the dataset written does not open again ({e}); no dataset written",
                path.display()
            )));
        }
        self.file.commit()?;
        Ok(header.file_length)
    }
}

/// A damaged part of a dataset met while reading: the node (or the root of the subtree whose
/// hierarchy page is damaged), the byte offset, and what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct Damage {
    pub key: NodeKey,
    pub offset: u64,
    pub message: String,
    /// A hierarchy page (the whole subtree below `key` is unreachable) rather than a node page.
    pub subtree: bool,
}

impl std::fmt::Display for Damage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.subtree {
            write!(
                f,
                "hierarchy page of subtree {} at byte {}: {}",
                self.key, self.offset, self.message
            )
        } else {
            write!(
                f,
                "node {} at byte {}: {}",
                self.key, self.offset, self.message
            )
        }
    }
}

/// An open dataset. Cheap to share: readers on many threads call it at once.
pub struct Dataset {
    bytes: Arc<dyn ByteSource>,
    path: PathBuf,
    pub meta: Metadata,
    root: PageRef,
    pub file_length: u64,
}

impl Dataset {
    /// Opens a dataset file, or a dataset on a web server (`http://`, `https://`: read by
    /// range requests, [`remote::HttpBytes`]).
    pub fn open(path: &Path) -> Result<Dataset> {
        if remote::is_url(path) {
            let url = path.to_str().expect("a URL is text");
            return Dataset::from_source(Arc::new(remote::HttpBytes::open(url)?), path);
        }
        Dataset::from_source(Arc::new(FileBytes::open(path)?), path)
    }

    /// Requests made and bytes fetched so far, for a dataset read over a network.
    pub fn fetched(&self) -> Option<(u64, u64)> {
        self.bytes.fetched()
    }

    /// Opens a dataset from any byte source; `name` labels errors.
    pub fn from_source(bytes: Arc<dyn ByteSource>, name: &Path) -> Result<Dataset> {
        let len = bytes.len();
        if len < HEADER_LEN as u64 {
            return Err(Error::at_byte(
                name,
                len,
                "file ends inside the 64-byte dataset header",
            ));
        }
        let head = bytes
            .read_at(0, HEADER_LEN)
            .map_err(|e| Error::io(name, e))?;
        let header = Header::decode(head.as_slice().try_into().unwrap())
            .map_err(|(at, m)| Error::at_byte(name, at, m))?;
        if header.file_length != len {
            return Err(Error::at_byte(
                name,
                len,
                format!(
                    "file has {len} bytes, its header says {} (truncated?)",
                    header.file_length
                ),
            ));
        }
        let m = header.metadata;
        if m.offset.saturating_add(m.length as u64) > len {
            return Err(Error::at_byte(
                name,
                16,
                "metadata lies past the end of the file",
            ));
        }
        let json = bytes
            .read_at(m.offset, m.length as usize)
            .map_err(|e| Error::io(name, e))?;
        if crc32fast::hash(&json) != m.crc {
            return Err(Error::at_byte(name, m.offset, "metadata checksum mismatch"));
        }
        let meta = serde_json::from_slice::<Value>(&json)
            .map_err(|e| e.to_string())
            .and_then(|v| Metadata::from_json(&v))
            .map_err(|e| Error::at_byte(name, m.offset, format!("metadata: {e}")))?;
        Ok(Dataset {
            bytes,
            path: name.to_path_buf(),
            meta,
            root: header.hierarchy,
            file_length: len,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    fn read_checked(&self, r: PageRef) -> std::result::Result<Vec<u8>, String> {
        if r.offset.saturating_add(r.length as u64) > self.file_length {
            return Err("page lies past the end of the file".into());
        }
        let b = self
            .bytes
            .read_at(r.offset, r.length as usize)
            .map_err(|e| e.to_string())?;
        if crc32fast::hash(&b) != r.crc {
            return Err("checksum mismatch".into());
        }
        Ok(b)
    }

    /// The root hierarchy page's reference (the only page opening reads).
    pub fn root_page(&self) -> ChildPage {
        ChildPage {
            key: NodeKey::ROOT,
            page: self.root,
        }
    }

    /// Reads one hierarchy page.
    pub fn hierarchy_page(&self, p: &ChildPage) -> std::result::Result<HierarchyPage, Damage> {
        let damage = |offset: u64, message: String| Damage {
            key: p.key,
            offset,
            message,
            subtree: true,
        };
        let b = self
            .read_checked(p.page)
            .map_err(|m| damage(p.page.offset, m))?;
        HierarchyPage::decode(&b).map_err(|(at, m)| damage(p.page.offset + at as u64, m))
    }

    /// Every node entry reachable through undamaged hierarchy pages, and the damage met.
    pub fn nodes(&self) -> (Vec<NodeEntry>, Vec<Damage>) {
        self.nodes_where(&|_| true)
    }

    /// [`Dataset::nodes`], reading a page only where `keep` accepts the bounds of the subtree
    /// it holds (its root's cube; where nodes store bounds, those of the node above it): a box
    /// query reads the pages it meets, not all of them. The entries of the pages read are all
    /// returned.
    pub fn nodes_where(&self, keep: &dyn Fn(&Aabb) -> bool) -> (Vec<NodeEntry>, Vec<Damage>) {
        let mut nodes = Vec::new();
        let mut damage = Vec::new();
        let mut todo = vec![self.root_page()];
        while let Some(p) = todo.pop() {
            match self.hierarchy_page(&p) {
                Ok(page) => {
                    // The bounds entries store (kd, mwkd), by key: looked up once per page.
                    let stored: HashMap<NodeKey, Aabb> = (page.nodes.iter())
                        .filter_map(|n| Some((n.key, n.bounds?)))
                        .collect();
                    for c in page.children {
                        let bounds = stored.get(&c.key.parent()).copied();
                        if keep(&bounds.unwrap_or_else(|| c.key.bounds(&self.meta.root))) {
                            todo.push(c);
                        }
                    }
                    nodes.extend(page.nodes);
                }
                Err(d) => damage.push(d),
            }
        }
        nodes.sort_by_key(|n| n.key);
        (nodes, damage)
    }

    /// Reads and decodes a node's points, with every column of the dataset.
    pub fn read_node(&self, e: &NodeEntry) -> std::result::Result<PointBatch, Damage> {
        self.read_node_columns(e, &self.meta.schema)
    }

    /// Reads and decodes a node's splat page (`mwkd`); `None` for nodes without one.
    pub fn read_splats(&self, e: &NodeEntry) -> std::result::Result<Option<splat::Splats>, Damage> {
        let Some(info) = e.splats else {
            return Ok(None);
        };
        let damage = |offset: u64, message: String| Damage {
            key: e.key,
            offset,
            message,
            subtree: false,
        };
        if e.points == 0 {
            return Ok(Some(splat::Splats::default()));
        }
        let b = self
            .read_checked(info.page)
            .map_err(|m| damage(info.page.offset, m))?;
        splat::decode(&b, e.points as usize, info.radius)
            .map(Some)
            .map_err(|m| damage(info.page.offset, m))
    }

    /// Reads and decodes a node's points with the columns of `schema` only.
    pub fn read_node_columns(
        &self,
        e: &NodeEntry,
        schema: &Schema,
    ) -> std::result::Result<PointBatch, Damage> {
        let damage = |offset: u64, message: String| Damage {
            key: e.key,
            offset,
            message,
            subtree: false,
        };
        if e.page.length == 0 {
            if e.points != 0 {
                return Err(damage(0, format!("{} points but no page", e.points)));
            }
            return Ok(PointBatch::with_schema(schema, 0));
        }
        let b = self
            .read_checked(e.page)
            .map_err(|m| damage(e.page.offset, m))?;
        let batch = page::decode(&b, schema, &self.meta.quantization)
            .map_err(|pe| damage(e.page.offset + pe.at as u64, pe.message))?;
        if batch.len() != e.points as usize {
            return Err(damage(
                e.page.offset,
                format!(
                    "page holds {} points, the hierarchy says {}",
                    batch.len(),
                    e.points
                ),
            ));
        }
        Ok(batch)
    }

    /// A damage report as an error naming the file.
    pub fn damage_error(&self, d: &Damage) -> Error {
        let msg = if d.subtree {
            format!("hierarchy page of subtree {}: {}", d.key, d.message)
        } else {
            format!("node {}: {}", d.key, d.message)
        };
        Error::at_byte(&self.path, d.offset, msg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, bounds: Aabb) -> (PathBuf, Result<u64>) {
        let path = dir.join(name);
        let quant = Quantization {
            scale: [0.01; 3],
            offset: [0.0; 3],
        };
        let w = DatasetWriter::create(&path, true, quant).unwrap();
        let schema = Schema::new(vec![]);
        let mut batch = PointBatch::with_schema(&schema, 2);
        batch.positions = vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]];
        w.write_node(NodeKey::ROOT, &batch, &[2], &[1.0], NodeShape::default())
            .unwrap();
        let meta = Metadata {
            structure: "nested-octree".into(),
            parameters: serde_json::json!({}),
            points: 2,
            nodes: 0,
            depth: 0,
            bounds,
            root: Aabb::new([0.0; 3], [8.0; 3]),
            quantization: quant,
            crs: None,
            schema,
            sources: vec![],
            las_header: None,
            software: "test".into(),
            levels: vec![],
        };
        let r = w.finish(meta);
        (path, r)
    }

    /// Metadata with a number JSON cannot hold is refused before the rename: nothing appears
    /// under the output's name, no temporary file stays, and a good dataset opens as written.
    #[test]
    fn finish_refuses_metadata_that_would_not_read_back() {
        let dir = std::env::temp_dir().join(format!("myriad-format-finish-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (good, r) = write(
            &dir,
            "good.myr",
            Aabb::new([1.0, 2.0, 3.0], [4.0, 5.0, 6.0]),
        );
        r.unwrap();
        let ds = Dataset::open(&good).unwrap();
        assert_eq!(ds.meta.bounds.max, [4.0, 5.0, 6.0]);
        assert_eq!(ds.meta.points, 2);
        let (bad, r) = write(
            &dir,
            "bad.myr",
            Aabb::new([f64::NAN, 2.0, 3.0], [4.0, 5.0, 6.0]),
        );
        let e = r.unwrap_err().to_string();
        assert!(
            e.contains("metadata: bounds.min is [NaN, 2.0, 3.0], not finite"),
            "{e}"
        );
        assert!(!bad.exists());
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left, vec![std::ffi::OsString::from("good.myr")]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
