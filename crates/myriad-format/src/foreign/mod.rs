//! The field's cloud formats read in place, as datasets: COPC ([`copc`]), EPT ([`ept`]) and
//! Potree 2.0 ([`potree`]). Each is an octree whose nodes are keyed as Myriad's are (level and
//! cell), with a hierarchy in pages of its own making (COPC's EVLR pages, EPT's JSON files,
//! Potree's hierarchy chunks) and its points in its own encoding. A [`Dataset`](crate::Dataset)
//! opened from one reads through a [`Foreign`] reader instead of `.myr` pages, so that the
//! selection, the loader, the tools and the exporters read it as they read a `.myr`, and nothing
//! is written next to it.
//!
//! The selection expects the hierarchy in pages of [`PAGE_LEVELS`] levels, each rooted at a
//! level that is a multiple of it; the formats page theirs as they like. [`Tree`] keeps what has
//! been read of a format's own pages and answers for [`PAGE_LEVELS`]-level pages, reading the
//! format's pages a requested page needs the first time it needs them.

pub mod copc;
pub mod ept;
pub mod potree;
pub mod tiles;

use crate::hierarchy::PAGE_LEVELS;
use crate::{ByteSource, ChildPage, Damage, HierarchyPage, NodeEntry, PageRef};
use myriad_core::{Error, NodeKey, PointBatch, Result};
use serde_json::Value;
use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

pub(crate) use crate::Foreign;

/// The format a path names, by its name, or `None`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Copc,
    Ept,
    Potree,
    /// Many tiles as one: a `.vpc`, or a folder of COPC files ([`tiles`]).
    Tiles,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::Copc => "COPC",
            Kind::Ept => "EPT",
            Kind::Potree => "Potree 2.0",
            Kind::Tiles => "tiles",
        }
    }
}

/// What `path` names: a COPC file (`.copc.laz`, or a LAZ file whose first VLR is COPC's info),
/// an EPT dataset (its `ept.json`, or a folder holding one), a Potree 2.0 dataset (its
/// `metadata.json`, or a folder holding one with `hierarchy.bin`), a set of tiles (a `.vpc`, or
/// a folder whose LAS/LAZ files are all COPC), or none of them. A URL is
/// told by its name alone.
pub fn kind_of(path: &Path) -> Option<Kind> {
    let s = path.to_string_lossy();
    let lower = s.to_ascii_lowercase();
    if lower.ends_with(".copc.laz") {
        return Some(Kind::Copc);
    }
    if lower.ends_with("ept.json") {
        return Some(Kind::Ept);
    }
    if lower.ends_with("metadata.json") && potree_metadata(path) {
        return Some(Kind::Potree);
    }
    if lower.ends_with(".vpc") {
        // A local set of plain LAS/LAZ tiles is a scan, built as a folder of them is.
        #[cfg(not(target_arch = "wasm32"))]
        if tiles::vpc_scans(path).is_some() {
            return None;
        }
        return Some(Kind::Tiles);
    }
    if is_url(path) {
        return None;
    }
    if path.is_dir() {
        if path.join("ept.json").is_file() {
            return Some(Kind::Ept);
        }
        if path.join("metadata.json").is_file() && path.join("hierarchy.bin").is_file() {
            return Some(Kind::Potree);
        }
        #[cfg(not(target_arch = "wasm32"))]
        if !tiles::folder_tiles(path).is_empty() {
            return Some(Kind::Tiles);
        }
        return None;
    }
    let ext = path.extension().map(|e| e.to_ascii_lowercase());
    if ext.as_deref() == Some(std::ffi::OsStr::new("laz")) && copc::has_info(path) {
        return Some(Kind::Copc);
    }
    None
}

/// Whether a `metadata.json` is Potree 2.0's: a URL by its name; a file by the
/// `hierarchy.bin` beside it.
fn potree_metadata(path: &Path) -> bool {
    is_url(path) || path.with_file_name("hierarchy.bin").is_file()
}

/// Whether `path` is a URL (`http(s)://`, `s3://`).
pub(crate) fn is_url(path: &Path) -> bool {
    path.to_str().is_some_and(|s| {
        s.starts_with("http://") || s.starts_with("https://") || s.starts_with("s3://")
    })
}

