//! The drawn nodes of a frame as a small array octree that the shaders walk per point, for
//! adaptive point sizes (Scheiblauer 2006, section 4.4; Discher et al. 2018, section 5.1).

use crate::Hierarchy;
use crate::selection::{Selected, Selection};
use myriad_core::{Aabb, NodeKey};
use std::collections::HashMap;

/// The drawn nodes as a small octree that the GPU walks per point (adaptive point size,
/// Scheiblauer 2006 section 4.4 and Discher et al. 2018 section 5.1, per point as Potree does):
/// from the point's own node down through the drawn children that contain it, the spacing of the
/// finest one is the point's. So a coarse point shrinks where finer nodes are drawn around it, and
/// stays large where nothing finer is drawn (yet), covering the hole.
///
/// A sparse node drawn whole (its spacing more than [`SPARSE`] times its drawn ancestors') takes
/// theirs: its points, with its ancestors' in its cube, sample that cube at least as densely as
/// the ancestors alone. It (a few points, separated at a coarse level of its own) would otherwise
/// size every point in its octant, its parent's too, by its coarse spacing: squares dozens of
/// pixels wide amid points a few pixels wide. A node drawn in part (a coarse prefix of its
/// levels, as far as the budget went) keeps its own, as before.
///
/// Entries in breadth-first order, children of a node contiguous in octant order:
/// `[child mask, index of the first child, spacing as f32 bits (0: not drawn), 0]`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DrawnTree {
    pub entries: Vec<[u32; 4]>,
    pub index: HashMap<NodeKey, u32>,
}

/// A node drawn whole is sparse where its spacing exceeds its drawn ancestors' this many times
/// (then it takes theirs): a leaf's finest level, sized from its own density, may well lie a
/// little above its parent's level drawn; a sparse node's, separated at a coarse level of its own,
/// lies several times above (KY's edges: 4 to 6).
pub const SPARSE: f32 = 2.0;

impl DrawnTree {
    /// The nodes of `selection` (of `h`) for which `drawn` holds, and their ancestors (as
    /// pass-through entries when not drawn themselves).
    pub fn new(
        selection: &Selection,
        h: &Hierarchy,
        drawn: impl Fn(&NodeKey) -> bool,
    ) -> DrawnTree {
        // Drawn whole: all its points (a sparse one then takes its ancestors' spacing).
        let whole = |n: &Selected| h.get(&n.key).is_some_and(|e| n.points >= e.points);
        let mut spacing: HashMap<NodeKey, f32> = HashMap::new();
        let mut capped: HashMap<NodeKey, bool> = HashMap::new();
        for n in selection.nodes.iter().filter(|n| drawn(&n.key)) {
            spacing.insert(n.key, n.spacing as f32);
            capped.insert(n.key, whole(n));
            let mut k = n.key;
            while k.level > 0 {
                k = k.parent();
                spacing.entry(k).or_insert(0.0);
            }
        }
        let mut t = DrawnTree::default();
        if spacing.is_empty() {
            return t;
        }
        let mut keys = vec![NodeKey::ROOT];
        // The finest spacing drawn above each key (its ancestors').
        let mut above = vec![f32::INFINITY];
        let mut i = 0;
        while i < keys.len() {
            let key = keys[i];
            let own = spacing[&key];
            let s = match (own > 0.0, capped.get(&key) == Some(&true)) {
                (false, _) => 0.0,
                (true, true) if own > SPARSE * above[i] => above[i],
                (true, _) => own,
            };
            let below = if own > 0.0 { s } else { above[i] };
            let first = keys.len() as u32;
            let mut mask = 0u32;
            for o in 0..8 {
                let c = key.child(o);
                if spacing.contains_key(&c) {
                    mask |= 1 << o;
                    keys.push(c);
                    above.push(below);
                }
            }
            t.entries.push([mask, first, s.to_bits(), 0]);
            t.index.insert(key, i as u32);
            i += 1;
        }
        t
    }

    /// The spacing drawn node `key`'s points are drawn at (at most its drawn ancestors'); None
    /// when it is not drawn.
    pub fn spacing(&self, key: &NodeKey) -> Option<f64> {
        let s = f32::from_bits(self.entries[*self.index.get(key)? as usize][2]);
        (s > 0.0).then_some(s as f64)
    }

    /// The spacing the GPU gives a point at `p` of the drawn node `key` (as the shaders walk
    /// the tree); None when `key` is not in the tree.
    pub fn spacing_at(&self, root: &Aabb, key: &NodeKey, p: [f64; 3]) -> Option<f64> {
        let mut i = *self.index.get(key)? as usize;
        let mut s = f32::from_bits(self.entries[i][2]) as f64;
        let mut cube = key.bounds(root);
        loop {
            let [mask, first, _, _] = self.entries[i];
            let c = cube.center();
            let o = (0..3)
                .map(|a| ((p[a] >= c[a]) as usize) << a)
                .sum::<usize>();
            if mask & (1 << o) == 0 {
                return Some(s);
            }
            i = (first + (mask & ((1 << o) - 1)).count_ones()) as usize;
            let min: [f64; 3] =
                std::array::from_fn(|a| if o >> a & 1 == 1 { c[a] } else { cube.min[a] });
            cube = Aabb::new(min, std::array::from_fn(|a| min[a] + cube.size()[a] / 2.0));
            let cs = f32::from_bits(self.entries[i][2]) as f64;
            if cs > 0.0 {
                s = cs;
            }
        }
    }
}
