//! A build drawn while it runs (issue 41): what `convert` has written so far, made readable as a
//! dataset every so often ([`Growing::latest`]), for `view` and `serve` to show until the
//! dataset is complete.
//!
//! The octree's chunks are built one by one (largest first) and each one's nodes below its root
//! are written as they are made; the chunks' roots and the levels above them come at the end.
//! A snapshot ([`DatasetWriter::snapshot`]) holds every node written so far, stand-ins for the
//! nodes above them (empty: the selection passes through them to what lies below, and draws the
//! coarsest level of a node none of whose ancestors has points, however fine), and, in the
//! chunk cells with nothing built below their roots yet, the scan's preview (the sample read without decoding,
//! [`crate::cached::preview_batch`]): the preview fills what is not built, the build replaces it
//! chunk by chunk. The file is not changed by a snapshot: the finished dataset is the one
//! `convert` writes without it.

use myriad_core::{Aabb, NodeKey, PointBatch, Schema};
use myriad_format::{Dataset, DatasetWriter, Metadata, NodeEntry, PageRef, Snapshot};
use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How often a snapshot is made while the chunks are built, unless asked otherwise.
pub const DEFAULT_EVERY: Duration = Duration::from_secs(1);

/// One snapshot of a build: its number (counting from 1), the dataset it reads as, its bytes,
/// and how far the build had come.
#[derive(Clone)]
pub struct Shown {
    pub version: u64,
    pub dataset: Arc<Dataset>,
    pub bytes: Arc<Snapshot>,
    /// Chunks built, of all chunks.
    pub built: usize,
    pub chunks: usize,
}

/// The shared state of a build drawn while it runs: given to `convert`
/// ([`crate::convert::ConvertOptions::growing`]), read by whoever draws it.
pub struct Growing {
    every: Duration,
    fill: Mutex<Option<PointBatch>>,
    latest: Mutex<Option<Shown>>,
    last: Mutex<Option<Instant>>,
    /// Held while a snapshot is made (one at a time; others skip theirs).
    making: Mutex<()>,
    /// Where the viewer looks: the chunks nearest it are built first.
    focus: Mutex<Option<[f64; 3]>>,
    /// The chunks built, in the order they were.
    order: Mutex<Vec<NodeKey>>,
    /// Points sampled from what the build decodes (every `stride`th), added to the fill.
    decoded: Mutex<Decoded>,
}

#[derive(Default)]
struct Decoded {
    stride: u64,
    seen: u64,
    points: Option<PointBatch>,
}

/// Most points sampled from what a build decodes (about 10 MB).
pub const DECODED_SAMPLE: u64 = 1 << 18;

impl std::fmt::Debug for Growing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Growing")
            .field("every", &self.every)
            .finish_non_exhaustive()
    }
}

impl Growing {
    /// A snapshot at most every `every` while chunks are built, and one when they all are.
    pub fn new(every: Duration) -> Arc<Growing> {
        Arc::new(Growing {
            every,
            fill: Mutex::new(None),
            latest: Mutex::new(None),
            last: Mutex::new(None),
            making: Mutex::new(()),
            focus: Mutex::new(None),
            order: Mutex::new(Vec::new()),
            decoded: Mutex::new(Decoded::default()),
        })
    }

    /// The build will read about `points`: one point in `points / DECODED_SAMPLE` is sampled.
    pub(crate) fn expect(&self, points: u64) {
        let mut d = self.decoded.lock().expect("decoded lock");
        d.stride = (points / DECODED_SAMPLE).max(1);
    }

