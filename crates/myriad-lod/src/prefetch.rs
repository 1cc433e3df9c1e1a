//! Prefetching (Goswami et al. 2010, section IV): the nodes the view will want next, loaded before
//! it does.

use crate::hierarchy::Hierarchy;
use crate::select::select_where;
use crate::selection::{SelectOptions, Selection};
use crate::view::Camera;
use myriad_core::{Aabb, NodeKey};

/// Nodes to load before the view needs them (Goswami et al. 2010, section IV, prefetching): those a
/// view just wider than `cam` would draw and `main` does not (`cam` widened by `widen` in field of
/// view and image alike, so that the pixel scale and with it the level of detail stay), and, where
/// nodes replace their parents (`mwkd`), the parents of the front (zooming out). Best first, at
/// most `limit`. (Not the hierarchy pages that view would want: where memory for pages is
/// short they push out pages in use and are dropped again, read after read.)
pub fn prefetch(
    h: &Hierarchy,
    cam: &Camera,
    o: &SelectOptions,
    keep: &dyn Fn(&Aabb) -> bool,
    main: &Selection,
    widen: f64,
    limit: usize,
) -> Vec<NodeKey> {
    let have: std::collections::HashSet<NodeKey> = main.nodes.iter().map(|n| n.key).collect();
    let mut wide = *cam;
    let t = (cam.fov_y.to_radians() / 2.0).tan() * widen;
    wide.fov_y = (2.0 * t.atan()).to_degrees().min(170.0);
    wide.width = ((cam.width as f64 * widen).round() as u32).max(1);
    wide.height = ((cam.height as f64 * widen).round() as u32).max(1);
    let around = select_where(h, &wide, o, keep);
    let mut out: Vec<NodeKey> = around
        .nodes
        .iter()
        .map(|n| n.key)
        .filter(|k| !have.contains(k))
        .take(limit)
        .collect();
    if h.splats() {
        for n in &main.nodes {
            if out.len() >= limit {
                break;
            }
            let p = n.key.parent();
            if n.key.level > 0 && !have.contains(&p) && !out.contains(&p) && h.get(&p).is_some() {
                out.push(p);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::select::select;
    use crate::select::tests::{looking_down, tree};

    /// Goswami et al. 2010's prefetching: the nodes a slightly wider view would draw, none of those
    /// drawn.
    #[test]
    fn prefetch_takes_the_nodes_just_outside_the_view() {
        let h = tree(4, 100.0, 4000);
        let mut cam = looking_down(&h, 20.0);
        cam.target = [30.0, 30.0, 0.0];
        cam.position = [30.0, 30.0 - 1e-3, h.root.max[2] + 20.0];
        let o = SelectOptions {
            budget: u64::MAX,
            min_pixels: 1.0,
        };
        let main = select(&h, &cam, &o);
        let ahead = prefetch(&h, &cam, &o, &|_| true, &main, 1.3, 10_000);
        assert!(!ahead.is_empty());
        let drawn: std::collections::HashSet<NodeKey> = main.nodes.iter().map(|n| n.key).collect();
        assert!(ahead.iter().all(|k| !drawn.contains(k)));
        // Outside the view, all of them: the wider view draws what this one does inside.
        let f = cam.frustum();
        assert!(ahead.iter().all(|k| !f.intersects(&h.bounds(k))));
        // Best first, at most the limit; nothing without widening.
        assert_eq!(prefetch(&h, &cam, &o, &|_| true, &main, 1.3, 3), ahead[..3]);
        assert!(prefetch(&h, &cam, &o, &|_| true, &main, 1.0, 100).is_empty());
    }
}
