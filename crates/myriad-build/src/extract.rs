//! Reading a dataset back: `extract` (the original points in a box at a level of detail, to
//! LAS/LAZ/PLY, streaming, node by node) and `verify` (every page read, checksums and the
//! structure's invariants checked).

use myriad_core::{Aabb, Attribute, Error, NodeKey, Result, Schema};
use myriad_format::{Damage, Dataset, NodeEntry};
use myriad_io::las::{LasSink, LasWriteOptions};
use myriad_io::ply::PlySink;
use myriad_measure::{Filter, Region};
use std::collections::HashSet;
use std::path::Path;
use std::sync::Arc;

#[derive(Debug, Clone, Default)]
pub struct ExtractOptions {
    /// Only points inside this box (bounds inclusive).
    pub bbox: Option<Aabb>,
    /// Only points in this region too (a profile's corridor, a polygon).
    pub region: Option<Arc<dyn Region>>,
    /// Only the points this filter keeps (classes, attribute ranges).
    pub filter: Filter,
    /// Only the levels of detail whose point spacing is at least this; `None`: every point.
    pub spacing: Option<f64>,
    pub force: bool,
}

#[derive(Debug, Clone, Default)]
pub struct ExtractSummary {
    pub points: u64,
    pub nodes_read: u64,
    /// Damaged pages met (their nodes were skipped).
    pub damage: Vec<Damage>,
}

enum Sink {
    Las(LasSink),
    Ply(PlySink),
}

/// The LAS format to write: the input's own (from the stored header) when it holds every
/// attribute of the dataset, else the smallest LAS 1.4 format that does.
pub(crate) fn las_options(ds: &Dataset) -> Result<LasWriteOptions> {
    let m = &ds.meta;
    let q = m.quantization;
    if let Some(bytes) = &m.las_header {
        let header = myriad_io::las::header_from_bytes(bytes)?;
        let fmt = header.point_format();
        let holds = Schema::for_las_format(fmt.to_u8().unwrap_or(0));
        let covered = m
            .schema
            .attributes
            .iter()
            .all(|a| matches!(a, Attribute::Extra(_)) || holds.has(a))
            && fmt.extra_bytes as usize == m.schema.extra_bytes;
        // A header without its CRS records (the points were moved into another CRS) takes the
        // dataset's as WKT, which LAS 1.4 holds; an older version gets the format below.
        let crs_kept = header.has_crs_vlrs() || m.crs.is_none() || header.version().minor >= 4;
        if covered && crs_kept {
            let o = LasWriteOptions::like(&header).with_transforms(q.scale, q.offset)?;
            return match &m.crs {
                Some(wkt) if !header.has_crs_vlrs() && !wkt.starts_with("EPSG:") => {
                    o.with_wkt_crs(wkt)
                }
                _ => Ok(o),
            };
        }
    }
    let o = LasWriteOptions::for_schema(&m.schema, q.scale, q.offset)?;
    match &m.crs {
        Some(wkt) if !wkt.starts_with("EPSG:") => o.with_wkt_crs(wkt),
        _ => Ok(o),
    }
}

/// The nodes a query touches, in key order: those whose cube meets the box and whose coarsest
/// level is not finer than the spacing.
/// The hierarchy's entries, read only from the pages whose subtrees meet the box (all without
/// one), and the damage met on the way.
pub(crate) fn hierarchy_for(ds: &Dataset, o: &ExtractOptions) -> (Vec<NodeEntry>, Vec<Damage>) {
    if o.bbox.is_none() && o.region.is_none() {
        return ds.nodes();
    }
    ds.nodes_where(&|cube| meets(o, cube))
}

/// Whether a node's cube may hold points of the box and the region.
fn meets(o: &ExtractOptions, cube: &Aabb) -> bool {
    o.bbox.is_none_or(|b| Region::meets(&b, cube))
        && o.region.as_ref().is_none_or(|r| r.meets(cube))
}

pub(crate) fn wanted(ds: &Dataset, nodes: Vec<NodeEntry>, o: &ExtractOptions) -> Vec<NodeEntry> {
    nodes
        .into_iter()
        .filter(|n| {
            let meets = meets(o, &n.bounds_in(&ds.meta.root));
            let coarse_enough = match o.spacing {
                Some(s) => n.spacing.first().is_some_and(|&top| top >= s),
                None => true,
            };
            // Aggregates (mwkd's inner nodes) were made for drawing: not the user's points.
            meets && coarse_enough && n.points > 0 && !n.aggregate()
        })
        .collect()
}

