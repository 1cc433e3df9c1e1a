//! `export`: a dataset in the formats other tools read, COPC 1.0, Potree 2.0 and 3D Tiles (1.1
//! or 1.0), or LAS/LAZ as `extract`, with the same box and spacing as `extract`.
//!
//! A dataset whose nodes are the cells of an octree (octree, layered) is exported node for node:
//! each node's page is decoded and written as a COPC chunk, Potree node or tile of the same key, the
//! tree is never rebuilt. The other structures (kd, mwkd) are first re-placed: their original
//! points (never mwkd's aggregates) are extracted to a temporary LAS file, built into an octree
//! with `convert`'s out-of-core pipeline, and that is exported. Memory is bounded by the group of
//! nodes in flight ([`GROUP_POINTS`]) and, when re-placing, by `convert`'s budget.
//!
//! COPC: a parent all of whose children are leaves takes their points into its chunk where it
//! and they together hold at most [`COPC_JOIN`] times the dataset's node capacity (deepest
//! first, so it may join its own parent's family): each LAZ chunk starts its models afresh, and
//! the dataset's small leaves compressed alone made the file larger than other builders' (a
//! COPC node may hold any points of its cube). Only whole families: a leaf joined into an
//! interior node (the rule until December 7) was drawn by every viewer that stopped there,
//! and Myriad's COPC settled in twice the `.myr`'s time.

use crate::convert::{self, ConvertOptions, Report};
use crate::extract::{self, ExtractOptions};
use myriad_core::{Aabb, Attribute, Error, NodeKey, PointBatch, Result};
use myriad_format::{Damage, Dataset, NodeEntry};
use myriad_io::copc::CopcSink;
use myriad_io::potree::{Frame, PotreeSink};
use myriad_io::tiles3d::{self, TilesSink};
use myriad_measure::Filter;
use rayon::prelude::*;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Points decoded at once (the nodes of one group are read and encoded in parallel).
pub const GROUP_POINTS: u64 = 4_000_000;

/// COPC: a family of leaves joins its parent's chunk where they hold at most this many times
/// the dataset's node capacity together (measured on KY, the 50 M point city and a 40 M point
/// tile: the guide).
pub const COPC_JOIN: u64 = 3;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    Copc,
    Potree,
    /// 3D Tiles (a folder of tileset.json and tiles).
    Tiles,
    Las,
    Laz,
}

impl Target {
    pub fn parse(s: &str) -> std::result::Result<Target, String> {
        match s.to_ascii_lowercase().as_str() {
            "copc" => Ok(Target::Copc),
            "potree" => Ok(Target::Potree),
            "3dtiles" => Ok(Target::Tiles),
            "las" => Ok(Target::Las),
            "laz" => Ok(Target::Laz),
            _ => Err(format!(
                "\"{s}\": expected copc, potree, 3dtiles, las or laz"
            )),
        }
    }

    /// The target an output's name implies: `.copc.laz` COPC, `.las`/`.laz` LAS/LAZ, a name
    /// without an extension (a folder) Potree.
    pub fn from_output(out: &Path) -> Option<Target> {
        let name = out.file_name()?.to_string_lossy().to_ascii_lowercase();
        if name.ends_with(".copc.laz") {
            Some(Target::Copc)
        } else if name.ends_with(".laz") {
            Some(Target::Laz)
        } else if name.ends_with(".las") {
            Some(Target::Las)
        } else if out.is_dir() || !name.contains('.') {
            Some(Target::Potree)
        } else {
            None
        }
    }
}

