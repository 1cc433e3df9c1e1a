//! Occlusion queries (Scheiblauer 2006) on every path this machine runs (hardware queries on the
//! GPU paths, their mirror on the CPU): a wall hides the box behind it and nothing else, a box seen
//! through a hole is kept; in a scene, the node behind the wall is culled from the next frame on
//! and comes back when the eye moves round the wall: in the frame that sees it (queries in the same
//! frame), and along a walk round the wall no frame differs from culling off. Checked culling (the default) leaves no pixel
//! of a room seen through a slit in its wall different from culling off, where the software
//! test alone loses what shows through the slit.

mod common;

use common::paths;
use myriad_core::{Aabb, Attribute, NodeKey, PointBatch, Schema};
use myriad_format::{NodeEntry, PageRef};
use myriad_lod::{Camera, Hierarchy, Occlusion, PageReader, SelectOptions};
use myriad_render::{ColorBy, Passes, PointSize, Points, Scene, Shape, Style};
use std::sync::Arc;

/// Looking along +x from x = -20 at the middle of a wall at x = 2 (y and z 0 to 10).
fn camera() -> Camera {
    Camera {
        position: [-20.0, 5.0, 5.0],
        target: [0.0, 5.0, 5.0],
        up: [0.0, 0.0, 1.0],
        fov_y: 60.0,
        width: 200,
        height: 200,
        near: 0.1,
        far: 100.0,
    }
}

/// Points 0.1 apart (0.8 pixels from the eye; drawn 2 pixels wide, no gaps) on the wall,
/// leaving out those inside `hole` (y and z ranges).
fn wall(hole: Option<[f64; 2]>) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    for i in 0..=100 {
        for j in 0..=100 {
            let (y, z) = (i as f64 * 0.1, j as f64 * 0.1);
            let inside = |v: f64, h: [f64; 2]| v > h[0] && v < h[1];
            if hole.is_some_and(|h| inside(y, h) && inside(z, h)) {
                continue;
            }
            out.push([2.0, y, z]);
        }
    }
    out
}

fn style() -> Style {
    Style {
        size: PointSize::Fixed(2.0),
        shape: Shape::Square,
        passes: Passes::default(),
        background: [0, 0, 0, 255],
        clip: None,
    }
}

#[test]
fn queries_find_what_a_wall_hides_on_every_path() {
    let b = |lo: [f64; 3], hi: [f64; 3]| Aabb::new(lo, hi).corners();
    let solid = [
        (b([6.0, 4.0, 4.0], [8.0, 6.0, 6.0]), false, "behind"),
        (b([10.0, 1.0, 1.0], [12.0, 9.0, 9.0]), false, "far behind"),
        (b([6.0, 11.0, 4.0], [8.0, 13.0, 6.0]), true, "beside"),
        (
            b([6.0, 9.0, 4.0], [8.0, 13.0, 6.0]),
            true,
            "across the edge",
        ),
        (b([0.0, 4.0, 4.0], [1.0, 6.0, 6.0]), true, "in front"),
        (
            b([-21.0, 4.0, 4.0], [8.0, 6.0, 6.0]),
            true,
            "around the eye",
        ),
    ];
    let holed = [
        (
            b([6.0, 4.6, 4.6], [8.0, 5.4, 5.4]),
            true,
            "through the hole",
        ),
        (
            b([6.0, 1.0, 1.0], [8.0, 2.0, 2.0]),
            false,
            "behind the solid part",
        ),
    ];
    for (gpu, r) in &paths() {
        // Before any frame, every box is visible.
        assert_eq!(r.query(gpu, &[solid[0].0]), [true], "{:?}", r.path);
        for (hole, cases) in [(None, &solid[..]), (Some([4.3, 5.7]), &holed[..])] {
            let positions = wall(hole);
            let p = Points::upload(gpu, [0.0; 3], &positions, &vec![[200; 4]; positions.len()]);
            r.render(gpu, &camera(), &[p.all(0.1)], &[], &style());
            let boxes: Vec<_> = cases.iter().map(|c| c.0).collect();
            let got = r.query(gpu, &boxes);
            for (c, v) in cases.iter().zip(got) {
                assert_eq!(v, c.1, "{:?}: {}", r.path, c.2);
            }
        }
    }
}

/// Nodes whose points and colour are functions of their key.
struct Scripted {
    points: fn(&NodeKey) -> Vec<[f64; 3]>,
    colour: fn(&NodeKey) -> [u16; 3],
}

