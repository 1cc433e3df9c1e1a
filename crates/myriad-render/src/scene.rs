//! A dataset on screen: each frame selects what the view needs within the point budget, asks
//! the loader for what is missing (never waiting for it), uploads what has landed to GPU buffers
//! and draws every selected node that has its buffer. A node still loading is covered by its
//! parent's points, drawn meanwhile; the image refines as pages land. The hierarchy is read the
//! same way: the root page on opening, the pages below as the selection reaches them
//! ([`myriad_lod::hierarchy`]), within a byte budget ([`Scene::pages`]).

mod many;
mod queried;
mod words;

pub use many::{frame_many, frame_many_threaded};

use crate::selector::{Request, Selector};
use crate::{ColorBy, Draw, Gpu, NodeBuffers, Rasterizer, Style};
use myriad_core::{Aabb, NodeKey};
use myriad_format::NodeEntry;
use myriad_lod::{
    Camera, DrawnTree, Hierarchy, Loader, Occlusion, PageCache, PageReader, SelectOptions,
    Selection, robust_bounds,
};
use std::collections::{HashMap, HashSet};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A point found under the cursor.
#[derive(Clone)]
pub struct Picked {
    pub position: [f64; 3],
    /// Eye depth.
    pub depth: f64,
    pub node: NodeKey,
    /// Its node's points (all its attributes), and its index there.
    pub batch: Arc<myriad_lod::stream::Loaded>,
    pub index: usize,
}

pub struct Scene {
    /// The hierarchy as far as its pages are loaded; shared with the selection thread
    /// ([`Scene::frame_threaded`]), which gets a new copy when pages land.
    pub hierarchy: Arc<Hierarchy>,
    /// Which hierarchy pages were used when, and the byte budget they are kept within.
    pub pages: PageCache,
    pub loader: Loader,
    pub buffers: NodeBuffers,
    /// The root cube's centre (f32 positions are relative to it).
    pub origin: [f64; 3],
    /// The dataset's grid: positions are quantized on it per node, without loss where a node
    /// spans at most 2^30 steps an axis (None: on a grid fitted to each node's points).
    pub grid: Option<myriad_format::page::Quantization>,
    /// Upload f32 positions (16 bytes a point with colour) instead: the layout before
    /// quantization, for comparisons.
    pub f32_positions: bool,
    /// The heights the elevation ramp spans.
    pub z_range: (f64, f64),
    /// Where the data is, without its outliers: for framing the view.
    pub view_bounds: Aabb,
    /// The last frame's selection (what picking searches).
    pub last: Selection,
    /// The nodes drawn in the last frame (`mwkd` draws them again in place of front nodes not
    /// yet on the GPU).
    pub(crate) drawn: HashSet<NodeKey>,
    colour: ColorBy,
    /// How hidden nodes are culled during selection.
    pub occlusion: Occlusion,
    /// Cells per side of the coarse depth buffer of software occlusion culling.
    pub occlusion_size: u32,
    /// The nodes the last frame's occlusion queries found hidden (`Occlusion::Queries`).
    hidden: Arc<HashSet<NodeKey>>,
    /// The nodes the software test culled that the last queries found showing
    /// (`Occlusion::Checked`): not culled by it until they are hidden again.
    shown: Arc<HashSet<NodeKey>>,
    /// The view and nodes drawn when the seen ones were last tested ([`view_hash`]).
    queried_view: Option<u64>,
    /// Whether a frame waits for its occlusion queries' results (else they are read in a later
    /// frame, when the GPU has them: the viewer's way).
    pub query_wait: bool,
    /// With `query_wait`: the nodes a selection culled as hidden are queried against the frame
    /// just drawn, and those that show are drawn in the same frame (Scheiblauer 2006, as Gobbetti
    /// and Marton schedule the queries), not from the next one.
    pub same_frame: bool,
    /// Queries submitted and not read yet, and their nodes.
    pending: Option<(crate::QueryTicket, Vec<NodeKey>)>,
    /// Most bytes uploaded to the GPU in one frame (the rest follow in later frames).
    pub upload_limit: usize,
    /// Prefetching (Goswami et al. 2010): nodes of the view widened by this factor are loaded
    /// ahead, at most [`PREFETCH_NODES`] a frame; 1 or less: off.
    pub prefetch: f64,
    /// `mwkd`: a front node not loaded yet that nothing drawn last frame can stand in for (it
    /// has just come into view) has its nearest ancestor on the GPU drawn in its place (on by
    /// default; off only to measure what it gives: `bench prefetch`).
    pub ancestor_stand_ins: bool,
    /// `mwkd`: how far behind their place stand-ins are drawn, as a share of their distance
    /// ([`crate::Draw::behind`]): they fill holes and lose to loaded detail where they overlap
    /// it. 0: in place (`bench prefetch --behind` measures it).
    pub stand_ins_behind: f32,
    /// The selection thread, started by the first threaded frame.
    selector: Option<Selector>,
    /// The newest answer of the selection thread for this scene alone (before a shared budget).
    alone: Option<crate::selector::Answer>,
    /// The settings the loader threads make nodes' GPU words for ([`words`]).
    prepared_for: Option<words::Words>,
    /// Nodes uploaded with the words the loader made, and encoded at their upload.
    pub uploads_prepared: usize,
    pub uploads_encoded: usize,
}

