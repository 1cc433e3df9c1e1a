//! Occlusion culling on the CPU (Kanzok et al. 2015, section 3.2.2): a coarse depth buffer
//! (128 x 128 cells over the screen, as the paper's; the size is a parameter) holds, per cell, a
//! depth behind which everything in that cell is hidden; a candidate node whose box (or contour)
//! lies wholly behind the cells it covers is culled before it takes budget or a load, and its
//! subtree with it.
//!
//! The buffer is filled during the selection from the nodes already selected (in benefit order:
//! the near and large first): each resident node's points are splatted as squares of their
//! level's spacing, the size the renderer gives them. Conservative by construction:
//! - a cell's depth is the farthest of its sub-cells' (a 4 x 4 finer grid), a sub-cell covered
//!   where a splat covers its centre (as a rasterizer covers pixels); a sub-cell left open keeps
//!   its cell open;
//! - a splat's depth is its point's pushed back by the splat's side (a tilted surface);
//! - a box with a corner before the near plane is never culled; its screen rectangle is the
//!   bounds of its projected corners and every cell that rectangle touches is tested.
//!
//! Only the coarse levels of a node are splatted (those whose spacing spans at least two
//! sub-cells: finer ones add nothing at this resolution), so the cost follows the buffer's
//! resolution, not the point budget.

use crate::view::Camera;
use myriad_core::NodeKey;
use myriad_format::NodeEntry;
use std::collections::HashSet;
use std::sync::Arc;

/// The paper's buffer size, in cells per side.
pub const DEFAULT_SIZE: u32 = 128;
/// Sub-cells per cell and side.
const SUB: u32 = 4;

/// How hidden nodes are found (`--occlusion`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Occlusion {
    Off,
    /// The coarse depth buffer of this module.
    Software,
    /// Occlusion queries (Scheiblauer 2006): each frame the boxes of the nodes drawn and culled are
    /// tested against the frame's depth (on the GPU, or the CPU path's mirror); the next selection
    /// culls those of which no pixel showed.
    Queries,
    /// The software test, its culls checked: after each frame the boxes of the nodes it culled
    /// are queried against the frame's depth, and one of which a pixel shows is not culled from
    /// the next selection on (while it keeps showing) but selected after the nodes in the open,
    /// as far as the budget goes. The software test alone culls what shows through gaps narrower
    /// than its splats; checked, a view that settles loses nothing the budget could draw, and
    /// under a budget the points still go to what is in the open first.
    Checked,
}

impl Occlusion {
    pub fn parse(s: &str) -> Result<Occlusion, String> {
        match s {
            "off" => Ok(Occlusion::Off),
            "software" => Ok(Occlusion::Software),
            "queries" => Ok(Occlusion::Queries),
            "checked" => Ok(Occlusion::Checked),
            _ => Err(format!("\"{s}\": checked, software, queries or off")),
        }
    }

    /// Whether frames run occlusion queries after them.
    pub fn queries(self) -> bool {
        matches!(self, Occlusion::Queries | Occlusion::Checked)
    }
}

/// The coarse depth buffer of one view.
pub struct DepthMap {
    cam: Camera,
    basis: ([f64; 3], [f64; 3], [f64; 3]),
    focal: f64,
    /// Cells per side.
    size: u32,
    /// Sub-cells per side (`size * SUB`).
    fine_side: u32,
    /// Per sub-cell, the nearest depth of a splat covering it whole (infinite: open).
    fine: Vec<f32>,
    /// Per cell, the farthest of its sub-cells, where it is not `dirty`.
    cells: Vec<f32>,
    /// Cells whose sub-cells changed since their depth was last taken (taken again when a test
    /// reads them: a node's splats may span the screen, its tests a few cells).
    dirty: Vec<bool>,
}

impl DepthMap {
    /// An empty buffer of `size` x `size` cells over `cam`'s image.
    pub fn new(cam: &Camera, size: u32) -> DepthMap {
        let size = size.clamp(1, 4096);
        let fine_side = size * SUB;
        DepthMap {
            cam: *cam,
            basis: cam.basis(),
            focal: cam.focal(),
            size,
            fine_side,
            fine: vec![f32::INFINITY; (fine_side * fine_side) as usize],
            cells: vec![f32::INFINITY; (size * size) as usize],
            dirty: vec![false; (size * size) as usize],
        }
    }

