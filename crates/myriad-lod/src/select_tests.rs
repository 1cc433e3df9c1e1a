//! Tests of `select.rs` (shared with the front's and occlusion's tests: `tree`, `entry`).

use super::*;
use crate::DrawnTree;
use crate::hierarchy::DetailContour;
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
    // Both children drawn: the root takes the finest spacing among them (Discher et al. 2018,
    // section 5.1).
    assert_eq!(s.nodes[0].key, NodeKey::ROOT);
    assert_eq!(s.nodes[0].spacing, 0.1);
    // Looking along +x from x = -20: the near child [0, 1] has the larger benefit.
    assert_eq!(s.nodes[1].key, near.key);
    // A camera at x = 5.5 looking along +x culls the near child by its bounds; a child out
    // of view does not stop the pull-up, so the root takes the far child's spacing.
    let mut cam2 = cam;
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

/// Kanzok et al. 2015, section 3.1: a flat node's contour is its oriented box; outside the frustum
/// it is culled even though its cube is in view, and seen edge-on it is worth less than face-on.
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
        ..cam
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

/// The root, 65,536 points in four levels of detail (a plate's spacings over the unit cube).
fn four_levels() -> NodeEntry {
    NodeEntry::new(
        NodeKey::ROOT,
        PageRef {
            offset: 64,
            length: 100,
            crc: 0,
        },
        65_536,
        vec![64, 1024, 16_384, 65_536],
        vec![1.0 / 8.0, 1.0 / 32.0, 1.0 / 128.0, 1.0 / 256.0],
    )
}

/// A 400x400 camera with a 60 degree field of view.
fn camera(position: [f64; 3], target: [f64; 3], up: [f64; 3]) -> Camera {
    Camera {
        position,
        target,
        up,
        fov_y: 60.0,
        width: 400,
        height: 400,
        near: 0.01,
        far: 100.0,
    }
}

/// The contour-driven detail of Kanzok et al. 2015: a flat node (a plate of 65,536 points in four
/// levels) draws as many levels face-on as its spacing allows, edge-on at the same distance only
/// its coarsest (its contour covers a line of pixels); without a contour, the spacing alone
/// decides.
#[test]
fn a_flat_node_seen_edge_on_draws_fewer_points_than_face_on() {
    let root = Aabb::new([0.0; 3], [1.0; 3]);
    let mut plate = four_levels();
    plate.contour = Some(Obb {
        center: [0.5, 0.5, 0.5],
        axes: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        half_extents: [0.5, 0.5, 0.0005],
    });
    let cam = |position, up| camera(position, [0.5; 3], up);
    let face = cam([0.5, 0.5, 3.0], [0.0, 1.0, 0.0]);
    let edge = cam([0.5, -2.0, 0.5], [0.0, 0.0, 1.0]);
    let o = SelectOptions {
        budget: u64::MAX,
        min_pixels: 1.0,
    };
    let drawn = |h: &Hierarchy, c: &Camera| select(h, c, &o).points;
    let with = Hierarchy::new(root, [plate.clone()]);
    plate.contour = None;
    let without = Hierarchy::new(root, [plate]);
    // Face-on: the spacing's three levels (1/128 shows as 1.1 pixels, 1/256 does not).
    assert_eq!(drawn(&without, &face), 16_384);
    assert_eq!(drawn(&with, &face), 16_384);
    // Edge-on: the spacing alone would draw as many; the contour, a line, its coarsest level.
    assert_eq!(drawn(&without, &edge), 16_384);
    assert_eq!(drawn(&with, &edge), 64);
}