/// How the web viewer's WebAssembly opens a URL for range reads (its workers' synchronous
/// requests), with the first `head` bytes in the opening request where it can.
#[cfg(target_arch = "wasm32")]
pub type UrlOpener = fn(&str, usize) -> std::io::Result<Arc<dyn ByteSource>>;

#[cfg(target_arch = "wasm32")]
static URL_OPENER: std::sync::OnceLock<UrlOpener> = std::sync::OnceLock::new();

/// Sets how URLs are opened in WebAssembly (once, by the web viewer).
#[cfg(target_arch = "wasm32")]
pub fn set_url_opener(f: UrlOpener) {
    let _ = URL_OPENER.set(f);
}

/// `url` opened for range reads: over HTTP natively, through the web viewer in WebAssembly.
pub(crate) fn open_url(url: &str, head: usize) -> Result<Arc<dyn ByteSource>> {
    #[cfg(not(target_arch = "wasm32"))]
    return Ok(Arc::new(crate::remote::HttpBytes::open_with_head(
        url, head,
    )?));
    #[cfg(target_arch = "wasm32")]
    match URL_OPENER.get() {
        Some(f) => f(url, head).map_err(|e| Error::io(Path::new(url), e)),
        None => Err(Error::Invalid(format!("{url}: no way to open URLs here"))),
    }
}

/// Where a dataset of several files lies (a folder, or a URL's folder), and the counts of what
/// was fetched from it.
pub(crate) struct Place {
    /// The dataset's own file (`ept.json`, `metadata.json`): others are relative to it.
    base: String,
    url: bool,
    requests: AtomicU64,
    bytes: AtomicU64,
    changed: Mutex<Option<String>>,
}

/// The first bytes of a whole small file asked for in one request (an EPT node or JSON page,
/// read whole): bigger files take a second.
const WHOLE_HEAD: usize = 4 << 20;
/// The most bytes a JSON file of a dataset (ept.json, a hierarchy page, metadata.json) may have.
pub(crate) const MAX_JSON: u64 = 64 << 20;
/// The most bytes one node's data may have.
pub(crate) const MAX_NODE: u64 = 1 << 30;

impl Place {
    pub(crate) fn new(base: &Path) -> Place {
        let base = base.to_string_lossy().into_owned();
        Place {
            url: is_url(Path::new(&base)),
            base,
            requests: AtomicU64::new(0),
            bytes: AtomicU64::new(0),
            changed: Mutex::new(None),
        }
    }

    /// How `rel` is named in errors: a path or URL.
    pub(crate) fn name(&self, rel: &str) -> String {
        match self.url {
            true => crate::linked::join_url(&self.base, rel),
            false => Path::new(&self.base)
                .parent()
                .unwrap_or(Path::new(""))
                .join(rel)
                .display()
                .to_string(),
        }
    }

    /// A file of the dataset opened for ranges (local, or by range requests with its first
    /// `head` bytes in the opening one).
    pub(crate) fn open(&self, rel: &str, head: usize) -> Result<Arc<dyn ByteSource>> {
        let name = self.name(rel);
        if self.url {
            // Counted by the source itself ([`ByteSource::fetched`]).
            return open_url(&name, head);
        }
        #[cfg(not(target_arch = "wasm32"))]
        return Ok(Arc::new(crate::FileBytes::open(Path::new(&name))?));
        #[cfg(target_arch = "wasm32")]
        Err(Error::Invalid(format!("{name}: no files here, only URLs")))
    }

    /// A file of the dataset read whole, refused past `most` bytes: one request over HTTP for
    /// files up to [`WHOLE_HEAD`].
    pub(crate) fn read(&self, rel: &str, most: u64) -> std::result::Result<Vec<u8>, String> {
        let name = self.name(rel);
        if !self.url {
            return myriad_io::read_small(Path::new(&name), most).map_err(|e| e.to_string());
        }
        let h = open_url(&name, WHOLE_HEAD).map_err(|e| e.to_string())?;
        if h.len() > most {
            self.count(&*h);
            return Err(format!("{name}: {} bytes, more than {most}", h.len()));
        }
        let b = h
            .read_at(0, h.len() as usize)
            .map_err(|e| format!("{name}: {e}"));
        self.count(&*h);
        b
    }