impl PageReader for Scripted {
    fn read(&self, node: &NodeEntry) -> Result<PointBatch, String> {
        let schema = Schema::new(vec![Attribute::Rgb]);
        let points = (self.points)(&node.key);
        let mut b = PointBatch::with_schema(&schema, points.len());
        let colour = (self.colour)(&node.key);
        for p in points {
            b.positions.push(p);
            b.rgb.as_mut().unwrap().push(colour);
        }
        Ok(b)
    }
}

/// A node's entry: its points' count and bounds, one level of `spacing`.
fn entry_of(key: NodeKey, p: &[[f64; 3]], spacing: f64) -> NodeEntry {
    let mut bounds = Aabb::EMPTY;
    for &q in p {
        bounds.extend(q);
    }
    NodeEntry {
        key,
        page: PageRef {
            offset: 64,
            length: 100,
            crc: 0,
        },
        points: p.len() as u32,
        prefix: vec![p.len() as u32],
        spacing: vec![spacing],
        bounds: Some(bounds),
        contour: None,
        detail: None,
        splats: None,
    }
}

/// A wall (the root, white), a box of points behind it (child 0, red) and one beside it
/// (child 1, green).
const WALLED: Scripted = Scripted {
    points: node_points,
    colour: |k| {
        [[255, 255, 255], [255, 0, 0], [0, 255, 0]]
            [k.level as usize + (k.level > 0 && k.cell[0] == 1) as usize]
    },
};

/// The scenes' cube and nodes: a root and two children.
fn three_nodes() -> (Aabb, [NodeKey; 3]) {
    let keys = [
        NodeKey::ROOT,
        NodeKey::ROOT.child(0),
        NodeKey::ROOT.child(1),
    ];
    (Aabb::new([0.0; 3], [20.0; 3]), keys)
}

/// A box of 10 x 10 x 10 points `step` apart from `lo`.
fn cube(lo: [f64; 3], step: f64) -> Vec<[f64; 3]> {
    (0..1000)
        .map(|i| {
            let f = |k: usize| (k % 10) as f64 * step;
            [lo[0] + f(i), lo[1] + f(i / 10), lo[2] + f(i / 100)]
        })
        .collect()
}

fn node_points(key: &NodeKey) -> Vec<[f64; 3]> {
    // The one behind is the larger: the selection reaches it first.
    match key.level {
        0 => wall(None),
        _ if key.cell[0] == 0 => cube([6.0, 4.0, 4.0], 0.3),
        _ => cube([6.0, 11.0, 4.0], 0.2),
    }
}

fn entry(key: NodeKey) -> NodeEntry {
    entry_of(key, &node_points(&key), 0.1)
}

