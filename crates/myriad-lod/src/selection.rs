//! What a selection is: the options it takes, the nodes it chose and what it left to load; and
//! the order both traversals (`select`, `front`) keep their candidates in.

use crate::view::Camera;
use myriad_core::{Aabb, NodeKey};
use myriad_format::ChildPage;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelectOptions {
    /// Most points drawn.
    pub budget: u64,
    /// Spacing, in pixels, below which a level adds nothing visible (Scheiblauer 2006 uses 1 or 2).
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
    /// drawn node around it: [`crate::DrawnTree`]).
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
    /// Nodes to load ahead, not to draw ([`crate::prefetch`]), best first.
    pub prefetch: Vec<NodeKey>,
}

pub(crate) struct Candidate {
    pub(crate) benefit: f64,
    pub(crate) key: NodeKey,
    /// Comes after every candidate that is not (`Occlusion::Checked`: a node the software test
    /// would cull, which the last queries saw through a gap: drawn where the budget allows).
    pub(crate) deferred: bool,
}
impl PartialEq for Candidate {
    fn eq(&self, o: &Self) -> bool {
        self.benefit == o.benefit && self.key == o.key && self.deferred == o.deferred
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
        (o.deferred.cmp(&self.deferred))
            .then_with(|| self.benefit.total_cmp(&o.benefit))
            .then_with(|| o.key.cmp(&self.key))
    }
}

/// The nearest eye depth of a box (its corners; clamped to the near plane).
pub(crate) fn nearest_depth(cam: &Camera, b: &Aabb) -> f64 {
    nearest_depth_of(cam, &b.corners())
}

pub(crate) fn nearest_depth_of(cam: &Camera, corners: &[[f64; 3]; 8]) -> f64 {
    corners
        .iter()
        .map(|&p| cam.to_eye(p)[2])
        .fold(f64::INFINITY, f64::min)
        .max(cam.near)
}