/// How far behind their place `mwkd` stand-ins are drawn by default, as a share of their
/// distance from the camera (measured with `bench prefetch --behind`: the guide's figures).
pub const STAND_INS_BEHIND: f32 = 0.01;

/// How much wider than the view prefetching looks by default.
pub const DEFAULT_PREFETCH: f64 = 1.3;
pub use crate::selector::PREFETCH_NODES;

/// Most times a frame that waits for its queries selects and draws again for the culled nodes
/// they found showing ([`Scene::same_frame`]).
pub const REVEAL_ROUNDS: usize = 4;

/// Memory for hierarchy pages a scene keeps by default (about 1.5 million nodes' entries).
pub const DEFAULT_HIERARCHY_BYTES: usize = 256 << 20;

/// What a frame did.
#[derive(Debug, Clone, Default)]
pub struct FrameStats {
    /// Selected nodes and their points.
    pub selected_nodes: usize,
    pub selected_points: u64,
    /// Drawn (selected and on the GPU).
    pub nodes: usize,
    pub points: u64,
    /// Nodes uploaded to the GPU in this frame, and their bytes.
    pub uploads: usize,
    pub upload_bytes: usize,
    /// Bytes the point pass reads for the drawn points (the position words it needs, colours,
    /// splat codes: [`crate::Rasterizer::bytes_read`]).
    pub read_bytes: u64,
    /// Points on the GPU and the bytes they take (the GPU cache).
    pub gpu_points: u64,
    pub gpu_bytes: usize,
    /// Loads queued or being read after this frame (nodes and hierarchy pages).
    pub in_flight: usize,
    /// Hierarchy pages the selection wants and does not have (queued, being read).
    pub pages_wanted: usize,
    /// Hierarchy pages loaded and the memory they take.
    pub hierarchy_pages: usize,
    pub hierarchy_bytes: usize,
    /// Every selected node drawn (or failed to load).
    pub complete: bool,
    /// Selected nodes not drawn whose region nothing drawn stands in for (no ancestor and no
    /// descendant drawn): where the frame has a hole.
    pub holes: usize,
    /// Nodes culled as hidden.
    pub culled: usize,
    /// On the frame thread: selecting (or, threaded, asking and taking the answer).
    pub select: Duration,
    /// Threaded frames: how long the traversal drawn took on the selection thread (zero before
    /// the first answer), how many requests are newer than it, and whether it was made for this
    /// frame's camera (always, unthreaded).
    pub select_thread: Duration,
    pub select_lag: u64,
    pub select_current: bool,
    /// The point budget the drawn selection was made with (a threaded frame's may be an
    /// earlier frame's budget).
    pub select_budget: u64,
    pub upload: Duration,
    pub draw: Duration,
    /// Occlusion queries after the frame (`Occlusion::Queries`).
    pub query: Duration,
    /// Nodes the selection culled as hidden that this frame's queries found showing, and drew
    /// in this frame ([`Scene::same_frame`]).
    pub revealed: usize,
}