    /// Samples the points just decoded (positions, intensity, class, colour) into the fill.
    pub(crate) fn sample(&self, b: &PointBatch) {
        let mut d = self.decoded.lock().expect("decoded lock");
        let stride = d.stride.max(1);
        let first = (stride - d.seen % stride) % stride;
        d.seen += b.len() as u64;
        let idx: Vec<u32> = (first..b.len() as u64)
            .step_by(stride as usize)
            .map(|i| i as u32)
            .collect();
        if idx.is_empty() {
            return;
        }
        let mut taken = PointBatch {
            positions: idx.iter().map(|&i| b.positions[i as usize]).collect(),
            ..Default::default()
        };
        taken.intensity =
            (b.intensity.as_ref()).map(|v| idx.iter().map(|&i| v[i as usize]).collect());
        taken.classification =
            (b.classification.as_ref()).map(|v| idx.iter().map(|&i| v[i as usize]).collect());
        taken.rgb = (b.rgb.as_ref()).map(|v| idx.iter().map(|&i| v[i as usize]).collect());
        match &mut d.points {
            Some(all) => {
                if all.intensity.is_some() != taken.intensity.is_some()
                    || all.classification.is_some() != taken.classification.is_some()
                    || all.rgb.is_some() != taken.rgb.is_some()
                {
                    return;
                }
                all.append(&taken);
            }
            None => d.points = Some(taken),
        }
    }

    /// The fill: the preview and the points sampled from what is decoded so far.
    fn fill(&self) -> Option<PointBatch> {
        let preview = self.fill.lock().expect("fill lock").clone();
        let decoded = self.decoded.lock().expect("decoded lock").points.clone();
        match (preview, decoded) {
            (Some(p), Some(d)) => Some(merge_fill(&p, &d)),
            (p, d) => p.or(d),
        }
    }

    /// While the build reads (nothing written yet): at most every `every`, a snapshot of the
    /// fill alone, a small dataset in memory.
    pub(crate) fn offer_decoded(&self) {
        if !self.due(false) {
            return;
        }
        let Ok(_making) = self.making.try_lock() else {
            return;
        };
        let Some(fill) = self.fill().filter(|f| !f.is_empty()) else {
            return;
        };
        let Some(snap) = fill_snapshot(&fill) else {
            return;
        };
        self.publish(snap, 0, 0);
    }

    /// Whether a snapshot is due: the last is older than `every` (always when `force`).
    fn due(&self, force: bool) -> bool {
        force || !(self.last.lock().expect("last lock")).is_some_and(|t| t.elapsed() < self.every)
    }

    fn publish(&self, snap: Snapshot, built: usize, chunks: usize) {
        let bytes = Arc::new(snap);
        let name = std::path::PathBuf::from("(being built)");
        let Ok(ds) = Dataset::from_source(bytes.clone(), &name) else {
            return;
        };
        *self.last.lock().expect("last lock") = Some(Instant::now());
        let mut latest = self.latest.lock().expect("latest lock");
        let version = latest.as_ref().map_or(1, |s| s.version + 1);
        *latest = Some(Shown {
            version,
            dataset: Arc::new(ds),
            bytes,
            built,
            chunks,
        });
    }

    /// Where the viewer looks (the camera's target), or `None`: the chunks still to build that
    /// are nearest this point are built next (else the largest first).
    pub fn set_focus(&self, at: Option<[f64; 3]>) {
        *self.focus.lock().expect("focus lock") = at.filter(|p| p.iter().all(|v| v.is_finite()));
    }

    pub fn focus(&self) -> Option<[f64; 3]> {
        *self.focus.lock().expect("focus lock")
    }

    /// The chunks built so far (their cells), in the order they were built.
    pub fn built_order(&self) -> Vec<NodeKey> {
        self.order.lock().expect("order lock").clone()
    }

    pub(crate) fn built(&self, chunk: NodeKey) {
        self.order.lock().expect("order lock").push(chunk);
    }

    /// The points that stand in for chunks not built yet (the scan's preview: positions and any
    /// of intensity, classification and colour).
    pub fn set_fill(&self, points: PointBatch) {
        *self.fill.lock().expect("fill lock") = Some(points);
    }

    /// The newest snapshot, if one was made.
    pub fn latest(&self) -> Option<Shown> {
        self.latest.lock().expect("latest lock").clone()
    }

