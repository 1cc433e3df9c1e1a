//! Many tiles read in place as one dataset: a folder of COPC files, or a virtual point cloud
//! (`.vpc`: QGIS's and PDAL wrench's STAC ItemCollection, each item's `data` asset a COPC, EPT,
//! Potree 2.0 or `.myr` tile, on disk or by URL relative to the `.vpc`).
//!
//! Opening reads each tile's header and root hierarchy page (in parallel), never its points;
//! a `.vpc` of more than [`OPENED_FIRST`] tiles whose items all give their bounds and count
//! (`proj:bbox`, `pc:count`, as PDAL wrench writes them) opens only that many, spread through
//! it, and each other tile the first time the selection asks for the hierarchy page its root
//! heads (nodes of no points, *stubs*, lead from its place down to the next page's level).
//! The tiles then hang under a few *virtual* levels: the set is split in up to eight groups by
//! the octant of their centres (by their order where centres coincide), again and again until
//! each group is one tile, whose root takes the group's key; a tile's own nodes take the keys
//! below it. Every node carries its bounds (a virtual node: its tiles' bounds; a tile's node: its
//! cube within the tile's bounds), so the selection culls and orders them as kd-tree nodes.
//!
//! Points at every zoom, each point once: a virtual node draws a share of the root nodes of up
//! to [`SOURCES`] of its tiles (spread through them), the first points of each root in the
//! spread order ([`super::spread`]: every prefix a sample), the shallowest level first; the
//! tile's root keeps the rest. A share is the tile's footprint over the node's, times the tiles
//! it stands for (at most a quarter of the root), so a virtual node holds about as many points
//! as one tile's root, and all shares together stay under [`VIRTUAL_POINTS`] (the deepest
//! virtual levels give way first). A tile's shares are decoded once, with its root, on all
//! cores, and kept (bounded by that total): the first image of a thousand tiles waits for 64
//! roots, the converged overview decodes each root once.

use super::{Foreign, damage, open_json};
use crate::hierarchy::PAGE_LEVELS;
use crate::{ChildPage, Damage, Dataset, HierarchyPage, Metadata, NodeEntry, PageRef};
use myriad_core::{Aabb, Error, NodeKey, PointBatch, Result, Schema};
use serde_json::json;
use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

/// The most points all virtual nodes together hold (what their shares keep in memory).
pub const VIRTUAL_POINTS: u64 = 2_000_000;
/// The most tiles a virtual node draws from: its first image waits for their roots only.
const SOURCES: usize = 64;
/// The most tiles one set opens.
const MAX_TILES: usize = 100_000;
/// Tiles opened at once (their header and root page; over HTTP, requests in flight).
const OPENING: usize = 8;
/// A `.vpc` of more tiles than this that gives each tile's bounds and count opens only this
/// many, spread over it, up front (their roots are what the virtual levels draw); the others
/// when a view reaches them.
const OPENED_FIRST: usize = SOURCES;

/// One tile: its dataset and root node (opened on opening the set, or, in a large `.vpc` that
/// gives each tile's bounds and count, the first time a view reaches it), and the shares of its
/// root the virtual levels draw.
struct Tile {
    name: String,
    /// Its dataset and its root node as its own hierarchy gives it, or why not.
    opened: OnceLock<std::result::Result<Opened, String>>,
    /// The key of its root among the set's nodes.
    key: NodeKey,
    /// Its points' bounds (a tile not opened yet: as the `.vpc` gives them).
    bounds: Aabb,
    /// The first points of its spread root the virtual levels draw (from `shares` in order).
    taken: usize,
    /// Those points, decoded once.
    head: Mutex<Option<Arc<PointBatch>>>,
}

/// A node above the tiles.
struct Virtual {
    bounds: Aabb,
    spacing: f64,
    /// (tile, the points of its spread root drawn here).
    shares: Vec<(usize, Range<usize>)>,
}

pub(crate) struct Tiles {
    tiles: Vec<Tile>,
    virtuals: HashMap<NodeKey, Virtual>,
    /// Nodes of no points between a tile opened only when a view reaches it and its place:
    /// its root then lies at the top of a hierarchy page of its own, read (and the tile
    /// opened) only when the selection asks for that page.
    stubs: HashMap<NodeKey, usize>,
    /// The set's CRS (its first tile's), which every tile must share.
    crs: Option<String>,
    /// Tiles by their root's key.
    by_key: HashMap<NodeKey, usize>,
    schema: Schema,
    /// Tiles' hierarchy pages read so far, by (tile, page root in the tile's keys).
    pages: Mutex<HashMap<(usize, NodeKey), Arc<HierarchyPage>>>,
}