impl Scene {
    /// A scene over `hierarchy` read through `reader` by `threads` loader threads, with RAM and
    /// GPU caches of `ram_bytes` and `gpu_bytes`.
    pub fn new(
        reader: Arc<dyn PageReader>,
        hierarchy: Hierarchy,
        view_bounds: Aabb,
        threads: usize,
        ram_bytes: usize,
        gpu_bytes: usize,
    ) -> Scene {
        let mut scene = Scene {
            origin: hierarchy.root.center(),
            grid: None,
            f32_positions: false,
            hierarchy: Arc::new(hierarchy),
            pages: PageCache::new(DEFAULT_HIERARCHY_BYTES),
            loader: Loader::new(reader, threads, ram_bytes),
            buffers: NodeBuffers::new(gpu_bytes),
            z_range: (view_bounds.min[2], view_bounds.max[2]),
            view_bounds,
            last: Selection::default(),
            drawn: HashSet::new(),
            colour: ColorBy::Rgb,
            occlusion: Occlusion::Checked,
            occlusion_size: myriad_lod::occlusion::DEFAULT_SIZE,
            hidden: Default::default(),
            shown: Default::default(),
            queried_view: None,
            query_wait: true,
            same_frame: true,
            pending: None,
            upload_limit: usize::MAX,
            prefetch: DEFAULT_PREFETCH,
            ancestor_stand_ins: true,
            stand_ins_behind: STAND_INS_BEHIND,
            selector: None,
            alone: None,
            prepared_for: None,
            uploads_prepared: 0,
            uploads_encoded: 0,
        };
        scene.prepare_words(scene.words());
        scene
    }

    /// A scene over a dataset, of whose hierarchy only the root page is read (an empty scene
    /// when it is damaged: check [`myriad_format::Dataset::hierarchy_page`] first to say so).
    /// The view bounds are those of the root node's points (a sample of the whole) without the
    /// outer 0.5 % on each side of each axis.
    pub fn open(dataset: Arc<myriad_format::Dataset>, ram_bytes: usize, gpu_bytes: usize) -> Scene {
        Scene::open_filtered(dataset, myriad_measure::Bound::all(), ram_bytes, gpu_bytes)
    }

    /// [`Scene::open`] drawing only the points `filter` keeps.
    pub fn open_filtered(
        dataset: Arc<myriad_format::Dataset>,
        filter: myriad_measure::Bound,
        ram_bytes: usize,
        gpu_bytes: usize,
    ) -> Scene {
        let meta = &dataset.meta;
        let mut h = match dataset.hierarchy_page(&dataset.root_page()) {
            Ok(page) => Hierarchy::from_root_page(meta.root, page, meta.depth),
            Err(_) => Hierarchy::new(meta.root, []),
        };
        let mut view_bounds = meta.bounds;
        let mut root_node = None;
        if let Some(root) = h.get(&NodeKey::ROOT).filter(|n| n.points > 0)
            && let Ok(b) = dataset.read_node(root)
        {
            let sample = robust_bounds(&b.positions, 0.005);
            if !sample.is_empty() {
                view_bounds = sample;
            }
            // Resident from the start (the first frame draws it), unless it has splats to read.
            if root.splats.is_none() {
                let mut b = b;
                filter.retain(&mut b);
                root_node = Some(myriad_lod::stream::Loaded {
                    points: b,
                    splats: None,
                    prepared: None,
                });
            }
        }
        // Normal cones cull only where normals have a sign (the input's, or estimated ones
        // turned towards their scanners): others were turned up, so a ceiling would face its
        // room from behind.
        h.cull_backfaces = matches!(
            dataset
                .meta
                .parameters
                .get("normals")
                .and_then(|v| v.as_str()),
            Some("input" | "oriented")
        );
        let threads = std::thread::available_parallelism().map_or(2, |n| n.get().clamp(2, 8));
        let grid = meta.quantization;
        let reader: Arc<dyn PageReader> = if filter.is_all() {
            dataset
        } else {
            Arc::new(myriad_lod::stream::Filtered {
                inner: dataset,
                filter,
            })
        };
        let mut scene = Scene::new(reader, h, view_bounds, threads, ram_bytes, gpu_bytes);
        scene.grid = Some(grid);
        let words = scene.words();
        scene.prepare_words(words);
        if let (Some(mut n), Some(e)) = (root_node, scene.hierarchy.get(&NodeKey::ROOT).cloned()) {
            n.prepared = Some(words.prepare(&e, &n));
            scene.loader.insert(NodeKey::ROOT, n);
        }
        scene
    }