    /// Called by the build after each chunk (`built` of `chunks` done): makes a snapshot when
    /// the last is older than `every` (always when `force`), unless another is being made.
    /// A snapshot that fails is skipped: the build goes on.
    pub(crate) fn offer(
        &self,
        writer: &DatasetWriter,
        meta: &Metadata,
        chunks: &[NodeKey],
        built: &Mutex<HashSet<NodeKey>>,
        force: bool,
    ) {
        if !self.due(force) {
            return;
        }
        let Ok(_making) = self.making.try_lock() else {
            return;
        };
        let fill = self.fill();
        // The chunks built before the snapshot's pages are taken: all their nodes are in it.
        let built = built.lock().expect("built lock").clone();
        let snap = writer.snapshot(meta, &|written| {
            stand_ins(written, meta, chunks, &built, fill.as_ref())
        });
        if let Ok(snap) = snap {
            self.publish(snap, built.len(), chunks.len());
        }
    }
}

/// Two fills as one (the columns both have).
fn merge_fill(a: &PointBatch, b: &PointBatch) -> PointBatch {
    let mut out = PointBatch {
        positions: [a.positions.as_slice(), b.positions.as_slice()].concat(),
        ..Default::default()
    };
    if let (Some(x), Some(y)) = (&a.intensity, &b.intensity) {
        out.intensity = Some([x.as_slice(), y.as_slice()].concat());
    }
    if let (Some(x), Some(y)) = (&a.classification, &b.classification) {
        out.classification = Some([x.as_slice(), y.as_slice()].concat());
    }
    if let (Some(x), Some(y)) = (&a.rgb, &b.rgb) {
        out.rgb = Some([x.as_slice(), y.as_slice()].concat());
    }
    out
}

/// A dataset of the fill alone, in memory: its points in the cells of level 2 of a cube around
/// them (level 0 when few), empty nodes above.
fn fill_snapshot(fill: &PointBatch) -> Option<Snapshot> {
    use myriad_format::Quantization;
    let mut bounds = Aabb::EMPTY;
    for p in &fill.positions {
        bounds.extend(*p);
    }
    let side = (0..3)
        .map(|a| bounds.max[a] - bounds.min[a])
        .fold(0.0f64, f64::max)
        .max(1e-3)
        * 1.001;
    let root = Aabb::new(bounds.min, std::array::from_fn(|a| bounds.min[a] + side));
    let schema = fill.schema();
    let meta = Metadata {
        structure: "nested-octree".into(),
        parameters: serde_json::json!({}),
        points: 0,
        nodes: 0,
        depth: 0,
        bounds,
        root,
        quantization: Quantization {
            scale: [side / f64::from(1u32 << 30); 3],
            offset: root.min,
        },
        crs: None,
        schema,
        sources: Vec::new(),
        las_header: None,
        levels: Vec::new(),
        files: Vec::new(),
        software: format!("myriad {}", env!("CARGO_PKG_VERSION")),
    };
    let level = if fill.len() < 20_000 { 0 } else { 2 };
    let cells: HashSet<NodeKey> = (fill.positions.iter())
        .map(|p| cell_of(*p, &root, level))
        .collect();
    let cells: Vec<NodeKey> = cells.into_iter().collect();
    let nodes = stand_ins(&[], &meta, &cells, &HashSet::new(), Some(fill));
    Snapshot::in_memory(&meta, nodes).ok()
}

/// The cell of level `level` holding `p` (clamped into the root cube).
fn cell_of(p: [f64; 3], root: &Aabb, level: u32) -> NodeKey {
    let n = 1u64 << level;
    let side = root.size()[0] / n as f64;
    let cell = std::array::from_fn(|a| {
        let c = ((p[a] - root.min[a]) / side).floor();
        c.clamp(0.0, (n - 1) as f64) as u32
    });
    NodeKey { level, cell }
}

