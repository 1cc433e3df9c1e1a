//! The Myriad dataset file, `.myr`: a 64-byte header, node pages, metadata (JSON) and a hierarchy
//! stored in pages (like COPC), every page with a CRC-32. Writers append node pages from any
//! thread as nodes are built and write the hierarchy, metadata and header last; readers work on
//! byte ranges ([`ByteSource`]: a file now, HTTP range requests later) and are shared between
//! threads. Opening a dataset of any size reads the header, the metadata and the root hierarchy
//! page. The byte layout is in docs/format.md.
//!
//! This crate decides nothing about levels of detail: it stores what a builder gives it.

// The WebAssembly build (the web viewer) reads only: the writer's helpers go unused there.
#![cfg_attr(target_arch = "wasm32", allow(dead_code))]

pub mod hierarchy;
pub mod linked;
pub mod page;
pub mod splat;

mod codec;
pub mod edits;
pub mod foreign;
pub mod metadata;
#[cfg(not(target_arch = "wasm32"))]
pub mod remote;
#[cfg(not(target_arch = "wasm32"))]
pub mod s3;
#[cfg(not(target_arch = "wasm32"))]
mod tls;
#[cfg(not(target_arch = "wasm32"))]
mod writer;

pub use hierarchy::{ChildPage, HierarchyPage, NodeEntry, PageRef};
pub use metadata::{Level, Metadata};
pub use page::Quantization;
#[cfg(not(target_arch = "wasm32"))]
pub use writer::{DatasetWriter, NodeShape, Snapshot};

use myriad_core::{Aabb, Error, NodeKey, PointBatch, Result, Schema};
use serde_json::Value;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub const MAGIC: &[u8; 8] = b"MYRIAD\x00\x1a";

/// Whether `path` is a dataset: a URL (over HTTP only datasets are read), a file that starts
/// with [`MAGIC`], or a dataset of the field's cloud formats read in place (COPC, EPT, Potree
/// 2.0: [`foreign::kind_of`]).
#[cfg(not(target_arch = "wasm32"))]
pub fn is_dataset(path: &std::path::Path) -> bool {
    use std::io::Read;
    if remote::is_url(path) || foreign::kind_of(path).is_some() {
        return true;
    }
    let mut head = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && &head == MAGIC
}
/// 2: hierarchy entries carry optional node bounds, contours and splat pages (the kd, layered and
/// mwkd structures).
pub const FORMAT_VERSION: u32 = 2;
/// The version of a dataset of several files ([`linked`]): a reader of 2 alone would find
/// pages past the end of the file.
pub const LINKED_VERSION: u32 = 3;
pub const HEADER_LEN: usize = 64;

/// The 64-byte file header.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Header {
    version: u32,
    metadata: PageRef,
    hierarchy: PageRef,
    file_length: u64,
    points: u64,
}