    /// Reads every hierarchy page now, on this thread, and keeps them all (what needs every
    /// node: a reference image of every point). Damaged pages are left out; returns them.
    pub fn read_every_page(
        &mut self,
        dataset: &myriad_format::Dataset,
    ) -> Vec<myriad_format::hierarchy::ChildPage> {
        self.pages.budget = usize::MAX;
        let h = Arc::make_mut(&mut self.hierarchy);
        let mut damaged = Vec::new();
        loop {
            let todo: Vec<_> = h
                .unloaded()
                .into_iter()
                .filter(|p| !damaged.contains(p))
                .collect();
            if todo.is_empty() {
                return damaged;
            }
            for p in todo {
                match dataset.hierarchy_page(&p) {
                    Ok(page) => {
                        h.insert_page(p.key, page);
                    }
                    Err(_) => damaged.push(p),
                }
            }
        }
    }

    /// Changing the scheme drops the GPU buffers (colours are baked into them).
    pub fn set_colour(&mut self, c: ColorBy) {
        if c != self.colour {
            self.colour = c;
            self.buffers.clear();
            self.prepare_words(self.words());
        }
    }

    /// The point drawn nearest the eye within `radius` pixels of pixel (`x`, `y`) of the last
    /// frame seen by `camera`, searched among the resident nodes it drew.
    pub fn pick(&self, camera: &Camera, x: f64, y: f64, radius: f64) -> Option<Picked> {
        let focal = camera.focal();
        let (cx, cy) = (camera.width as f64 / 2.0, camera.height as f64 / 2.0);
        let mut best: Option<Picked> = None;
        for n in &self.last.nodes {
            let Some(batch) = self.loader.get(&n.key) else {
                continue;
            };
            for (i, &p) in batch.positions[..(n.points as usize).min(batch.len())]
                .iter()
                .enumerate()
            {
                let e = camera.to_eye(p);
                if e[2] <= camera.near {
                    continue;
                }
                let dx = cx + e[0] * focal / e[2] - x;
                let dy = cy - e[1] * focal / e[2] - y;
                if dx * dx + dy * dy > radius * radius {
                    continue;
                }
                if best.as_ref().is_none_or(|b| e[2] < b.depth) {
                    best = Some(Picked {
                        position: p,
                        depth: e[2],
                        node: n.key,
                        batch: batch.clone(),
                        index: i,
                    });
                }
            }
        }
        best
    }

    pub fn colour(&self) -> ColorBy {
        self.colour
    }

    /// Selects for `camera`, requests what is missing and takes in what has landed, without
    /// waiting for anything.
    pub fn update(&mut self, camera: &Camera, options: &SelectOptions) -> Selection {
        self.update_clipped(camera, options, None)
    }

    /// [`Scene::update`] skipping the nodes a clipping box hides entirely.
    pub fn update_clipped(
        &mut self,
        camera: &Camera,
        options: &SelectOptions,
        clip: Option<crate::Clip>,
    ) -> Selection {
        let selection = self.select(camera, options, clip);
        self.take(&selection);
        selection
    }