/// `points` with every column of `schema`: those it has copied, the others zero.
fn conform(points: &PointBatch, schema: &Schema) -> PointBatch {
    let n = points.len();
    let mut b = PointBatch::with_schema(schema, n);
    let zeros = vec![0u8; b.row_size()];
    for _ in 0..n {
        b.push_row(&zeros);
    }
    b.positions.clone_from(&points.positions);
    if let (Some(to), Some(from)) = (&mut b.intensity, &points.intensity) {
        to.clone_from(from);
    }
    if let (Some(to), Some(from)) = (&mut b.classification, &points.classification) {
        to.clone_from(from);
    }
    if let (Some(to), Some(from)) = (&mut b.rgb, &points.rgb) {
        to.clone_from(from);
    }
    b
}

/// What a snapshot adds to the nodes `written`: in each of the `chunks` (cells that split the
/// root cube between them) not `built` (or built with nothing written below its root yet), the
/// fill's points in it, as its node; and an empty node for every ancestor not written.
fn stand_ins(
    written: &[NodeEntry],
    meta: &Metadata,
    chunks: &[NodeKey],
    built: &HashSet<NodeKey>,
    fill: Option<&PointBatch>,
) -> Vec<(NodeEntry, Vec<u8>)> {
    let root = meta.root;
    let spacing = |k: &NodeKey| root.size()[0] / (1u64 << k.level) as f64 / 128.0;
    let have: HashSet<NodeKey> = written.iter().map(|e| e.key).collect();
    // Cells with written nodes below them.
    let mut under: HashSet<NodeKey> = HashSet::new();
    for k in &have {
        let mut k = *k;
        while k.level > 0 {
            k = k.parent();
            if !under.insert(k) {
                break;
            }
        }
    }
    // Chunks not built, or built but with all their points still in their root (the build
    // writes a chunk's root with the levels above, at the end): the fill shows there.
    let waiting: HashSet<NodeKey> = (chunks.iter())
        .filter(|k| !have.contains(k) && (!built.contains(k) || !under.contains(k)))
        .copied()
        .collect();
    let mut levels: Vec<u32> = chunks.iter().map(|k| k.level).collect();
    levels.sort_unstable();
    levels.dedup();
    let mut out = Vec::new();
    let mut filled: HashSet<NodeKey> = HashSet::new();
    if let Some(fill) = fill.filter(|f| !f.is_empty()) {
        let mut cells: HashMap<NodeKey, Vec<u32>> = HashMap::new();
        for (i, p) in fill.positions.iter().enumerate() {
            let waits = (levels.iter())
                .map(|&l| cell_of(*p, &root, l))
                .find(|k| waiting.contains(k));
            if let Some(k) = waits {
                cells.entry(k).or_default().push(i as u32);
            }
        }
        let all = conform(fill, &meta.schema);
        for (k, idx) in cells {
            let b = all.gather(&idx);
            let page = myriad_format::page::encode(&b, &meta.quantization);
            // Samples spread over a surface in the cell: about side / sqrt(n) apart.
            let side = root.size()[0] / (1u64 << k.level) as f64;
            let e = NodeEntry::new(
                k,
                PageRef::default(),
                b.len() as u32,
                vec![b.len() as u32],
                vec![side / (b.len() as f64).sqrt()],
            );
            filled.insert(k);
            out.push((e, page));
        }
    }
    // Every ancestor of what is there, that is not there.
    let mut above: HashSet<NodeKey> = HashSet::new();
    for k in have.iter().chain(&filled) {
        let mut k = *k;
        while k.level > 0 {
            k = k.parent();
            if have.contains(&k) || filled.contains(&k) || !above.insert(k) {
                break;
            }
        }
    }
    if have.is_empty() && filled.is_empty() {
        above.insert(NodeKey::ROOT);
    }
    for k in above {
        let e = NodeEntry::new(k, PageRef::default(), 0, vec![0], vec![spacing(&k)]);
        out.push((e, Vec::new()));
    }
    out
}