/// The tiles a folder holds: its COPC files, sorted by name; empty when any LAS/LAZ file in it
/// is not COPC (a folder of plain tiles is converted, not read in place).
pub fn folder_tiles(dir: &Path) -> Vec<PathBuf> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for e in rd.flatten() {
        let p = e.path();
        let ext = p.extension().map(|e| e.to_ascii_lowercase());
        match ext.as_deref().and_then(|e| e.to_str()) {
            Some("laz") if super::copc::has_info(&p) => out.push(p),
            Some("las" | "laz") => return Vec::new(),
            _ => {}
        }
    }
    out.sort();
    out
}

/// What a `.vpc` item says of its tile before it is opened: its points (`pc:count`) and
/// bounds (`proj:bbox`, in the tiles' CRS: 3D, or 2D with the heights left open).
#[derive(Clone, Copy)]
struct Told {
    points: u64,
    bounds: Aabb,
}

fn told(properties: &serde_json::Value) -> Option<Told> {
    // At most what a 100,000-tile set of them may add up to without overflowing.
    let points = properties["pc:count"].as_u64().filter(|&n| n <= 1 << 44)?;
    let b: Vec<f64> = (properties["proj:bbox"].as_array()?.iter())
        .map(|v| v.as_f64().filter(|x| x.is_finite()))
        .collect::<Option<_>>()?;
    let bounds = match b[..] {
        [x0, y0, z0, x1, y1, z1] => Aabb::new([x0, y0, z0], [x1, y1, z1]),
        [x0, y0, x1, y1] => Aabb::new([x0, y0, f64::NAN], [x1, y1, f64::NAN]),
        _ => return None,
    };
    let ordered = (0..3).all(|a| !(bounds.min[a] > bounds.max[a]));
    ordered.then_some(Told { points, bounds })
}

/// The tiles a `.vpc` names: each item's `data` asset (else its first), relative to the
/// `.vpc`'s folder or URL, with what the item tells of it.
fn vpc_tiles(path: &Path) -> Result<Vec<(String, Option<Told>)>> {
    let file = path
        .file_name()
        .map_or("set.vpc".into(), |f| f.to_string_lossy().into_owned());
    let (place, name, v) = open_json(path, &file)?;
    let bad = |m: String| Error::Invalid(format!("{}: {m}", name.display()));
    let features = v["features"].as_array().ok_or_else(|| {
        bad("not a virtual point cloud (a STAC ItemCollection with \"features\")".into())
    })?;
    let mut out = Vec::new();
    for (i, f) in features.iter().enumerate() {
        let assets = f["assets"]
            .as_object()
            .ok_or_else(|| bad(format!("item {i} has no assets")))?;
        let data = assets
            .values()
            .find(|a| {
                a["roles"]
                    .as_array()
                    .is_some_and(|r| r.iter().any(|r| r == "data"))
            })
            .or_else(|| assets.values().next());
        let href = data
            .and_then(|a| a["href"].as_str())
            .ok_or_else(|| bad(format!("item {i}: no asset with an \"href\"")))?;
        let name = match super::is_url(Path::new(href)) || Path::new(href).is_absolute() {
            true => href.to_string(),
            false => place.name(href.strip_prefix("./").unwrap_or(href)),
        };
        out.push((name, told(&f["properties"])));
    }
    Ok(out)
}

/// The files of a local `.vpc` whose tiles are all plain LAS/LAZ (no COPC among them): a scan
/// cut into tiles, built into a dataset as a folder of them is, not read in place. `None` for
/// any other `.vpc` (or one that cannot be read: opening it as a set says why).
pub fn vpc_scans(path: &Path) -> Option<Vec<PathBuf>> {
    if super::is_url(path) {
        return None;
    }
    // Asked often (every open, a server's watch every few seconds): kept per path while the
    // `.vpc`'s size and time stay.
    type Seen = HashMap<PathBuf, ((u64, std::time::SystemTime), Option<Vec<PathBuf>>)>;
    static SEEN: Mutex<Option<Seen>> = Mutex::new(None);
    let meta = std::fs::metadata(path).ok()?;
    let stamp = (meta.len(), meta.modified().ok()?);
    if let Some((s, files)) = SEEN.lock().ok()?.get_or_insert_default().get(path)
        && *s == stamp
    {
        return files.clone();
    }
    let files = plain_tiles(path);
    if let Ok(mut seen) = SEEN.lock() {
        let seen = seen.get_or_insert_default();
        if seen.len() > 64 {
            seen.clear();
        }
        seen.insert(path.to_path_buf(), (stamp, files.clone()));
    }
    files
}