#[derive(Debug, Clone)]
pub struct ExportOptions {
    pub target: Target,
    /// Only points inside this box (bounds inclusive).
    pub bbox: Option<Aabb>,
    /// Only the levels of detail whose spacing is at least this.
    pub spacing: Option<f64>,
    /// Only the points this filter keeps (classes, attribute ranges).
    pub filter: Filter,
    pub force: bool,
    /// Memory budget of the re-placing build (kd, mwkd), in bytes.
    pub memory: u64,
    pub threads: usize,
    /// Levels per COPC hierarchy page (tests use few, to make many pages).
    pub copc_page_levels: u32,
    /// COPC: families of leaves join their parent's chunk up to this many points together (0: node for
    /// node; `None`: [`COPC_JOIN`] times the dataset's node capacity).
    pub copc_node_points: Option<u64>,
    /// COPC: the join limit as times the dataset's node capacity (`None`: [`COPC_JOIN`]);
    /// `copc_node_points`, where given, wins.
    pub copc_join: Option<f64>,
    /// Move the points into another CRS (`--to-crs`): they are re-placed into an octree of
    /// the target's coordinates, as kd and mwkd datasets are.
    pub reproject: Option<myriad_io::reproject::Reproject>,
    /// 3D Tiles: the dataset's CRS where it names none (`--from-crs`).
    pub from_crs: Option<String>,
    /// 3D Tiles: 1.1 (glTF) or 1.0 (.pnts).
    pub tiles_version: tiles3d::Version,
}

impl ExportOptions {
    pub fn new(target: Target) -> ExportOptions {
        ExportOptions {
            target,
            bbox: None,
            spacing: None,
            filter: Filter::all(),
            force: false,
            memory: convert::default_memory(),
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            copc_page_levels: myriad_io::copc::PAGE_LEVELS,
            copc_node_points: None,
            copc_join: None,
            reproject: None,
            from_crs: None,
            tiles_version: tiles3d::Version::V1_1,
        }
    }
}

#[derive(Debug, Clone, Default)]
pub struct ExportSummary {
    pub points: u64,
    /// Nodes written (with points).
    pub nodes: u64,
    /// Bytes written.
    pub bytes: u64,
    /// Damaged pages met: their nodes were left out.
    pub damage: Vec<Damage>,
    /// What the target could not hold, one line each.
    pub not_kept: Vec<String>,
    /// Whether the points were re-placed into an octree (kd, mwkd, another CRS).
    pub replaced: bool,
    /// Points that did not move into the target CRS (`--to-crs`, 3D Tiles' Earth-centred
    /// coordinates), left out.
    pub not_transformed: u64,
    /// 3D Tiles: the tileset files written (tileset.json and the external ones).
    pub tilesets: u64,
}

/// Whether the dataset's nodes are the cells of an octree holding original points.
pub fn is_octree(nodes: &[NodeEntry]) -> bool {
    nodes.iter().all(|n| n.bounds.is_none() && !n.aggregate())
}