    fn eye(&self, p: [f64; 3]) -> [f64; 3] {
        let (r, u, f) = self.basis;
        let d = [
            p[0] - self.cam.position[0],
            p[1] - self.cam.position[1],
            p[2] - self.cam.position[2],
        ];
        let dot = |a: [f64; 3]| a[0] * d[0] + a[1] * d[1] + a[2] * d[2];
        [dot(r), dot(u), dot(f)]
    }

    /// Pixel coordinates (x right, y down) of an eye point in front of the near plane.
    fn pixel(&self, e: [f64; 3]) -> [f64; 2] {
        [
            self.cam.width as f64 / 2.0 + e[0] * self.focal / e[2],
            self.cam.height as f64 / 2.0 - e[1] * self.focal / e[2],
        ]
    }

    /// Sub-cells per pixel, across and down.
    fn fine_scale(&self) -> [f64; 2] {
        [
            self.fine_side as f64 / self.cam.width.max(1) as f64,
            self.fine_side as f64 / self.cam.height.max(1) as f64,
        ]
    }

    /// Adds a square splat of side `side` (world units) around `p`.
    fn splat(&mut self, p: [f64; 3], side: f64) {
        let e = self.eye(p);
        if e[2] <= self.cam.near {
            return;
        }
        let [px, py] = self.pixel(e);
        let half = 0.5 * side * self.focal / e[2];
        let [sx, sy] = self.fine_scale();
        let n = self.fine_side as f64;
        // Sub-cells whose centres the splat covers (as a rasterizer covers pixels: splats
        // that tile a surface leave no sub-cell open between them).
        let x0 = ((px - half) * sx - 0.5).ceil().max(0.0);
        let x1 = ((px + half) * sx - 0.5).ceil().min(n);
        let y0 = ((py - half) * sy - 0.5).ceil().max(0.0);
        let y1 = ((py + half) * sy - 0.5).ceil().min(n);
        if !(x0 < x1 && y0 < y1) {
            return;
        }
        let r = [x0 as u32, y0 as u32, x1 as u32, y1 as u32];
        let depth = (e[2] + side) as f32;
        for y in r[1]..r[3] {
            let row = (y * self.fine_side) as usize;
            for d in &mut self.fine[row + r[0] as usize..row + r[2] as usize] {
                *d = d.min(depth);
            }
        }
        // The cells these sub-cells are in or ring.
        let (c0, c1) = (
            (r[0].saturating_sub(1)) / SUB,
            (r[2] + 1).div_ceil(SUB).min(self.size),
        );
        for cy in r[1].saturating_sub(1) / SUB..(r[3] + 1).div_ceil(SUB).min(self.size) {
            let row = (cy * self.size) as usize;
            self.dirty[row + c0 as usize..row + c1 as usize].fill(true);
        }
    }

    /// A cell's depth: the farthest of its sub-cells and of the ring of sub-cells around them
    /// (the coverage eroded by one sub-cell: a splat reaches up to half its side beyond the
    /// surface's edge, and a node just behind a silhouette must not be culled).
    fn cell(&mut self, cx: u32, cy: u32) -> f32 {
        let i = (cy * self.size + cx) as usize;
        if self.dirty[i] {
            let mut far = 0f32;
            let last = self.fine_side - 1;
            let (x0, x1) = ((cx * SUB).saturating_sub(1), ((cx + 1) * SUB).min(last));
            for y in (cy * SUB).saturating_sub(1)..=((cy + 1) * SUB).min(last) {
                let row = (y * self.fine_side) as usize;
                for &d in &self.fine[row + x0 as usize..=row + x1 as usize] {
                    far = far.max(d);
                }
            }
            self.cells[i] = far;
            self.dirty[i] = false;
        }
        self.cells[i]
    }

