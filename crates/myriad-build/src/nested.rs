//! The nested octree inside one chunk (Scheiblauer 2006, chapter 4): an outer octree whose nodes
//! each hold a MOSPT ([`crate::mospt`]) of original points.
//!
//! A node with more than `capacity` points keeps one point per occupied cell of its inner grid
//! (the deepest inner level, at most `inner_depth`, whose MOSPT prefix fits the capacity) and
//! passes the rest, the thesis's rejected points, down to its eight children. A node with at most
//! `capacity` points, or at `max_level`, keeps them all (the thesis's leaf strategy 3.a). Every
//! point ends in exactly one node; a node's points are stored in MOSPT order, so a prefix of a node
//! is a coarser level of detail of that node.

use crate::{mospt, ntree};
pub use myriad_core::NodeKey;
use myriad_core::{Aabb, Obb, PointBatch};
use myriad_format::NodeShape;
use myriad_format::splat::Splats;

#[derive(Debug, Clone, Copy)]
pub struct NestedParams {
    /// Most points in a node.
    pub capacity: usize,
    /// Depth of a node's inner grid (its MOSPT) below the node's cube.
    pub inner_depth: u32,
    /// Deepest outer level; nodes there keep every point they get.
    pub max_level: u32,
    /// The `layered` structure (Kanzok et al. 2015): representatives from the adaptive n-tree
    /// ([`crate::ntree`]) and a contour per node, instead of the MOSPT.
    pub ntree: bool,
}

/// A built node: its points in MOSPT order, with the prefix count and spacing of each level.
#[derive(Debug, Clone)]
pub struct BuiltNode {
    pub key: NodeKey,
    pub points: PointBatch,
    pub prefix: Vec<u64>,
    pub spacing: Vec<f64>,
    /// Stored bounds and contour (kd and layered structures).
    pub shape: NodeShape,
    /// Normals and radii of the points, and whether they are aggregates (`mwkd`).
    pub splats: Option<(Splats, bool)>,
    /// Whether each level's points are in acquisition order already (as the writer puts them).
    pub acquisition: bool,
}

/// How many points of a MOSPT a node with at most `capacity` points keeps: the prefix of the
/// deepest inner level that fits (at least the root point). The last prefix entry is the rest
/// that no inner level separates, so it is never taken here.
pub(crate) fn fitting_prefix(m: &mospt::Mospt, capacity: usize) -> usize {
    let inner_levels = m.prefix.len() - 1;
    let l = (0..inner_levels)
        .rev()
        .find(|&l| m.prefix[l] as usize <= capacity)
        .unwrap_or(0);
    m.prefix[l] as usize
}

/// The node holding the first `keep` points of `batch`'s MOSPT `m`, with the levels they span.
pub(crate) fn node_from_prefix(
    key: NodeKey,
    batch: &PointBatch,
    m: &mospt::Mospt,
    keep: usize,
) -> BuiltNode {
    let kept_levels = m
        .prefix
        .iter()
        .take_while(|&&p| (p as usize) < keep)
        .count()
        + 1;
    let prefix: Vec<u64> = m.prefix[..kept_levels]
        .iter()
        .map(|&p| p.min(keep as u64))
        .collect();
    let spacing = m.spacing[..kept_levels].to_vec();
    // Put in the order the writer wants before the one gather.
    let kept = &m.order[..keep];
    let order: Vec<u32> =
        crate::order::acquisition_permutation(batch, Some(kept), keep, &prefix, &spacing)
            .into_iter()
            .map(|p| kept[p as usize])
            .collect();
    BuiltNode {
        key,
        points: batch.gather(&order),
        prefix,
        spacing,
        shape: NodeShape::default(),
        splats: None,
        acquisition: true,
    }
}

/// Builds the subtree rooted at `key` (whose cube, over `root`, holds every point of `batch`),
/// returning its nodes parents first.
pub fn build_subtree(
    batch: PointBatch,
    root: &Aabb,
    key: NodeKey,
    params: &NestedParams,
) -> Vec<BuiltNode> {
    let mut out = Vec::new();
    build_subtree_with(batch, root, key, params, &mut |n| {
        out.push(n);
        Ok::<(), ()>(())
    })
    .expect("collecting cannot fail");
    out.sort_by_key(|n| n.key);
    out
}

