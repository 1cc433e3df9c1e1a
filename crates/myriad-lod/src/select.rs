//! Selection of what to draw in a frame (Scheiblauer 2006, sections 4.3-4.4): the outer tree is
//! traversed from the root in benefit order (projected size over the angle to the view centre),
//! nodes outside the frustum or whose points would fall below the pixel threshold are skipped,
//! and traversal stops at the point budget. Inside a node, the prefix of levels whose spacing
//! still covers at least the threshold in pixels is drawn (a prefix of a node is a coarser level
//! of detail of it). Children are visited only below a node drawn whole: they refine it.
//!
//! Adaptive point size (Scheiblauer 2006, section 4.4; Discher et al. 2018, section 5.1): each
//! selected node gets the spacing of the finest level it draws; where nodes are octree cells, the
//! shaders then size each point from the finest drawn node around it ([`crate::DrawnTree`]); in
//! kd-trees, a node all of whose children in view are drawn takes their finest spacing, pulled up
//! the tree.
//!
//! The structures whose nodes are not plain octree cells: layered nodes carry a contour, kd
//! nodes their box; both are culled by it and weighed by its projected area. mwkd trees, whose
//! nodes replace their parents, are selected as a front ([`crate::front`]).

use crate::hierarchy::Hierarchy;
use crate::occlusion::{Occluder, Verdict};
pub(crate) use crate::selection::{Candidate, nearest_depth, nearest_depth_of};
pub use crate::selection::{SelectOptions, Selected, Selection};
use crate::view::{Camera, Frustum};
use myriad_core::{Aabb, NodeKey, Obb};
use myriad_format::NodeEntry;
use myriad_format::hierarchy::PAGE_LEVELS;
use std::collections::{BinaryHeap, HashMap};

/// The distance between neighbouring points of each level of detail of a node. A level's cell
/// size is that distance where the level has a point in every occupied cell, which holds for the
/// coarse levels; the finest levels of a node hold its leftover points (few, in tiny cells), and
/// there the cell size says nothing about their density: a level with k times the points of the
/// level before on the same surface has points 1/sqrt(k) as far apart. The larger of the two.
pub fn point_spacing(e: &NodeEntry) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::with_capacity(e.spacing.len());
    for (l, &cell) in e.spacing.iter().enumerate() {
        let s = match (l, out.last()) {
            (0, _) | (_, None) => cell,
            (_, Some(&prev)) => {
                let k = e.prefix[l] as f64 / e.prefix[l - 1].max(1) as f64;
                cell.max(prev / k.max(1.0).sqrt())
            }
        };
        out.push(s);
    }
    out
}

/// The radius within which a point of node `e` needs another of its points to not be lone
/// (`myriad_core::geometry::lone_points`; renderers draw a lone point of a leaf small, having no
/// surface around it to close): two of the spacings its finest level is drawn at
/// ([`point_spacing`]: a point drawn that wide, one and a half spacings at the default scale,
/// with no other within two, stands apart from everything around it). 0 (none lone) for a node
/// without spacings.
pub fn lone_radius(e: &NodeEntry) -> f64 {
    point_spacing(e).last().map_or(0.0, |s| 2.0 * s)
}

/// Nodes within this angle (radians, about 17 degrees) of the view axis count as central alike.
/// Scheiblauer 2006 floors the angle only against division by zero; a wider floor spreads the
/// budget more evenly over the middle of the view: `myriad bench render` (PSNR at a 1 M budget
/// against every point, KY and sheridan, three views) gains up to 1.35 dB with 0.3 over 0.001 and
/// loses nowhere by more than 0.06 dB; ignoring the angle altogether (3.2) loses 0.8 dB looking
/// straight down.
const CENTRAL_ANGLE: f64 = 0.3;

/// The unit direction from the eye to `p` (the view direction when they coincide).
fn sight(cam: &Camera, p: [f64; 3]) -> [f64; 3] {
    let v: [f64; 3] = std::array::from_fn(|a| p[a] - cam.position[a]);
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if len > 0.0 {
        v.map(|x| x / len)
    } else {
        cam.forward()
    }
}

