//! Writing a dataset (native builds only: the web viewer reads).

use crate::hierarchy::{self, ChildPage, HierarchyPage, NodeEntry, PageRef};
use crate::metadata::{Level, Metadata};
use crate::page::{self, Quantization};
use crate::{Dataset, HEADER_LEN, Header, splat};
use myriad_core::{Aabb, Error, NodeKey, Obb, PointBatch, Result};
use myriad_io::atomic::AtomicFile;
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// A node's stored outline: bounds for nodes that are not their key's octree cell, a contour
/// where the structure has one.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NodeShape {
    pub bounds: Option<Aabb>,
    pub contour: Option<Obb>,
    /// The contour of the node's own points where it differs from `contour` (layered nodes
    /// that pass points down).
    pub detail: Option<Obb>,
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
        entry.detail = shape.detail;
        self.entries.lock().expect("entries lock").push(entry);
        Ok(bytes.len() as u64)
    }

    /// Appends a node page as another dataset with the same quantization stored it (`page`, as
    /// [`Dataset::node_page`] gives it) under `entry` (its key, counts and levels; the page's
    /// place is this file's). Splat pages are not copied: for octree and layered datasets.
    pub fn copy_node(&self, entry: &NodeEntry, page: &[u8]) -> Result<u64> {
        let (offset, crc) = self.append(page)?;
        let mut e = entry.clone();
        e.page = PageRef {
            offset: if page.is_empty() { 0 } else { offset },
            length: page.len() as u32,
            crc,
        };
        e.splats = None;
        self.entries.lock().expect("entries lock").push(e);
        Ok(page.len() as u64)
    }

    /// Adds `entry`, read from a dataset that stays where it is, as linked file `file` (its
    /// index in the `files` of the metadata given to [`DatasetWriter::finish`]): its page is
    /// not copied, the entry refers to it there ([`crate::linked`]). Splat pages are not
    /// linked: for octree and layered datasets.
    pub fn link_node(&self, entry: &NodeEntry, file: usize) {
        let mut e = entry.clone();
        if e.page.length > 0 {
            e.page.offset += crate::linked::base(file);
        }
        e.splats = None;
        self.entries.lock().expect("entries lock").push(e);
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

    /// What a reader of the dataset as written so far sees: the pages appended until now (made
    /// readable), the nodes `extra` adds to those written (given their entries, it returns new
    /// entries with their pages, placed after them: what stands in for the nodes not built
    /// yet), and a hierarchy, metadata (`meta`, counted anew) and header made for them, in
    /// memory. The file itself is not changed: the build goes on.
    pub fn snapshot(&self, meta: &Metadata, extra: &StandIns<'_>) -> Result<Snapshot> {
        let prefix = {
            let mut out = self.out.lock().expect("writer lock");
            out.w.flush().map_err(|e| Error::io(&self.path, e))?;
            out.pos
        };
        let entries: Vec<NodeEntry> = (self.entries.lock().expect("entries lock").iter())
            .filter(|e| e.page.offset + e.page.length as u64 <= prefix)
            .cloned()
            .collect();
        let splats = self.splats.lock().expect("splats lock").clone();
        let extra = extra(&entries);
        let (tail, header) = with_pages(entries, extra, splats, meta, prefix)
            .map_err(|m| Error::Invalid(format!("{}: metadata: {m}", self.path.display())))?;
        let file = File::open(self.file.temp_path()).map_err(|e| Error::io(&self.path, e))?;
        Ok(Snapshot {
            file: Some(file),
            prefix,
            header: header.encode(),
            tail,
        })
    }

    /// Writes the hierarchy pages (children before parents), the metadata and the header, syncs,
    /// and renames the file to its name. `meta.nodes` and `meta.depth` are set here. Returns the
    /// file's size.
    pub fn finish(self, meta: Metadata) -> Result<u64> {
        self.finish_checked(meta, |_| Ok(()))
    }

    /// As [`DatasetWriter::finish`], with `check` run on the dataset written before it is
    /// renamed to its name: where it fails, nothing is renamed (a dataset being replaced stays
    /// as it was) and its error is returned.
    pub fn finish_checked(
        self,
        mut meta: Metadata,
        check: impl FnOnce(&Dataset) -> Result<()>,
    ) -> Result<u64> {
        let path = self.path.clone();
        let io = |e| Error::io(&path, e);
        let entries = self.entries.into_inner().expect("entries lock");
        let splats = self.splats.into_inner().expect("splats lock");
        let mut out = self.out.into_inner().expect("writer lock");
        let (tail, header) = encode_tail(entries, splats, &mut meta, out.pos).map_err(|m| {
            Error::Invalid(format!(
                "{}: metadata: {m}; no dataset written",
                path.display()
            ))
        })?;
        out.w.write_all(&tail).map_err(io)?;
        out.pos += tail.len() as u64;
        // Everything else is on disk before the header that makes the file a dataset.
        out.w.flush().map_err(io)?;
        let mut f = out.w.into_inner().map_err(|e| io(e.into_error()))?;
        f.sync_data().map_err(io)?;
        f.seek(SeekFrom::Start(0)).map_err(io)?;
        f.write_all(&header.encode()).map_err(io)?;
        f.sync_all().map_err(io)?;
        drop(f);
        // What is renamed into place opens, with this metadata and every hierarchy page intact.
        let reopened = Dataset::open_stored(self.file.temp_path()).and_then(|ds| {
            if ds.meta != meta {
                return Err(Error::Invalid(
                    "its metadata differs from what was written".into(),
                ));
            }
            match ds.nodes() {
                (nodes, damage) if damage.is_empty() && nodes.len() as u64 == meta.nodes => Ok(ds),
                (_, damage) => Err(match damage.first() {
                    Some(d) => ds.damage_error(d),
                    None => Error::Invalid("its hierarchy lacks nodes".into()),
                }),
            }
        });
        let ds = match reopened {
            Ok(ds) => ds,
            Err(e) => {
                return Err(Error::Invalid(format!(
                    "{}: the dataset written does not open again ({e}); no dataset written",
                    path.display()
                )));
            }
        };
        check(&ds)?;
        drop(ds);
        self.file.commit()?;
        Ok(header.file_length)
    }
}