#[test]
fn a_node_behind_a_wall_is_culled_from_the_next_frame_until_it_shows() {
    for (gpu, raster) in &paths() {
        let (root, keys) = three_nodes();
        let h = Hierarchy::new(root, keys.map(entry));
        let mut scene = Scene::new(Arc::new(WALLED), h, root, 1, usize::MAX, usize::MAX);
        scene.set_colour(ColorBy::Rgb);
        scene.occlusion = Occlusion::Queries;
        // The queries' results used from the next frame (the viewer's schedule).
        scene.same_frame = false;
        let options = SelectOptions {
            budget: 1_000_000,
            min_pixels: 0.0,
        };
        let green = |img: &[u8]| {
            img.chunks_exact(4)
                .filter(|p| p[1] == 255 && p[0] == 0)
                .count()
        };
        let red = |img: &[u8]| {
            img.chunks_exact(4)
                .filter(|p| p[0] == 255 && p[1] == 0)
                .count()
        };
        let cam = camera();
        scene.converge(&cam, &options, None);
        // The first frame knows nothing hidden: all three drawn; its queries find the box.
        let (_, first) = scene.frame(gpu, raster, &cam, &options, &style());
        assert_eq!((first.nodes, first.culled), (3, 0), "{:?}", raster.path);
        for _ in 0..2 {
            let (img, s) = scene.frame(gpu, raster, &cam, &options, &style());
            assert_eq!((s.nodes, s.culled), (2, 1), "{:?}", raster.path);
            assert_eq!(s.points, first.points - 1000);
            assert!(green(&img) > 20 && red(&img) == 0, "{:?}", raster.path);
        }
        // From the other side of the wall the box is in front: it is queried while culled,
        // and drawn again from the frame after.
        let mut back = cam;
        back.position = [30.0, 5.0, 5.0];
        back.target = [0.0, 5.0, 5.0];
        scene.converge(&back, &options, None);
        let (_, s) = scene.frame(gpu, raster, &back, &options, &style());
        assert_eq!(
            s.culled, 1,
            "{:?}: this frame still uses the last queries",
            raster.path
        );
        let (img, s) = scene.frame(gpu, raster, &back, &options, &style());
        assert_eq!((s.nodes, s.culled), (3, 0), "{:?}", raster.path);
        assert!(red(&img) > 20, "{:?}", raster.path);
        // Queried in the same frame (the default where a frame waits for its queries): the
        // box found showing is drawn in the frame that found it.
        scene.same_frame = true;
        for _ in 0..2 {
            scene.frame(gpu, raster, &cam, &options, &style());
        }
        let (_, s) = scene.frame(gpu, raster, &cam, &options, &style());
        assert_eq!((s.nodes, s.culled), (2, 1), "{:?}", raster.path);
        let (img, s) = scene.frame(gpu, raster, &back, &options, &style());
        assert_eq!(
            (s.nodes, s.culled, s.revealed),
            (3, 0, 1),
            "{:?}",
            raster.path
        );
        assert!(red(&img) > 20, "{:?}", raster.path);

        // A budget for the wall and one box: the one behind the wall (the larger, reached
        // first) takes it in the first frame; once the queries have found it hidden, its share
        // goes to the box beside it.
        let h = Hierarchy::new(root, keys.map(entry));
        let mut scene = Scene::new(Arc::new(WALLED), h, root, 1, usize::MAX, usize::MAX);
        scene.set_colour(ColorBy::Rgb);
        scene.occlusion = Occlusion::Queries;
        let tight = SelectOptions {
            budget: first.points - 1000,
            min_pixels: 0.0,
        };
        let mut last = None;
        for _ in 0..3 {
            scene.converge(&cam, &tight, None);
            last = Some(scene.frame(gpu, raster, &cam, &tight, &style()));
        }
        let (img, s) = last.expect("drawn");
        assert_eq!((s.nodes, s.culled), (2, 1), "{:?}", raster.path);
        assert!(green(&img) > 20, "{:?}: the box beside", raster.path);

        // Not waiting for the results (the viewer's way): the box is culled a frame or more
        // later, when the GPU has answered.
        let h = Hierarchy::new(root, keys.map(entry));
        let mut scene = Scene::new(Arc::new(WALLED), h, root, 1, usize::MAX, usize::MAX);
        scene.occlusion = Occlusion::Queries;
        scene.query_wait = false;
        scene.converge(&cam, &options, None);
        let mut culled = Vec::new();
        for _ in 0..50 {
            let (_, s) = scene.frame(gpu, raster, &cam, &options, &style());
            culled.push(s.culled);
            if s.culled == 1 {
                break;
            }
        }
        assert!(
            culled[0] == 0 && culled.ends_with(&[1]),
            "{:?}: {culled:?}",
            raster.path
        );
    }
}

/// A wall with a slit 0.6 wide (the root, white; its level's spacing, 0.8, wider than the slit:
/// what the software test's splats close), a box seen through the slit (child 0, red) and one
/// behind the solid part (child 1, blue).
const SLIT: Scripted = Scripted {
    points: slit_points,
    colour: |k| match (k.level, k.cell[0]) {
        (0, _) => [255, 255, 255],
        (_, 0) => [255, 0, 0],
        _ => [0, 0, 255],
    },
};

fn slit_points(key: &NodeKey) -> Vec<[f64; 3]> {
    match key.level {
        0 => (0..=100)
            .flat_map(|i| (0..=100).map(move |j| [2.0, i as f64 * 0.1, j as f64 * 0.1]))
            .filter(|p| !(p[1] > 4.75 && p[1] < 5.25))
            .collect(),
        _ if key.cell[0] == 0 => cube([6.0, 4.0, 4.0], 0.2),
        _ => cube([6.0, 1.0, 1.0], 0.1),
    }
}

fn slit_entry(key: NodeKey) -> NodeEntry {
    entry_of(
        key,
        &slit_points(&key),
        if key.level == 0 { 0.8 } else { 0.1 },
    )
}