/// Scheiblauer 2006, section 4.3: a projected size over the angle between the view direction and
/// `dir` (the direction to the node's centre), the angle floored at [`CENTRAL_ANGLE`].
fn over_angle(cam: &Camera, projected: f64, dir: [f64; 3]) -> f64 {
    let f = cam.forward();
    let cos = (dir[0] * f[0] + dir[1] * f[1] + dir[2] * f[2]).clamp(-1.0, 1.0);
    projected / cos.acos().max(CENTRAL_ANGLE)
}

/// An octree cell's benefit: its side as seen at its nearest depth.
fn benefit(cam: &Camera, cube: &Aabb, depth: f64) -> f64 {
    let projected = cube.size()[0] * cam.pixels_per_unit(depth);
    over_angle(cam, projected, sight(cam, cube.center()))
}

/// Points a node with a contour draws at most per pixel its contour covers ([`contour_pixels`]):
/// a surface facing the eye at the spacing that shows holds about one a pixel; the margin keeps
/// such a node's levels whole.
pub const CONTOUR_POINTS: f64 = 1.5;

/// A contour is flat (Kanzok et al. 2015: an oriented box of the node's own points, on one surface)
/// where its thinnest side is at most this share of its longest; a box around several surfaces says
/// nothing of how many of its points show, and keeps its levels.
pub const FLAT_CONTOUR: f64 = 0.1;

pub fn flat(c: &Obb) -> bool {
    let h = c.half_extents;
    let thinnest = h.iter().copied().fold(f64::INFINITY, f64::min);
    thinnest <= FLAT_CONTOUR * h.iter().copied().fold(0.0, f64::max)
}

/// The pixels a contour covers seen from `cam` at `ppu` pixels a unit: its area across the line
/// of sight (as [`benefit_of_box`] takes it), each side grown by half a pixel, so that a flat
/// contour seen edge-on covers the line it is drawn as.
fn contour_pixels(cam: &Camera, c: &Obb, ppu: f64) -> f64 {
    let dir = sight(cam, c.center);
    let grow = 0.5 / ppu.max(1e-300);
    let h = c.half_extents.map(|v| v + grow);
    let d = |i: usize| (0..3).map(|k| c.axes[i][k] * dir[k]).sum::<f64>().abs();
    4.0 * (h[1] * h[2] * d(0) + h[0] * h[2] * d(1) + h[0] * h[1] * d(2)) * ppu * ppu
}

/// A box of any orientation (a contour, Kanzok et al. 2015, section 3.1; a kd box): the square root
/// of its area projected along the line of sight to its centre (a flat contour seen edge-on is
/// small), in pixels at its nearest depth.
fn benefit_of_box(cam: &Camera, b: &Obb) -> f64 {
    let depth = nearest_depth_of(cam, &b.corners());
    let dir = sight(cam, b.center);
    let h = b.half_extents;
    let d = |i: usize| (0..3).map(|k| b.axes[i][k] * dir[k]).sum::<f64>().abs();
    let area = 4.0 * (h[1] * h[2] * d(0) + h[0] * h[2] * d(1) + h[0] * h[1] * d(2));
    over_angle(cam, area.sqrt() * cam.pixels_per_unit(depth), dir)
}

/// Whether a node may be in view: its box, and its contour where it has one, against the
/// frustum (its points lie in both; an oriented contour can reach out of the box, and a node
/// whose box is out of view has nothing to draw, and its page is never asked for).
fn in_view(h: &Hierarchy, frustum: &Frustum, e: &NodeEntry) -> bool {
    frustum.intersects(&h.bounds(&e.key))
        && e.contour.as_ref().is_none_or(|c| frustum.intersects_obb(c))
}

/// Chooses the nodes and prefixes to draw for `cam`.
pub fn select(h: &Hierarchy, cam: &Camera, o: &SelectOptions) -> Selection {
    select_where(h, cam, o, &|_| true)
}

/// [`select`] among the nodes whose cube `keep` accepts (a clipping box: nodes it hides entirely
/// take no budget).
pub fn select_where(
    h: &Hierarchy,
    cam: &Camera,
    o: &SelectOptions,
    keep: &dyn Fn(&Aabb) -> bool,
) -> Selection {
    select_occluded(h, cam, o, keep, None)
}

