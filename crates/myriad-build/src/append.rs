//! `convert NEW... --append DATASET` (issue 19): scans added to an octree or layered dataset
//! without building it again.
//!
//! The tree is cut at a level `k` (the one that handles the fewest old points again:
//! [`cut_level`]). Below the cut, each cell's subtree is kept or rebuilt whole:
//! - a cell that the new points fall in is rebuilt from every point it holds: its old subtree's,
//!   the new ones, and the points of the levels above the cut that lie in it (the builder moved
//!   them up from this cell);
//! - any other cell keeps its subtree's pages byte for byte (pages hold their own origin), but
//!   for its top node, which takes back the points above the cut that lie in it (where they fit
//!   in one node; else the cell is rebuilt too).
//!
//! The levels above the cut are then built again from the cells' top nodes, as `convert` builds
//! them ([`nested::build_tops`]), so the new points are represented at every level. Every point
//! of the old dataset and every new one ends in exactly one node. New points outside the old
//! root cube grow the tree: new levels above the old root, whose nodes keep their cubes (and
//! pages), their keys moved down.
//!
//! The dataset is written under a temporary name, read back whole and checked (as `verify`
//! does), and only then renamed over the old one: until then the old dataset is there, whole; a
//! killed or failed append leaves it as it was.
//! Memory: the new points, and per thread one rebuilt cell; refused up front where that exceeds
//! the budget (from the headers' counts, then from the cells to rebuild).