/// Kanzok et al. 2015 size a node's detail by the contour of its own points: a node whose own
/// points are a plate but whose subtree fills the cube (its stored contour, not flat) draws its
/// coarsest level edge-on; without the own points' contour, the subtree's says nothing and the
/// spacing decides. Culling still goes by the subtree's: seen where only the subtree's contour is
/// in view, the node is drawn.
#[test]
fn the_contour_of_a_nodes_own_points_sizes_its_detail_and_the_subtrees_culls() {
    let root = Aabb::new([0.0; 3], [1.0; 3]);
    let mut node = four_levels();
    node.contour = Some(Obb::from_aabb(&root));
    node.detail = Some(Obb {
        center: [0.5, 0.5, 0.1],
        axes: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        half_extents: [0.5, 0.5, 0.0005],
    });
    let cam = |position, target| camera(position, target, [0.0, 0.0, 1.0]);
    let o = SelectOptions {
        budget: u64::MAX,
        min_pixels: 1.0,
    };
    let drawn = |h: &Hierarchy, c: &Camera| select(h, c, &o).points;
    let with = Hierarchy::new(root, [node.clone()]);
    let mut subtree_only = node.clone();
    subtree_only.detail = None;
    let without = Hierarchy::new(root, [subtree_only]);
    // Edge-on to the plate, 2.5 units from it.
    let edge = cam([0.5, -2.0, 0.1], [0.5, 0.5, 0.1]);
    assert_eq!(drawn(&without, &edge), 16_384);
    assert_eq!(drawn(&with, &edge), 64);
    // By the subtree's contour alone, as a dataset without own contours; by the own one.
    let by = |rule| {
        let mut h = with.clone();
        h.detail_contour = rule;
        drawn(&h, &edge)
    };
    assert_eq!(by(DetailContour::Subtree), 16_384);
    assert_eq!(by(DetailContour::Own), 64);
    assert_eq!(by(DetailContour::Tighter), 64);
    // Looking at the top of the cube, the plate (at z 0.1) below the view: the subtree's
    // contour is in view, so the node is drawn.
    let above = cam([0.5, -0.2, 0.95], [0.5, 0.5, 0.95]);
    assert!(
        !above
            .frustum()
            .intersects_obb(node.detail.as_ref().unwrap())
    );
    assert!(drawn(&with, &above) > 0);
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
                detail: None,
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
        far.nodes.iter().map(|n| n.key.level).max() < near.nodes.iter().map(|n| n.key.level).max()
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
        detail: None,
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
    let t = DrawnTree::new(&s, &h, |_| true);
    assert_eq!(t.entries.len(), s.nodes.len());
    let leaf = NodeKey::ROOT.child(0).child(0);
    let p = [1.0, 1.0, 1.0];
    let got = t.spacing_at(&h.root, &NodeKey::ROOT, p).unwrap();
    assert_eq!(got, spacing(&leaf) as f32 as f64);
    assert!(got < spacing(&NodeKey::ROOT));
    // That leaf not drawn (still loading): its parent's spacing there, the leaf's sibling
    // still its own.
    let t = DrawnTree::new(&s, &h, |k| *k != leaf);
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
    let t = DrawnTree::new(&s, &h, |k| *k == leaf);
    assert_eq!(t.entries.len(), 3);
    assert_eq!(t.entries[0][2], 0);
    assert_eq!(t.entries[0][0], 1, "only octant 0 below the root");
    assert!(DrawnTree::new(&s, &h, |_| false).entries.is_empty());
    // A sparse leaf (its few points separated at a coarse level: a spacing above its
    // parent's): no point in its cube is drawn wider than the parent's spacing.
    let mut sparse = s.clone();
    let coarse = 10.0 * spacing(&NodeKey::ROOT);
    sparse
        .nodes
        .iter_mut()
        .find(|n| n.key == leaf)
        .unwrap()
        .spacing = coarse;
    let t = DrawnTree::new(&sparse, &h, |_| true);
    let parent_spacing = spacing(&parent) as f32 as f64;
    assert_eq!(t.spacing(&leaf), Some(parent_spacing));
    assert_eq!(t.spacing_at(&h.root, &leaf, p), Some(parent_spacing));
    assert_eq!(
        t.spacing_at(&h.root, &NodeKey::ROOT, p),
        Some(parent_spacing)
    );
    // Drawn in part (a coarse prefix), it keeps its own.
    let mut part = sparse.clone();
    part.nodes
        .iter_mut()
        .find(|n| n.key == leaf)
        .unwrap()
        .points -= 1;
    let part = DrawnTree::new(&part, &h, |_| true);
    assert_eq!(part.spacing(&leaf), Some(coarse as f32 as f64));
    // Its sibling, finer than the parent, keeps its own.
    assert_eq!(
        t.spacing(&parent.child(1)),
        Some(spacing(&parent.child(1)) as f32 as f64)
    );
}
