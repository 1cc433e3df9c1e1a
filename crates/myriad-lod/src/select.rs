//! Selection of what to draw in a frame (Scheiblauer 2006, sections 4.3-4.4): the outer tree is
//! traversed from the root in benefit order (projected size over the angle to the view centre),
//! nodes outside the frustum or whose points would fall below the pixel threshold are skipped,
//! and traversal stops at the point budget. Inside a node, the prefix of levels whose spacing
//! still covers at least the threshold in pixels is drawn (a prefix of a node is a coarser level
//! of detail of it). Children are visited only below a node drawn whole: they refine it.
//!
//! Adaptive point size (003 section 4.4, 002 section 5.1): each selected node gets the spacing
//! of the finest level it draws; where nodes are octree cells, the shaders then size each point
//! from the finest drawn node around it ([`DrawnTree`]); in kd-trees, a node all of whose
//! children in view are drawn takes their finest spacing, pulled up the tree.
//!
//! The structures whose nodes are not plain octree cells: layered nodes carry a contour, kd
//! nodes their box; both are culled by it and weighed by its projected area. mwkd trees, whose
//! nodes replace their parents, are selected as a front ([`crate::front`]).

pub use crate::drawn::DrawnTree;
pub use crate::hierarchy::Hierarchy;
use crate::occlusion::Occluder;
use crate::view::{Camera, Frustum};
use myriad_core::{Aabb, NodeKey, Obb};
use myriad_format::hierarchy::PAGE_LEVELS;
use myriad_format::{ChildPage, NodeEntry};
use std::collections::{BinaryHeap, HashMap};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelectOptions {
    /// Most points drawn.
    pub budget: u64,
    /// Spacing, in pixels, below which a level adds nothing visible (003: usually 1 or 2).
    pub min_pixels: f64,
}

impl Default for SelectOptions {
    fn default() -> Self {
        SelectOptions {
            budget: 1_000_000,
            min_pixels: 1.0,
        }
    }
}

/// A node to draw this frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Selected {
    pub key: NodeKey,
    /// Points to draw: a prefix of the node.
    pub points: u32,
    /// Spacing of the finest level drawn, in world units (a point's size comes from the finest
    /// drawn node around it: [`DrawnTree`]).
    /// from the finest fully drawn descendants (the adaptive point size).
    pub spacing: f64,
    pub benefit: f64,
    /// Smallest eye depth of the node's cube (clamped to the near plane), for point sizes.
    pub depth: f64,
}

#[derive(Debug, Clone, Default, PartialEq)]
pub struct Selection {
    /// In the order they were chosen (highest benefit first).
    pub nodes: Vec<Selected>,
    pub points: u64,
    /// Whether the budget stopped the traversal.
    pub budget_reached: bool,
    /// Nodes culled as hidden ([`crate::occlusion`]; their subtrees not visited), and which.
    pub culled: usize,
    pub hidden: Vec<NodeKey>,
    /// Hierarchy pages not loaded yet below nodes the traversal would have refined, best first:
    /// what to load so that the view refines ([`crate::hierarchy`]).
    pub pages: Vec<ChildPage>,
    /// The loaded pages (by their root's key) whose root the traversal reached.
    pub used_pages: Vec<NodeKey>,
    /// Nodes to load ahead, not to draw ([`prefetch`]), best first.
    pub prefetch: Vec<NodeKey>,
}

pub(crate) struct Candidate {
    pub(crate) benefit: f64,
    pub(crate) key: NodeKey,
}
impl PartialEq for Candidate {
    fn eq(&self, o: &Self) -> bool {
        self.benefit == o.benefit && self.key == o.key
    }
}
impl Eq for Candidate {}
impl PartialOrd for Candidate {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Candidate {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.benefit
            .total_cmp(&o.benefit)
            .then_with(|| o.key.cmp(&self.key))
    }
}

/// The nearest eye depth of a box (its corners; clamped to the near plane).
pub(crate) fn nearest_depth(cam: &Camera, b: &Aabb) -> f64 {
    nearest_depth_of(cam, &b.corners())
}

fn nearest_depth_of(cam: &Camera, corners: &[[f64; 3]; 8]) -> f64 {
    corners
        .iter()
        .map(|&p| cam.to_eye(p)[2])
        .fold(f64::INFINITY, f64::min)
        .max(cam.near)
}

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