/// Writes the points of `ds` that the options select to `out` in the target format. Damaged
/// nodes are left out and listed in the summary.
pub fn export(
    ds: &Dataset,
    out: &Path,
    o: &ExportOptions,
    report: &dyn Report,
) -> Result<ExportSummary> {
    // An attribute the dataset lacks is said before anything is written.
    (o.filter.bind(&ds.meta.schema)).map_err(Error::Invalid)?;
    if let Some(r) = &o.reproject
        && ds.meta.crs.is_none()
        && r.from.is_none()
    {
        return Err(Error::Invalid(format!(
            "{}: names no coordinate system to move its points from: give --from-crs",
            ds.path().display()
        )));
    }
    if o.target == Target::Tiles {
        if o.reproject.is_some() {
            return Err(Error::Invalid(
                "--to-crs does not apply to 3D Tiles: their coordinates are always Earth-centred \
                 (EPSG:4978); give the dataset's own CRS with --from-crs where it names none"
                    .into(),
            ));
        }
        if ds.meta.crs.is_none() && o.from_crs.is_none() {
            return Err(Error::Invalid(format!(
                "{}: names no coordinate system, and 3D Tiles place points on the globe: give \
                 --from-crs",
                ds.path().display()
            )));
        }
    }
    if matches!(o.target, Target::Las | Target::Laz) && o.reproject.is_none() {
        let want = if o.target == Target::Las {
            "las"
        } else {
            "laz"
        };
        let ext = out
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        if ext.as_deref() != Some(want) {
            return Err(Error::unsupported(
                out,
                format!("--to {want} writes a .{want} file"),
            ));
        }
        report.phase("exporting", ds.meta.points);
        let s = extract::extract(
            ds,
            out,
            &ExtractOptions {
                bbox: o.bbox,
                spacing: o.spacing,
                force: o.force,
                filter: o.filter.clone(),
                ..Default::default()
            },
        )?;
        report.advance(s.points);
        return Ok(ExportSummary {
            points: s.points,
            nodes: s.nodes_read,
            bytes: std::fs::metadata(out).map_or(0, |m| m.len()),
            damage: s.damage,
            ..Default::default()
        });
    }
    if !o.force && out.exists() {
        return Err(Error::Invalid(format!(
            "{}: output exists (use --force to replace it)",
            out.display()
        )));
    }
    // With a box, only the hierarchy pages it meets.
    let (nodes, damage) = extract::hierarchy_for(
        ds,
        &ExtractOptions {
            bbox: o.bbox,
            spacing: o.spacing,
            force: o.force,
            ..Default::default()
        },
    );
    if is_octree(&nodes) && o.reproject.is_none() {
        let mut s = export_octree(ds, nodes, out, o, report)?;
        s.damage.splice(0..0, damage);
        Ok(s)
    } else {
        replace(ds, damage, out, o, report)
    }
}

/// Temporary files beside the output, removed when dropped.
struct Temps(Vec<PathBuf>);