    /// This scene's selection alone, culling hidden nodes as [`Scene::occlusion`] says (the
    /// resident nodes hide those behind them).
    pub fn select(
        &self,
        camera: &Camera,
        options: &SelectOptions,
        clip: Option<crate::Clip>,
    ) -> Selection {
        crate::selector::select_for(
            &self.hierarchy,
            camera,
            options,
            self.culling(clip),
            &|k| self.loader.get(k),
            crate::selector::Queried {
                hidden: &self.hidden,
                shown: &self.shown,
            },
            &self.previous(),
        )
    }

    /// The front the last selection chose (`mwkd`: the next one is updated from it).
    fn previous(&self) -> Vec<NodeKey> {
        if !self.hierarchy.splats() {
            return Vec::new();
        }
        self.last.nodes.iter().map(|n| n.key).collect()
    }

    /// This scene's culling settings with `clip`.
    fn culling(&self, clip: Option<crate::Clip>) -> crate::selector::Culling {
        crate::selector::Culling {
            clip,
            occlusion: self.occlusion,
            occlusion_size: self.occlusion_size,
            prefetch: self.prefetch,
        }
    }

    /// Selects and waits until every selected node is in (or failed to load), selecting again
    /// as pages land (resident nodes hide others, finer nodes become wanted): the converged
    /// view's selection.
    pub fn converge(
        &mut self,
        camera: &Camera,
        options: &SelectOptions,
        clip: Option<crate::Clip>,
    ) -> Selection {
        self.converge_with(&|scene: &Scene| scene.select(camera, options, clip))
    }

    /// [`Scene::converge`] for any selection (`select`: this scene's, e.g. both eyes' at once).
    pub fn converge_with(&mut self, select: &dyn Fn(&Scene) -> Selection) -> Selection {
        loop {
            let s = select(self);
            self.take(&s);
            // A page the selection wanted that has not failed is either still coming or has
            // landed since (then the view refines: select again).
            let missing = |scene: &Scene| {
                let failed = scene.loader.failed_pages();
                s.nodes.iter().any(|n| {
                    scene.hierarchy.get(&n.key).is_some_and(|e| e.points > 0)
                        && !scene.loader.is_resident(&n.key)
                        && !scene.loader.failed().contains_key(&n.key)
                }) || s.pages.iter().any(|p| !failed.contains_key(&p.key))
            };
            if !missing(self) {
                return s;
            }
            while self.loader.in_flight() > 0 && missing(self) {
                if self.poll() == 0 {
                    std::thread::sleep(Duration::from_millis(1));
                }
            }
        }
    }

    /// Requests what `selection` needs (nodes, and the hierarchy pages it would refine into)
    /// and takes in what has landed, without waiting; drops the hierarchy pages unused longest
    /// while they take more than the budget.
    pub fn take(&mut self, selection: &Selection) {
        let parents = self.parents_wanted(selection);
        let wanted: Vec<NodeEntry> = (parents.iter())
            .filter_map(|k| self.hierarchy.get(k).cloned())
            .chain((selection.nodes.iter()).filter_map(|n| self.hierarchy.get(&n.key).cloned()))
            .collect();
        // An answer of the selection thread may ask for pages that landed since.
        let pages: Vec<_> = (selection.pages.iter())
            .filter(|p| !self.hierarchy.has_page(&p.key))
            .copied()
            .collect();
        self.loader.request_with_pages(&wanted, &pages);
        let ahead: Vec<NodeEntry> = (selection.prefetch.iter())
            .filter_map(|k| self.hierarchy.get(k).cloned())
            .collect();
        self.loader.prefetch(&ahead);
        self.poll();
        self.pages.touch(selection);
        self.pages.evict(&mut self.hierarchy);
    }