/// [`select_where`] culling the nodes hidden behind those selected before them, where an
/// occluder is given ([`crate::occlusion`]; not for `mwkd` fronts).
pub fn select_occluded(
    h: &Hierarchy,
    cam: &Camera,
    o: &SelectOptions,
    keep: &dyn Fn(&Aabb) -> bool,
    occluder: Option<&mut Occluder>,
) -> Selection {
    select_occluded_from(h, cam, o, keep, occluder, &[])
}

/// [`select_occluded`] that, for `mwkd` fronts, updates the front drawn last (`previous`)
/// where the budget allows ([`crate::front::update_front`]) rather than starting from the root.
pub fn select_occluded_from(
    h: &Hierarchy,
    cam: &Camera,
    o: &SelectOptions,
    keep: &dyn Fn(&Aabb) -> bool,
    occluder: Option<&mut Occluder>,
    previous: &[NodeKey],
) -> Selection {
    if h.splats() {
        let mut s = match (!previous.is_empty())
            .then(|| crate::front::update_front(h, cam, o, keep, previous))
            .flatten()
        {
            Some((s, _)) => s,
            None => crate::front::select_front(h, cam, o, keep),
        };
        if let Some(occ) = occluder {
            cull_front(h, &mut s, occ);
        }
        return s;
    }
    select_eyes(h, std::slice::from_ref(cam), o, keep, occluder)
}

/// Occlusion culling of an `mwkd` front (a cut through the tree: a node hides no subtree of
/// its own): its nodes from the nearest, each tested against what the nodes before it cover;
/// a hidden one leaves the front, the others cover what lies behind them. The points of the
/// nodes culled leave the selection (the front is not refined again with them).
fn cull_front(h: &Hierarchy, s: &mut Selection, occ: &mut Occluder) {
    let mut order: Vec<usize> = (0..s.nodes.len()).collect();
    order.sort_by(|&a, &b| s.nodes[a].depth.total_cmp(&s.nodes[b].depth));
    let mut culled = vec![false; s.nodes.len()];
    for i in order {
        let n = &s.nodes[i];
        let Some(e) = h.get(&n.key) else { continue };
        if matches!(
            occ.test(&n.key, &h.bounds(&n.key).corners()),
            Verdict::Hidden
        ) {
            culled[i] = true;
            s.culled += 1;
            s.hidden.push(n.key);
            s.points -= n.points as u64;
            continue;
        }
        occ.cover(e, &e.spacing, n.points as usize);
    }
    let mut i = 0;
    s.nodes.retain(|_| {
        i += 1;
        !culled[i - 1]
    });
}