    /// Adds the first `count` points of a node (its drawn prefix), as far as their levels'
    /// spacing (`spacing`: [`crate::select::point_spacing`]) shows at the buffer's resolution;
    /// returns how many points it splatted.
    pub fn cover(
        &mut self,
        e: &NodeEntry,
        spacing: &[f64],
        positions: &[[f64; 3]],
        count: usize,
    ) -> usize {
        let count = count.min(positions.len());
        if count == 0 || spacing.is_empty() {
            return 0;
        }
        // The node's typical depth: the median of its first points (its coarsest level, spread
        // over it). Nearer points get larger splats than needed, farther ones may cover
        // nothing (only less culling); the points splatted stay about as many as the buffer
        // resolves there, not all the node's.
        let mut depths: Vec<f64> = positions[..count]
            .iter()
            .take(64)
            .map(|&p| self.eye(p)[2])
            .collect();
        depths.sort_by(f64::total_cmp);
        let typical = depths[depths.len() / 2].max(self.cam.near);
        let [sx, sy] = self.fine_scale();
        let fine_per_unit = self.focal / typical * sx.min(sy);
        // The finest level still spanning two sub-cells at that depth.
        let Some(level) = (0..spacing.len()).rev().find(|&l| {
            spacing[l] * fine_per_unit >= 2.0 && (l == 0 || (e.prefix[l - 1] as usize) < count)
        }) else {
            return 0;
        };
        let n = (e.prefix[level] as usize).min(count);
        let side = spacing[level];
        for &p in &positions[..n] {
            self.splat(p, side);
        }
        n
    }

    /// Whether a box given by its 8 corners is hidden behind what the buffer holds.
    pub fn hides(&mut self, corners: &[[f64; 3]; 8]) -> bool {
        let Some((nearest, [x0, y0, x1, y1])) = self.cam.box_on_screen(corners) else {
            return false;
        };
        let (w, h) = (self.cam.width as f64, self.cam.height as f64);
        let (x0, x1, y0, y1) = (x0.max(0.0), x1.min(w), y0.max(0.0), y1.min(h));
        if !(x0 < x1 && y0 < y1) {
            // Off screen: the frustum's business.
            return false;
        }
        let s = self.size as f64;
        let cx0 = (x0 / w * s).floor() as u32;
        let cx1 = ((x1 / w * s).ceil() as u32).min(self.size);
        let cy0 = (y0 / h * s).floor() as u32;
        let cy1 = ((y1 / h * s).ceil() as u32).min(self.size);
        let nearest = nearest as f32;
        (cy0..cy1).all(|cy| (cx0..cx1).all(|cx| self.cell(cx, cy) < nearest))
    }

    /// The share of cells that hide something (a depth is set).
    #[cfg(test)]
    fn filled(&mut self) -> f64 {
        let n = self.size;
        let set = (0..n * n)
            .filter(|i| self.cell(i % n, i / n).is_finite())
            .count();
        set as f64 / (n * n) as f64
    }
}

/// What an [`Occluder`] knows of a node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Verdict {
    /// Not hidden.
    Open,
    /// Culled.
    Hidden,
    /// Hidden to the software test, but the last queries saw it (`Occlusion::Checked`): it is
    /// selected after the nodes in the open, as far as the budget goes.
    Seen,
}

/// What a selection with occlusion culling needs: the software test's buffer and the points of
/// resident nodes (a node not loaded yet covers nothing), or the nodes the last frame's
/// occlusion queries found hidden.
pub struct Occluder<'a> {
    pub map: Option<DepthMap>,
    pub points: &'a dyn Fn(&NodeKey) -> Option<Arc<crate::stream::Loaded>>,
    pub hidden: Option<&'a HashSet<NodeKey>>,
    /// Nodes the map may not cull (`Occlusion::Checked`: the last queries saw them).
    pub shown: Option<&'a HashSet<NodeKey>>,
}