    /// Adds a source's requests and bytes to the place's (after its reads).
    fn count(&self, h: &dyn ByteSource) {
        let (r, b) = h.fetched().unwrap_or_default();
        self.requests.fetch_add(r, Ordering::Relaxed);
        self.bytes.fetch_add(b, Ordering::Relaxed);
        if let Some(c) = h.changed() {
            *self.changed.lock().expect("changed lock") = Some(c);
        }
    }

    pub(crate) fn fetched(&self) -> Option<(u64, u64)> {
        self.url.then(|| {
            (
                self.requests.load(Ordering::Relaxed),
                self.bytes.load(Ordering::Relaxed),
            )
        })
    }

    pub(crate) fn changed(&self) -> Option<String> {
        self.changed.lock().expect("changed lock").clone()
    }
}

/// One node as a format's own hierarchy gives it: its points and where its data lie.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Known {
    pub points: u64,
    pub at: u64,
    pub len: u64,
}

/// One of a format's own hierarchy pages, read: its nodes, and the pages below it (by the key
/// of the node each holds first, with where the page lies).
#[derive(Debug, Default)]
pub(crate) struct SourcePage {
    pub nodes: Vec<(NodeKey, Known)>,
    pub below: Vec<(NodeKey, PageRef)>,
}

/// A format's own hierarchy pages, read on demand, answered as [`PAGE_LEVELS`]-level pages.
pub(crate) struct Tree {
    state: Mutex<TreeState>,
    /// Spacing of the root level; each level below halves it.
    spacing: f64,
}

#[derive(Default)]
struct TreeState {
    known: HashMap<NodeKey, Known>,
    /// Pages not read yet, by the key of the node they hold first.
    unread: HashMap<NodeKey, PageRef>,
    /// Pages that could not be read, and why.
    damaged: HashMap<NodeKey, Damage>,
    read: HashSet<NodeKey>,
}

impl Tree {
    /// A tree whose root page is `root` (holding the root node), unread.
    pub(crate) fn new(root: PageRef, spacing: f64) -> Tree {
        let mut s = TreeState::default();
        s.unread.insert(NodeKey::ROOT, root);
        Tree {
            state: Mutex::new(s),
            spacing,
        }
    }

    /// Whether node `key` exists as far as the pages read say (listed, or the first of a page
    /// not read yet).
    fn exists(s: &TreeState, key: &NodeKey) -> bool {
        s.known.contains_key(key) || s.unread.contains_key(key)
    }

    /// Node `key`'s entry, reading the page it is the first of if that is not read yet.
    fn entry(
        &self,
        key: NodeKey,
        read: &dyn Fn(NodeKey, PageRef) -> std::result::Result<SourcePage, Damage>,
    ) -> std::result::Result<Option<Known>, Damage> {
        let r = {
            let s = self.state.lock().expect("tree lock");
            if let Some(k) = s.known.get(&key) {
                return Ok(Some(*k));
            }
            if let Some(d) = s.damaged.get(&key) {
                return Err(d.clone());
            }
            match s.unread.get(&key) {
                Some(r) => *r,
                None => return Ok(None),
            }
        };
        // Read without the lock (another thread may read the same page: the first kept).
        let page = read(key, r);
        let mut s = self.state.lock().expect("tree lock");
        match page {
            Ok(p) => {
                if s.read.insert(key) {
                    s.unread.remove(&key);
                    for (k, n) in p.nodes {
                        s.known.entry(k).or_insert(n);
                    }
                    for (k, r) in p.below {
                        if !s.known.contains_key(&k) && !s.read.contains(&k) {
                            s.unread.insert(k, r);
                        }
                    }
                }
                Ok(s.known.get(&key).copied())
            }
            Err(d) => {
                s.damaged.insert(key, d.clone());
                Err(d)
            }
        }
    }