/// What follows byte `prefix` of a snapshot: the pages of `extra` (their entries placed there,
/// added to `entries`), then the hierarchy and metadata ([`encode_tail`], `meta` counted anew);
/// and the header that points at them.
fn with_pages(
    mut entries: Vec<NodeEntry>,
    extra: Vec<(NodeEntry, Vec<u8>)>,
    splats: HashMap<NodeKey, splat::SplatInfo>,
    meta: &Metadata,
    prefix: u64,
) -> std::result::Result<(Vec<u8>, Header), String> {
    let mut tail = Vec::new();
    for (mut e, page) in extra {
        e.page = PageRef {
            offset: if page.is_empty() {
                0
            } else {
                prefix + tail.len() as u64
            },
            length: page.len() as u32,
            crc: crc32fast::hash(&page),
        };
        tail.extend_from_slice(&page);
        entries.push(e);
    }
    let mut meta = meta.clone();
    let (rest, header) = encode_tail(entries, splats, &mut meta, prefix + tail.len() as u64)?;
    tail.extend_from_slice(&rest);
    Ok((tail, header))
}

/// The hierarchy pages (children before parents) and the metadata of `entries`, as they follow
/// byte `start` of a file, and the header that points at them; sets `meta`'s counts (nodes,
/// depth, points, levels). The error: what is wrong with the metadata.
fn encode_tail(
    mut entries: Vec<NodeEntry>,
    mut splats: HashMap<NodeKey, splat::SplatInfo>,
    meta: &mut Metadata,
    start: u64,
) -> std::result::Result<(Vec<u8>, Header), String> {
    // Each node's normal cone widened to hold its children's (deepest first): culling a
    // node that faces away then never hides a child that does not.
    let mut keys: Vec<NodeKey> = splats.keys().copied().collect();
    keys.sort_by_key(|k| std::cmp::Reverse(k.level));
    for k in keys {
        if k.level == 0 {
            continue;
        }
        let child = splats[&k].cone;
        if let Some(parent) = splats.get_mut(&k.parent()) {
            parent.cone = splat::cone_union(parent.cone, child);
        }
    }
    for e in &mut entries {
        e.splats = splats.remove(&e.key);
    }
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
        start: u64,
        out: &mut Vec<u8>,
    ) -> PageRef {
        let mut children = Vec::new();
        for &c in below.get(&key).map(|v| v.as_slice()).unwrap_or(&[]) {
            children.push(ChildPage {
                key: c,
                page: write_page(c, pages, below, start, out),
            });
        }
        let mut nodes = pages.remove(&key).unwrap_or_default();
        nodes.sort_by_key(|n| n.key);
        let bytes = HierarchyPage { nodes, children }.encode();
        let r = PageRef {
            offset: start + out.len() as u64,
            length: bytes.len() as u32,
            crc: crc32fast::hash(&bytes),
        };
        out.extend_from_slice(&bytes);
        r
    }
    let mut out = Vec::new();
    let hierarchy = write_page(NodeKey::ROOT, &mut pages, &below, start, &mut out);
    meta.check_finite()?;
    let json = serde_json::to_vec_pretty(&meta.to_json()).expect("JSON of plain values");
    let metadata = PageRef {
        offset: start + out.len() as u64,
        length: json.len() as u32,
        crc: crc32fast::hash(&json),
    };
    out.extend_from_slice(&json);
    let header = Header {
        version: if meta.files.is_empty() {
            crate::FORMAT_VERSION
        } else {
            crate::LINKED_VERSION
        },
        metadata,
        hierarchy,
        file_length: start + out.len() as u64,
        points: meta.points,
    };
    Ok((out, header))
}