impl<'a> Occluder<'a> {
    /// The software test.
    pub fn new(
        cam: &Camera,
        size: u32,
        points: &'a dyn Fn(&NodeKey) -> Option<Arc<crate::stream::Loaded>>,
    ) -> Occluder<'a> {
        Occluder {
            map: Some(DepthMap::new(cam, size)),
            points,
            hidden: None,
            shown: None,
        }
    }

    /// The software test, except for the nodes in `shown` (`Occlusion::Checked`).
    pub fn checked(
        cam: &Camera,
        size: u32,
        points: &'a dyn Fn(&NodeKey) -> Option<Arc<crate::stream::Loaded>>,
        shown: &'a HashSet<NodeKey>,
    ) -> Occluder<'a> {
        Occluder {
            shown: Some(shown),
            ..Occluder::new(cam, size, points)
        }
    }

    /// The results of the last frame's occlusion queries.
    pub fn queried(hidden: &'a HashSet<NodeKey>) -> Occluder<'a> {
        Occluder {
            map: None,
            points: &|_| None,
            hidden: Some(hidden),
            shown: None,
        }
    }

    /// What is known of node `key` (its box's corners).
    pub(crate) fn test(&mut self, key: &NodeKey, corners: &[[f64; 3]; 8]) -> Verdict {
        if self.hidden.is_some_and(|h| h.contains(key)) {
            return Verdict::Hidden;
        }
        if !self.map.as_mut().is_some_and(|m| m.hides(corners)) {
            return Verdict::Open;
        }
        if self.shown.is_some_and(|s| s.contains(key)) {
            Verdict::Seen
        } else {
            Verdict::Hidden
        }
    }

    /// A selected node's first `count` points cover what lies behind them (software test).
    pub(crate) fn cover(&mut self, e: &NodeEntry, spacing: &[f64], count: usize) {
        if let Some(map) = self.map.as_mut()
            && let Some(b) = (self.points)(&e.key)
        {
            map.cover(e, spacing, &b.positions, count);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::select::select_occluded;
    use crate::select::tests::entry;
    use crate::stream::Loaded;
    use crate::{Hierarchy, SelectOptions};
    use myriad_core::Aabb;

    /// Looking along +x from x = -20 at the middle of a wall in the plane x = 2 (y and z from
    /// 0 to 10), 400 x 400 pixels.
    fn camera() -> Camera {
        Camera {
            position: [-20.0, 5.0, 5.0],
            target: [0.0, 5.0, 5.0],
            up: [0.0, 0.0, 1.0],
            fov_y: 60.0,
            width: 400,
            height: 400,
            near: 0.1,
            far: 100.0,
        }
    }

    /// The wall's points on a 0.2 grid, leaving out those inside `hole` (y and z ranges).
    fn wall(hole: Option<[f64; 2]>) -> Vec<[f64; 3]> {
        let mut out = Vec::new();
        for i in 0..=50 {
            for j in 0..=50 {
                let (y, z) = (i as f64 * 0.2, j as f64 * 0.2);
                let inside = |v: f64, h: [f64; 2]| v > h[0] && v < h[1];
                if hole.is_some_and(|h| inside(y, h) && inside(z, h)) {
                    continue;
                }
                out.push([2.0, y, z]);
            }
        }
        out
    }

    fn covered(points: &[[f64; 3]]) -> DepthMap {
        let mut map = DepthMap::new(&camera(), DEFAULT_SIZE);
        let e = entry(NodeKey::ROOT, points.len() as u32, 0.2);
        let n = map.cover(&e, &e.spacing, points, points.len());
        assert_eq!(n, points.len());
        map
    }

    #[test]
    fn a_wall_hides_what_is_behind_it_and_nothing_else() {
        let mut map = covered(&wall(None));
        let behind = Aabb::new([6.0, 4.0, 4.0], [8.0, 6.0, 6.0]);
        assert!(map.hides(&behind.corners()), "a box behind the wall");
        // Beside the wall (y beyond its edge, in view): kept.
        let beside = Aabb::new([6.0, 11.0, 4.0], [8.0, 13.0, 6.0]);
        assert!(!map.hides(&beside.corners()));
        // Straddling the wall's edge: partly in the open, kept.
        let edge = Aabb::new([6.0, 9.0, 4.0], [8.0, 11.0, 6.0]);
        assert!(!map.hides(&edge.corners()));
        // In front of the wall: kept.
        let front = Aabb::new([0.0, 4.0, 4.0], [1.0, 6.0, 6.0]);
        assert!(!map.hides(&front.corners()));
        // Just behind the wall, within a splat's side of it (a tilted surface): kept.
        let touching = Aabb::new([2.1, 4.0, 4.0], [3.0, 6.0, 6.0]);
        assert!(!map.hides(&touching.corners()));
        // Around the eye (a corner before the near plane): never culled.
        let around = Aabb::new([-21.0, 4.0, 4.0], [8.0, 6.0, 6.0]);
        assert!(!map.hides(&around.corners()));
        // The wall spans about 157 of 400 pixels each way: (157 / 400)² of the cells.
        assert!((map.filled() - 0.154).abs() < 0.02, "{}", map.filled());
    }

    #[test]
    fn a_node_seen_through_a_hole_is_kept() {
        let mut map = covered(&wall(Some([4.3, 5.7])));
        let behind = Aabb::new([6.0, 4.6, 4.6], [8.0, 5.4, 5.4]);
        assert!(!map.hides(&behind.corners()), "seen through the hole");
        // A box behind the solid part of the same wall is still culled.
        let solid = Aabb::new([6.0, 1.0, 1.0], [8.0, 2.0, 2.0]);
        assert!(map.hides(&solid.corners()));
    }

    #[test]
    fn sparse_points_cover_nothing() {
        // The same wall's corners alone: splats of their spacing leave every cell open.
        let pts: Vec<[f64; 3]> = wall(None).into_iter().step_by(97).collect();
        let mut map = DepthMap::new(&camera(), DEFAULT_SIZE);
        let e = entry(NodeKey::ROOT, pts.len() as u32, 0.2);
        map.cover(&e, &e.spacing, &pts, pts.len());
        let behind = Aabb::new([6.0, 4.0, 4.0], [8.0, 6.0, 6.0]);
        assert!(!map.hides(&behind.corners()));
    }

    /// In a selection: the wall (the root) is selected first and culls the node behind it, with
    /// its subtree, before it takes budget; the node beside it is drawn; without occlusion all
    /// are.
    #[test]
    fn selection_culls_nodes_behind_selected_ones() {
        let root = Aabb::new([0.0; 3], [20.0; 3]);
        let points = wall(None);
        let mut r = entry(NodeKey::ROOT, points.len() as u32, 0.2);
        r.bounds = Some(Aabb::new([2.0, 0.0, 0.0], [2.0, 10.0, 10.0]));
        let mut behind = entry(NodeKey::ROOT.child(0), 1000, 0.05);
        behind.bounds = Some(Aabb::new([6.0, 4.0, 4.0], [8.0, 6.0, 6.0]));
        let mut under = entry(NodeKey::ROOT.child(0).child(0), 1000, 0.02);
        under.bounds = Some(Aabb::new([6.0, 4.0, 4.0], [7.0, 5.0, 5.0]));
        let mut beside = entry(NodeKey::ROOT.child(1), 1000, 0.05);
        beside.bounds = Some(Aabb::new([6.0, 11.0, 4.0], [8.0, 13.0, 6.0]));
        let h = Hierarchy::new(root, [r, behind, under, beside.clone()]);
        let batch = Arc::new(Loaded {
            prepared: None,
            points: myriad_core::PointBatch {
                positions: points,
                ..Default::default()
            },
            splats: None,
        });
        let resident = |k: &NodeKey| (*k == NodeKey::ROOT).then(|| batch.clone());
        let cam = camera();
        let o = SelectOptions {
            budget: u64::MAX,
            min_pixels: 0.0,
        };
        let keep = |_: &Aabb| true;
        let all = select_occluded(&h, &cam, &o, &keep, None);
        assert_eq!(all.nodes.len(), 4);
        assert_eq!(all.culled, 0);
        let mut occ = Occluder::new(&cam, DEFAULT_SIZE, &resident);
        let s = select_occluded(&h, &cam, &o, &keep, Some(&mut occ));
        let keys: Vec<NodeKey> = s.nodes.iter().map(|n| n.key).collect();
        assert_eq!(keys, vec![NodeKey::ROOT, beside.key]);
        assert_eq!(s.culled, 1, "the node behind; its child never visited");
        // The wall not loaded yet: it hides nothing.
        let none = |_: &NodeKey| None;
        let mut occ = Occluder::new(&cam, DEFAULT_SIZE, &none);
        assert_eq!(select_occluded(&h, &cam, &o, &keep, Some(&mut occ)), all);
    }

    /// An `mwkd` front (Goswami et al. 2010): the wall and the node behind it are both in the front
    /// (a cut, not a subtree); the wall, nearer, covers first and the node behind it leaves the
    /// front, with its points; the node beside it stays.
    #[test]
    fn an_mwkd_front_loses_the_node_behind_a_wall() {
        let root = Aabb::new([0.0; 3], [20.0; 3]);
        let points = wall(None);
        let splat = |aggregate| myriad_format::splat::SplatInfo {
            page: myriad_format::PageRef {
                offset: 64,
                length: 10,
                crc: 0,
            },
            radius: [0.1, 0.2],
            cone: [0.0, 0.0, 1.0, -1.0],
            aggregate,
        };
        let node = |key: NodeKey, n: u32, spacing: f64, b: Aabb, aggregate| {
            let mut e = entry(key, n, spacing);
            e.bounds = Some(b);
            e.splats = Some(splat(aggregate));
            e
        };
        let top = node(NodeKey::ROOT, 10, 1.0, root, true);
        let wall_node = node(
            NodeKey::ROOT.child(0),
            points.len() as u32,
            0.2,
            Aabb::new([2.0, 0.0, 0.0], [2.0, 10.0, 10.0]),
            false,
        );
        let behind = node(
            NodeKey::ROOT.child(1),
            1000,
            0.05,
            Aabb::new([6.0, 4.0, 4.0], [8.0, 6.0, 6.0]),
            false,
        );
        let beside = node(
            NodeKey::ROOT.child(2),
            1000,
            0.05,
            Aabb::new([6.0, 11.0, 4.0], [8.0, 13.0, 6.0]),
            false,
        );
        let h = Hierarchy::new(
            root,
            [top, wall_node.clone(), behind.clone(), beside.clone()],
        );
        assert!(h.splats());
        let batch = Arc::new(Loaded {
            prepared: None,
            points: myriad_core::PointBatch {
                positions: points.clone(),
                ..Default::default()
            },
            splats: None,
        });
        let resident = |k: &NodeKey| (*k == wall_node.key).then(|| batch.clone());
        let cam = camera();
        let o = SelectOptions {
            budget: u64::MAX,
            min_pixels: 0.0,
        };
        let keep = |_: &Aabb| true;
        let sorted = |s: &crate::Selection| {
            let mut k: Vec<NodeKey> = s.nodes.iter().map(|n| n.key).collect();
            k.sort();
            k
        };
        let all = crate::select::select_occluded_from(&h, &cam, &o, &keep, None, &[]);
        let mut three = vec![wall_node.key, behind.key, beside.key];
        three.sort();
        assert_eq!(sorted(&all), three);
        let mut occ = Occluder::new(&cam, DEFAULT_SIZE, &resident);
        let s = crate::select::select_occluded_from(&h, &cam, &o, &keep, Some(&mut occ), &[]);
        let mut two = vec![wall_node.key, beside.key];
        two.sort();
        assert_eq!(sorted(&s), two);
        assert_eq!((s.culled, s.hidden.clone()), (1, vec![behind.key]));
        assert_eq!(s.points, all.points - 1000);
        // From the front the last frame drew too.
        let previous: Vec<NodeKey> = all.nodes.iter().map(|n| n.key).collect();
        let mut occ = Occluder::new(&cam, DEFAULT_SIZE, &resident);
        let again =
            crate::select::select_occluded_from(&h, &cam, &o, &keep, Some(&mut occ), &previous);
        assert_eq!(sorted(&again), sorted(&s));
    }
}