/// Nodes within this angle (radians, about 17 degrees) of the view axis count as central alike.
/// 003 floors the angle only against division by zero; a wider floor spreads the budget more
/// evenly over the middle of the view: `myriad bench render` (PSNR at a 1 M budget against every
/// point, KY and sheridan, three views) gains up to 1.35 dB with 0.3 over 0.001 and loses nowhere
/// by more than 0.06 dB; ignoring the angle altogether (3.2) loses 0.8 dB looking straight down.
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

/// 003 section 4.3: a projected size over the angle between the view direction and `dir` (the
/// direction to the node's centre), the angle floored at [`CENTRAL_ANGLE`].
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

/// A box of any orientation (a contour, 000 section 3.1; a kd box): the square root of its area
/// projected along the line of sight to its centre (a flat contour seen edge-on is small), in
/// pixels at its nearest depth.
fn benefit_of_box(cam: &Camera, b: &Obb) -> f64 {
    let depth = nearest_depth_of(cam, &b.corners());
    let dir = sight(cam, b.center);
    let h = b.half_extents;
    let d = |i: usize| (0..3).map(|k| b.axes[i][k] * dir[k]).sum::<f64>().abs();
    let area = 4.0 * (h[1] * h[2] * d(0) + h[0] * h[2] * d(1) + h[0] * h[1] * d(2));
    over_angle(cam, area.sqrt() * cam.pixels_per_unit(depth), dir)
}

/// Whether a node may be in view: its contour, else its box, against the frustum.
fn in_view(h: &Hierarchy, frustum: &Frustum, e: &NodeEntry) -> bool {
    match &e.contour {
        Some(c) => frustum.intersects_obb(c),
        None => frustum.intersects(&h.bounds(&e.key)),
    }
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
        if !previous.is_empty()
            && let Some((s, _)) = crate::front::update_front(h, cam, o, keep, previous)
        {
            return s;
        }
        return crate::front::select_front(h, cam, o, keep);
    }
    select_eyes(h, std::slice::from_ref(cam), o, keep, occluder)
}