#[test]
fn checked_culling_changes_no_pixel_where_the_software_test_loses_a_slit() {
    for (gpu, raster) in &paths() {
        let (root, keys) = three_nodes();
        let options = SelectOptions {
            budget: 1_000_000,
            min_pixels: 0.0,
        };
        let cam = camera();
        let red = |img: &[u8]| {
            img.chunks_exact(4)
                .filter(|p| p[0] == 255 && p[1] == 0)
                .count()
        };
        // Settled: frames until the selection no longer changes.
        let settled = |occlusion: Occlusion| {
            let h = Hierarchy::new(root, keys.map(slit_entry));
            let mut scene = Scene::new(Arc::new(SLIT), h, root, 1, usize::MAX, usize::MAX);
            scene.set_colour(ColorBy::Rgb);
            scene.occlusion = occlusion;
            let mut last = None;
            let mut frames = 0;
            for _ in 0..6 {
                scene.converge(&cam, &options, None);
                let (img, s) = scene.frame(gpu, raster, &cam, &options, &style());
                frames += 1;
                let same =
                    last.as_ref()
                        .is_some_and(|(_, l): &(Vec<u8>, myriad_render::FrameStats)| {
                            (l.nodes, l.culled) == (s.nodes, s.culled)
                        });
                last = Some((img, s));
                if same {
                    break;
                }
            }
            let (img, s) = last.expect("drawn");
            (img, s, frames)
        };
        let (off, s, _) = settled(Occlusion::Off);
        assert_eq!((s.nodes, s.culled), (3, 0), "{:?}", raster.path);
        assert!(
            red(&off) > 10,
            "{:?}: the red box shows through the slit",
            raster.path
        );
        // The software test closes the slit: both boxes culled, the red pixels lost.
        let (soft, s, _) = settled(Occlusion::Software);
        assert_eq!((s.nodes, s.culled), (1, 2), "{:?}", raster.path);
        assert_eq!(red(&soft), 0, "{:?}", raster.path);
        // Checked (the default): the red box's query shows it, so it is drawn from the next
        // frame; the blue one stays culled. Not one pixel differs from culling off.
        let h = Hierarchy::new(root, keys.map(slit_entry));
        let fresh = Scene::new(Arc::new(SLIT), h, root, 1, usize::MAX, usize::MAX);
        assert_eq!(fresh.occlusion, Occlusion::Checked);
        let (checked, s, frames) = settled(Occlusion::Checked);
        assert_eq!((s.nodes, s.culled), (2, 1), "{:?}", raster.path);
        assert!(frames <= 4, "{:?}: settled in {frames} frames", raster.path);
        let differ = off.iter().zip(&checked).filter(|(a, b)| a != b).count();
        assert_eq!(
            differ, 0,
            "{:?}: bytes that differ from culling off",
            raster.path
        );
    }
}

#[test]
fn a_walk_round_a_wall_has_no_frame_with_a_hole_with_queries_in_the_same_frame() {
    // 24 steps on a circle round the wall (radius 25 about its middle): each frame against the
    // same view with culling off. Queries used from the next frame leave the box behind the
    // wall out of the frames where it comes into sight; queried in the same frame, none.
    for (gpu, raster) in &paths() {
        let (root, keys) = three_nodes();
        let options = SelectOptions {
            budget: 1_000_000,
            min_pixels: 0.0,
        };
        let scene = |occlusion, same_frame| {
            let h = Hierarchy::new(root, keys.map(entry));
            let mut s = Scene::new(Arc::new(WALLED), h, root, 1, usize::MAX, usize::MAX);
            s.set_colour(ColorBy::Rgb);
            s.occlusion = occlusion;
            s.same_frame = same_frame;
            s
        };
        let mut off = scene(Occlusion::Off, true);
        let mut late = scene(Occlusion::Queries, false);
        let mut same = scene(Occlusion::Queries, true);
        let mut checked = scene(Occlusion::Checked, true);
        // The viewer's frame on the CPU: the scenes drawn together, waiting for their queries.
        let mut many = scene(Occlusion::Queries, true);
        let mut holes = [0; 4];
        let mut culled = 0;
        for step in 0..24 {
            let a = step as f64 / 24.0 * std::f64::consts::TAU;
            let cam = Camera {
                position: [4.0 - 25.0 * a.cos(), 5.0 + 25.0 * a.sin(), 5.0],
                target: [4.0, 5.0, 5.0],
                ..camera()
            };
            let frame = |s: &mut Scene| {
                s.converge(&cam, &options, None);
                s.frame(gpu, raster, &cam, &options, &style())
            };
            let (want, _) = frame(&mut off);
            for (k, s) in [&mut late, &mut same, &mut checked].into_iter().enumerate() {
                let (img, stats) = frame(s);
                holes[k] += usize::from(img != want);
                if k == 1 {
                    culled += stats.culled;
                }
            }
            many.converge(&cam, &options, None);
            let (img, _) =
                myriad_render::frame_many(&mut [&mut many], gpu, raster, &cam, &options, &style());
            holes[3] += usize::from(img != want);
        }
        assert!(
            holes[0] > 0,
            "{:?}: the late queries left no hole",
            raster.path
        );
        assert_eq!(holes[1..], [0, 0, 0], "{:?}", raster.path);
        assert!(culled > 0, "{:?}: the queries culled nothing", raster.path);
    }
}
