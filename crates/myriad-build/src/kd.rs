//! The `kd` structure (Discher et al. 2018, section 3.1): a balanced binary kd-tree. A node with
//! more than `capacity` points keeps a representative subset of them, one point per occupied cell
//! of its inner grid (the deepest MOSPT prefix within the capacity, over the cube around the
//! node's box), and splits the rest at their median along the longest axis of its box into two
//! children of equal count. So the tree is balanced whatever the points' distribution, and every
//! point ends in exactly one node. A node's bounds are the box of its subtree's points; the keys
//! number the tree (child 0 and 1 of a key are its first two octree children), so the file
//! format and hierarchy pages are those of the octree, with the bounds stored per node.
//!
//! Out of core, as the octree: the distribution's chunks are grouped by the same median rule,
//! weighted by their counts, until a group fits the chunk budget (so splits above the groups fall
//! on chunk boundaries: balanced to a chunk); each group's subtree is built in memory with exact
//! medians; the nodes above the groups take their representatives up from their two children
//! ([`take_up`]).

use crate::mospt;
use crate::nested::{
    BuiltNode, NestedParams, fitting_prefix, keep_rest, node_from_prefix, union_of,
};
use myriad_core::{Aabb, NodeKey, PointBatch};

/// Deepest kd level (node keys have 31 levels; a balanced tree of 2^16-point leaves reaches 31
/// at 10^14 points).
pub const MAX_LEVEL: u32 = 31;

/// The box of `positions`.
pub fn bounds_of(positions: &[[f64; 3]]) -> Aabb {
    let mut b = Aabb::EMPTY;
    positions.iter().for_each(|&p| b.extend(p));
    b
}

/// The cube with `b`'s minimum corner and its longest side: the MOSPT grid of a node.
fn cube_around(b: &Aabb) -> Aabb {
    let side = b.size().into_iter().fold(0.0, f64::max).max(1e-9);
    Aabb::new(b.min, b.min.map(|m| m + side))
}

fn longest_axis(b: &Aabb) -> usize {
    let s = b.size();
    (0..3).max_by(|&i, &j| s[i].total_cmp(&s[j])).unwrap_or(0)
}

/// Discher et al. 2018 (section 5.1) size points "based on a node's bounding box rather than its
/// LoD": the spacing of the first `p` points of a node is that of `p` points spread over its box's
/// two largest extents (the area of the surface the box can hold).
fn box_spacing(bounds: &Aabb, prefix: &[u64]) -> Vec<f64> {
    let mut s = bounds.size();
    s.sort_by(|a, b| b.total_cmp(a));
    let area = (s[0] * s[1].max(s[0] * 1e-3)).max(1e-12);
    prefix
        .iter()
        .map(|&p| (area / p.max(1) as f64).sqrt())
        .collect()
}

/// Finishes a built node: its bounds, and its spacing from them.
fn with_bounds(mut node: BuiltNode, bounds: Aabb) -> BuiltNode {
    node.spacing = box_spacing(&bounds, &node.prefix);
    node.shape.bounds = Some(bounds);
    node
}

/// A node holding all of `batch` in MOSPT order (a leaf).
fn leaf(key: NodeKey, batch: &PointBatch, bounds: Aabb) -> BuiltNode {
    let m = mospt::build(batch, &cube_around(&bounds), mospt::CODE_LEVELS);
    with_bounds(node_from_prefix(key, batch, &m, batch.len()), bounds)
}

/// Builds the kd subtree rooted at `key` over `batch`, handing each node to `emit` as it is
/// built (the root first).
pub fn build_subtree_with<E>(
    batch: PointBatch,
    key: NodeKey,
    params: &NestedParams,
    emit: &mut dyn FnMut(BuiltNode) -> Result<(), E>,
) -> Result<(), E> {
    let mut work = vec![(key, batch)];
    while let Some((key, batch)) = work.pop() {
        let n = batch.len();
        if n == 0 {
            continue;
        }
        let bounds = bounds_of(&batch.positions);
        if n <= params.capacity || key.level >= MAX_LEVEL {
            emit(leaf(key, &batch, bounds))?;
            continue;
        }
        let m = mospt::build(&batch, &cube_around(&bounds), params.inner_depth);
        let keep = fitting_prefix(&m, params.capacity);
        let node = with_bounds(node_from_prefix(key, &batch, &m, keep), bounds);
        let mut rest_mask = vec![true; n];
        for &i in &m.order[..keep] {
            rest_mask[i as usize] = false;
        }
        drop(m);
        let mut rest = batch;
        rest.retain_mask(&rest_mask);
        // The median along the longest axis: the lower half goes to child 0.
        let axis = longest_axis(&bounds);
        let mut order: Vec<u32> = (0..rest.len() as u32).collect();
        let half = rest.len() / 2;
        if half > 0 {
            let p = &rest.positions;
            order.select_nth_unstable_by(half, |&a, &b| {
                p[a as usize][axis].total_cmp(&p[b as usize][axis])
            });
        }
        let (lower, upper) = order.split_at(half);
        work.push((key.child(1), rest.gather(upper)));
        work.push((key.child(0), rest.gather(lower)));
        drop(rest);
        emit(node)?;
    }
    Ok(())
}