    /// `mwkd`: the parents of front nodes with no ancestor on the GPU (just come into view),
    /// to read first and upload, so that they can stand in for their children while those load.
    pub(crate) fn parents_wanted(&self, selection: &Selection) -> Vec<NodeKey> {
        let mut out = Vec::new();
        if !self.hierarchy.splats() || !self.ancestor_stand_ins {
            return out;
        }
        let mut seen = HashSet::new();
        for n in selection.nodes.iter().filter(|n| n.key.level > 0) {
            let mut k = n.key;
            let mut covered = self.buffers.contains(&k);
            while !covered && k.level > 0 {
                k = k.parent();
                covered = self.buffers.contains(&k);
            }
            if !covered && seen.insert(n.key.parent()) {
                out.push(n.key.parent());
            }
        }
        out
    }

    /// Takes in the nodes and hierarchy pages that have landed; never waits. How many came
    /// back.
    pub fn poll(&mut self) -> usize {
        let n = self.loader.poll();
        let landed = self.loader.take_pages();
        if !landed.is_empty() {
            // The selection thread keeps the copy it has; the next request carries this one.
            let h = Arc::make_mut(&mut self.hierarchy);
            for (key, page) in landed {
                h.insert_page(key, page);
            }
        }
        n
    }

    /// The hierarchy pages `selection` wants that are neither loaded nor failed.
    pub fn pages_missing(&self, selection: &Selection) -> usize {
        let failed = self.loader.failed_pages();
        selection
            .pages
            .iter()
            .filter(|p| !self.hierarchy.has_page(&p.key) && !failed.contains_key(&p.key))
            .count()
    }

    /// `mwkd` (Goswami et al. 2010, section IV, transitions): for each front node not on the GPU
    /// yet, what was drawn in the last frame in its place and still is on the GPU: its nearest such
    /// ancestor (the front refined), else such descendants (the front coarsened). Until the node
    /// lands, they are drawn instead, so the view never has a hole where it had points.
    fn stand_ins(&self, selection: &Selection) -> Vec<NodeKey> {
        if !self.hierarchy.splats() {
            return Vec::new();
        }
        let mut out = Vec::new();
        let mut seen = HashSet::new();
        let usable = |k: &NodeKey| self.drawn.contains(k) && self.buffers.contains(k);
        for n in &selection.nodes {
            if self.buffers.contains(&n.key) {
                continue;
            }
            let mut k = n.key;
            let mut found = false;
            while k.level > 0 {
                k = k.parent();
                if usable(&k) {
                    found = true;
                    if seen.insert(k) {
                        out.push(k);
                    }
                    break;
                }
            }
            if !found {
                let mut below: Vec<NodeKey> = self
                    .drawn
                    .iter()
                    .filter(|d| d.level > n.key.level && d.is_within(&n.key) && usable(d))
                    .copied()
                    .collect();
                below.sort();
                found = !below.is_empty();
                for d in below {
                    if seen.insert(d) {
                        out.push(d);
                    }
                }
            }
            // Nothing was drawn there (the node has just come into view): its nearest
            // ancestor on the GPU, whose aggregates cover its subtree.
            if !found && self.ancestor_stand_ins {
                let mut k = n.key;
                while k.level > 0 {
                    k = k.parent();
                    if self.buffers.contains(&k) {
                        if seen.insert(k) {
                            out.push(k);
                        }
                        break;
                    }
                }
            }
        }
        out
    }

    /// Selected nodes not on the GPU whose region nothing drawn stands in for: no ancestor
    /// drawn (an octree's are drawn whole wherever a child is selected, their points sized for
    /// the children missing), no descendant drawn (`mwkd`'s stand-ins). `drawn`: the keys a
    /// frame drew.
    pub(crate) fn holes(&self, selection: &Selection, drawn: &HashSet<NodeKey>) -> usize {
        let failed = self.loader.failed();
        (selection.nodes.iter())
            .filter(|n| !self.buffers.contains(&n.key) && !failed.contains_key(&n.key))
            .filter(|n| {
                let mut k = n.key;
                while k.level > 0 {
                    k = k.parent();
                    if drawn.contains(&k) {
                        return false;
                    }
                }
                !drawn
                    .iter()
                    .any(|d| d.level > n.key.level && d.is_within(&n.key))
            })
            .count()
    }