/// [`build_subtree`], handing each node to `emit` as soon as it is built (so a caller can write
/// it out and free it), the subtree's root first.
pub fn build_subtree_with<E>(
    batch: PointBatch,
    root: &Aabb,
    key: NodeKey,
    params: &NestedParams,
    emit: &mut dyn FnMut(BuiltNode) -> Result<(), E>,
) -> Result<(), E> {
    // Sorted once by Morton code: every node below is a list of its points' indices in that
    // order, with their codes relative to its own cube (its parent's shifted by one level).
    // The rest moves down as indices and codes, in order: a node's codes are not gathered
    // from the chunk's (for a 2 M point chunk, reads all over 16 MB); a node gathers only the
    // points it keeps (a layered node, whose n-tree works on a batch, all of its points).
    let (order, sorted_codes) = mospt::sort_codes(&mospt::codes(&batch, &key.bounds(root)));
    let below = (1u64 << (3 * mospt::CODE_LEVELS)) - 1;
    let top = 3 * (mospt::CODE_LEVELS - 1);
    let mut work = vec![(key, order, sorted_codes)];
    while let Some((node_key, ids, node_codes)) = work.pop() {
        if ids.is_empty() {
            continue;
        }
        let n = ids.len();
        let cube = node_key.bounds(root);
        let leaf = n <= params.capacity || node_key.level >= params.max_level;
        let depth = if leaf {
            mospt::CODE_LEVELS
        } else {
            params.inner_depth
        };
        // The node, and the places (in `ids`) of the points it keeps when it passes some down.
        let (node, kept) = if params.ntree {
            let own = batch.gather(&ids);
            let (m, pca) = ntree::build(&own, params.capacity, leaf);
            let keep = m.order.len();
            let mut node = node_from_prefix(node_key, &own, &m, keep);
            node.shape.contour = Some(ntree::contour(&own.positions, &pca));
            if keep < n {
                node.shape.detail = own_contour(&node.points);
            }
            (node, (keep < n).then(|| m.order[..keep].to_vec()))
        } else {
            // A node that passes points down orders only those it keeps.
            let fit = (!leaf).then_some(params.capacity);
            let mut m = mospt::build_places(&batch, &ids, &node_codes, &cube, depth, fit);
            let keep = if leaf {
                n
            } else {
                fitting_prefix(&m, params.capacity)
            };
            debug_assert_eq!(m.order.len(), keep);
            let kept = (keep < n).then(|| m.order.clone());
            m.order.iter_mut().for_each(|p| *p = ids[*p as usize]);
            (node_from_prefix(node_key, &batch, &m, keep), kept)
        };
        if let Some(kept) = kept {
            // The rest goes down; in Morton order each child's points are one run, whose
            // octant is the top three bits of the node's code.
            let mut rest = vec![true; n];
            for &k in &kept {
                rest[k as usize] = false;
            }
            let mut at = 0;
            while at < n {
                if !rest[at] {
                    at += 1;
                    continue;
                }
                let octant = node_codes[at] >> top;
                let (mut child, mut child_codes) = (Vec::new(), Vec::new());
                while at < n && node_codes[at] >> top == octant {
                    if rest[at] {
                        child.push(ids[at]);
                        child_codes.push((node_codes[at] << 3) & below);
                    }
                    at += 1;
                }
                work.push((node_key.child(octant as usize), child, child_codes));
            }
        }
        emit(node)?;
    }
    Ok(())
}

/// The contour of a node's own points (Kanzok et al. 2015, section 3.1), which sizes its detail
/// where it passes points down (its stored contour holds the whole subtree, for culling). None for
/// a node left without points (its parent took them all).
pub(crate) fn own_contour(points: &PointBatch) -> Option<Obb> {
    (!points.is_empty()).then(|| ntree::contour(&points.positions, &ntree::pca(&points.positions)))
}

/// A contour holding every point of `points` and every box of `boxes` (the contour of
/// Kanzok et al. 2015, made from the points and the boxes' corners): a parent's over its
/// children's, a cell's grown to hold points it takes back.
pub(crate) fn enclosing<'a>(points: &PointBatch, boxes: impl IntoIterator<Item = &'a Obb>) -> Obb {
    let mut outline = points.positions.clone();
    boxes.into_iter().for_each(|b| outline.extend(b.corners()));
    ntree::contour(&outline, &ntree::pca(&outline))
}

/// The node of `batch` at `key`: all of it in level order (a leaf's content).
pub(crate) fn leaf_node(
    key: NodeKey,
    batch: PointBatch,
    root: &Aabb,
    params: &NestedParams,
) -> BuiltNode {
    let m = if params.ntree {
        ntree::build(&batch, batch.len(), true).0
    } else {
        mospt::build(&batch, &key.bounds(root), 21)
    };
    BuiltNode {
        key,
        points: batch.gather(&m.order),
        prefix: m.prefix,
        spacing: m.spacing,
        shape: NodeShape::default(),
        splats: None,
        acquisition: false,
    }
}