use crate::convert::{self, Report};
use crate::distribute;
use crate::nested::{self, BuiltNode, NestedParams};
use myriad_core::{Aabb, Error, NodeKey, PointBatch, Result};
use myriad_format::{Dataset, DatasetWriter, NodeEntry};
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Most levels the root may grow by (each doubles the cube's side).
const MAX_GROWTH: u32 = 16;

#[derive(Debug, Clone, Default)]
pub struct AppendSummary {
    pub added: u64,
    pub points: u64,
    /// Nodes of the dataset written, every one read back and checked before it replaced the
    /// old one.
    pub nodes: u64,
    /// Nodes built anew and nodes whose pages were copied as they were.
    pub rebuilt: u64,
    pub copied: u64,
    /// The level the tree was cut at, and the cells there rebuilt, of those the dataset has.
    pub cut: u32,
    pub cells_rebuilt: usize,
    pub cells: usize,
    /// Levels added above the old root.
    pub grown: u32,
    pub skipped_non_finite: u64,
    pub bytes: u64,
    pub seconds: f64,
}

/// The level-`level` cell under `root` holding `p` (points on the far faces in the last cell).
pub(crate) fn cell_of(root: &Aabb, level: u32, p: [f64; 3]) -> NodeKey {
    let n = 1u64 << level;
    let side = root.size()[0] / n as f64;
    NodeKey {
        level,
        cell: std::array::from_fn(|a| {
            (((p[a] - root.min[a]) / side).floor().max(0.0) as u64).min(n - 1) as u32
        }),
    }
}

/// The ancestor of `key` at `level` (at most its own level).
fn ancestor(key: NodeKey, level: u32) -> NodeKey {
    let up = key.level - level;
    NodeKey {
        level,
        cell: key.cell.map(|c| c >> up),
    }
}

/// Points of `b` grouped by their level-`level` cell.
fn by_cell(b: PointBatch, root: &Aabb, level: u32) -> HashMap<NodeKey, PointBatch> {
    let mut idx: HashMap<NodeKey, Vec<u32>> = HashMap::new();
    for (i, &p) in b.positions.iter().enumerate() {
        idx.entry(cell_of(root, level, p))
            .or_default()
            .push(i as u32);
    }
    idx.into_iter().map(|(k, v)| (k, b.gather(&v))).collect()
}

/// The level to cut the tree at: the one that handles the fewest old points again, those above
/// the cut (read, given back to their cells, built up again) and those in the cells the new
/// points fall in (rebuilt); the shallower of equals.
fn cut_level(entries: &[NodeEntry], new: &PointBatch, root: &Aabb, top: u32, depth: u32) -> u32 {
    let finest: HashSet<NodeKey> = new
        .positions
        .iter()
        .map(|&p| cell_of(root, depth, p))
        .collect();
    (top..=depth)
        .min_by_key(|&k| {
            let touched: HashSet<NodeKey> = finest.iter().map(|&c| ancestor(c, k)).collect();
            entries
                .iter()
                .filter(|e| e.key.level < k || touched.contains(&ancestor(e.key, k)))
                .map(|e| e.points as u64)
                .sum::<u64>()
        })
        .unwrap_or(top)
}

/// Refuses an append that needs more than `memory` bytes.
fn check_memory(inputs: &[PathBuf], need: u64, memory: u64) -> Result<()> {
    if need <= memory {
        return Ok(());
    }
    let gb = |b: u64| b as f64 / (1u64 << 30) as f64;
    Err(Error::Invalid(format!(
        "{}: appending needs about {:.1} GB in memory (the new points and each rebuilt part of \
         the tree), over the {:.1} GB budget: give --memory, or convert the scans together",
        inputs[0].display(),
        gb(need),
        gb(memory)
    )))
}

/// Adds the points of `inputs` to the dataset at `dataset`, in place, within about `memory`
/// bytes (refused up front where that cannot hold).
pub fn append(
    dataset: &Path,
    inputs: &[PathBuf],
    open: &myriad_io::OpenOptions,
    memory: u64,
    report: &dyn Report,
) -> Result<AppendSummary> {
    let start = Instant::now();
    let (ds, params, entries) = open_dataset(dataset, inputs)?;
    let mut meta = ds.meta.clone();

    // 1. The new points, in the dataset's columns.
    let schema = meta.schema.clone();
    let (new, skipped) = read_new(dataset, inputs, open, memory, &mut meta, report)?;
    let added = new.len() as u64;
    let mut bounds = Aabb::EMPTY;
    for &p in &new.positions {
        bounds.extend(p);
    }

    // 2. A root cube that holds them: the old root becomes a child, then a grandchild, ...
    let (root, grown, offset) = grow_root(meta.root, &bounds, inputs)?;
    let entries = rekeyed(entries, grown, offset);

    // 3. The cut, the cells the new points fall in, and the points above the cut by cell.
    let mut cut = Cut::new(&ds, &entries, new, &root, grown, &params)?;
    let row = PointBatch::with_schema(&schema, 0).row_size() as u64;
    check_memory(
        inputs,
        2 * added * row
            + rayon::current_num_threads() as u64 * cut.largest() * convert::BUILD_BYTES_PER_POINT,
        memory,
    )?;

    let writer = DatasetWriter::create(dataset, true, meta.quantization)?;
    report.phase("building", (cut.cells.len()) as u64);
    // 4. Each cell: its top node for the levels above, the rest written (rebuilt or copied).
    let cells = Cells {
        ds: &ds,
        root: &root,
        params: &params,
        writer: &writer,
    };
    let (roots, mut rebuilt, copied) = cells.build(&mut cut, report)?;

    // 5. The levels above the cut, from the cells' top nodes.
    report.phase("merging", roots.len() as u64);
    for node in nested::build_tops(roots, &root, &params) {
        crate::nodes::write(&writer, node)?;
        rebuilt += 1;
    }
    let (written, _, _) = writer.totals();
    let points = meta.points + added;
    if written != points {
        return Err(Error::Invalid(format!(
            "{}: internal error: {points} points, {written} in the nodes; nothing appended",
            dataset.display()
        )));
    }
    report.phase("writing", 1);
    meta.points = points;
    meta.bounds = meta.bounds.union(&bounds);
    meta.root = root;
    meta.software = format!("myriad {}", env!("CARGO_PKG_VERSION"));
    let (nodes, bytes) = write_checked(writer, meta, dataset)?;
    report.advance(1);
    Ok(AppendSummary {
        added,
        points,
        nodes,
        rebuilt,
        copied,
        cut: cut.level,
        cells_rebuilt: cut.rebuild.len(),
        cells: cut.cells.len(),
        grown,
        skipped_non_finite: skipped,
        bytes,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The dataset appended to, opened and checked: an octree or layered one (its parameters, as it
/// was built with them), its nodes listed without damage.
fn open_dataset(
    dataset: &Path,
    inputs: &[PathBuf],
) -> Result<(Dataset, NestedParams, Vec<NodeEntry>)> {
    myriad_io::atomic::refuse_input_as_output(dataset, inputs)?;
    myriad_io::atomic::refuse_repeated_inputs(inputs)?;
    convert::remove_stale(dataset);
    // The points as stored: edits kept beside the dataset stay beside it.
    let ds = Dataset::open_stored(dataset)?;
    let meta = &ds.meta;
    let ntree = match meta.structure.as_str() {
        "nested-octree" | "octree" => false,
        "layered" => true,
        s => {
            return Err(Error::unsupported(
                dataset,
                format!(
                    "--append adds to octree and layered datasets, this one is {s}: convert the \
                     scans together instead"
                ),
            ));
        }
    };
    let param = |k: &str, d: u64| meta.parameters.get(k).and_then(|v| v.as_u64()).unwrap_or(d);
    let params = NestedParams {
        capacity: param("capacity", convert::DEFAULT_CAPACITY as u64) as usize,
        inner_depth: param("inner_depth", convert::DEFAULT_INNER_DEPTH as u64) as u32,
        max_level: param("max_level", convert::DEFAULT_MAX_LEVEL as u64) as u32,
        ntree,
    };
    let (entries, damage) = ds.nodes();
    if let Some(d) = damage.first() {
        return Err(Error::Invalid(format!(
            "{} (nothing appended: `myriad verify` lists the damage)",
            ds.damage_error(d)
        )));
    }
    Ok((ds, params, entries))
}

/// Step 1: the points of `inputs` in the dataset's columns (each input listed in `meta`'s
/// sources, with the points taken from it), and those skipped for coordinates that are no
/// numbers. Refused where an input has columns the dataset lacks, where the headers' counts
/// will not fit `memory`, or where the inputs hold no points.
fn read_new(
    dataset: &Path,
    inputs: &[PathBuf],
    open: &myriad_io::OpenOptions,
    memory: u64,
    meta: &mut myriad_format::Metadata,
    report: &dyn Report,
) -> Result<(PointBatch, u64)> {
    let schema = meta.schema.clone();
    // Each input opened once: its header checked and counted before any point is read.
    let mut sources = Vec::with_capacity(inputs.len());
    for path in inputs {
        sources.push(myriad_io::open(path, open)?);
    }
    let declared: u64 = sources.iter().filter_map(|s| s.info().points).sum();
    // The new points are held in memory (as rows, then grouped by cell): refused up front
    // when their headers say they will not fit the budget.
    let row = PointBatch::with_schema(&schema, 0).row_size() as u64;
    check_memory(inputs, 2 * declared * row, memory)?;
    report.phase("reading", declared);
    let mut new = PointBatch::with_schema(&schema, 0);
    let mut skipped = 0;
    for (path, mut src) in inputs.iter().zip(sources) {
        let info = src.info().clone();
        if let Some(a) = info.schema.attributes.iter().find(|a| !schema.has(a)) {
            return Err(Error::unsupported(
                path,
                format!(
                    "has {}, which {} lacks: convert the scans together instead",
                    a.name(),
                    dataset.display()
                ),
            ));
        }
        if info.schema.extra_bytes > 0 && info.schema.extra_bytes != schema.extra_bytes {
            return Err(Error::unsupported(
                path,
                format!(
                    "has {} extra bytes per point, {} has {}",
                    info.schema.extra_bytes,
                    dataset.display(),
                    schema.extra_bytes
                ),
            ));
        }
        let before = new.len();
        while let Some(b) = src.read_batch(myriad_io::DEFAULT_BATCH)? {
            report.advance(b.len() as u64);
            new.append(&distribute::conform(b, &schema));
        }
        skipped += src.skipped_non_finite();
        let mut listed = convert::source(&info, (new.len() - before) as u64);
        listed["appended"] = true.into();
        meta.sources.push(listed);
    }
    if new.is_empty() {
        return Err(Error::Invalid(format!(
            "{}: the inputs hold no points",
            inputs[0].display()
        )));
    }
    Ok((new, skipped))
}

/// Step 2: the root cube grown from `root` until it holds `bounds`, each level doubling its
/// side away from the points outside: the new root, the levels added, and the old root's cell
/// at the new level (its nodes' keys move by that much).
fn grow_root(root: Aabb, bounds: &Aabb, inputs: &[PathBuf]) -> Result<(Aabb, u32, [u32; 3])> {
    let mut root = root;
    let (mut grown, mut offset) = (0u32, [0u32; 3]);
    let inside = |r: &Aabb| (0..3).all(|a| bounds.min[a] >= r.min[a] && bounds.max[a] <= r.max[a]);
    while !inside(&root) {
        if grown == MAX_GROWTH {
            return Err(Error::Invalid(format!(
                "{}: the new points lie more than 2^{MAX_GROWTH} times the dataset's size away \
                 from it: convert the scans together instead",
                inputs[0].display()
            )));
        }
        let side = root.size()[0];
        let mut min = root.min;
        for a in 0..3 {
            if bounds.min[a] < root.min[a] {
                min[a] -= side;
                offset[a] += 1 << grown;
            }
        }
        root = Aabb::new(min, min.map(|v| v + 2.0 * side));
        grown += 1;
    }
    Ok((root, grown, offset))
}

/// The old nodes with their keys in the grown tree: `grown` levels deeper, moved over to the old
/// root's cell (`offset`) at its new level.
fn rekeyed(entries: Vec<NodeEntry>, grown: u32, offset: [u32; 3]) -> Vec<NodeEntry> {
    let rekey = |k: NodeKey| NodeKey {
        level: k.level + grown,
        cell: std::array::from_fn(|a| k.cell[a] + (offset[a] << k.level)),
    };
    entries
        .into_iter()
        .map(|mut e| {
            e.key = rekey(e.key);
            e
        })
        .collect()
}

/// Step 3: where the tree is cut ([`cut_level`]) and what each cell at the cut gets: its old
/// nodes, the new points and the points above the cut that lie in it, and whether it is
/// rebuilt.
struct Cut<'a> {
    level: u32,
    /// The new points by cell, and the points of the levels above the cut by cell (taken out as
    /// the cells are built).
    new_cells: HashMap<NodeKey, PointBatch>,
    returned: HashMap<NodeKey, PointBatch>,
    /// The old nodes at and below the cut, by cell.
    below: BTreeMap<NodeKey, Vec<&'a NodeEntry>>,
    rebuild: HashSet<NodeKey>,
    cells: BTreeSet<NodeKey>,
}

impl<'a> Cut<'a> {
    /// The cut for the `new` points in a tree of `entries` (rekeyed) under `root`, grown by
    /// `grown` levels: the nodes above the cut are read and their points given back to their
    /// cells; a cell is rebuilt where new points fall in it, where it lacks its top node, or
    /// where its top node cannot take back its points.
    fn new(
        ds: &Dataset,
        entries: &'a [NodeEntry],
        new: PointBatch,
        root: &Aabb,
        grown: u32,
        params: &NestedParams,
    ) -> Result<Cut<'a>> {
        let depth = entries.iter().map(|e| e.key.level).max().unwrap_or(grown);
        let k = cut_level(entries, &new, root, grown, depth);
        let new_cells = by_cell(new, root, k);
        let mut above = PointBatch::with_schema(&ds.meta.schema, 0);
        let mut below: BTreeMap<NodeKey, Vec<&NodeEntry>> = BTreeMap::new();
        for e in entries {
            if e.key.level < k {
                above.append(&ds.read_node(e).map_err(|d| ds.damage_error(&d))?);
            } else {
                below.entry(ancestor(e.key, k)).or_default().push(e);
            }
        }
        let returned = by_cell(above, root, k);
        let mut rebuild: HashSet<NodeKey> = new_cells.keys().copied().collect();
        // A cell without its top node (none is written so, but a kept cell needs it): rebuilt.
        for (cell, v) in &below {
            if !v.iter().any(|e| e.key == *cell) {
                rebuild.insert(*cell);
            }
        }
        for (cell, got) in &returned {
            let top = below
                .get(cell)
                .and_then(|v| v.iter().find(|e| e.key == *cell));
            if top.is_none_or(|t| t.points as usize + got.len() > params.capacity) {
                rebuild.insert(*cell);
            }
        }
        let cells: BTreeSet<NodeKey> = below.keys().chain(rebuild.iter()).copied().collect();
        Ok(Cut {
            level: k,
            new_cells,
            returned,
            below,
            rebuild,
            cells,
        })
    }

    /// The most points of a rebuilt cell: each thread builds one rebuilt cell at a time, all of
    /// its points in memory.
    fn largest(&self) -> u64 {
        self.rebuild
            .iter()
            .map(|c| {
                let old: u64 = self
                    .below
                    .get(c)
                    .map_or(0, |v| v.iter().map(|e| e.points as u64).sum());
                let add = |m: &HashMap<NodeKey, PointBatch>| m.get(c).map_or(0, |b| b.len() as u64);
                old + add(&self.new_cells) + add(&self.returned)
            })
            .max()
            .unwrap_or(0)
    }
}

/// Step 4: what the cells at the cut are built with and written to.
struct Cells<'a> {
    ds: &'a Dataset,
    root: &'a Aabb,
    params: &'a NestedParams,
    writer: &'a DatasetWriter,
}

impl Cells<'_> {
    /// Every cell of `cut`, in parallel, rebuilt or kept: the cells' top nodes (for the levels
    /// above), the nodes rebuilt and the nodes copied.
    fn build(&self, cut: &mut Cut, report: &dyn Report) -> Result<(Vec<BuiltNode>, u64, u64)> {
        let work: Vec<(NodeKey, Option<PointBatch>, Option<PointBatch>)> = (cut.cells.iter())
            .map(|c| (*c, cut.new_cells.remove(c), cut.returned.remove(c)))
            .collect();
        let tops: Vec<(BuiltNode, u64, u64)> = work
            .into_par_iter()
            .map(|(cell, fresh, back)| -> Result<(BuiltNode, u64, u64)> {
                let old = cut.below.get(&cell).map(Vec::as_slice).unwrap_or(&[]);
                let result = if cut.rebuild.contains(&cell) {
                    self.rebuild(cell, old, fresh, back)?
                } else {
                    self.keep(cell, old, back)?
                };
                report.advance(1);
                Ok(result)
            })
            .collect::<Result<Vec<_>>>()?;
        let (mut rebuilt, mut copied) = (0, 0);
        let mut roots = Vec::with_capacity(tops.len());
        for (top, r, c) in tops {
            rebuilt += r;
            copied += c;
            roots.push(top);
        }
        Ok((roots, rebuilt, copied))
    }

    /// A cell rebuilt from every point it holds (its `old` nodes', the `fresh` ones, those given
    /// `back` from above the cut): its top node and the nodes written below it.
    fn rebuild(
        &self,
        cell: NodeKey,
        old: &[&NodeEntry],
        fresh: Option<PointBatch>,
        back: Option<PointBatch>,
    ) -> Result<(BuiltNode, u64, u64)> {
        let ds = self.ds;
        let mut batch = PointBatch::with_schema(&ds.meta.schema, 0);
        for e in old {
            batch.append(&ds.read_node(e).map_err(|d| ds.damage_error(&d))?);
        }
        for b in [fresh, back].into_iter().flatten() {
            batch.append(&b);
        }
        let mut top = None;
        let mut written = 0;
        nested::build_subtree_with(batch, self.root, cell, self.params, &mut |node| {
            if node.key == cell {
                top = Some(node);
            } else {
                crate::nodes::write(self.writer, node)?;
                written += 1;
            }
            Ok::<(), Error>(())
        })?;
        Ok((top.expect("a rebuilt cell has points"), written, 0))
    }

    /// A cell kept: its nodes' pages copied as they are, but for its top node, which takes the
    /// points given `back` from above the cut: that node and the pages copied.
    fn keep(
        &self,
        cell: NodeKey,
        old: &[&NodeEntry],
        back: Option<PointBatch>,
    ) -> Result<(BuiltNode, u64, u64)> {
        let ds = self.ds;
        let mut copied = 0;
        let mut top = None;
        for e in old {
            if e.key == cell {
                let mut batch = ds.read_node(e).map_err(|d| ds.damage_error(&d))?;
                if let Some(b) = &back {
                    batch.append(b);
                }
                // Its contour grows to hold the points taken back (the levels above
                // kept them from reaching it: the old contour need not hold them).
                let contour = e.contour.map(|c| nested::enclosing(&batch, [&c]));
                let mut n = nested::leaf_node(cell, batch, self.root, self.params);
                n.shape.contour = contour;
                n.shape.detail = contour.and_then(|_| nested::own_contour(&n.points));
                top = Some(n);
            } else {
                let page = ds.node_page(e).map_err(|d| ds.damage_error(&d))?;
                self.writer.copy_node(e, &page)?;
                copied += 1;
            }
        }
        Ok((top.expect("a kept cell has its top node"), 0, copied))
    }
}

/// The dataset written and read back whole before it replaces the old one: every page's
/// checksum, the counts, the invariants; where anything is wrong the old dataset stays as it
/// was. Its nodes and bytes.
fn write_checked(
    writer: DatasetWriter,
    meta: myriad_format::Metadata,
    dataset: &Path,
) -> Result<(u64, u64)> {
    let mut nodes = 0;
    let bytes = writer.finish_checked(meta, |ds| {
        let r = crate::extract::verify(ds, |_| {});
        nodes = r.nodes;
        match r.damage.first() {
            None => Ok(()),
            Some(d) => Err(Error::Invalid(format!(
                "{}: the dataset appended to fails its check (node {} at byte {} of what was \
                 written: {}); nothing appended, it is as it was (please report this)",
                dataset.display(),
                d.key,
                d.offset,
                d.message
            ))),
        }
    })?;
    Ok((nodes, bytes))
}