    /// The draws of `selection` whose buffers are on the GPU (and, `mwkd`, the stand-ins of
    /// those that are not), the keys drawn, and the drawn tree they index, its entries numbered
    /// from `base` (for a frame of several scenes).
    pub(crate) fn draws(
        &self,
        selection: &Selection,
        base: u32,
    ) -> (Vec<Draw<'_>>, Vec<[u32; 4]>, HashSet<NodeKey>) {
        // Points sized per point from the drawn tree where nodes are octree cells; per node
        // (the selection's spacing) in kd-trees.
        let cells = self.hierarchy.cells();
        let tree = if cells {
            DrawnTree::new(selection, &self.hierarchy, |k| self.buffers.contains(k))
        } else {
            DrawnTree::default()
        };
        let draws = selection
            .nodes
            .iter()
            .filter_map(|n| {
                let p = self.buffers.get(&n.key)?;
                // A filtered node holds fewer points than the selection counted: the same share
                // of those kept (the kept points keep their level-of-detail order).
                let total = self.hierarchy.get(&n.key).map_or(p.len, |e| e.points);
                let count = if p.len < total {
                    (n.points as u64 * p.len as u64).div_ceil(total as u64) as u32
                } else {
                    n.points
                };
                let mut d = p.prefix(count, n.spacing);
                // A leaf drawn whole: its lone points are lone in the dataset.
                d.lone = self.hierarchy.is_leaf(&n.key) && count == p.len;
                if cells {
                    // At most its drawn ancestors' spacing (the tree's).
                    d.spacing = tree.spacing(&n.key).unwrap_or(n.spacing);
                    d.node = Some((tree.index[&n.key] + base, self.hierarchy.bounds(&n.key)));
                }
                Some((n.key, d))
            })
            .chain(self.stand_ins(selection).into_iter().filter_map(|k| {
                let p = self.buffers.get(&k)?;
                let spacing = self.hierarchy.get(&k)?.spacing.first().copied()?;
                let mut d = p.all(spacing);
                d.behind = self.stand_ins_behind;
                Some((k, d))
            }))
            .collect::<Vec<_>>();
        let keys = draws.iter().map(|(k, _)| *k).collect();
        let draws = draws.into_iter().map(|(_, d)| d).collect();
        let entries = tree
            .entries
            .iter()
            .map(|&[mask, first, spacing, pad]| [mask, first + base, spacing, pad])
            .collect();
        (draws, entries, keys)
    }

    /// What a frame of `selection` did, given what was drawn.
    pub(crate) fn stats(&self, selection: &Selection, draws: &[Draw]) -> FrameStats {
        let failed = self.loader.failed();
        FrameStats {
            gpu_points: self.buffers.values().map(|p| p.len as u64).sum(),
            gpu_bytes: self.buffers.bytes(),
            selected_nodes: selection.nodes.len(),
            selected_points: selection.points,
            culled: selection.culled,
            nodes: draws.len(),
            points: draws.iter().map(|d| d.count as u64).sum(),
            in_flight: self.loader.in_flight(),
            pages_wanted: self.pages_missing(selection),
            hierarchy_pages: self.hierarchy.pages(),
            hierarchy_bytes: self.hierarchy.bytes(),
            complete: selection
                .nodes
                .iter()
                .all(|n| self.buffers.contains(&n.key) || failed.contains_key(&n.key))
                && self.pages_missing(selection) == 0,
            ..Default::default()
        }
    }

    /// What the selection thread needs to select for `camera`: the options, and the resident
    /// points of the nodes selected last (what occlusion culling splats).
    fn request(
        &self,
        camera: &Camera,
        options: &SelectOptions,
        clip: Option<crate::Clip>,
    ) -> Request {
        let resident: HashMap<NodeKey, Arc<myriad_lod::stream::Loaded>> = self
            .last
            .nodes
            .iter()
            .map(|n| n.key)
            .chain(self.drawn.iter().copied())
            .filter_map(|k| Some((k, self.loader.get(&k)?)))
            .collect();
        Request {
            hierarchy: self.hierarchy.clone(),
            camera: *camera,
            options: *options,
            culling: self.culling(clip),
            resident,
            hidden: self.hidden.clone(),
            shown: self.shown.clone(),
            previous: self.previous(),
        }
    }