impl Drop for Temps {
    fn drop(&mut self) {
        for p in &self.0 {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// kd and mwkd, or another CRS: the selected original points to a temporary LAS file, built
/// into an octree (their coordinates moved into the target CRS), exported.
fn replace(
    ds: &Dataset,
    mut damage: Vec<Damage>,
    out: &Path,
    o: &ExportOptions,
    report: &dyn Report,
) -> Result<ExportSummary> {
    let dir = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let stem = out
        .file_name()
        .map_or_else(|| "export".into(), |n| n.to_string_lossy().into_owned());
    let pid = std::process::id();
    let las = dir.join(format!(".{stem}.{pid}.points.las"));
    let myr = dir.join(format!(".{stem}.{pid}.octree.myr"));
    let temps = Temps(vec![las.clone(), myr.clone()]);
    report.phase("extracting", ds.meta.points);
    let s = extract::extract(
        ds,
        &las,
        &ExtractOptions {
            bbox: o.bbox,
            spacing: o.spacing,
            force: true,
            filter: o.filter.clone(),
            ..Default::default()
        },
    )?;
    report.advance(s.points);
    let damaged: std::collections::HashSet<NodeKey> = damage.iter().map(|d| d.key).collect();
    damage.extend(s.damage.into_iter().filter(|d| !damaged.contains(&d.key)));
    let mut co = ConvertOptions::new(&myr);
    co.force = true;
    co.memory = o.memory;
    co.threads = o.threads;
    co.open.reproject = o
        .reproject
        .as_ref()
        .map(|r| myriad_io::reproject::Reproject {
            to: r.to.clone(),
            from: r.from.clone().or_else(|| ds.meta.crs.clone()),
        });
    let built = convert::convert(std::slice::from_ref(&las), &co, report)?;
    let _ = std::fs::remove_file(&las);
    let octree = Dataset::open_stored(&myr)?;
    let (nodes, more) = octree.nodes();
    damage.extend(more);
    let inner = ExportOptions {
        bbox: None,
        spacing: None,
        filter: Filter::all(),
        reproject: None,
        ..o.clone()
    };
    let mut summary = if matches!(o.target, Target::Las | Target::Laz) {
        let s = extract::extract(
            &octree,
            out,
            &ExtractOptions {
                force: o.force,
                ..Default::default()
            },
        )?;
        ExportSummary {
            points: s.points,
            nodes: s.nodes_read,
            bytes: std::fs::metadata(out).map_or(0, |m| m.len()),
            damage: s.damage,
            ..Default::default()
        }
    } else {
        export_octree(&octree, nodes, out, &inner, report)?
    };
    summary.not_transformed += built.not_transformed;
    drop(temps);
    summary.damage.splice(0..0, damage);
    summary.replaced = true;
    if ds.meta.schema.has(&Attribute::Normal) {
        summary.not_kept.push(format!(
            "normals (the {} structure's points are re-placed into an octree through LAS)",
            ds.meta.structure
        ));
    }
    Ok(summary)
}

/// Either sink.
enum Sink {
    Copc(Box<CopcSink>),
    Potree(Box<PotreeSink>),
    Tiles(Box<TilesSink>),
}

/// Normals as three f32 extra dimensions after the others (COPC: extra bytes).
fn normals_as_extra(b: &mut PointBatch) {
    let Some(normals) = b.normal.take() else {
        return;
    };
    let old = b.extra_stride;
    let stride = old + 12;
    let mut bytes = Vec::with_capacity(normals.len() * stride);
    for (i, n) in normals.iter().enumerate() {
        if let Some(e) = &b.extra_bytes {
            bytes.extend_from_slice(&e[i * old..(i + 1) * old]);
        } else {
            bytes.resize(bytes.len() + old, 0);
        }
        for v in n {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    b.extra_bytes = Some(bytes);
    b.extra_stride = stride;
}

/// COPC's chunks, joining whole families only: a parent all of whose children are leaves
/// takes their points where it and they hold at most `limit` points together, and is a leaf
/// from then on (deepest first, so it may join its own parent's family). No interior node
/// holds a leaf's points: a viewer that stops at an interior node draws only its own.
fn join_families(
    nodes: Vec<NodeEntry>,
    limit: u64,
    spacing: Option<f64>,
) -> (Vec<NodeEntry>, HashMap<NodeKey, Vec<NodeEntry>>) {
    let mut joined: HashMap<NodeKey, Vec<NodeEntry>> = HashMap::new();
    if limit == 0 {
        return (nodes, joined);
    }
    let mut load: HashMap<NodeKey, u64> = (nodes.iter())
        .map(|n| (n.key, extract::prefix_for(n, spacing) as u64))
        .collect();
    let mut children: HashMap<NodeKey, Vec<usize>> = HashMap::new();
    for (i, n) in nodes.iter().enumerate().filter(|(_, n)| n.key.level > 0) {
        children.entry(n.key.parent()).or_default().push(i);
    }
    let mut parents: Vec<NodeKey> = children.keys().copied().collect();
    parents.sort_by_key(|k| std::cmp::Reverse(k.level));
    let mut gone = vec![false; nodes.len()];
    for p in parents {
        let Some(&own) = load.get(&p) else { continue };
        let kids = &children[&p];
        if kids.iter().any(|&i| children.contains_key(&nodes[i].key)) {
            continue;
        }
        let theirs: u64 = kids.iter().map(|&i| load[&nodes[i].key]).sum();
        if own + theirs > limit {
            continue;
        }
        load.insert(p, own + theirs);
        let mut moved = Vec::new();
        for &i in kids {
            moved.extend(joined.remove(&nodes[i].key).unwrap_or_default());
            moved.push(nodes[i].clone());
            gone[i] = true;
        }
        joined.entry(p).or_default().extend(moved);
        children.remove(&p);
    }
    let kept = (nodes.into_iter().zip(gone))
        .filter_map(|(n, g)| (!g).then_some(n))
        .collect();
    (kept, joined)
}

/// An octree dataset, node for node.
fn export_octree(
    ds: &Dataset,
    nodes: Vec<NodeEntry>,
    out: &Path,
    o: &ExportOptions,
    report: &dyn Report,
) -> Result<ExportSummary> {
    let m = &ds.meta;
    let cube = m.root;
    let spacing = nodes
        .iter()
        .find(|n| n.key == NodeKey::ROOT)
        .and_then(|n| n.spacing.last().copied())
        .filter(|s| s.is_finite() && *s > 0.0)
        .unwrap_or(cube.size()[0] / 128.0);
    let mut summary = ExportSummary::default();
    let mut sink = match o.target {
        Target::Copc => {
            let q = m.quantization;
            let (options, lost) = myriad_io::copc::header_for(
                &m.schema,
                (q.scale, q.offset),
                m.las_header.as_deref(),
                m.crs.as_deref(),
            )?;
            summary.not_kept.extend(lost);
            Sink::Copc(Box::new(
                CopcSink::create(out, options, cube, spacing, o.force)?
                    .with_page_levels(o.copc_page_levels),
            ))
        }
        Target::Tiles => {
            let b = if m.bounds.is_empty() { cube } else { m.bounds };
            let frame = tiles3d::Frame {
                cube,
                centre: std::array::from_fn(|a| (b.min[a] + b.max[a]) / 2.0),
                spacing,
                crs: m
                    .crs
                    .clone()
                    .or_else(|| o.from_crs.clone())
                    .ok_or_else(|| {
                        Error::Invalid(format!(
                            "{}: names no coordinate system",
                            ds.path().display()
                        ))
                    })?,
            };
            let (s, lost) = TilesSink::create(out, &m.schema, frame, o.tiles_version, o.force)?;
            summary.not_kept.extend(lost);
            Sink::Tiles(Box::new(s))
        }
        _ => {
            let frame = Frame {
                cube,
                scale: m.quantization.scale,
                grid_offset: m.quantization.offset,
                spacing,
                crs: m.crs.clone(),
            };
            let (s, lost) = PotreeSink::create(out, &m.schema, frame, o.force)?;
            summary.not_kept.extend(lost);
            Sink::Potree(Box::new(s))
        }
    };
    let extract_options = ExtractOptions {
        bbox: o.bbox,
        spacing: o.spacing,
        force: o.force,
        ..Default::default()
    };
    let wanted = extract::wanted(ds, nodes, &extract_options);
    let copc = matches!(sink, Sink::Copc(_));
    let (wanted, mut joined) = if copc {
        let capacity = (m.parameters.get("capacity").and_then(|v| v.as_u64()))
            .unwrap_or(convert::DEFAULT_CAPACITY as u64);
        let times = o.copc_join.unwrap_or(COPC_JOIN as f64);
        let limit = (o.copc_node_points).unwrap_or((times * capacity as f64).round() as u64);
        join_families(wanted, limit, o.spacing)
    } else {
        (wanted, HashMap::new())
    };
    let filter = (o.filter.bind(&m.schema)).map_err(Error::Invalid)?;
    report.phase("exporting", wanted.iter().map(|n| n.points as u64).sum());
    // Each node with the leaves that joined it and the points of them all.
    let mut group: Vec<(NodeEntry, Vec<NodeEntry>, u64)> = Vec::new();
    let mut in_group = 0u64;
    let read_one = |n: &NodeEntry| {
        let count = extract::prefix_for(n, o.spacing);
        ds.read_node_prefix(n, &ds.meta.schema, count).map(|mut b| {
            if let Some(bx) = &o.bbox {
                let keep: Vec<bool> = b.positions.iter().map(|&p| bx.contains(p)).collect();
                b.retain_mask(&keep);
            }
            filter.retain(&mut b);
            if copc {
                normals_as_extra(&mut b);
            }
            b
        })
    };
    let mut flush = |group: &mut Vec<(NodeEntry, Vec<NodeEntry>, u64)>,
                     summary: &mut ExportSummary|
     -> Result<()> {
        // Each node's points, then those of the leaves that joined it; a damaged one leaves
        // out its own points only.
        let read: Vec<(NodeEntry, u64, Option<PointBatch>, Vec<Damage>)> = group
            .par_drain(..)
            .map(|(n, leaves, total)| {
                let mut damage = Vec::new();
                let mut points: Option<PointBatch> = None;
                for m in std::iter::once(&n).chain(&leaves) {
                    match (read_one(m), &mut points) {
                        (Ok(b), Some(p)) => p.append(&b),
                        (Ok(b), None) => points = Some(b),
                        (Err(d), _) => damage.push(d),
                    }
                }
                (n, total, points, damage)
            })
            .collect();
        let mut batches = Vec::with_capacity(read.len());
        for (n, total, b, damage) in read {
            report.advance(total);
            summary.damage.extend(damage);
            if let Some(b) = b.filter(|b| !b.is_empty()) {
                summary.points += b.len() as u64;
                summary.nodes += 1;
                batches.push((n.key, b));
            }
        }
        match &mut sink {
            Sink::Copc(s) => s.write_nodes(&batches),
            Sink::Potree(s) => s.write_nodes(&batches),
            Sink::Tiles(s) => s.write_nodes(&batches),
        }
    };
    for n in wanted {
        let leaves = joined.remove(&n.key).unwrap_or_default();
        let total = n.points as u64 + leaves.iter().map(|l| l.points as u64).sum::<u64>();
        in_group += total;
        group.push((n, leaves, total));
        if in_group >= GROUP_POINTS {
            flush(&mut group, &mut summary)?;
            in_group = 0;
        }
    }
    flush(&mut group, &mut summary)?;
    // Nothing of a dataset that changed on its server while it was read.
    ds.check_unchanged()?;
    summary.bytes = match sink {
        Sink::Copc(s) => s.finish()?.bytes,
        Sink::Potree(s) => s.finish()?.bytes,
        Sink::Tiles(s) => {
            let t = s.finish()?;
            summary.points = t.points;
            summary.nodes = t.tiles;
            summary.not_transformed = t.not_transformed;
            summary.tilesets = t.tilesets;
            t.bytes
        }
    };
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_format::hierarchy::PageRef;

    fn node(key: NodeKey, points: u32) -> NodeEntry {
        NodeEntry::new(key, PageRef::default(), points, vec![points], vec![1.0])
    }

    #[test]
    fn whole_families_join_their_parent_deepest_first_within_the_limit() {
        let root = NodeKey::ROOT;
        let (a, b) = (root.child(0), root.child(1));
        let (a0, a1, b0, b1) = (a.child(0), a.child(1), b.child(0), b.child(1));
        let nodes = vec![
            node(root, 100),
            node(a, 100),
            node(b, 100),
            node(a0, 30),
            node(a1, 30),
            node(b0, 30),
            node(b1, 500),
        ];
        // a's family joins a (160); b's cannot (b1 is too big, and b0 never joins alone); the
        // root keeps b, an interior node, so its family stays apart: no interior node holds
        // a leaf's points.
        let (kept, joined) = join_families(nodes.clone(), 300, None);
        let keys: Vec<NodeKey> = kept.iter().map(|n| n.key).collect();
        assert_eq!(keys, vec![root, a, b, b0, b1]);
        let mut into_a: Vec<NodeKey> = joined[&a].iter().map(|n| n.key).collect();
        into_a.sort();
        assert_eq!(into_a, vec![a0, a1]);
        assert_eq!(joined.len(), 1);
        // A larger limit: b's family joins b (630), then the root's, all leaves now (890).
        let (kept, joined) = join_families(nodes.clone(), 1000, None);
        assert_eq!(kept.iter().map(|n| n.key).collect::<Vec<_>>(), vec![root]);
        assert_eq!(joined[&root].len(), 6);
        let total: u32 = kept.iter().map(|n| n.points).sum::<u32>()
            + joined.values().flatten().map(|n| n.points).sum::<u32>();
        assert_eq!(total, 890);
        let (kept, joined) = join_families(nodes, 0, None);
        assert_eq!((kept.len(), joined.len()), (7, 0));
    }
}