/// One selection for several eyes seen together (Discher et al. 2018's stereo: one selection for
/// both eyes): a node is in view where any eye's frustum meets it, and its benefit and its level of
/// detail are those of the eye that sees it best (the nearest). Occlusion, where given, is tested
/// as the first eye sees. `mwkd` fronts are selected for the first eye.
pub fn select_eyes(
    h: &Hierarchy,
    eyes: &[Camera],
    o: &SelectOptions,
    keep: &dyn Fn(&Aabb) -> bool,
    mut occluder: Option<&mut Occluder>,
) -> Selection {
    let cam = &eyes[0];
    if h.splats() {
        return crate::front::select_front(h, cam, o, keep);
    }
    let frustums: Vec<Frustum> = eyes.iter().map(Camera::frustum).collect();
    let seen = |e: &NodeEntry| frustums.iter().any(|f| in_view(h, f, e));
    let best = |f: &dyn Fn(&Camera) -> f64| eyes.iter().map(f).fold(f64::NEG_INFINITY, f64::max);
    let mut out = Selection::default();
    let mut queue = BinaryHeap::new();
    let consider = |key: NodeKey, queue: &mut BinaryHeap<Candidate>| {
        let Some(e) = h.get(&key) else { return };
        let cube = h.bounds(&key);
        let contour = e.contour;
        if !seen(e) || !keep(&cube) {
            return;
        }
        let benefit = match &contour {
            // An octree cell: its side (Scheiblauer 2006).
            None if h.cells() => best(&|cam| benefit(cam, &cube, nearest_depth(cam, &cube))),
            // A contour (Kanzok et al. 2015) or a kd box (Discher et al. 2018): the square root of
            // its projected area.
            Some(c) => best(&|cam| benefit_of_box(cam, c)),
            None => best(&|cam| benefit_of_box(cam, &Obb::from_aabb(&cube))),
        };
        queue.push(Candidate {
            benefit,
            key,
            deferred: false,
        });
    };
    if h.get(&NodeKey::ROOT).is_some() {
        consider(NodeKey::ROOT, &mut queue);
    }
    while let Some(Candidate {
        benefit,
        key,
        deferred,
    }) = queue.pop()
    {
        let Some(e) = h.get(&key) else { continue };
        if key.level % PAGE_LEVELS == 0 {
            out.used_pages.push(key);
        }
        let corners = match &e.contour {
            Some(c) => c.corners(),
            None => h.bounds(&key).corners(),
        };
        match occluder.as_deref_mut().map(|occ| occ.test(&key, &corners)) {
            Some(Verdict::Hidden) => {
                out.culled += 1;
                out.hidden.push(key);
                continue;
            }
            // Hidden as far as the software test knows, seen by the last queries: after
            // every node in the open.
            Some(Verdict::Seen) if !deferred => {
                queue.push(Candidate {
                    benefit,
                    key,
                    deferred: true,
                });
                continue;
            }
            _ => {}
        }
        let depth = eyes
            .iter()
            .map(|cam| nearest_depth_of(cam, &corners))
            .fold(f64::INFINITY, f64::min);
        let ppu = cam.pixels_per_unit(depth);
        // Levels whose spacing still shows; none: the node (and all below) adds nothing.
        let spacing = point_spacing(e);
        let levels = spacing
            .iter()
            .take_while(|&&s| s * ppu >= o.min_pixels)
            .count();
        // A node whose spacing no longer shows adds nothing to what its ancestors drew; where
        // none of them has points (a dataset still being built: `myriad_build::growing`'s
        // stand-ins), its coarsest level is drawn instead.
        let covered = || {
            let mut k = key;
            while k.level > 0 {
                k = k.parent();
                if h.get(&k).is_none_or(|a| a.points > 0) {
                    return true;
                }
            }
            key.level == 0
        };
        let levels = if levels == 0 && e.points > 0 {
            if covered() {
                continue;
            }
            1
        } else {
            levels
        };
        // Kanzok et al. 2015, section 3.2.2: the projected size of the node's contour is its level
        // of detail. A flat node's levels stop at the first holding more points than its contour
        // covers pixels (seen edge-on it covers a line: its coarse levels draw it); its coarsest
        // level is always drawn. Both of its contours hold its own points (its subtree's and,
        // for a node that passes points down, its own points'): by default the tighter flat
        // one counts ([`crate::hierarchy::DetailContour`]).
        let most = h
            .detail_contour
            .of(e)
            .into_iter()
            .flatten()
            .filter(|c| flat(c))
            .map(|c| CONTOUR_POINTS * contour_pixels(cam, c, ppu) / (o.min_pixels * o.min_pixels))
            .fold(f64::INFINITY, f64::min);
        let levels = if levels > 1 && o.min_pixels > 0.0 && most.is_finite() {
            let mut l = levels;
            while l > 1 && e.prefix[l - 1] as f64 > most {
                l -= 1;
            }
            l
        } else {
            levels
        };
        let whole = levels == e.prefix.len();
        let mut count = if e.points == 0 {
            0
        } else {
            e.prefix[levels - 1] as u64
        };
        if out.points + count > o.budget {
            count = o.budget - out.points;
            out.budget_reached = true;
        }
        if count > 0 {
            let drawn_level = e
                .prefix
                .iter()
                .position(|&p| p as u64 >= count)
                .unwrap_or(e.prefix.len() - 1);
            out.points += count;
            if let Some(occ) = occluder.as_deref_mut() {
                occ.cover(e, &spacing, count as usize);
            }
            out.nodes.push(Selected {
                key,
                points: count as u32,
                spacing: spacing[drawn_level],
                benefit,
                depth,
            });
        }
        if out.budget_reached {
            // Pages whose root would come after this node in benefit order would not be
            // reached: not asked for (where the root's benefit is known from its key: octree
            // cells without contours).
            if h.cells() && !h.contours() {
                out.pages.retain(|p| {
                    let cube = p.key.bounds(&h.root);
                    best(&|cam| self::benefit(cam, &cube, nearest_depth(cam, &cube))) >= benefit
                });
            }
            break;
        }
        if whole || e.points == 0 {
            for c in h.children(&key) {
                consider(c.key, &mut queue);
            }
            // Where nodes are their keys' cubes, a page whose root is out of view or
            // clipped away holds nothing this view draws: not asked for.
            out.pages.extend(h.unloaded_below(&key).filter(|p| {
                let cube = p.key.bounds(&h.root);
                !h.cells() || (frustums.iter().any(|f| f.intersects(&cube)) && keep(&cube))
            }));
        }
    }
    if !h.cells() {
        pull_up_spacing(h, &mut out, &frustums);
    }
    out
}