fn plain_tiles(path: &Path) -> Option<Vec<PathBuf>> {
    let items = vpc_tiles(path).ok()?;
    let files: Vec<PathBuf> = items.into_iter().map(|(n, _)| PathBuf::from(n)).collect();
    let plain = |f: &PathBuf| {
        let ext = f.extension().map(|e| e.to_ascii_lowercase());
        matches!(ext.as_deref().and_then(|e| e.to_str()), Some("las" | "laz"))
            && !super::is_url(f)
            && !super::copc::has_info(f)
    };
    (!files.is_empty() && files.iter().all(plain)).then_some(files)
}

/// A tile opened: its dataset and its root node.
type Opened = (Dataset, NodeEntry);

/// Opens every tile (header and root page), `OPENING` at a time, in the given order (in the
/// web viewer's WebAssembly, which has no threads, one after another).
fn open_all(names: &[String]) -> Vec<Result<Opened>> {
    if cfg!(target_arch = "wasm32") {
        return names.iter().map(|n| open_tile(n)).collect();
    }
    let next = AtomicUsize::new(0);
    let out: Vec<Mutex<Option<Result<Opened>>>> = names.iter().map(|_| Mutex::new(None)).collect();
    std::thread::scope(|s| {
        for _ in 0..OPENING.min(names.len()) {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(name) = names.get(i) else { break };
                    *out[i].lock().expect("tile lock") = Some(open_tile(name));
                }
            });
        }
    });
    out.into_iter()
        .map(|m| {
            m.into_inner()
                .expect("tile lock")
                .expect("every tile opened")
        })
        .collect()
}

#[cfg(not(target_arch = "wasm32"))]
fn open_dataset(name: &str) -> Result<Dataset> {
    let path = Path::new(name);
    if !crate::remote::is_url(path) && super::kind_of(path).is_none() && !crate::is_dataset(path) {
        return Err(Error::Invalid(format!(
            "{name}: a tile must be COPC, EPT, Potree 2.0 or .myr (a LAS/LAZ file without an index is converted first)"
        )));
    }
    // A set's tiles are read as stored: the set's own edits apply to what they give.
    Dataset::open_stored(path)
}

/// The web viewer's: a tile by its URL, of the cloud formats.
#[cfg(target_arch = "wasm32")]
fn open_dataset(name: &str) -> Result<Dataset> {
    Dataset::open_url(Path::new(name))
}

fn open_tile(name: &str) -> Result<Opened> {
    // A set is no tile (a `.vpc` naming itself, or two naming each other, opened without end).
    if super::kind_of(Path::new(name)) == Some(super::Kind::Tiles) {
        return Err(Error::Invalid(format!(
            "{name}: a set of tiles cannot be a tile of a set"
        )));
    }
    let ds = open_dataset(name)?;
    let page = (ds.hierarchy_page(&ds.root_page())).map_err(|d| ds.damage_error(&d))?;
    let root = (page.nodes.iter().find(|n| n.key == NodeKey::ROOT).cloned())
        .ok_or_else(|| Error::Invalid(format!("{name}: no root node")))?;
    Ok((ds, root))
}

/// A tile's points' bounds, or its cube where it does not know them.
fn points_box(ds: &Dataset) -> Aabb {
    match ds.meta.bounds.is_empty() {
        true => ds.meta.root,
        false => ds.meta.bounds,
    }
}

/// Area of a box's footprint, never zero.
fn footprint(b: &Aabb) -> f64 {
    let s = b.size();
    (s[0].max(1e-9) * s[1].max(1e-9)).max(1e-12)
}