/// Every child's points, child after child: what a parent takes its representatives from.
pub(crate) fn union_of(children: &[BuiltNode]) -> PointBatch {
    let mut union: Option<PointBatch> = None;
    for child in children {
        match &mut union {
            Some(u) => u.append(&child.points),
            None => union = Some(child.points.clone()),
        }
    }
    union.unwrap_or_default()
}

/// After a parent took the points `up` (indices into [`union_of`] the children), each child that
/// lost some is rebuilt by `rebuild` from the points it keeps.
pub(crate) fn keep_rest(
    children: &mut [BuiltNode],
    up: &[u32],
    rebuild: &dyn Fn(&BuiltNode, PointBatch) -> BuiltNode,
) {
    let total: usize = children.iter().map(|c| c.points.len()).sum();
    let mut moved = vec![false; total];
    up.iter().for_each(|&i| moved[i as usize] = true);
    let mut start = 0;
    for child in children.iter_mut() {
        let n = child.points.len();
        let stay: Vec<u32> = (0..n as u32)
            .filter(|&i| !moved[start + i as usize])
            .collect();
        if stay.len() != n {
            *child = rebuild(child, child.points.gather(&stay));
        }
        start += n;
    }
}

/// One step of [`build_tops`]: the node `parent` takes one point per occupied cell of its inner
/// grid from its `children`'s points (the deepest MOSPT prefix within `capacity`); each child
/// keeps the rest, in a rebuilt MOSPT. Returns the parent and the children as they are now.
pub fn take_up(
    parent: NodeKey,
    mut children: Vec<BuiltNode>,
    root: &Aabb,
    params: &NestedParams,
) -> (BuiltNode, Vec<BuiltNode>) {
    let union = union_of(&children);
    let (m, keep, contour) = if params.ntree {
        let (m, _) = ntree::build(&union, params.capacity, false);
        // The contour holds the children's contours, hence the whole subtree.
        let contour = enclosing(
            &union,
            children.iter().filter_map(|c| c.shape.contour.as_ref()),
        );
        let keep = m.order.len();
        (m, keep, Some(contour))
    } else {
        let m = mospt::build(&union, &parent.bounds(root), params.inner_depth);
        let keep = fitting_prefix(&m, params.capacity).min(union.len());
        (m, keep, None)
    };
    keep_rest(&mut children, &m.order[..keep], &|child, stay| {
        let mut c = leaf_node(child.key, stay, root, params);
        c.shape = child.shape;
        if params.ntree {
            // The subtree's contour still holds all of it; the node's own points are fewer.
            c.shape.detail = own_contour(&c.points);
        }
        c
    });
    let mut top = node_from_prefix(parent, &union, &m, keep);
    top.shape.contour = contour;
    if params.ntree {
        top.shape.detail = own_contour(&top.points);
    }
    (top, children)
}