/// A set of chunks (by their boxes and point counts) to be built as one subtree.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    pub key: NodeKey,
    /// Indices of the chunks.
    pub chunks: Vec<usize>,
    pub points: u64,
}

/// Splits `chunks` (box, points) into `arity` parts of about equal count by their centres along
/// the longest axis of their boxes (the count-weighted median for 2), recursively, until a group
/// holds at most `limit` points or one chunk. Part `i` of a group is its key's child `i`.
pub fn group_chunks(chunks: &[(Aabb, u64)], limit: u64, arity: usize) -> Vec<Group> {
    let mut out = Vec::new();
    let mut work = vec![(NodeKey::ROOT, (0..chunks.len()).collect::<Vec<_>>())];
    while let Some((key, mut idx)) = work.pop() {
        let points: u64 = idx.iter().map(|&i| chunks[i].1).sum();
        if points <= limit || idx.len() == 1 || key.level >= MAX_LEVEL {
            out.push(Group {
                key,
                chunks: idx,
                points,
            });
            continue;
        }
        let b = idx.iter().fold(Aabb::EMPTY, |b, &i| b.union(&chunks[i].0));
        let axis = longest_axis(&b);
        idx.sort_by(|&i, &j| chunks[i].0.center()[axis].total_cmp(&chunks[j].0.center()[axis]));
        // Part j ends where the running count first reaches (j + 1) / arity of the whole;
        // every part keeps at least one chunk.
        let parts = arity.clamp(2, 8).min(idx.len());
        let mut cuts: Vec<usize> = Vec::with_capacity(parts);
        let mut below = 0;
        for (k, &i) in idx.iter().enumerate() {
            below += chunks[i].1;
            let j = cuts.len();
            if j + 1 < parts && below * parts as u64 >= points * (j as u64 + 1) {
                let first = cuts.last().map_or(1, |&c| c + 1);
                cuts.push((k + 1).max(first).min(idx.len() - (parts - 1 - j)));
            }
        }
        while cuts.len() + 1 < parts {
            let next = cuts.last().map_or(1, |&c| c + 1);
            cuts.push(next);
        }
        cuts.push(idx.len());
        let mut start = 0;
        for (j, &end) in cuts.iter().enumerate() {
            work.push((key.child(j), idx[start..end].to_vec()));
            start = end;
        }
    }
    out.sort_by_key(|g| g.key);
    out
}