/// How many of a node's points (a prefix) have spacing at least `spacing`.
pub(crate) fn prefix_for(n: &NodeEntry, spacing: Option<f64>) -> usize {
    match spacing {
        None => n.points as usize,
        Some(s) => n
            .spacing
            .iter()
            .zip(&n.prefix)
            .take_while(|(sp, _)| **sp >= s)
            .last()
            .map_or(0, |(_, &p)| p as usize),
    }
}

/// Writes the points of `ds` that the options select to `out` (.las, .laz or .ply). Damaged
/// nodes are reported in the summary and skipped.
pub fn extract(ds: &Dataset, out: &Path, o: &ExtractOptions) -> Result<ExtractSummary> {
    extract_within(ds, out, o, u64::MAX, &|| false)
}

/// Why [`extract_within`] stopped before the end.
pub const TOO_MANY_POINTS: &str = "the box holds more than";
pub const CANCELLED: &str = "extraction cancelled";

/// [`extract`], refusing a selection of more than `max_points` points (at once where the
/// nodes wholly inside the box already hold more, else as soon as the count passes it) and
/// stopping at the next node once `cancelled` says so; nothing is written then.
pub fn extract_within(
    ds: &Dataset,
    out: &Path,
    o: &ExtractOptions,
    max_points: u64,
    cancelled: &dyn Fn() -> bool,
) -> Result<ExtractSummary> {
    let too_many = || {
        Error::Invalid(format!(
            "{TOO_MANY_POINTS} {max_points} points: ask for a smaller box or a coarser spacing"
        ))
    };
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    let mut sink = match ext.as_str() {
        "las" | "laz" => Sink::Las(LasSink::create(out, las_options(ds)?, o.force)?),
        "ply" => Sink::Ply(PlySink::create(out, &ds.meta.schema, o.force)?),
        _ => {
            return Err(Error::unsupported(out, "extract writes .las, .laz or .ply"));
        }
    };
    let filter = (o.filter.bind(&ds.meta.schema)).map_err(Error::Invalid)?;
    let (nodes, mut damage) = hierarchy_for(ds, o);
    let mut summary = ExtractSummary::default();
    let nodes = wanted(ds, nodes, o);
    // Nodes wholly in the box hold that many points surely, when nothing else filters them.
    // (Edits that remove points make stored counts no promise.)
    if max_points < u64::MAX && o.region.is_none() && filter.is_all() && ds.edits().is_none() {
        let surely: u64 = nodes
            .iter()
            .filter(|n| {
                let cube = n.bounds_in(&ds.meta.root);
                o.bbox.is_none_or(|b| {
                    (0..3).all(|a| b.min[a] <= cube.min[a] && cube.max[a] <= b.max[a])
                })
            })
            .map(|n| prefix_for(n, o.spacing) as u64)
            .sum();
        if surely > max_points {
            return Err(too_many());
        }
    }
    for n in nodes {
        if cancelled() {
            return Err(Error::Invalid(CANCELLED.into()));
        }
        // The levels asked for as stored, then the edits.
        let mut batch = match ds.read_node_prefix(&n, &ds.meta.schema, prefix_for(&n, o.spacing)) {
            Ok(b) => b,
            Err(d) => {
                damage.push(d);
                continue;
            }
        };
        summary.nodes_read += 1;
        if o.bbox.is_some() || o.region.is_some() || !filter.is_all() {
            let keep: Vec<bool> = (0..batch.len())
                .map(|i| {
                    let p = batch.positions[i];
                    o.bbox.is_none_or(|b| b.contains(p))
                        && o.region.as_ref().is_none_or(|r| r.contains(p))
                        && filter.keeps(&batch, i)
                })
                .collect();
            batch.retain_mask(&keep);
        }
        if batch.is_empty() {
            continue;
        }
        summary.points += batch.len() as u64;
        if summary.points > max_points {
            return Err(too_many());
        }
        match &mut sink {
            Sink::Las(s) => s.write(&batch)?,
            Sink::Ply(s) => s.write(&batch)?,
        }
    }
    // Nothing of a dataset that changed on its server while it was read.
    ds.check_unchanged()?;
    match sink {
        Sink::Las(s) => s.finish()?,
        Sink::Ply(s) => s.finish()?,
    };
    summary.damage = damage;
    Ok(summary)
}