/// One selection for several eyes seen together (002's stereo: one selection for both eyes):
/// a node is in view where any eye's frustum meets it, and its benefit and its level of detail
/// are those of the eye that sees it best (the nearest). Occlusion, where given, is tested as
/// the first eye sees. `mwkd` fronts are selected for the first eye.
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
            // An octree cell: its side (003).
            None if h.cells() => best(&|cam| benefit(cam, &cube, nearest_depth(cam, &cube))),
            // A contour (000) or a kd box (002): the square root of its projected area.
            Some(c) => best(&|cam| benefit_of_box(cam, c)),
            None => best(&|cam| benefit_of_box(cam, &Obb::from_aabb(&cube))),
        };
        queue.push(Candidate { benefit, key });
    };
    if h.get(&NodeKey::ROOT).is_some() {
        consider(NodeKey::ROOT, &mut queue);
    }
    while let Some(Candidate { benefit, key }) = queue.pop() {
        let Some(e) = h.get(&key) else { continue };
        if key.level % PAGE_LEVELS == 0 {
            out.used_pages.push(key);
        }
        let corners = match &e.contour {
            Some(c) => c.corners(),
            None => h.bounds(&key).corners(),
        };
        if let Some(occ) = occluder.as_deref_mut()
            && occ.hides(&key, &corners)
        {
            out.culled += 1;
            out.hidden.push(key);
            continue;
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
        if levels == 0 && e.points > 0 {
            continue;
        }
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

/// Adaptive point size per node for trees whose nodes are not octree cells (002 section 5.1):
/// a node drawn whole, all of whose children in view are drawn, takes the finest spacing among
/// them (pulled up from the deepest drawn descendants), so its points shrink where its children
/// fill in between them. A node with a child in view that is not drawn keeps its own spacing:
/// there its points are all there is.
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

/// Selection over several datasets sharing one point budget (002 section 3.1): each is selected
/// alone with the whole budget, then their nodes are taken in one benefit order (each dataset's
/// own order kept, so parents still come before children) until the budget is spent.
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
    loop {
        // The dataset whose next node has the highest benefit.
        let Some(k) = (0..alone.len())
            .filter(|&k| next[k] < alone[k].nodes.len())
            .max_by(|&a, &b| {
                alone[a].nodes[next[a]]
                    .benefit
                    .total_cmp(&alone[b].nodes[next[b]].benefit)
            })
        else {
            break;
        };
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
        s.pages = a.pages;
        s.used_pages = a.used_pages;
        s.prefetch = a.prefetch;
    }
    out
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use myriad_format::PageRef;

    /// The selection's point count is its nodes' and each node comes after its parent.
    fn assert_counted_parents_first(s: &Selection) {
        assert_eq!(
            s.points,
            s.nodes.iter().map(|n| n.points as u64).sum::<u64>()
        );
        for (i, n) in s.nodes.iter().enumerate() {
            if n.key.level > 0 {
                let p = n.key.parent();
                assert!(
                    s.nodes[..i].iter().any(|m| m.key == p),
                    "{} before its parent",
                    n.key
                );
            }
        }
    }

    /// A node entry with one level of detail (shared with the front's tests).
    pub(crate) fn entry(key: NodeKey, points: u32, spacing: f64) -> NodeEntry {
        NodeEntry::new(
            key,
            PageRef {
                offset: 64,
                length: 100,
                crc: 0,
            },
            points,
            vec![points],
            vec![spacing],
        )
    }

    fn looking_down_x() -> Camera {
        Camera {
            position: [-20.0, 0.5, 0.5],
            target: [0.0, 0.5, 0.5],
            up: [0.0, 0.0, 1.0],
            fov_y: 60.0,
            width: 400,
            height: 400,
            near: 0.01,
            far: 1000.0,
        }
    }

    /// A kd-tree: two children splitting x in [0, 1] and [1, 10]; bounds come from the entries,
    /// not the keys (whose cubes would put both children in the first octants of the root cube).
    #[test]
    fn kd_nodes_are_selected_by_their_stored_bounds() {
        let root = Aabb::new([0.0; 3], [10.0; 3]);
        let mut r = entry(NodeKey::ROOT, 100, 1.0);
        r.bounds = Some(Aabb::new([0.0; 3], [10.0, 1.0, 1.0]));
        let mut near = entry(NodeKey::ROOT.child(0), 100, 0.1);
        near.bounds = Some(Aabb::new([0.0; 3], [1.0, 1.0, 1.0]));
        let mut far = entry(NodeKey::ROOT.child(1), 100, 0.5);
        far.bounds = Some(Aabb::new([1.0, 0.0, 0.0], [10.0, 1.0, 1.0]));
        let h = Hierarchy::new(root, [r, near.clone(), far.clone()]);
        assert!(!h.cells());
        assert_eq!(h.bounds(&near.key), near.bounds.unwrap());
        let cam = looking_down_x();
        let o = SelectOptions {
            budget: 1000,
            min_pixels: 0.0,
        };
        let s = select(&h, &cam, &o);
        assert_counted_parents_first(&s);
        assert_eq!(s.nodes.len(), 3);
        // Both children drawn: the root takes the finest spacing among them (002 5.1).
        assert_eq!(s.nodes[0].key, NodeKey::ROOT);
        assert_eq!(s.nodes[0].spacing, 0.1);
        // Looking along +x from x = -20: the near child [0, 1] has the larger benefit.
        assert_eq!(s.nodes[1].key, near.key);
        // A camera at x = 5.5 looking along +x culls the near child by its bounds; a child out
        // of view does not stop the pull-up, so the root takes the far child's spacing.
        let mut cam2 = cam.clone();
        cam2.position = [5.5, 0.5, 0.5];
        cam2.target = [9.0, 0.5, 0.5];
        let s = select(&h, &cam2, &o);
        let keys: Vec<NodeKey> = s.nodes.iter().map(|n| n.key).collect();
        assert_eq!(keys, vec![NodeKey::ROOT, far.key]);
        assert_eq!(s.nodes[0].spacing, 0.5);
        // When the budget ends before the far child, the root keeps its own spacing there.
        let s = select(&h, &cam, &SelectOptions { budget: 150, ..o });
        assert_eq!(s.nodes[0].spacing, 1.0);
    }

    /// 000 section 3.1: a flat node's contour is its oriented box; outside the frustum it is
    /// culled even though its cube is in view, and seen edge-on it is worth less than face-on.
    #[test]
    fn contours_cull_and_weigh_flat_nodes() {
        let root = Aabb::new([0.0; 3], [1.0; 3]);
        let plate = |z: f64| Obb {
            center: [0.5, 0.5, z],
            axes: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            half_extents: [0.5, 0.5, 0.001],
        };
        let mut r = entry(NodeKey::ROOT, 100, 0.01);
        r.contour = Some(plate(0.999));
        let h = Hierarchy::new(root, [r.clone()]);
        assert!(h.cells());
        // From inside the cube, below the plate, looking down: the plate is behind the eye.
        let cam = Camera {
            position: [0.5, 0.5, 0.9],
            target: [0.5, 0.5, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_y: 60.0,
            width: 100,
            height: 100,
            near: 0.01,
            far: 100.0,
        };
        let o = SelectOptions {
            budget: 1000,
            min_pixels: 0.0,
        };
        assert!(
            select(&h, &cam, &o).nodes.is_empty(),
            "the plate is behind the eye"
        );
        let no_contour = Hierarchy::new(root, [entry(NodeKey::ROOT, 100, 0.01)]);
        assert_eq!(
            select(&no_contour, &cam, &o).nodes.len(),
            1,
            "the cube is in view"
        );
        // Face-on versus edge-on, same distance: the projected area decides.
        let face = Camera {
            position: [0.5, 0.5, 20.0],
            target: [0.5, 0.5, 0.5],
            up: [0.0, 1.0, 0.0],
            ..cam.clone()
        };
        let edge = Camera {
            position: [0.5, -19.0, 0.999],
            target: [0.5, 0.5, 0.999],
            up: [0.0, 0.0, 1.0],
            ..cam
        };
        let b = |c: &Camera| select(&h, c, &o).nodes[0].benefit;
        assert!(b(&face) > 10.0 * b(&edge), "{} {}", b(&face), b(&edge));
    }

    /// A full octree of `depth` levels over the unit cube scaled to `side`, each node with
    /// `per_node` points in 3 LOD levels whose spacing follows the node size (as on a surface:
    /// 16 times the points at a quarter of the spacing).
    pub(crate) fn tree(depth: u32, side: f64, per_node: u32) -> Hierarchy {
        let root = Aabb::new([0.0; 3], [side; 3]);
        let mut entries = Vec::new();
        let mut level_keys = vec![NodeKey::ROOT];
        for level in 0..depth {
            let mut next = Vec::new();
            for k in level_keys {
                let s = side / (1u64 << level) as f64;
                entries.push(NodeEntry {
                    key: k,
                    page: PageRef {
                        offset: 64,
                        length: 100,
                        crc: 0,
                    },
                    points: per_node,
                    prefix: vec![1, per_node / 16, per_node],
                    spacing: vec![s, s / 4.0, s / 16.0],
                    bounds: None,
                    contour: None,
                    splats: None,
                });
                next.extend((0..8).map(|o| k.child(o)));
            }
            level_keys = next;
        }
        Hierarchy::new(root, entries)
    }

    pub(crate) fn looking_down(h: &Hierarchy, height: f64) -> Camera {
        let c = h.root.center();
        Camera {
            position: [c[0], c[1] - 1e-3, h.root.max[2] + height],
            target: [c[0], c[1], h.root.min[2]],
            up: [0.0, 0.0, 1.0],
            fov_y: 60.0,
            width: 800,
            height: 600,
            near: 0.1,
            far: 1e6,
        }
    }

    #[test]
    fn one_selection_for_two_eyes_holds_what_either_sees_and_nothing_else() {
        let h = tree(5, 100.0, 4000);
        let mut cam = looking_down(&h, 20.0);
        cam.fov_y = 30.0;
        // Eyes 40 apart: each sees what the other does not.
        let eyes = cam.eyes(40.0);
        let o = SelectOptions {
            budget: u64::MAX,
            min_pixels: 1.0,
        };
        let keep = |_: &Aabb| true;
        let both = select_eyes(&h, &eyes, &o, &keep, None);
        assert_counted_parents_first(&both);
        let keys: std::collections::HashSet<NodeKey> = both.nodes.iter().map(|n| n.key).collect();
        for eye in &eyes {
            let alone = select(&h, eye, &o);
            for n in &alone.nodes {
                assert!(
                    keys.contains(&n.key),
                    "{} seen by one eye is missing",
                    n.key
                );
            }
            assert!(alone.nodes.len() < both.nodes.len());
        }
        let frustums = eyes.map(|e| e.frustum());
        for n in &both.nodes {
            let b = n.key.bounds(&h.root);
            assert!(
                frustums.iter().any(|f| f.intersects(&b)),
                "{} seen by neither",
                n.key
            );
        }
        // The eyes are 40 apart, looking in parallel, level with the camera.
        assert!((eyes[1].position[0] - eyes[0].position[0]).abs() > 39.99);
        assert_eq!(eyes[0].position[2], cam.position[2]);
    }

    #[test]
    fn budget_and_parents_first() {
        let h = tree(4, 100.0, 4000);
        for budget in [1, 500, 20_000, 200_000, u64::MAX] {
            let s = select(
                &h,
                &looking_down(&h, 50.0),
                &SelectOptions {
                    budget,
                    min_pixels: 1.0,
                },
            );
            assert!(s.points <= budget, "{} > {budget}", s.points);
            // Every selected node's parent was selected before it: no holes.
            assert_counted_parents_first(&s);
            if budget < h.points() {
                assert!(s.budget_reached || s.points < budget);
            }
        }
    }

    #[test]
    fn frustum_culls_and_distance_coarsens() {
        let h = tree(5, 100.0, 4000);
        let near = select(
            &h,
            &looking_down(&h, 20.0),
            &SelectOptions {
                budget: u64::MAX,
                min_pixels: 1.0,
            },
        );
        let far = select(
            &h,
            &looking_down(&h, 5000.0),
            &SelectOptions {
                budget: u64::MAX,
                min_pixels: 1.0,
            },
        );
        assert!(
            far.points < near.points,
            "far {} near {}",
            far.points,
            near.points
        );
        assert!(
            far.nodes.iter().map(|n| n.key.level).max()
                < near.nodes.iter().map(|n| n.key.level).max()
        );
        // Looking away: nothing.
        let mut away = looking_down(&h, 20.0);
        away.target = [
            away.position[0],
            away.position[1] - 1.0,
            away.position[2] + 10.0,
        ];
        let s = select(&h, &away, &SelectOptions::default());
        assert!(s.nodes.is_empty());
        // Low, at one corner, looking across: the near half is refined deeper than the far.
        let across = Camera {
            position: [-5.0, -5.0, 50.0],
            target: [100.0, 100.0, 50.0],
            ..looking_down(&h, 20.0)
        };
        let s = select(
            &h,
            &across,
            &SelectOptions {
                budget: u64::MAX,
                min_pixels: 8.0,
            },
        );
        let deepest = |near: bool| {
            s.nodes
                .iter()
                .filter(|n| {
                    let c = n.key.bounds(&h.root).center();
                    (c[0] + c[1] < 100.0) == near
                })
                .map(|n| n.key.level)
                .max()
                .unwrap_or(0)
        };
        assert!(
            deepest(true) > deepest(false),
            "near {} far {}",
            deepest(true),
            deepest(false)
        );
    }

    #[test]
    fn benefit_prefers_the_view_centre_and_the_near() {
        let cam = Camera {
            position: [0.0, -100.0, 0.0],
            target: [0.0, 0.0, 0.0],
            up: [0.0, 0.0, 1.0],
            fov_y: 60.0,
            width: 800,
            height: 600,
            near: 0.1,
            far: 1e6,
        };
        let cube = |x: f64, y: f64| Aabb::new([x - 1.0, y - 1.0, -1.0], [x + 1.0, y + 1.0, 1.0]);
        let b = |c: Aabb| benefit(&cam, &c, nearest_depth(&cam, &c));
        assert!(b(cube(0.0, 0.0)) > b(cube(45.0, 0.0)), "on axis first");
        assert!(
            b(cube(10.0, -50.0)) > b(cube(20.0, 0.0)),
            "nearer, same angle, first"
        );
        // With a small budget, what is drawn lies towards the view centre.
        let h = tree(4, 100.0, 4000);
        // (Near enough that the cells off the centre are outside CENTRAL_ANGLE.)
        let top = looking_down(&h, 60.0);
        let s = select(
            &h,
            &top,
            &SelectOptions {
                budget: 400_000,
                min_pixels: 0.5,
            },
        );
        assert!(s.budget_reached);
        let deep: Vec<&Selected> = s.nodes.iter().filter(|n| n.key.level == 3).collect();
        assert!(!deep.is_empty());
        let off = |n: &Selected| {
            let c = n.key.bounds(&h.root).center();
            ((c[0] - 50.0).powi(2) + (c[1] - 50.0).powi(2)).sqrt()
        };
        let mean = deep.iter().map(|n| off(n)).sum::<f64>() / deep.len() as f64;
        // All level-3 cells: mean distance from the centre is about 38; the chosen are central.
        assert!(mean < 30.0, "mean off-axis distance {mean}");
    }

    #[test]
    fn several_datasets_share_one_budget() {
        let a = tree(4, 100.0, 4000);
        // The same tree 1000 units further away along the view.
        let far_root = Aabb::new([0.0, 0.0, -1100.0], [100.0, 100.0, -1000.0]);
        let b = Hierarchy::new(far_root, a.entries().cloned().collect::<Vec<_>>());
        let cam = looking_down(&a, 100.0);
        let o = SelectOptions {
            budget: 200_000,
            min_pixels: 0.5,
        };
        let s = select_many(&[&a, &b], &cam, &o, &|_| true);
        let total = s[0].points + s[1].points;
        assert!(total <= o.budget && s[0].budget_reached);
        assert_eq!(total, o.budget);
        // The near dataset gets most of it; each keeps its parents before its children.
        assert!(
            s[0].points > 3 * s[1].points,
            "{} {}",
            s[0].points,
            s[1].points
        );
        for sel in &s {
            assert_counted_parents_first(sel);
        }
        // One dataset alone: the same as select.
        assert_eq!(
            select_many(&[&a], &cam, &o, &|_| true)[0],
            select(&a, &cam, &o)
        );
        // A filter that keeps only the near dataset's cubes: the far one gets nothing.
        let near_only = |c: &Aabb| c.min[2] >= -1.0;
        let s = select_many(&[&a, &b], &cam, &o, &near_only);
        assert_eq!(s[1].points, 0);
        assert_eq!(s[0].points, o.budget);
    }

    #[test]
    fn point_spacing_follows_density_where_cells_stop_saying() {
        let e = NodeEntry {
            key: NodeKey::ROOT,
            page: PageRef {
                offset: 64,
                length: 100,
                crc: 0,
            },
            points: 1300,
            // Full levels (4x points, half the cell), then leftovers: 20 % more points in
            // cells 8 and 64 times smaller.
            prefix: vec![1, 4, 16, 64, 256, 1024, 1229, 1300],
            spacing: vec![64.0, 32.0, 16.0, 8.0, 4.0, 2.0, 0.25, 0.03125],
            bounds: None,
            contour: None,
            splats: None,
        };
        let s = point_spacing(&e);
        assert_eq!(&s[..6], &e.spacing[..6], "full levels: the cell size");
        let want = 2.0 / (1229.0f64 / 1024.0).sqrt();
        assert!((s[6] - want).abs() < 1e-9, "{} {want}", s[6]);
        assert!(s[7] < s[6] && s[7] > 1.5, "{}", s[7]);
    }

    #[test]
    fn points_take_the_spacing_of_the_finest_drawn_node_around_them() {
        let h = tree(3, 100.0, 4000);
        let s = select(
            &h,
            &looking_down(&h, 1000.0),
            &SelectOptions {
                budget: u64::MAX,
                min_pixels: 1e-6,
            },
        );
        assert_eq!(s.points, h.points());
        let spacing = |k: &NodeKey| s.nodes.iter().find(|n| n.key == *k).unwrap().spacing;
        // Everything drawn: a root point in the first level-2 cell takes that cell's spacing.
        let t = DrawnTree::new(&s, |_| true);
        assert_eq!(t.entries.len(), s.nodes.len());
        let leaf = NodeKey::ROOT.child(0).child(0);
        let p = [1.0, 1.0, 1.0];
        let got = t.spacing_at(&h.root, &NodeKey::ROOT, p).unwrap();
        assert_eq!(got, spacing(&leaf) as f32 as f64);
        assert!(got < spacing(&NodeKey::ROOT));
        // That leaf not drawn (still loading): its parent's spacing there, the leaf's sibling
        // still its own.
        let t = DrawnTree::new(&s, |k| *k != leaf);
        let parent = NodeKey::ROOT.child(0);
        assert_eq!(
            t.spacing_at(&h.root, &NodeKey::ROOT, p).unwrap(),
            spacing(&parent) as f32 as f64
        );
        let sibling_point = [30.0, 1.0, 1.0];
        assert_eq!(
            t.spacing_at(&h.root, &NodeKey::ROOT, sibling_point)
                .unwrap(),
            spacing(&parent.child(1)) as f32 as f64
        );
        assert_eq!(t.spacing_at(&h.root, &leaf, p), None);
        // Only a deep node drawn: its ancestors pass through with no spacing of their own.
        let t = DrawnTree::new(&s, |k| *k == leaf);
        assert_eq!(t.entries.len(), 3);
        assert_eq!(t.entries[0][2], 0);
        assert_eq!(t.entries[0][0], 1, "only octant 0 below the root");
        assert!(DrawnTree::new(&s, |_| false).entries.is_empty());
    }
}