/// One step above the groups: `parent` takes its representatives from its children's points
/// (the deepest MOSPT prefix within `capacity` over the cube around their boxes); each child keeps
/// the rest. Returns the parent and the children as they are now.
pub fn take_up(
    parent: NodeKey,
    mut children: Vec<BuiltNode>,
    params: &NestedParams,
) -> (BuiltNode, Vec<BuiltNode>) {
    let union = union_of(&children);
    let bounds = children
        .iter()
        .filter_map(|c| c.shape.bounds)
        .fold(Aabb::EMPTY, |a, b| a.union(&b));
    let m = mospt::build(&union, &cube_around(&bounds), params.inner_depth);
    let keep = fitting_prefix(&m, params.capacity).min(union.len());
    keep_rest(&mut children, &m.order[..keep], &|child, stay| {
        leaf(child.key, &stay, child.shape.bounds.unwrap_or(bounds))
    });
    (
        with_bounds(node_from_prefix(parent, &union, &m, keep), bounds),
        children,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_core::{Attribute, Schema};

    fn batch(n: usize) -> PointBatch {
        let mut b = PointBatch::with_schema(&Schema::new(vec![Attribute::Intensity]), 0);
        let mut s = 12345u64;
        for i in 0..n {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let r = |k: u32| ((s >> k) & 0xffff) as f64 / 65536.0;
            // Skewed: most points crowd near x = 0, so an octree would be unbalanced.
            b.positions
                .push([r(16).powi(4) * 100.0, r(32) * 10.0, r(48)]);
            b.intensity.as_mut().unwrap().push(i as u16);
        }
        b
    }

    fn params() -> NestedParams {
        NestedParams {
            capacity: 500,
            inner_depth: 5,
            max_level: 20,
            ntree: false,
        }
    }

    #[test]
    fn balanced_and_nothing_lost() {
        let b = batch(20_000);
        let mut nodes = Vec::new();
        build_subtree_with(b, NodeKey::ROOT, &params(), &mut |n| {
            nodes.push(n);
            Ok::<(), ()>(())
        })
        .unwrap();
        // Every point once.
        let mut ids: Vec<u16> = nodes
            .iter()
            .flat_map(|n| n.points.intensity.clone().unwrap())
            .collect();
        ids.sort_unstable();
        assert_eq!(ids, (0..20_000u32).map(|i| i as u16).collect::<Vec<_>>());
        // Balanced: leaves are all at the same depth or one apart, in spite of the skew.
        let levels: Vec<u32> = nodes
            .iter()
            .filter(|n| {
                !nodes
                    .iter()
                    .any(|c| c.key.level == n.key.level + 1 && c.key.parent() == n.key)
            })
            .map(|n| n.key.level)
            .collect();
        let (lo, hi) = (levels.iter().min().unwrap(), levels.iter().max().unwrap());
        assert!(hi - lo <= 1, "leaf levels {lo}..{hi}");
        // Binary: children are octants 0 and 1 only; bounds hold the node's points.
        for n in &nodes {
            assert!(n.key.cell[1] == 0 && n.key.cell[2] == 0);
            let b = n.shape.bounds.unwrap();
            assert!(n.points.positions.iter().all(|&p| b.contains(p)));
            assert!(n.points.len() <= params().capacity);
        }
        // Siblings split the parent's rest in halves: within one point.
        for n in &nodes {
            if n.key.level > 0 && n.key.cell[0] % 2 == 0 {
                let sib = nodes
                    .iter()
                    .find(|m| m.key == n.key.parent().child(1))
                    .unwrap();
                let count = |k: NodeKey| -> usize {
                    nodes
                        .iter()
                        .filter(|m| {
                            m.key.level >= k.level && {
                                let mut a = m.key;
                                while a.level > k.level {
                                    a = a.parent();
                                }
                                a == k
                            }
                        })
                        .map(|m| m.points.len())
                        .sum()
                };
                let (a, b) = (count(n.key), count(sib.key));
                assert!(a.abs_diff(b) <= 1, "{} {a} {b}", n.key);
            }
        }
    }

    #[test]
    fn groups_split_by_count() {
        // Ten chunks along x, the first holding as many points as the other nine.
        let chunks: Vec<(Aabb, u64)> = (0..10)
            .map(|i| {
                let x = i as f64;
                (
                    Aabb::new([x, 0.0, 0.0], [x + 1.0, 1.0, 1.0]),
                    if i == 0 { 900 } else { 100 },
                )
            })
            .collect();
        let groups = group_chunks(&chunks, 1000, 2);
        assert_eq!(groups.len(), 2);
        assert_eq!(groups[0].chunks, vec![0]);
        assert_eq!(groups[0].key, NodeKey::ROOT.child(0));
        assert_eq!(groups[1].points, 900);
        let all: u64 = groups.iter().map(|g| g.points).sum();
        assert_eq!(all, 1800);
        // Five ways: every chunk in one part, parts in order along x, about 1800 / 5 each
        // where the chunks allow.
        let groups = group_chunks(&chunks, 500, 5);
        let mut seen: Vec<usize> = groups.iter().flat_map(|g| g.chunks.clone()).collect();
        seen.sort_unstable();
        assert_eq!(seen, (0..10).collect::<Vec<_>>());
        assert_eq!(groups[0].chunks, vec![0]);
        assert!(groups.iter().all(|g| g.points <= 900));
        assert_eq!(groups.len(), 5);
    }

    #[test]
    fn take_up_moves_points_up_once() {
        let b = batch(4000);
        let half = b.slice(0..2000);
        let other = b.slice(2000..4000);
        let kids = vec![
            leaf(NodeKey::ROOT.child(0), &half, bounds_of(&half.positions)),
            leaf(NodeKey::ROOT.child(1), &other, bounds_of(&other.positions)),
        ];
        let (top, kids) = take_up(NodeKey::ROOT, kids, &params());
        assert!(top.points.len() <= 500 && !top.points.is_empty());
        let total: usize = top.points.len() + kids.iter().map(|k| k.points.len()).sum::<usize>();
        assert_eq!(total, 4000);
        let b = top.shape.bounds.unwrap();
        assert!(
            kids.iter()
                .all(|k| k.points.positions.iter().all(|&p| b.contains(p)))
        );
    }
}