    /// The [`PAGE_LEVELS`]-level page rooted at `root`, each entry made by `entry`.
    pub(crate) fn page(
        &self,
        root: NodeKey,
        read: &dyn Fn(NodeKey, PageRef) -> std::result::Result<SourcePage, Damage>,
    ) -> std::result::Result<HierarchyPage, Damage> {
        let mut out = HierarchyPage::default();
        let mut todo = vec![root];
        while let Some(k) = todo.pop() {
            let Some(n) = self.entry(k, read)? else {
                continue;
            };
            let page = PageRef {
                offset: n.at,
                length: u32::try_from(n.len).unwrap_or(u32::MAX),
                crc: 0,
            };
            let points = u32::try_from(n.points).unwrap_or(u32::MAX);
            let spacing = self.spacing / (1u64 << k.level.min(62)) as f64;
            out.nodes
                .push(NodeEntry::new(k, page, points, vec![points], vec![spacing]));
            let s = self.state.lock().expect("tree lock");
            for o in 0..8 {
                let c = k.child(o);
                if !Tree::exists(&s, &c) {
                    continue;
                }
                if c.level == root.level + PAGE_LEVELS {
                    out.children.push(ChildPage {
                        key: c,
                        page: PageRef::default(),
                    });
                } else {
                    todo.push(c);
                }
            }
        }
        out.nodes.sort_by_key(|n| n.key);
        Ok(out)
    }
}

/// A damage report of node or page `key`, at `at`.
pub(crate) fn damage(key: NodeKey, at: u64, message: impl Into<String>, subtree: bool) -> Damage {
    Damage {
        key,
        offset: at,
        message: message.into(),
        subtree,
    }
}

/// A node's points in an order whose every prefix is spread over the whole node: the selection
/// draws a prefix of the last node within its budget, which in a `.myr` node is a coarser level
/// of detail; the formats read here store points in any order (often sorted in space, where a
/// prefix would be one corner). A stride through the points near the golden ratio of their
/// count, coprime with it, visits each once.
pub(crate) fn spread(b: PointBatch) -> PointBatch {
    let n = b.len() as u64;
    if n < 3 {
        return b;
    }
    let gcd = |mut a: u64, mut b: u64| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let mut step = ((n as f64) * 0.618_033_988_75) as u64;
    while gcd(step, n) != 1 {
        step += 1;
    }
    let order: Vec<u32> = (0..n).map(|i| (i * step % n) as u32).collect();
    b.gather(&order)
}

/// A node's error as a damage report: its byte offset where it names one, else `at`, and its
/// message without the file's name (the report names the dataset).
pub(crate) fn as_damage(key: NodeKey, e: Error, at: u64) -> Damage {
    match e {
        Error::Format {
            location: myriad_core::Location::Byte(b),
            message,
            ..
        } => damage(key, b, message, false),
        e => damage(key, at, e.to_string(), false),
    }
}

/// A dataset's JSON document (`ept.json`, `metadata.json`) named `file`, given as its path or
/// URL or as the folder holding it: where the dataset lies, the document's name, and the
/// document (a syntax error named by its line).
pub(crate) fn open_json(path: &Path, file: &str) -> Result<(Place, std::path::PathBuf, Value)> {
    let name = match !is_url(path) && path.is_dir() {
        true => path.join(file),
        false => path.to_path_buf(),
    };
    let place = Place::new(&name);
    let text = place
        .read(file, MAX_JSON)
        .map_err(|m| Error::Invalid(format!("{}: {m}", name.display())))?;
    let v = serde_json::from_slice(&text)
        .map_err(|e| Error::at_line(&name, e.line() as u64, e.to_string()))?;
    Ok((place, name, v))
}

/// A JSON document's number array of `n` entries at `field`.
pub(crate) fn numbers<const N: usize>(v: &serde_json::Value, field: &str) -> Option<[f64; N]> {
    let a = v.get(field)?.as_array()?;
    if a.len() != N {
        return None;
    }
    let mut out = [0.0; N];
    for (o, x) in out.iter_mut().zip(a) {
        *o = x.as_f64().filter(|x| x.is_finite())?;
    }
    Some(out)
}