    /// [`Scene::frame`] with the selection on its own thread ([`frame_many_threaded`]).
    pub fn frame_threaded(
        &mut self,
        gpu: &Gpu,
        raster: &Rasterizer,
        camera: &Camera,
        options: &SelectOptions,
        style: &Style,
    ) -> (Vec<u8>, FrameStats) {
        let (image, mut stats) =
            frame_many_threaded(&mut [self], gpu, raster, camera, options, style);
        (image, stats.remove(0))
    }

    /// One frame: select, load (never waiting), upload, draw; the image and what it took.
    pub fn frame(
        &mut self,
        gpu: &Gpu,
        raster: &Rasterizer,
        camera: &Camera,
        options: &SelectOptions,
        style: &Style,
    ) -> (Vec<u8>, FrameStats) {
        let t = Instant::now();
        let mut selection = self.update_clipped(camera, options, style.clip);
        let select = t.elapsed();
        let queries = self.occlusion.queries();
        let render = |draws: &[Draw], tree: &[[u32; 4]]| {
            if queries {
                raster.keep_depth();
            }
            let image = raster.render(gpu, camera, draws, tree, style);
            (image, raster.bytes_read(gpu, camera, draws, style))
        };
        let (mut image, mut stats, mut keys) =
            self.draw_selected(gpu, &selection, select, options, render);
        // Nodes culled that show are drawn in this frame: selected and drawn again, as long as
        // that reveals more (a node revealed brings its subtree back, and the software test
        // may cull others behind what is drawn now).
        let (mut select, mut query, mut revealed) = (select, Duration::ZERO, 0);
        // Whether the culled nodes of the selection drawn were all queried and none showed.
        let mut still_hidden = false;
        for _ in 0..REVEAL_ROUNDS {
            if !(queries && self.query_wait && self.same_frame) {
                break;
            }
            let t = Instant::now();
            let more = self.reveal(gpu, raster, &selection);
            query += t.elapsed();
            if more == 0 {
                still_hidden = true;
                break;
            }
            revealed += more;
            let t = Instant::now();
            selection = self.update_clipped(camera, options, style.clip);
            select += t.elapsed();
            (image, stats, keys) = self.draw_selected(gpu, &selection, select, options, render);
        }
        stats.revealed = revealed;
        stats.query = query;
        let t = Instant::now();
        self.query_hidden(gpu, raster, camera, &selection, still_hidden);
        stats.query += t.elapsed();
        self.drawn = keys;
        self.last = selection;
        (image, stats)
    }

    /// The rest of a frame of `selection` (taken in, made in `select`): uploads, the draws
    /// drawn by `render` (the image and the bytes the point pass read), the frame's statistics
    /// and the keys drawn.
    pub(crate) fn draw_selected(
        &mut self,
        gpu: &Gpu,
        selection: &Selection,
        select: Duration,
        options: &SelectOptions,
        render: impl FnOnce(&[Draw], &[[u32; 4]]) -> (Vec<u8>, u64),
    ) -> (Vec<u8>, FrameStats, HashSet<NodeKey>) {
        let t = Instant::now();
        let (uploads, upload_bytes) = self.upload(gpu, selection);
        let upload = t.elapsed();
        let t = Instant::now();
        let (draws, tree, keys) = self.draws(selection, 0);
        let (image, read_bytes) = render(&draws, &tree);
        let mut stats = FrameStats {
            uploads,
            upload_bytes,
            read_bytes,
            select,
            select_current: true,
            select_budget: options.budget,
            upload,
            ..self.stats(selection, &draws)
        };
        drop(draws);
        stats.holes = self.holes(selection, &keys);
        stats.draw = t.elapsed();
        (image, stats, keys)
    }
}