impl Tiles {
    /// Opens the set `path` names (a `.vpc`, or a folder of COPC files).
    pub(crate) fn open(path: &Path) -> Result<(Metadata, Tiles)> {
        let (items, format) = match path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("vpc"))
        {
            true => (vpc_tiles(path)?, "VPC"),
            false => {
                let files = folder_tiles(path);
                let items = (files.iter()).map(|p| (p.display().to_string(), None));
                (items.collect(), "COPC tiles")
            }
        };
        if items.is_empty() {
            return Err(Error::Invalid(format!("{}: no tiles", path.display())));
        }
        if items.len() > MAX_TILES {
            return Err(Error::Invalid(format!(
                "{}: {} tiles, more than {MAX_TILES}",
                path.display(),
                items.len()
            )));
        }
        // Which tiles open now: all, but for a large `.vpc` that tells every tile's bounds
        // and count: the first and others spread through it, the rest when a view reaches
        // them.
        let lazy = items.len() > OPENED_FIRST && items.iter().all(|(_, t)| t.is_some());
        let first_ones: Vec<usize> = match lazy {
            true => (0..items.len())
                .step_by(items.len().div_ceil(OPENED_FIRST))
                .collect(),
            false => (0..items.len()).collect(),
        };
        let names: Vec<String> = first_ones.iter().map(|&i| items[i].0.clone()).collect();
        // A set opened whole fails on its first tile that cannot be opened; a lazy one keeps
        // such a tile as a hole (named when reached), as it would one opened later.
        let mut opened: HashMap<usize, Opened> = HashMap::new();
        let mut failed: HashMap<usize, String> = HashMap::new();
        for (i, r) in first_ones.into_iter().zip(open_all(&names)) {
            match r {
                Ok(o) => {
                    opened.insert(i, o);
                }
                Err(e) if lazy => {
                    failed.insert(i, e.to_string());
                }
                Err(e) => return Err(e),
            }
        }
        let mut order: Vec<usize> = opened.keys().copied().collect();
        order.sort_unstable();
        let Some(&one) = order.first() else {
            return Err(Error::Invalid(format!(
                "{}: none of the tiles opened first could be opened ({})",
                path.display(),
                failed.values().next().map_or("", |m| m.as_str())
            )));
        };
        let first = &opened[&one].0.meta;
        for i in &order {
            if let (Some(a), Some(b)) = (&first.crs, &opened[i].0.meta.crs)
                && a != b
            {
                return Err(Error::Invalid(format!(
                    "{}: its coordinate system differs from {}'s (one set, one CRS)",
                    items[*i].0, items[one].0
                )));
            }
        }
        let schema = first.schema.clone();
        let (crs, quantization) = (first.crs.clone(), first.quantization);
        // Heights a 2D `proj:bbox` leaves open: those of the tiles opened.
        let mut heights = Aabb::EMPTY;
        for (ds, _) in opened.values() {
            heights = heights.union(&points_box(ds));
        }
        let told_bounds = |t: &Told| {
            let mut b = t.bounds;
            if b.min[2].is_nan() || b.max[2].is_nan() {
                (b.min[2], b.max[2]) = (heights.min[2], heights.max[2]);
            }
            b
        };
        let mut bounds = Aabb::EMPTY;
        let mut points = 0u64;
        let mut sources = Vec::new();
        let mut tiles = Vec::new();
        for (i, (name, told)) in items.into_iter().enumerate() {
            let slot = OnceLock::new();
            let (b, n, kind) = match opened.remove(&i) {
                Some((ds, root)) => {
                    let b = points_box(&ds);
                    let kind = ds.foreign_format().unwrap_or(".myr").to_string();
                    let n = ds.meta.points;
                    let _ = slot.set(Ok((ds, root)));
                    (b, n, kind)
                }
                None => {
                    let t = told.expect("a lazy set's items each tell their bounds");
                    let kind = match failed.remove(&i) {
                        Some(why) => {
                            let _ = slot.set(Err(why));
                            "could not be opened"
                        }
                        None => "not opened yet",
                    };
                    (told_bounds(&t), t.points, kind.to_string())
                }
            };
            bounds = bounds.union(&b);
            points = points.saturating_add(n);
            sources.push(json!({"path": name, "format": kind, "points": n}));
            tiles.push(Tile {
                name,
                opened: slot,
                key: NodeKey::ROOT,
                bounds: b,
                taken: 0,
                head: Mutex::new(None),
            });
        }
        let mut set = Tiles {
            tiles,
            virtuals: HashMap::new(),
            stubs: HashMap::new(),
            crs: crs.clone(),
            by_key: HashMap::new(),
            schema,
            pages: Mutex::new(HashMap::new()),
        };
        let all: Vec<usize> = (0..set.tiles.len()).collect();
        set.place(all, NodeKey::ROOT);
        set.share();
        let side = (0..3)
            .map(|a| bounds.size()[a])
            .fold(0.0, f64::max)
            .max(1e-9);
        let root = Aabb::new(bounds.min, bounds.min.map(|m| m + side));
        let meta = Metadata {
            structure: "tiles".into(),
            parameters: json!({"format": format, "read_in_place": true, "tiles": set.tiles.len()}),
            points,
            nodes: 0,
            depth: 0,
            bounds,
            root,
            quantization,
            crs,
            schema: set.schema.clone(),
            sources,
            las_header: None,
            software: String::new(),
            levels: Vec::new(),
            files: Vec::new(),
        };
        Ok((meta, set))
    }

    /// Tile `t`'s dataset and root node, opened the first time it is asked for (a tile that
    /// cannot be opened, or of another CRS, is a hole named as its subtree's damage).
    fn opened(&self, t: usize) -> std::result::Result<&Opened, Damage> {
        let tile = &self.tiles[t];
        let r = tile.opened.get_or_init(|| {
            let (ds, root) = open_tile(&tile.name).map_err(|e| e.to_string())?;
            if let (Some(a), Some(b)) = (&self.crs, &ds.meta.crs)
                && a != b
            {
                return Err(format!(
                    "{}: its coordinate system differs from the set's (one set, one CRS)",
                    tile.name
                ));
            }
            Ok((ds, root))
        });
        r.as_ref()
            .map_err(|m| damage(tile.key, 0, format!("a tile not opened: {m}"), true))
    }

    /// Gives the tiles `group` keys below `key`: a tile alone takes `key`; a group is a virtual
    /// node whose children are its tiles split by the octant of their centres (by their order
    /// where the centres coincide).
    fn place(&mut self, group: Vec<usize>, key: NodeKey) {
        if let [t] = group[..] {
            // A tile not opened yet (or that could not be: a hole of its own, not of the
            // page above): its root at the top of a page of its own, below nodes of no points.
            let mut key = key;
            if !matches!(self.tiles[t].opened.get(), Some(Ok(_))) {
                while !key.level.is_multiple_of(PAGE_LEVELS) {
                    self.stubs.insert(key, t);
                    key = key.child(0);
                }
            }
            self.tiles[t].key = key;
            self.by_key.insert(key, t);
            return;
        }
        let mut b = Aabb::EMPTY;
        let mut centres = Aabb::EMPTY;
        for &t in &group {
            b = b.union(&self.tiles[t].bounds);
            centres.extend(self.tiles[t].bounds.center());
        }
        self.virtuals.insert(
            key,
            Virtual {
                bounds: b,
                spacing: 0.0,
                shares: Vec::new(),
            },
        );
        let mid = centres.center();
        let size = centres.size();
        let mut parts: [Vec<usize>; 8] = Default::default();
        let spread_out = (0..3).any(|a| size[a] > 1e-9 * (1.0 + mid[a].abs()));
        if spread_out && key.level < 24 {
            for &t in &group {
                let c = self.tiles[t].bounds.center();
                let o = (0..3).fold(0, |o, a| {
                    o | (((size[a] > 0.0 && c[a] > mid[a]) as usize) << a)
                });
                parts[o].push(t);
            }
        }
        if parts.iter().filter(|p| !p.is_empty()).count() < 2 {
            let per = group.len().div_ceil(8);
            parts = Default::default();
            for (i, t) in group.into_iter().enumerate() {
                parts[i / per].push(t);
            }
        }
        for (o, p) in parts.into_iter().enumerate() {
            if !p.is_empty() {
                self.place(p, key.child(o));
            }
        }
    }

    /// Decides each tile's shares of its root for the virtual levels above it, level by level
    /// from the top: a virtual node draws from at most [`SOURCES`] of its tiles, spread through
    /// them (its tiles are in the order they were split by octant), each giving its footprint
    /// over the node's (times the tiles each stands for, at most a quarter of its root); the
    /// level that would pass [`VIRTUAL_POINTS`] is cut to fit and the levels below it draw
    /// nothing.
    fn share(&mut self) {
        let n = self.tiles.len();
        let mut below: HashMap<NodeKey, Vec<usize>> = HashMap::new();
        for t in 0..n {
            let mut k = self.tiles[t].key;
            while k.level > 0 {
                k = k.parent();
                below.entry(k).or_default().push(t);
            }
        }
        let mut keys: Vec<NodeKey> = self.virtuals.keys().copied().collect();
        keys.sort_by_key(|k| (k.level, k.cell));
        let mut at = vec![0usize; n];
        let mut total = 0u64;
        for level in keys.chunk_by(|a, b| a.level == b.level) {
            let mut wants = Vec::new();
            for key in level {
                // The tiles opened (all but in a large `.vpc`, where those opened first stand
                // for the others).
                let open: Vec<usize> = (below[key].iter().copied())
                    .filter(|&t| self.tiles[t].opened.get().is_some_and(|o| o.is_ok()))
                    .collect();
                if open.is_empty() {
                    continue;
                }
                let step = open.len().div_ceil(SOURCES);
                let chosen: Vec<usize> = open.iter().copied().step_by(step).collect();
                let stands_for = below[key].len() as f64 / chosen.len() as f64;
                let area = footprint(&self.virtuals[key].bounds);
                for t in chosen {
                    let tile = &self.tiles[t];
                    let Some(Ok((_, root))) = tile.opened.get() else {
                        continue;
                    };
                    let points = root.points as usize;
                    let frac = (footprint(&tile.bounds) / area * stands_for).min(0.25);
                    let want =
                        ((points as f64 * frac) as usize).min((points / 2).saturating_sub(at[t]));
                    wants.push((*key, t, want));
                }
            }
            let sum: u64 = wants.iter().map(|w| w.2 as u64).sum();
            let scale = match total + sum > VIRTUAL_POINTS {
                true => (VIRTUAL_POINTS - total) as f64 / sum as f64,
                false => 1.0,
            };
            for (key, t, want) in wants {
                let w = (want as f64 * scale) as usize;
                if w > 0 {
                    let v = self.virtuals.get_mut(&key).expect("a virtual node");
                    v.shares.push((t, at[t]..at[t] + w));
                    at[t] += w;
                    total += w as u64;
                }
            }
            if scale < 1.0 {
                break;
            }
        }
        for (t, taken) in at.into_iter().enumerate() {
            self.tiles[t].taken = taken;
        }
        // A virtual node's spacing: its footprint over its points (the tiles are surveys seen
        // from above, their points spread over their ground).
        for v in self.virtuals.values_mut() {
            let points: usize = v.shares.iter().map(|(_, r)| r.len()).sum();
            v.spacing = (footprint(&v.bounds) / points.max(1) as f64).sqrt();
        }
    }

    /// The tile whose subtree holds `key`, and `key` in the tile's own keys.
    fn tile_of(&self, key: NodeKey) -> Option<(usize, NodeKey)> {
        let mut k = key;
        loop {
            if let Some(&t) = self.by_key.get(&k) {
                let l = key.level - k.level;
                let local = NodeKey {
                    level: l,
                    cell: std::array::from_fn(|a| key.cell[a] - (k.cell[a] << l)),
                };
                return Some((t, local));
            }
            if k.level == 0 {
                return None;
            }
            k = k.parent();
        }
    }

    /// Key `local` of tile `t` among the set's keys.
    fn global(&self, t: usize, local: NodeKey) -> NodeKey {
        let k = self.tiles[t].key;
        NodeKey {
            level: k.level + local.level,
            cell: std::array::from_fn(|a| (k.cell[a] << local.level) + local.cell[a]),
        }
    }

    /// Tile `t`'s hierarchy page holding its node `local` (read the first time).
    fn tile_page(
        &self,
        t: usize,
        local: NodeKey,
    ) -> std::result::Result<Arc<HierarchyPage>, Damage> {
        let mut root = local;
        while !root.level.is_multiple_of(PAGE_LEVELS) {
            root = root.parent();
        }
        if let Some(p) = self.pages.lock().expect("pages lock").get(&(t, root)) {
            return Ok(p.clone());
        }
        let (ds, _) = self.opened(t)?;
        let page = ds
            .hierarchy_page(&ChildPage {
                key: root,
                page: PageRef::default(),
            })
            .map_err(|d| self.tile_damage(t, d))?;
        let page = Arc::new(page);
        self.pages
            .lock()
            .expect("pages lock")
            .insert((t, root), page.clone());
        Ok(page)
    }

    /// A tile's damage report as the set's (its key among the set's, the tile named).
    fn tile_damage(&self, t: usize, d: Damage) -> Damage {
        let what = if d.subtree {
            "hierarchy page of subtree"
        } else {
            "node"
        };
        damage(
            self.global(t, d.key),
            d.offset,
            format!(
                "tile {}, {what} {}: {}",
                self.tiles[t].name, d.key, d.message
            ),
            d.subtree,
        )
    }

    /// Tile `t`'s node `local` as its hierarchy lists it, and its children's keys.
    fn tile_node(
        &self,
        t: usize,
        local: NodeKey,
    ) -> std::result::Result<Option<(NodeEntry, Vec<NodeKey>)>, Damage> {
        let page = self.tile_page(t, local)?;
        let Ok(i) = page.nodes.binary_search_by_key(&local, |n| n.key) else {
            return Ok(None);
        };
        let mut children = Vec::new();
        for o in 0..8 {
            let c = local.child(o);
            let listed = match c.level.is_multiple_of(PAGE_LEVELS) {
                true => page.children.iter().any(|p| p.key == c),
                false => page.nodes.binary_search_by_key(&c, |n| n.key).is_ok(),
            };
            if listed {
                children.push(c);
            }
        }
        Ok(Some((page.nodes[i].clone(), children)))
    }

    /// Node `key` of the set, with its children's keys.
    fn node(&self, key: NodeKey) -> std::result::Result<Option<(NodeEntry, Vec<NodeKey>)>, Damage> {
        if let Some(v) = self.virtuals.get(&key) {
            let points: usize = v.shares.iter().map(|(_, r)| r.len()).sum();
            let mut e = NodeEntry::new(
                key,
                PageRef::default(),
                points as u32,
                vec![points as u32],
                vec![v.spacing],
            );
            e.bounds = Some(v.bounds);
            let children = (0..8)
                .map(|o| key.child(o))
                .filter(|c| {
                    self.virtuals.contains_key(c)
                        || self.by_key.contains_key(c)
                        || self.stubs.contains_key(c)
                })
                .collect();
            return Ok(Some((e, children)));
        }
        if let Some(&t) = self.stubs.get(&key) {
            let b = self.tiles[t].bounds;
            let spacing = footprint(&b).sqrt();
            let mut e = NodeEntry::new(key, PageRef::default(), 0, vec![0], vec![spacing]);
            e.bounds = Some(b);
            return Ok(Some((e, vec![key.child(0)])));
        }
        let Some((t, local)) = self.tile_of(key) else {
            return Ok(None);
        };
        let Some((inner, children)) = self.tile_node(t, local)? else {
            return Ok(None);
        };
        let tile = &self.tiles[t];
        let mut e = inner.clone();
        e.key = key;
        if local == NodeKey::ROOT {
            e.points = inner.points.saturating_sub(tile.taken as u32);
            e.prefix = vec![e.points];
            e.spacing = vec![inner.spacing.last().copied().unwrap_or(1.0)];
        }
        let ds = &self.opened(t)?.0;
        let cube = inner.bounds_in(&ds.meta.root);
        // The tile's own bounds (those a `.vpc` told of a tile opened late may be off).
        e.bounds = Some(intersect(&cube, &points_box(ds)).unwrap_or(cube));
        let children = children.into_iter().map(|c| self.global(t, c)).collect();
        Ok(Some((e, children)))
    }

    /// The first `tile.taken` points of tile `t`'s spread root, decoded once.
    fn head(&self, t: usize) -> std::result::Result<Arc<PointBatch>, Damage> {
        let tile = &self.tiles[t];
        let mut slot = tile.head.lock().expect("head lock");
        if let Some(h) = &*slot {
            return Ok(h.clone());
        }
        let (ds, root) = self.opened(t)?;
        let b = ds.read_node(root).map_err(|d| self.tile_damage(t, d))?;
        let h = Arc::new(self.conformed(b.slice(0..tile.taken.min(b.len()))));
        *slot = Some(h.clone());
        Ok(h)
    }

    /// The heads of `tiles`, decoded on all cores (a virtual node near the top draws from
    /// hundreds of tiles; each root is decoded once, whichever node asks first).
    fn heads(&self, tiles: &[usize]) -> std::result::Result<(), Damage> {
        let workers = match cfg!(target_arch = "wasm32") {
            true => 1,
            false => std::thread::available_parallelism().map_or(2, |n| n.get()),
        }
        .min(8)
        .min(tiles.len());
        if workers < 2 {
            return tiles.iter().try_for_each(|&t| self.head(t).map(|_| ()));
        }
        let next = AtomicUsize::new(0);
        let failed: Mutex<Option<Damage>> = Mutex::new(None);
        std::thread::scope(|s| {
            for _ in 0..workers {
                s.spawn(|| {
                    while let Some(&t) = tiles.get(next.fetch_add(1, Ordering::Relaxed)) {
                        if let Err(d) = self.head(t) {
                            failed.lock().expect("failed lock").get_or_insert(d);
                            break;
                        }
                    }
                });
            }
        });
        match failed.into_inner().expect("failed lock") {
            Some(d) => Err(d),
            None => Ok(()),
        }
    }

    fn conformed(&self, mut b: PointBatch) -> PointBatch {
        b.conform(&self.schema);
        b
    }
}