/// Adaptive point size per node for trees whose nodes are not octree cells (Discher et al. 2018,
/// section 5.1): a node drawn whole, all of whose children in view are drawn, takes the finest
/// spacing among them (pulled up from the deepest drawn descendants), so its points shrink where
/// its children fill in between them. A node with a child in view that is not drawn keeps its own
/// spacing: there its points are all there is.
fn pull_up_spacing(h: &Hierarchy, s: &mut Selection, frustums: &[Frustum]) {
    let index: HashMap<NodeKey, usize> = s
        .nodes
        .iter()
        .enumerate()
        .map(|(i, n)| (n.key, i))
        .collect();
    // Children are selected after their parents: walk backwards.
    for i in (0..s.nodes.len()).rev() {
        let key = s.nodes[i].key;
        let mut finest = f64::INFINITY;
        let mut all = true;
        for c in h.children(&key) {
            match index.get(&c.key) {
                Some(&j) => finest = finest.min(s.nodes[j].spacing),
                None => {
                    if c.points > 0 && frustums.iter().any(|f| in_view(h, f, c)) {
                        all = false;
                    }
                }
            }
        }
        if all && finest.is_finite() {
            s.nodes[i].spacing = s.nodes[i].spacing.min(finest);
        }
    }
}

/// Selection over several datasets sharing one point budget (Discher et al. 2018, section 3.1):
/// each is selected alone with the whole budget, then their nodes are taken in one benefit order
/// (each dataset's own order kept, so parents still come before children) until the budget is
/// spent.
pub fn select_many(
    hs: &[&Hierarchy],
    cam: &Camera,
    o: &SelectOptions,
    keep: &dyn Fn(&Aabb) -> bool,
) -> Vec<Selection> {
    let alone: Vec<Selection> = hs.iter().map(|h| select_where(h, cam, o, keep)).collect();
    merge(alone, o.budget)
}

/// Selections made alone (each with the whole budget), taken in one benefit order until the
/// budget is spent ([`select_many`]). A node a dataset culled as hidden came after the nodes
/// that hid it in that dataset's order, so it would have been cut with them.
pub fn merge(alone: Vec<Selection>, budget: u64) -> Vec<Selection> {
    let mut out: Vec<Selection> = vec![Selection::default(); alone.len()];
    let mut next = vec![0usize; alone.len()];
    let mut total = 0u64;
    // The dataset whose next node has the highest benefit.
    while let Some(k) = (0..alone.len())
        .filter(|&k| next[k] < alone[k].nodes.len())
        .max_by(|&a, &b| {
            alone[a].nodes[next[a]]
                .benefit
                .total_cmp(&alone[b].nodes[next[b]].benefit)
        })
    {
        let mut n = alone[k].nodes[next[k]].clone();
        next[k] += 1;
        let room = budget - total;
        let cut = (n.points as u64) > room;
        if cut {
            n.points = room as u32;
        }
        if n.points > 0 {
            total += n.points as u64;
            out[k].points += n.points as u64;
            out[k].nodes.push(n);
        }
        if cut {
            for s in &mut out {
                s.budget_reached = true;
            }
            break;
        }
    }
    if !out.iter().any(|s| s.budget_reached) {
        for (s, a) in out.iter_mut().zip(&alone) {
            s.budget_reached = a.budget_reached;
        }
    }
    for (s, a) in out.iter_mut().zip(alone) {
        s.culled = a.culled;
        // What the occlusion queries test after the frame (`Occlusion::Checked`, the same
        // frame's reveal): without them a node culled once would never be looked at again.
        s.hidden = a.hidden;
        s.pages = a.pages;
        s.used_pages = a.used_pages;
        s.prefetch = a.prefetch;
    }
    out
}

#[cfg(test)]
#[path = "select_tests.rs"]
pub(crate) mod tests;