impl Header {
    fn encode(&self) -> [u8; HEADER_LEN] {
        let mut b = [0u8; HEADER_LEN];
        b[..8].copy_from_slice(MAGIC);
        b[8..12].copy_from_slice(&self.version.to_le_bytes());
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
        if version != FORMAT_VERSION && version != LINKED_VERSION {
            return Err((
                8,
                format!(
                    "format version {version}; this build reads {FORMAT_VERSION} and {LINKED_VERSION} (convert the input again)"
                ),
            ));
        }
        let r = |at: usize| PageRef {
            offset: u64_at(at),
            length: u32_at(at + 8),
            crc: u32_at(at + 12),
        };
        Ok(Header {
            version,
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
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    fn read_at(&self, offset: u64, len: usize) -> std::io::Result<Vec<u8>>;
    /// Requests made and bytes fetched, for sources over a network.
    fn fetched(&self) -> Option<(u64, u64)> {
        None
    }
    /// Why the source is no longer the one opened (a resource replaced on its server), once it
    /// is known: what was read since may mix versions.
    fn changed(&self) -> Option<String> {
        None
    }
}

/// zstd's decompression of `b` into at most `limit` bytes (in both builds: the C library
/// natively, ruzstd in WebAssembly), for the other files datasets keep beside them.
pub fn decompress_zstd(b: &[u8], limit: usize) -> std::result::Result<Vec<u8>, String> {
    codec::decompress(b, limit)
}

/// A local file, read with positioned reads (no shared cursor).
#[cfg(not(target_arch = "wasm32"))]
pub struct FileBytes {
    file: std::fs::File,
    len: u64,
}

#[cfg(not(target_arch = "wasm32"))]
impl FileBytes {
    pub fn open(path: &Path) -> Result<FileBytes> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        FileBytes::of(file).map_err(|e| Error::io(path, e))
    }

    /// The bytes of a file already open, at the length it has now.
    pub fn of(file: std::fs::File) -> std::io::Result<FileBytes> {
        let len = file.metadata()?.len();
        Ok(FileBytes { file, len })
    }
}

#[cfg(not(target_arch = "wasm32"))]
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

/// A file's bytes, or a URL's by range requests (the linked files of a dataset opened so).
#[cfg(not(target_arch = "wasm32"))]
fn open_bytes(at: &str) -> std::io::Result<Arc<dyn ByteSource>> {
    let bytes: Arc<dyn ByteSource> = if remote::is_url(Path::new(at)) {
        Arc::new(remote::HttpBytes::open(at).map_err(std::io::Error::other)?)
    } else {
        Arc::new(FileBytes::of(std::fs::File::open(at)?)?)
    };
    Ok(bytes)
}

/// In the web viewer, linked files are opened through its own opener.
#[cfg(target_arch = "wasm32")]
fn open_bytes(at: &str) -> std::io::Result<Arc<dyn ByteSource>> {
    Err(std::io::Error::other(format!("{at}: not opened here")))
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

/// What a dataset in one of the field's formats read in place answers instead of `.myr` pages
/// ([`foreign`]).
pub(crate) trait Foreign: Send + Sync {
    /// The page of the subtree rooted at `key`, [`hierarchy::PAGE_LEVELS`] levels deep.
    fn hierarchy_page(&self, key: NodeKey) -> std::result::Result<HierarchyPage, Damage>;
    /// A node's points, every column.
    fn read_node(&self, e: &NodeEntry) -> std::result::Result<PointBatch, Damage>;
    /// Requests made and bytes fetched, where read over a network.
    fn fetched(&self) -> Option<(u64, u64)>;
    /// Why a source is no longer the one opened, once known.
    fn changed(&self) -> Option<String>;
}

/// No bytes: the source of a dataset whose files a [`Foreign`] reader opens itself.
struct NoBytes;

impl ByteSource for NoBytes {
    fn len(&self) -> u64 {
        0
    }
    fn read_at(&self, _: u64, _: usize) -> std::io::Result<Vec<u8>> {
        Err(std::io::Error::other("no bytes"))
    }
}

/// An open dataset. Cheap to share: readers on many threads call it at once.
pub struct Dataset {
    bytes: Arc<dyn ByteSource>,
    /// The other files holding its pages (none for a dataset of one file).
    linked: linked::Linked,
    path: PathBuf,
    pub meta: Metadata,
    root: PageRef,
    pub file_length: u64,
    /// Its header's CRC-32 (what a dataset linking this one records of it).
    pub header_crc: u32,
    /// The reader of a COPC, EPT or Potree 2.0 dataset read in place (`None`: a `.myr`).
    foreign: Option<Arc<dyn Foreign>>,
    /// The edits kept beside it, applied to every node read ([`edits`]).
    edits: Option<Arc<dyn edits::Edits>>,
}

impl Dataset {
    /// Opens a dataset file, or a dataset on a web server (`http://`, `https://`: read by
    /// range requests, [`remote::HttpBytes`]).
    /// On disk, the edits kept beside it come with it ([`edits::set_loader`]).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn open(path: &Path) -> Result<Dataset> {
        let mut ds = Dataset::open_stored(path)?;
        if !remote::is_url(path) {
            ds.edits = edits::load(path, &ds.meta)?;
        }
        Ok(ds)
    }

    /// [`Dataset::open`] without the edits kept beside it: the points as stored.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn open_stored(path: &Path) -> Result<Dataset> {
        match foreign::kind_of(path) {
            Some(foreign::Kind::Copc) if remote::is_url(path) => {
                let url = path.to_str().expect("a URL is text");
                let bytes = remote::HttpBytes::open_with_head(url, foreign::copc::HEAD)?;
                return Dataset::copc(Arc::new(bytes), path);
            }
            Some(foreign::Kind::Copc) => {
                return Dataset::copc(Arc::new(FileBytes::open(path)?), path);
            }
            Some(foreign::Kind::Ept) => {
                let (meta, ept) = foreign::ept::Ept::open(path)?;
                return Ok(Dataset::of_foreign(
                    Arc::new(NoBytes),
                    path,
                    meta,
                    Arc::new(ept),
                ));
            }
            Some(foreign::Kind::Potree) => {
                let (meta, p) = foreign::potree::Potree::open(path)?;
                return Ok(Dataset::of_foreign(
                    Arc::new(NoBytes),
                    path,
                    meta,
                    Arc::new(p),
                ));
            }
            Some(foreign::Kind::Tiles) => {
                let (meta, t) = foreign::tiles::Tiles::open(path)?;
                return Ok(Dataset::of_foreign(
                    Arc::new(NoBytes),
                    path,
                    meta,
                    Arc::new(t),
                ));
            }
            None => {}
        }
        if remote::is_url(path) {
            let url = path.to_str().expect("a URL is text");
            return Dataset::from_source(Arc::new(remote::HttpBytes::open(url)?), path);
        }
        Dataset::from_source(Arc::new(FileBytes::open(path)?), path)
    }

    /// A dataset of the cloud formats (COPC, EPT, Potree 2.0) at `url`, in the web viewer's
    /// WebAssembly: its requests go through [`foreign::set_url_opener`].
    #[cfg(target_arch = "wasm32")]
    pub fn open_url(url: &Path) -> Result<Dataset> {
        let text = url.to_string_lossy();
        let (meta, reader): (Metadata, Arc<dyn Foreign>) = match foreign::kind_of(url) {
            Some(foreign::Kind::Copc) => {
                let bytes = foreign::open_url(&text, foreign::copc::HEAD)?;
                return Dataset::copc(bytes, url);
            }
            Some(foreign::Kind::Ept) => {
                let (m, r) = foreign::ept::Ept::open(url)?;
                (m, Arc::new(r))
            }
            Some(foreign::Kind::Potree) => {
                let (m, r) = foreign::potree::Potree::open(url)?;
                (m, Arc::new(r))
            }
            Some(foreign::Kind::Tiles) => {
                let (m, r) = foreign::tiles::Tiles::open(url)?;
                (m, Arc::new(r))
            }
            _ => {
                return Err(Error::Invalid(format!(
                    "{text}: not a COPC file (.copc.laz), an EPT dataset (ept.json), a Potree 2.0 one (metadata.json) or a virtual point cloud (.vpc)"
                )));
            }
        };
        Ok(Dataset::of_foreign(Arc::new(NoBytes), url, meta, reader))
    }

    /// A COPC file in `bytes`, read in place.
    fn copc(bytes: Arc<dyn ByteSource>, name: &Path) -> Result<Dataset> {
        let (meta, copc) = foreign::copc::Copc::open(bytes.clone(), name)?;
        Ok(Dataset::of_foreign(bytes, name, meta, Arc::new(copc)))
    }

    fn of_foreign(
        bytes: Arc<dyn ByteSource>,
        name: &Path,
        meta: Metadata,
        reader: Arc<dyn Foreign>,
    ) -> Dataset {
        let none: linked::Opener = Arc::new(|_, _| Err(std::io::Error::other("no linked files")));
        Dataset {
            file_length: bytes.len(),
            bytes,
            linked: linked::Linked::new(Vec::new(), none, Arc::new(|s: &str| s.to_string())),
            path: name.to_path_buf(),
            meta,
            root: PageRef::default(),
            header_crc: 0,
            foreign: Some(reader),
            edits: None,
        }
    }

    /// The format of a dataset read in place ("COPC 1.0", "EPT", "Potree 2.0"), `None` for a
    /// `.myr`.
    pub fn foreign_format(&self) -> Option<&str> {
        self.foreign.as_ref()?;
        self.meta.parameters["format"].as_str()
    }

    /// Requests made and bytes fetched so far, for a dataset read over a network (its linked
    /// files' included).
    pub fn fetched(&self) -> Option<(u64, u64)> {
        if let Some(f) = &self.foreign {
            return f.fetched();
        }
        let mut total = self.bytes.fetched()?;
        for s in self.linked.opened() {
            let (r, b) = s.fetched().unwrap_or_default();
            total = (total.0 + r, total.1 + b);
        }
        Some(total)
    }

    /// An error naming the dataset when its source changed while it was read (a dataset on a
    /// web server replaced): a command's results from it cannot be trusted.
    pub fn check_unchanged(&self) -> Result<()> {
        if let Some(m) = self.foreign.as_ref().and_then(|f| f.changed()) {
            return Err(Error::Invalid(format!("{}: {m}", self.path.display())));
        }
        let linked = (self.linked.opened()).find_map(|s| s.changed());
        match self.bytes.changed().or(linked) {
            Some(m) => Err(Error::Invalid(format!("{}: {m}", self.path.display()))),
            None => Ok(()),
        }
    }

    /// The files besides its own that hold the dataset's pages (a merge's parts), as its
    /// metadata names them; empty for a dataset of one file.
    pub fn files(&self) -> &[linked::LinkedFile] {
        &self.linked.files
    }

    /// Opens and checks every linked file (length and header), as reading a page of it would:
    /// the first that is missing or not the one linked, named in one line.
    pub fn check_files(&self) -> Result<()> {
        for i in 0..self.linked.files.len() {
            self.linked.source(i).map_err(|m| {
                Error::Invalid(format!(
                    "{}: {m} (a file of {})",
                    self.linked.name(i),
                    self.path.display()
                ))
            })?;
        }
        Ok(())
    }

    /// Where page `r` lies: `None` in the dataset's own file, else the index of the linked
    /// file (in [`Dataset::files`]), and the reference with its offset in that file.
    pub fn locate(&self, r: PageRef) -> (Option<usize>, PageRef) {
        match (r.offset >> linked::SLOT_BITS) as usize {
            0 => (None, r),
            slot => (
                Some(slot - 1),
                PageRef {
                    offset: r.offset - linked::base(slot - 1),
                    ..r
                },
            ),
        }
    }

    /// Opens a dataset from any byte source; `name` labels errors, and linked files are
    /// opened beside it (a path, or a URL: `http(s)://`, `s3://`).
    pub fn from_source(bytes: Arc<dyn ByteSource>, name: &Path) -> Result<Dataset> {
        let text = name.to_string_lossy().into_owned();
        let at = text.clone();
        let resolve: Arc<dyn Fn(&str) -> String + Send + Sync> =
            Arc::new(move |rel: &str| match at.contains("://") {
                true => linked::join_url(&at, rel),
                false => Path::new(&at)
                    .parent()
                    .unwrap_or(Path::new(""))
                    .join(rel)
                    .display()
                    .to_string(),
            });
        let r = resolve.clone();
        let opener: linked::Opener =
            Arc::new(move |_, f: &linked::LinkedFile| open_bytes(&r(&f.path)));
        Dataset::from_source_linked(bytes, name, opener, resolve)
    }

    /// [`Dataset::from_source`] with linked files opened by `opener` and named in errors by
    /// `name_of` (given the path recorded).
    pub fn from_source_linked(
        bytes: Arc<dyn ByteSource>,
        name: &Path,
        opener: linked::Opener,
        name_of: Arc<dyn Fn(&str) -> String + Send + Sync>,
    ) -> Result<Dataset> {
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
        if head.starts_with(b"LASF") {
            // A COPC file at a URL not named .copc.laz.
            return Dataset::copc(bytes, name);
        }
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
        if header.version == LINKED_VERSION && meta.files.is_empty() {
            return Err(Error::at_byte(
                name,
                m.offset,
                "metadata: a dataset of several files that lists none",
            ));
        }
        Ok(Dataset {
            bytes,
            linked: linked::Linked::new(meta.files.clone(), opener, name_of),
            path: name.to_path_buf(),
            meta,
            root: header.hierarchy,
            file_length: len,
            header_crc: u32::from_le_bytes(head[12..16].try_into().unwrap()),
            foreign: None,
            edits: None,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The edits applied to the nodes read (`None`: the points as stored).
    pub fn edits(&self) -> Option<&Arc<dyn edits::Edits>> {
        self.edits.as_ref()
    }

    /// The column of heights above the terrain the dataset's edits hold (`myriad ground`),
    /// registered for colouring under the dataset's path; `None` where they hold none (and the
    /// path's terrain registered before, if any, is forgotten: colours made over it say none).
    pub fn above_ground(&self) -> Option<myriad_core::column::Column> {
        let key = self.path.display().to_string();
        match self.edits.as_ref().and_then(|e| e.ground()) {
            Some(g) => {
                let id = myriad_core::ground::register(&key, g);
                Some(myriad_core::column::Column::AboveGround(id))
            }
            None => {
                myriad_core::ground::register(&key, Arc::new(myriad_core::ground::NoGround));
                None
            }
        }
    }

    /// The colours `--color NAME` asks for (a scheme, or a column through a gradient over a
    /// range fitted to the overview where none is given: `myriad_core::colour::choose`), and
    /// `above-ground`: the height above the terrain the dataset's edits hold.
    pub fn choose_colour(
        &self,
        name: &str,
        gradient: Option<myriad_core::colour::Gradient>,
        range: Option<[f64; 2]>,
    ) -> std::result::Result<myriad_core::colour::ColorBy, String> {
        use myriad_core::colour::{ColorBy, Gradient, Ramp, choose};
        let n = name.trim().to_ascii_lowercase().replace('-', "_");
        if !matches!(n.as_str(), "above_ground" | "hag" | "height_above_ground") {
            return choose(name, gradient, range, &self.meta.schema, || {
                self.overview().unwrap_or_default()
            });
        }
        let column = self.above_ground().ok_or_else(|| {
            format!(
                "--color {name}: {} has no terrain (`myriad ground {}` finds it)",
                self.path.display(),
                self.path.display()
            )
        })?;
        let range = match range {
            Some(r) => r,
            None => self
                .overview()
                .and_then(|o| Ramp::fit(column, &o))
                .map_or([0.0, 1.0], |[_, hi]| [0.0, hi.max(1e-6)]),
        };
        Ok(ColorBy::Ramp(Ramp {
            column,
            gradient: gradient.unwrap_or(Gradient::Turbo),
            range,
        }))
    }

    /// Sets the edits applied to the nodes read (`None`: the points as stored).
    pub fn set_edits(&mut self, edits: Option<Arc<dyn edits::Edits>>) {
        self.edits = edits;
    }

    fn read_range(&self, r: PageRef) -> std::result::Result<Vec<u8>, String> {
        let (file, local) = self.locate(r);
        let Some(i) = file else {
            if r.offset.saturating_add(r.length as u64) > self.file_length {
                return Err("page lies past the end of the file".into());
            }
            return (self.bytes)
                .read_at(r.offset, r.length as usize)
                .map_err(|e| e.to_string());
        };
        if i >= self.linked.files.len() {
            return Err(format!(
                "page in file {} of {} linked",
                i + 1,
                self.linked.files.len()
            ));
        }
        let source = self.linked.source(i)?;
        if local.offset.saturating_add(local.length as u64) > source.len() {
            return Err("page lies past the end of the file".into());
        }
        (source.read_at(local.offset, local.length as usize)).map_err(|e| e.to_string())
    }

    fn read_checked(&self, r: PageRef) -> std::result::Result<Vec<u8>, String> {
        let b = self.read_range(r)?;
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
        if let Some(f) = &self.foreign {
            return f.hierarchy_page(p.key);
        }
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

    /// The root node's points: a sample of the whole (what a colour ramp's range is fitted to).
    pub fn overview(&self) -> Option<PointBatch> {
        let page = self.hierarchy_page(&self.root_page()).ok()?;
        let root = page.nodes.iter().find(|n| n.key == NodeKey::ROOT)?;
        self.read_node(root).ok()
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

    /// Reads and decodes a node's points with the columns of `schema` only, the edits kept
    /// beside the dataset applied.
    pub fn read_node_columns(
        &self,
        e: &NodeEntry,
        schema: &Schema,
    ) -> std::result::Result<PointBatch, Damage> {
        self.read_node_prefix(e, schema, e.points as usize)
    }

    /// The cube of node `e` grown by a quantization step (where its points may lie): what
    /// edits are tested against.
    pub fn edit_cube(&self, e: &NodeEntry) -> Aabb {
        let c = e.bounds_in(&self.meta.root);
        let s = self.meta.quantization.scale;
        Aabb::new(
            std::array::from_fn(|a| c.min[a] - s[a]),
            std::array::from_fn(|a| c.max[a] + s[a]),
        )
    }

    /// Node `e`'s first `count` points as stored (its coarser levels of detail), the edits
    /// kept beside the dataset then applied to them, with the columns of `schema` only.
    pub fn read_node_prefix(
        &self,
        e: &NodeEntry,
        schema: &Schema,
        count: usize,
    ) -> std::result::Result<PointBatch, Damage> {
        let cube = self.edit_cube(e);
        let Some(edits) = (self.edits.as_ref()).filter(|d| e.points > 0 && d.meets(&cube)) else {
            let mut b = self.read_node_stored(e, schema)?;
            b.truncate(count);
            return Ok(b);
        };
        // An edit may test any column (`--where`): all are read, those not asked for dropped.
        let mut b = self.read_node_stored(e, &self.meta.schema)?;
        b.truncate(count);
        Self::edited(e, edits.as_ref(), &cube, b, schema)
    }

    /// [`Dataset::decode_node`] with the dataset's edits applied (the web viewer decodes the
    /// pages it fetched).
    pub fn decode_node_edited(
        &self,
        e: &NodeEntry,
        page: &[u8],
        schema: &Schema,
    ) -> std::result::Result<PointBatch, Damage> {
        let cube = self.edit_cube(e);
        match (self.edits.as_ref()).filter(|d| e.points > 0 && d.meets(&cube)) {
            None => self.decode_node(e, page, schema),
            Some(edits) => {
                let b = self.decode_node(e, page, &self.meta.schema)?;
                Self::edited(e, edits.as_ref(), &cube, b, schema)
            }
        }
    }

    /// `b` (node `e`'s points, every column) with `edits` applied, then `schema`'s columns.
    fn edited(
        e: &NodeEntry,
        edits: &dyn edits::Edits,
        cube: &Aabb,
        mut b: PointBatch,
        schema: &Schema,
    ) -> std::result::Result<PointBatch, Damage> {
        edits.apply(cube, &mut b).map_err(|m| Damage {
            key: e.key,
            offset: 0,
            message: format!("its edits: {m}"),
            subtree: false,
        })?;
        b.keep_columns(schema);
        Ok(b)
    }

    /// Reads and decodes a node's points as stored, with the columns of `schema` only.
    pub fn read_node_stored(
        &self,
        e: &NodeEntry,
        schema: &Schema,
    ) -> std::result::Result<PointBatch, Damage> {
        if let Some(f) = &self.foreign {
            let mut b = foreign::spread(f.read_node(e)?);
            b.keep_columns(schema);
            return Ok(b);
        }
        if e.page.length == 0 {
            return self.decode_node(e, &[], schema);
        }
        let b = self.read_range(e.page).map_err(|m| Damage {
            key: e.key,
            offset: e.page.offset,
            message: m,
            subtree: false,
        })?;
        self.decode_node(e, &b, schema)
    }

    /// Node `e`'s page as stored, its checksum checked (to copy it into another dataset with
    /// the same quantization: a page holds its own origin).
    pub fn node_page(&self, e: &NodeEntry) -> std::result::Result<Vec<u8>, Damage> {
        self.no_pages(e)?;
        if e.page.length == 0 {
            return Ok(Vec::new());
        }
        self.read_checked(e.page).map_err(|m| Damage {
            key: e.key,
            offset: e.page.offset,
            message: m,
            subtree: false,
        })
    }

    /// Checks (CRC-32, point count) and decodes node `e`'s page, read elsewhere (the web
    /// viewer fetches pages itself), with the columns of `schema`.
    pub fn decode_node(
        &self,
        e: &NodeEntry,
        page: &[u8],
        schema: &Schema,
    ) -> std::result::Result<PointBatch, Damage> {
        self.no_pages(e)?;
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
        if page.len() != e.page.length as usize {
            return Err(damage(
                e.page.offset,
                format!("{} bytes read of a {}-byte page", page.len(), e.page.length),
            ));
        }
        if crc32fast::hash(page) != e.page.crc {
            return Err(damage(e.page.offset, "checksum mismatch".into()));
        }
        let batch = page::decode(page, schema, &self.meta.quantization)
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

    /// A dataset read in place has no `.myr` pages to copy or decode: an error naming its
    /// format.
    fn no_pages(&self, e: &NodeEntry) -> std::result::Result<(), Damage> {
        match self.foreign_format() {
            Some(f) => Err(Damage {
                key: e.key,
                offset: 0,
                message: format!("a {f} dataset has no Myriad pages (convert it first)"),
                subtree: false,
            }),
            None => Ok(()),
        }
    }

    /// A damage report as an error naming the file.
    pub fn damage_error(&self, d: &Damage) -> Error {
        let msg = if d.subtree {
            format!("hierarchy page of subtree {}: {}", d.key, d.message)
        } else {
            format!("node {}: {}", d.key, d.message)
        };
        match self.locate(PageRef {
            offset: d.offset,
            length: 0,
            crc: 0,
        }) {
            (Some(i), local) if i < self.linked.files.len() => Error::at_byte(
                Path::new(&self.linked.name(i)),
                local.offset,
                format!("{msg} (a file of {})", self.path.display()),
            ),
            _ => Error::at_byte(&self.path, d.offset, msg),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, bounds: Aabb) -> (PathBuf, Result<u64>) {
        write_checked(dir, name, bounds, |_| Ok(()))
    }

    fn write_checked(
        dir: &Path,
        name: &str,
        bounds: Aabb,
        check: impl FnOnce(&Dataset) -> Result<()>,
    ) -> (PathBuf, Result<u64>) {
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
            files: vec![],
        };
        let r = w.finish_checked(meta, check);
        (path, r)
    }

    /// The names of the files in `dir`.
    fn names(dir: &Path) -> Vec<std::ffi::OsString> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect()
    }

    /// A dataset whose check fails replaces nothing: the one under its name stays as it was,
    /// and no temporary file stays.
    #[test]
    fn a_failed_check_leaves_the_old_dataset() {
        let dir = std::env::temp_dir().join(format!("myriad-format-check-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let old = Aabb::new([1.0, 2.0, 3.0], [4.0, 5.0, 6.0]);
        let (path, r) = write(&dir, "d.myr", old);
        r.unwrap();
        let before = std::fs::read(&path).unwrap();
        let new = Aabb::new([1.0, 2.0, 3.0], [7.0, 7.0, 7.0]);
        let mut seen = None;
        let (_, r) = write_checked(&dir, "d.myr", new, |ds| {
            seen = Some(ds.meta.bounds);
            Err(Error::Invalid("d.myr: refused by the check".into()))
        });
        assert_eq!(seen, Some(new), "the check sees the dataset written");
        assert_eq!(r.unwrap_err().to_string(), "d.myr: refused by the check");
        assert_eq!(std::fs::read(&path).unwrap(), before);
        let left = names(&dir);
        assert_eq!(left, vec![std::ffi::OsString::from("d.myr")]);
        std::fs::remove_dir_all(&dir).unwrap();
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
        let left = names(&dir);
        assert_eq!(left, vec![std::ffi::OsString::from("good.myr")]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