/// Where two boxes meet, or `None`.
fn intersect(a: &Aabb, b: &Aabb) -> Option<Aabb> {
    let min: [f64; 3] = std::array::from_fn(|i| a.min[i].max(b.min[i]));
    let max: [f64; 3] = std::array::from_fn(|i| a.max[i].min(b.max[i]));
    (0..3)
        .all(|i| min[i] <= max[i])
        .then(|| Aabb::new(min, max))
}

impl Foreign for Tiles {
    fn hierarchy_page(&self, root: NodeKey) -> std::result::Result<HierarchyPage, Damage> {
        let mut out = HierarchyPage::default();
        let mut todo = vec![root];
        while let Some(k) = todo.pop() {
            let Some((e, children)) = self.node(k)? else {
                continue;
            };
            out.nodes.push(e);
            for c in children {
                match c.level == root.level + PAGE_LEVELS {
                    true => out.children.push(ChildPage {
                        key: c,
                        page: PageRef::default(),
                    }),
                    false => todo.push(c),
                }
            }
        }
        out.nodes.sort_by_key(|n| n.key);
        Ok(out)
    }

    fn read_node(&self, e: &NodeEntry) -> std::result::Result<PointBatch, Damage> {
        if let Some(v) = self.virtuals.get(&e.key) {
            let tiles: Vec<usize> = v.shares.iter().map(|(t, _)| *t).collect();
            self.heads(&tiles)?;
            let mut out = PointBatch::with_schema(&self.schema, e.points as usize);
            out.extra_stride = self.schema.extra_bytes;
            for (t, r) in &v.shares {
                let h = self.head(*t)?;
                let r = r.start.min(h.len())..r.end.min(h.len());
                out.append(&h.slice(r));
            }
            return Ok(out);
        }
        if self.stubs.contains_key(&e.key) {
            let mut out = PointBatch::with_schema(&self.schema, 0);
            out.extra_stride = self.schema.extra_bytes;
            return Ok(out);
        }
        let Some((t, local)) = self.tile_of(e.key) else {
            return Err(damage(e.key, 0, "not a node of the set", false));
        };
        let tile = &self.tiles[t];
        let Some((inner, _)) = self.tile_node(t, local)? else {
            return Err(damage(
                e.key,
                0,
                format!("tile {}: no node {local}", tile.name),
                false,
            ));
        };
        let b = (self.opened(t)?.0)
            .read_node(&inner)
            .map_err(|d| self.tile_damage(t, d))?;
        let b = match local == NodeKey::ROOT {
            true => b.slice(tile.taken.min(b.len())..b.len()),
            false => b,
        };
        Ok(self.conformed(b))
    }