/// Builds the levels above the chunks. `chunk_roots` are the roots of the chunks' subtrees (the
/// first node [`build_subtree`] returns for each chunk). Bottom-up, level by level, every parent
/// takes one point per occupied cell of its inner grid from its children's points (the deepest
/// MOSPT prefix within `capacity`); those points move up, so every point stays in exactly one
/// node, and each child keeps the rest in a rebuilt MOSPT. A child left empty stays in the tree
/// so that traversal still reaches its descendants.
///
/// Returns the new top nodes and the chunk roots as they are now, together, parents first.
/// Memory: the chunk roots (at most `capacity` points each) and the tops.
pub fn build_tops(
    chunk_roots: Vec<BuiltNode>,
    root: &Aabb,
    params: &NestedParams,
) -> Vec<BuiltNode> {
    use std::collections::BTreeMap;
    let mut by_level: BTreeMap<u32, Vec<BuiltNode>> = BTreeMap::new();
    for n in chunk_roots {
        by_level.entry(n.key.level).or_default().push(n);
    }
    let mut done = Vec::new();
    while let Some((&level, _)) = by_level.iter().next_back() {
        let nodes = by_level.remove(&level).expect("present");
        if level == 0 {
            done.extend(nodes);
            break;
        }
        let mut families: BTreeMap<NodeKey, Vec<BuiltNode>> = BTreeMap::new();
        for n in nodes {
            let parent = NodeKey {
                level: level - 1,
                cell: n.key.cell.map(|c| c / 2),
            };
            families.entry(parent).or_default().push(n);
        }
        for (parent, children) in families {
            let (top, children) = take_up(parent, children, root, params);
            done.extend(children);
            by_level.entry(level - 1).or_default().push(top);
        }
    }
    done.sort_by_key(|n| n.key);
    done
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::{HashMap, HashSet};

    fn random_batch(n: usize, seed: u64) -> PointBatch {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut b = PointBatch::with_schema(
            &myriad_core::Schema::new(vec![myriad_core::Attribute::GpsTime]),
            n,
        );
        for i in 0..n {
            // A terrain-like sheet with some scatter above it, and a few exact duplicates.
            let (x, y) = (next(), next());
            let z = if i % 5 == 0 {
                next()
            } else {
                0.3 + 0.1 * (x * 6.0).sin()
            };
            b.positions.push(if i % 97 == 0 {
                [0.5, 0.5, 0.5]
            } else {
                [x, y, z]
            });
            b.gps_time.as_mut().unwrap().push(i as f64);
        }
        b
    }

    #[test]
    fn every_point_once_in_a_node_that_contains_it() {
        let root = Aabb::new([0.0; 3], [1.0; 3]);
        let params = NestedParams {
            capacity: 3000,
            inner_depth: 5,
            max_level: 8,
            ntree: false,
        };
        let input = random_batch(60_000, 9);
        let nodes = build_subtree(input.clone(), &root, NodeKey::ROOT, &params);
        assert!(nodes.len() > 8, "{} nodes", nodes.len());
        let keys: HashSet<NodeKey> = nodes.iter().map(|n| n.key).collect();
        let mut seen = Vec::new();
        let mut per_node = HashMap::new();
        for n in &nodes {
            assert!(
                n.points.len() <= params.capacity || n.key.level == params.max_level,
                "{:?} holds {}",
                n.key,
                n.points.len()
            );
            assert_eq!(*n.prefix.last().unwrap() as usize, n.points.len());
            assert_eq!(n.prefix.len(), n.spacing.len());
            let cube = n.key.bounds(&root);
            assert!(
                n.points.positions.iter().all(|p| cube.contains(*p)),
                "{:?}: a point outside the node",
                n.key
            );
            if n.key.level > 0 {
                let parent = NodeKey {
                    level: n.key.level - 1,
                    cell: n.key.cell.map(|c| c / 2),
                };
                assert!(keys.contains(&parent), "{:?} has no parent", n.key);
            }
            // Each full level of the node's MOSPT holds one point per occupied cell.
            for l in 0..n.prefix.len() - 1 {
                let k = 1u64 << l;
                let cell = |p: [f64; 3]| {
                    (0..3)
                        .map(|a| {
                            (((p[a] - cube.min[a]) / cube.size()[a] * k as f64) as u64).min(k - 1)
                        })
                        .collect::<Vec<_>>()
                };
                let prefix: Vec<_> = n.points.positions[..n.prefix[l] as usize]
                    .iter()
                    .map(|p| cell(*p))
                    .collect();
                let all: HashSet<_> = n.points.positions.iter().map(|p| cell(*p)).collect();
                assert_eq!(
                    prefix.iter().cloned().collect::<HashSet<_>>().len(),
                    prefix.len(),
                    "{:?} level {l}: shared cell",
                    n.key
                );
                assert_eq!(
                    prefix.len(),
                    all.len(),
                    "{:?} level {l}: an occupied cell without point",
                    n.key
                );
            }
            seen.extend(
                n.points
                    .gps_time
                    .as_ref()
                    .unwrap()
                    .iter()
                    .map(|t| *t as u64),
            );
            per_node.insert(n.key, n.points.len());
        }
        seen.sort_unstable();
        assert_eq!(
            seen,
            (0..60_000).collect::<Vec<u64>>(),
            "every input point exactly once"
        );
        // Inner nodes are full: they pass points down only when they reached their capacity or
        // their inner grid.
        assert!(per_node[&NodeKey::ROOT] > 100);
    }

    #[test]
    fn small_input_is_one_leaf() {
        let root = Aabb::new([0.0; 3], [1.0; 3]);
        let nodes = build_subtree(
            random_batch(500, 2),
            &root,
            NodeKey::ROOT,
            &NestedParams {
                capacity: 1000,
                inner_depth: 6,
                max_level: 8,
                ntree: false,
            },
        );
        assert_eq!(nodes.len(), 1);
        assert_eq!(nodes[0].points.len(), 500);
    }
}
