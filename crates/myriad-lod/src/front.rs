//! The rendering front of a multi-way kd-tree (`mwkd`, Goswami et al. 2010, section IV): its
//! nodes replace their parents when drawn (inner nodes hold aggregates), so a frame draws a cut
//! through the tree rather than a subtree from the root.

use crate::hierarchy::Hierarchy;
use crate::selection::{Candidate, SelectOptions, Selected, Selection, nearest_depth};
use crate::view::Camera;
use myriad_core::{Aabb, NodeKey};
use myriad_format::NodeEntry;
use std::collections::{BinaryHeap, HashSet};

/// Whether a node's normals all face away from the eye (Goswami et al. 2010, section IV,
/// normal-cone culling): the angle between the cone's axis and the direction to the eye exceeds 90
/// degrees plus the cone's half angle plus the angle the node's bounding sphere subtends.
pub fn backfacing(cam: &Camera, bounds: &Aabb, cone: [f32; 4]) -> bool {
    if cone[3] <= 0.0 {
        return false;
    }
    let c = bounds.center();
    let s = bounds.size();
    let radius = 0.5 * (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
    let v: [f64; 3] = std::array::from_fn(|a| cam.position[a] - c[a]);
    let dist = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if dist <= radius {
        return false;
    }
    let cos = (0..3).map(|a| cone[a] as f64 * v[a]).sum::<f64>() / dist;
    let phi = cos.clamp(-1.0, 1.0).acos();
    let alpha = (cone[3] as f64).clamp(-1.0, 1.0).acos();
    let beta = (radius / dist).asin();
    phi > std::f64::consts::FRAC_PI_2 + alpha + beta
}

/// Goswami et al. 2010's LOD metric `(l_max - l + 1) / d^2` (their `c0 = c2 = 1, c1 = 0`), `d` the
/// distance from the eye to the node's box.
fn metric(h: &Hierarchy, cam: &Camera, e: &NodeEntry) -> f64 {
    let b = h.bounds(&e.key);
    let d: f64 = (0..3)
        .map(|a| {
            (b.min[a] - cam.position[a])
                .max(cam.position[a] - b.max[a])
                .max(0.0)
                .powi(2)
        })
        .sum();
    let d = d.sqrt().max(cam.near);
    (h.max_level - e.key.level + 1) as f64 / (d * d)
}

/// Whether a node may be in the front: in the frustum, kept by `keep`, and (with
/// [`Hierarchy::cull_backfaces`]) not facing away.
fn shows(
    h: &Hierarchy,
    cam: &Camera,
    frustum: &crate::view::Frustum,
    keep: &dyn Fn(&Aabb) -> bool,
    e: &NodeEntry,
) -> bool {
    let b = h.bounds(&e.key);
    frustum.intersects(&b)
        && keep(&b)
        && !(h.cull_backfaces && e.splats.is_some_and(|s| backfacing(cam, &b, s.cone)))
}

/// Whether a node's splats are smaller on screen than `min_pixels` (it is not refined).
fn fine(h: &Hierarchy, cam: &Camera, o: &SelectOptions, e: &NodeEntry) -> bool {
    let depth = nearest_depth(cam, &h.bounds(&e.key));
    let radius = e.spacing.first().copied().unwrap_or(0.0);
    2.0 * radius * cam.pixels_per_unit(depth) < o.min_pixels
}

/// The rendering front of a tree whose nodes replace their parents (`mwkd`, Goswami et al. 2010,
/// section IV, Figure 5): from the root, the node with the highest LOD metric is replaced by its
/// children in view while the count stays within the budget; the first node that cannot be refined
/// ends the refinement, and the front is every node reached. The metric is Goswami et al. 2010's
/// `(l_max - l + 1) / d^2` (their `c0 = c2 = 1, c1 = 0`), `d` the distance to the node's box; a
/// node whose splats are smaller than `min_pixels` on screen is not refined; nodes outside the
/// frustum, rejected by `keep`, or (with [`Hierarchy::cull_backfaces`]) facing away are left
/// out, their budget reclaimed.
pub fn select_front(
    h: &Hierarchy,
    cam: &Camera,
    o: &SelectOptions,
    keep: &dyn Fn(&Aabb) -> bool,
) -> Selection {
    let frustum = cam.frustum();
    let mut out = Selection::default();
    let visible = |e: &NodeEntry| shows(h, cam, &frustum, keep, e);
    let metric = |e: &NodeEntry| metric(h, cam, e);
    let Some(root) = h.get(&NodeKey::ROOT).filter(|e| visible(e)) else {
        return out;
    };
    let mut queue = BinaryHeap::new();
    queue.push(Candidate {
        deferred: false,
        benefit: metric(root),
        key: root.key,
    });
    let mut count = root.points as u64;
    let mut front: Vec<(NodeKey, f64)> = Vec::new();
    while let Some(top) = queue.peek() {
        let e = h.get(&top.key).expect("queued nodes exist");
        let kids: Vec<&NodeEntry> = h.children(&e.key).filter(|c| visible(c)).collect();
        let fine = fine(h, cam, o, e);
        // Children on pages not loaded yet: the node stays in the front until they are.
        let unloaded = h.unloaded_below(&e.key).next().is_some();
        if unloaded && !fine {
            out.pages.extend(h.unloaded_below(&e.key));
        }
        let leaf = unloaded || h.children(&e.key).next().is_none();
        if leaf || fine {
            let c = queue.pop().expect("peeked");
            front.push((c.key, c.benefit));
            continue;
        }
        let after = count - e.points as u64 + kids.iter().map(|c| c.points as u64).sum::<u64>();
        if after > o.budget {
            out.budget_reached = true;
            break;
        }
        queue.pop();
        count = after;
        for c in kids {
            queue.push(Candidate {
                deferred: false,
                benefit: metric(c),
                key: c.key,
            });
        }
    }
    front.extend(
        queue
            .into_sorted_vec()
            .into_iter()
            .rev()
            .map(|c| (c.key, c.benefit)),
    );
    for (key, benefit) in front {
        let e = h.get(&key).expect("front nodes exist");
        let room = o.budget.saturating_sub(out.points);
        let points = (e.points as u64).min(room);
        if points == 0 {
            out.budget_reached = true;
            continue;
        }
        out.points += points;
        out.nodes.push(Selected {
            key,
            points: points as u32,
            spacing: e.spacing.first().copied().unwrap_or(0.0),
            benefit,
            depth: nearest_depth(cam, &h.bounds(&key)),
        });
    }
    out
}

/// Goswami et al. 2010, section IV: the past frame's front refined and coarsened by the projected
/// size of its splats, rather than a front rebuilt from the root: each node of `previous` (or its
/// nearest ancestor still known), with the subtrees beside their paths at their roots so that the
/// whole tree is covered, climbs while its parent's splats are smaller than `min_pixels`
/// (coarsening) and descends into its visible children while its own are not (refining);
/// nodes out of view, rejected by `keep` or facing away drop out. Splats shrink down the tree,
/// so this is the front [`select_front`] reaches when the budget does not stop it: where it
/// would (more points than the budget), None, and the caller selects from the root (Figure 5).
/// Also returns the nodes it looked at.
pub fn update_front(
    h: &Hierarchy,
    cam: &Camera,
    o: &SelectOptions,
    keep: &dyn Fn(&Aabb) -> bool,
    previous: &[NodeKey],
) -> Option<(Selection, usize)> {
    let frustum = cam.frustum();
    let visible = |e: &NodeEntry| shows(h, cam, &frustum, keep, e);
    let fine = |e: &NodeEntry| fine(h, cam, o, e);
    // The past front as a cut through the whole tree.
    let mut cut: HashSet<NodeKey> = HashSet::new();
    for &k in previous {
        let mut k = k;
        while h.get(&k).is_none() && k.level > 0 {
            k = k.parent();
        }
        if h.get(&k).is_some() {
            cut.insert(k);
        }
    }
    if cut.is_empty() {
        cut.insert(NodeKey::ROOT);
    }
    let mut above: HashSet<NodeKey> = HashSet::new();
    for k in &cut {
        let mut a = *k;
        while a.level > 0 {
            a = a.parent();
            if !above.insert(a) {
                break;
            }
        }
    }
    // A node of the cut above another (the past front had both) gives way to it.
    cut.retain(|k| !above.contains(k));
    let beside: Vec<NodeKey> = (above.iter())
        .flat_map(|a| h.children(a).map(|c| c.key))
        .filter(|c| !above.contains(c) && !cut.contains(c))
        .collect();
    cut.extend(beside);
    let mut looked = 0;
    let mut count = 0u64;
    let mut front: HashSet<NodeKey> = HashSet::new();
    let mut out = Selection::default();
    let mut work: Vec<NodeKey> = cut.into_iter().collect();
    while let Some(k) = work.pop() {
        looked += 1;
        let Some(mut e) = h.get(&k) else { continue };
        // Coarsen while the parent's splats are below the threshold.
        while e.key.level > 0
            && let Some(p) = h.get(&e.key.parent())
            && fine(p)
        {
            looked += 1;
            e = p;
        }
        if front.contains(&e.key) || !visible(e) {
            continue;
        }
        let unloaded = h.unloaded_below(&e.key).next().is_some();
        if !fine(e) {
            if unloaded {
                out.pages.extend(h.unloaded_below(&e.key));
            } else if h.children(&e.key).next().is_some() {
                work.extend(h.children(&e.key).map(|c| c.key));
                continue;
            }
        }
        front.insert(e.key);
        count += e.points as u64;
        if count > o.budget {
            return None;
        }
    }
    let mut nodes: Vec<(&NodeEntry, f64)> = (front.iter())
        .filter_map(|k| h.get(k))
        .filter(|e| e.points > 0)
        .map(|e| (e, metric(h, cam, e)))
        .collect();
    nodes.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.key.cmp(&b.0.key)));
    for (e, benefit) in nodes {
        out.points += e.points as u64;
        out.nodes.push(Selected {
            key: e.key,
            points: e.points,
            spacing: e.spacing.first().copied().unwrap_or(0.0),
            benefit,
            depth: nearest_depth(cam, &h.bounds(&e.key)),
        });
    }
    out.pages.sort_by_key(|p| p.key);
    out.pages.dedup_by_key(|p| p.key);
    Some((out, looked))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::select::select;
    use crate::select::tests::entry;
    use myriad_format::PageRef;

    /// A tree of splats over the plane z = 0 of [0, 64]^3: every level's cells of the bottom
    /// layer, 100 points each, splats of a sixteenth of the cell.
    fn plane(depth: u32) -> Hierarchy {
        let mut entries = Vec::new();
        for level in 0..=depth {
            let n = 1u32 << level;
            let side = 64.0 / n as f64;
            for i in 0..n {
                for j in 0..n {
                    let key = NodeKey {
                        level,
                        cell: [i, j, 0],
                    };
                    let mut e = entry(key, 100, side / 16.0);
                    e.splats = Some(myriad_format::splat::SplatInfo {
                        page: PageRef {
                            offset: 64,
                            length: 10,
                            crc: 0,
                        },
                        radius: [0.0, 1.0],
                        cone: [0.0, 0.0, 1.0, -1.0],
                        aggregate: level < depth,
                    });
                    entries.push(e);
                }
            }
        }
        Hierarchy::new(Aabb::new([0.0; 3], [64.0; 3]), entries)
    }

    /// The front updated from the last frame's is the front rebuilt from the root, frame after
    /// frame along a flight that zooms in, turns and leaves; it looks at fewer nodes when the
    /// view moves a little; over the budget it leaves the choice to the root's traversal.
    #[test]
    fn the_front_updated_from_the_last_one_is_the_one_from_the_root() {
        let h = plane(6);
        let o = SelectOptions {
            budget: u64::MAX,
            min_pixels: 1.0,
        };
        let keep = |_: &Aabb| true;
        let mut previous: Vec<NodeKey> = Vec::new();
        let mut looked_total = 0;
        let mut fronts = 0;
        for step in 0..24 {
            let t = step as f64;
            let cam = Camera {
                position: [8.0 + t * 2.0, -20.0 + t * 3.0, 60.0 - t * 2.4],
                target: [32.0 + (t * 0.4).sin() * 20.0, 32.0, 0.0],
                up: [0.0, 0.0, 1.0],
                fov_y: 60.0,
                width: 640,
                height: 480,
                near: 0.01,
                far: 1000.0,
            };
            let whole = select_front(&h, &cam, &o, &keep);
            let sorted = |s: &Selection| {
                let mut v: Vec<(NodeKey, u32)> =
                    s.nodes.iter().map(|n| (n.key, n.points)).collect();
                v.sort();
                v
            };
            if !previous.is_empty() {
                let (updated, looked) =
                    update_front(&h, &cam, &o, &keep, &previous).expect("no budget");
                assert_eq!(sorted(&updated), sorted(&whole), "step {step}");
                assert_eq!(updated.points, whole.points);
                looked_total += looked;
                fronts += whole.nodes.len();
            }
            previous = whole.nodes.iter().map(|n| n.key).collect();
        }
        // About one look per front node (the root's traversal looks at every node above too).
        assert!(
            looked_total < 3 * fronts,
            "{looked_total} looks for {fronts} front nodes"
        );
        // Over the budget: None (the caller starts from the root).
        let tight = SelectOptions {
            budget: 500,
            min_pixels: 1.0,
        };
        let cam = Camera {
            position: [32.0, 32.0, 5.0],
            target: [32.0, 32.0, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_y: 60.0,
            width: 640,
            height: 480,
            near: 0.01,
            far: 1000.0,
        };
        assert!(update_front(&h, &cam, &tight, &keep, &previous).is_none());
        // A past front whose nodes are gone (pages dropped) starts from their ancestors.
        let gone = [NodeKey {
            level: 9,
            cell: [300, 300, 0],
        }];
        let (s, _) = update_front(&h, &cam, &o, &keep, &gone).expect("no budget");
        assert_eq!(s.points, select_front(&h, &cam, &o, &keep).points);
    }

    /// Goswami et al. 2010, section IV: a multi-way kd-tree's front refines a node only when its
    /// children fit the budget in its place; children out of view give their share back; normal
    /// cones cull nodes that face away.
    #[test]
    fn the_front_replaces_parents_within_the_budget() {
        let root = Aabb::new([0.0; 3], [10.0; 3]);
        let splat = |aggregate, cone: [f32; 4]| myriad_format::splat::SplatInfo {
            page: PageRef {
                offset: 64,
                length: 10,
                crc: 0,
            },
            radius: [0.01, 0.02],
            cone,
            aggregate,
        };
        let up = [0.0, 0.0, 1.0, 0.9];
        let node = |key: NodeKey, b: Aabb, aggregate| {
            let mut e = entry(key, 100, 0.01);
            e.bounds = Some(b);
            e.splats = Some(splat(aggregate, up));
            e
        };
        let r = node(NodeKey::ROOT, Aabb::new([0.0; 3], [10.0, 1.0, 1.0]), true);
        let a = node(
            NodeKey::ROOT.child(0),
            Aabb::new([0.0; 3], [5.0, 1.0, 1.0]),
            false,
        );
        let b = node(
            NodeKey::ROOT.child(1),
            Aabb::new([5.0, 0.0, 0.0], [10.0, 1.0, 1.0]),
            false,
        );
        let mut h = Hierarchy::new(root, [r, a.clone(), b.clone()]);
        assert!(h.splats());
        let above = Camera {
            position: [5.0, 0.5, 30.0],
            target: [5.0, 0.5, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_y: 60.0,
            width: 400,
            height: 400,
            near: 0.01,
            far: 1000.0,
        };
        let keys = |s: &Selection| s.nodes.iter().map(|n| n.key).collect::<Vec<_>>();
        let o = |budget| SelectOptions {
            budget,
            min_pixels: 0.0,
        };
        // 150: the children (200 points) do not fit in the root's place.
        let s = select(&h, &above, &o(150));
        assert_eq!(keys(&s), vec![NodeKey::ROOT]);
        assert!(s.budget_reached);
        // 250: they do; the root is not drawn with them.
        let s = select(&h, &above, &o(250));
        let mut k = keys(&s);
        k.sort();
        assert_eq!(k, vec![a.key, b.key]);
        assert_eq!(s.points, 200);
        // Only the second child in view: it alone replaces the root, within 100.
        let right = Camera {
            position: [8.0, 0.5, 3.0],
            target: [8.0, 0.5, 0.0],
            ..above
        };
        assert_eq!(keys(&select(&h, &right, &o(100))), vec![b.key]);
        // Seen from below, the up-facing nodes are culled, when culling is on.
        let below = Camera {
            position: [5.0, 0.5, -30.0],
            ..above
        };
        assert_eq!(select(&h, &below, &o(250)).nodes.len(), 2);
        h.cull_backfaces = true;
        assert!(select(&h, &below, &o(250)).nodes.is_empty());
        assert_eq!(select(&h, &above, &o(250)).nodes.len(), 2);
        assert!(backfacing(&below, &h.bounds(&a.key), up));
        assert!(!backfacing(
            &below,
            &h.bounds(&a.key),
            [0.0, 0.0, 1.0, -0.5]
        ));
    }
}