    fn fetched(&self) -> Option<(u64, u64)> {
        let mut total: Option<(u64, u64)> = None;
        for t in &self.tiles {
            let Some(Ok((ds, _))) = t.opened.get() else {
                continue;
            };
            if let Some((r, b)) = ds.fetched() {
                let s = total.get_or_insert((0, 0));
                *s = (s.0 + r, s.1 + b);
            }
        }
        total
    }

    fn changed(&self) -> Option<String> {
        self.tiles.iter().find_map(|t| match t.opened.get() {
            Some(Ok((ds, _))) => ds.check_unchanged().err().map(|e| e.to_string()),
            _ => None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What an item tells of its tile is taken only when it is whole and sound: a count a set
    /// may add up, a box whose corners are in order (a 2D one leaves the heights open).
    #[test]
    fn an_item_tells_its_bounds_and_count_or_nothing() {
        let t = told(&json!({"pc:count": 7, "proj:bbox": [0, 1, 2, 3, 4, 5]})).unwrap();
        assert_eq!(
            (t.points, t.bounds.min, t.bounds.max),
            (7, [0.0, 1.0, 2.0], [3.0, 4.0, 5.0])
        );
        let flat = told(&json!({"pc:count": 7, "proj:bbox": [0, 1, 3, 4]})).unwrap();
        assert!(flat.bounds.min[2].is_nan() && flat.bounds.max[0] == 3.0);
        for bad in [
            json!({"pc:count": 7, "proj:bbox": [0, 1, 5, 3, 4, 2]}),
            json!({"pc:count": 7, "proj:bbox": [3, 1, 0, 4]}),
            json!({"pc:count": u64::MAX, "proj:bbox": [0, 1, 2, 3, 4, 5]}),
            json!({"pc:count": 7, "proj:bbox": [0, 1, 2, 3, 4]}),
            json!({"proj:bbox": [0, 1, 2, 3, 4, 5]}),
            json!({"pc:count": 7}),
        ] {
            assert!(told(&bad).is_none(), "{bad}");
        }
    }
}