/// What a snapshot adds to the nodes written: given their entries, more entries with their pages.
pub type StandIns<'a> = dyn Fn(&[NodeEntry]) -> Vec<(NodeEntry, Vec<u8>)> + 'a;

/// A dataset still being written, as [`DatasetWriter::snapshot`] made it readable: the file's
/// pages up to `prefix` (its zeroed header replaced), then hierarchy and metadata in memory.
pub struct Snapshot {
    /// `None`: a dataset held in memory alone ([`Snapshot::in_memory`]).
    file: Option<File>,
    prefix: u64,
    header: [u8; HEADER_LEN],
    tail: Vec<u8>,
}

impl Snapshot {
    /// Bytes of the file it reads (the rest is in memory).
    pub fn prefix(&self) -> u64 {
        self.prefix
    }

    /// A dataset of `nodes` (their entries and pages) in memory, with `meta` (counted anew):
    /// what a build shows before it has written anything.
    pub fn in_memory(meta: &Metadata, nodes: Vec<(NodeEntry, Vec<u8>)>) -> Result<Snapshot> {
        let prefix = HEADER_LEN as u64;
        let (tail, header) = with_pages(Vec::new(), nodes, HashMap::new(), meta, prefix)
            .map_err(|m| Error::Invalid(format!("metadata: {m}")))?;
        Ok(Snapshot {
            file: None,
            prefix,
            header: header.encode(),
            tail,
        })
    }
}

impl crate::ByteSource for Snapshot {
    fn len(&self) -> u64 {
        self.prefix + self.tail.len() as u64
    }

    fn read_at(&self, offset: u64, len: usize) -> std::io::Result<Vec<u8>> {
        use std::os::unix::fs::FileExt;
        let end = offset.saturating_add(len as u64);
        if end > self.len() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "read past the end of the dataset",
            ));
        }
        let mut out = vec![0u8; len];
        // From the file (the header's bytes from memory), then from the tail.
        if offset < self.prefix {
            let upto = end.min(self.prefix);
            let part = &mut out[..(upto - offset) as usize];
            if let Some(f) = &self.file {
                f.read_exact_at(part, offset)?;
            }
            for (i, b) in part.iter_mut().enumerate() {
                if let Some(h) = self.header.get(offset as usize + i) {
                    *b = *h;
                } else {
                    break;
                }
            }
        }
        if end > self.prefix {
            let from = offset.max(self.prefix);
            let at = (from - offset) as usize;
            let t = (from - self.prefix) as usize;
            out[at..].copy_from_slice(&self.tail[t..t + (end - from) as usize]);
        }
        Ok(out)
    }
}