#[derive(Debug, Clone, Default)]
pub struct VerifyReport {
    pub nodes: u64,
    pub points: u64,
    pub pages_bytes: u64,
    pub damage: Vec<Damage>,
}

/// Reads every hierarchy and node page of `ds`; checks checksums, that every node's points lie
/// in its cube, that its levels of detail are consistent, that every node's parent exists, and
/// that the counts add up to the header's.
pub fn verify(ds: &Dataset, mut on_node: impl FnMut(u64)) -> VerifyReport {
    let (nodes, mut damage) = ds.nodes();
    let root = ds.meta.root;
    let q = ds.meta.quantization;
    let keys: HashSet<NodeKey> = nodes.iter().map(|n| n.key).collect();
    let mut report = VerifyReport::default();
    let node_damage = |n: &NodeEntry, message: String| Damage {
        key: n.key,
        offset: n.page.offset,
        message,
        subtree: false,
    };
    for n in &nodes {
        report.nodes += 1;
        on_node(n.points as u64);
        if n.key.level > 0 && !keys.contains(&n.key.parent()) {
            damage.push(node_damage(n, "its parent is not in the hierarchy".into()));
        }
        let prefix_ok = !n.prefix.is_empty()
            && n.prefix.len() == n.spacing.len()
            && n.prefix.windows(2).all(|w| w[0] <= w[1])
            && n.spacing.windows(2).all(|w| w[0] >= w[1])
            && *n.prefix.last().unwrap() == n.points;
        if !prefix_ok && n.points > 0 {
            damage.push(node_damage(
                n,
                "inconsistent level-of-detail prefixes".into(),
            ));
        }
        // The pages as stored, whatever edits are kept beside them.
        let batch = match ds.read_node_stored(n, &ds.meta.schema) {
            Ok(b) => b,
            Err(d) => {
                damage.push(d);
                continue;
            }
        };
        if !n.aggregate() {
            report.points += batch.len() as u64;
        }
        match ds.read_splats(n) {
            Err(d) => damage.push(d),
            Ok(Some(s))
                if s.normals
                    .iter()
                    .any(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2] - 1.0).abs() > 1e-3) =>
            {
                damage.push(node_damage(n, "a splat normal is not a unit vector".into()))
            }
            Ok(_) => {}
        }
        report.pages_bytes += n.page.length as u64;
        // Points lie in the node's cube (or stored bounds), give or take half a quantization
        // step, and in its contour.
        let cube = n.bounds_in(&root);
        let slack: [f64; 3] = std::array::from_fn(|a| q.scale[a] + cube.size()[a] * 1e-9);
        let outside = batch.positions.iter().position(|p| {
            (0..3).any(|a| p[a] < cube.min[a] - slack[a] || p[a] > cube.max[a] + slack[a])
        });
        if let Some(i) = outside {
            damage.push(node_damage(
                n,
                format!(
                    "point {i} {:?} lies outside the node's cube",
                    batch.positions[i]
                ),
            ));
        }
        for (c, name) in [(n.contour, "contour"), (n.detail, "own points' contour")] {
            let Some(c) = c else { continue };
            let slack = q.scale.into_iter().fold(0.0, f64::max)
                + c.half_extents.into_iter().fold(0.0, f64::max) * 1e-9;
            let loose = myriad_core::Obb {
                half_extents: c.half_extents.map(|h| h + slack),
                ..c
            };
            if let Some(i) = batch.positions.iter().position(|&p| !loose.contains(p)) {
                damage.push(node_damage(
                    n,
                    format!(
                        "point {i} {:?} lies outside the node's {name}",
                        batch.positions[i]
                    ),
                ));
            }
        }
    }
    if damage.is_empty() && report.points != ds.meta.points {
        damage.push(Damage {
            key: NodeKey::ROOT,
            offset: 0,
            message: format!(
                "the nodes hold {} points, the metadata says {}",
                report.points, ds.meta.points
            ),
            subtree: true,
        });
    }
    let levels = myriad_format::Level::table(&nodes);
    if damage.is_empty() && !ds.meta.levels.is_empty() && ds.meta.levels != levels {
        damage.push(Damage {
            key: NodeKey::ROOT,
            offset: 0,
            message: "the metadata's per-level table does not match the hierarchy".into(),
            subtree: true,
        });
    }
    report.damage = damage;
    report
}
