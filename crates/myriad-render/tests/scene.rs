//! The whole frame pipeline with a page reader that only answers when the test lets it: frames
//! keep coming while pages are out (the frame loop never waits for I/O), nothing is drawn where
//! nothing has landed, and the image refines as pages land: first the root, then its children.

mod common;

use myriad_core::{Aabb, Attribute, NodeKey, PointBatch, Schema};
use myriad_format::{NodeEntry, PageRef};
use myriad_lod::{Camera, Hierarchy, PageReader, SelectOptions};
use myriad_render::{ColorBy, Gpu, PointSize, Rasterizer, Scene, Style};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A flat square 0..64 x 0..64 at z = 0: the root holds a coarse grid (spacing 8), each of the
/// four children of the bottom layer a fine grid (spacing 1) over its quarter.
fn node_points(key: &NodeKey) -> Vec<[f64; 3]> {
    let (step, x0, y0, side) = if key.level == 0 {
        (8.0, 0.0, 0.0, 64.0)
    } else {
        (
            1.0,
            key.cell[0] as f64 * 32.0,
            key.cell[1] as f64 * 32.0,
            32.0,
        )
    };
    let n = (side / step) as usize;
    (0..n * n)
        .map(|i| {
            [
                x0 + (i % n) as f64 * step + step / 2.0,
                y0 + (i / n) as f64 * step + step / 2.0,
                0.0,
            ]
        })
        .collect()
}

fn entry(key: NodeKey) -> NodeEntry {
    let n = node_points(&key).len() as u32;
    let spacing = if key.level == 0 { 8.0 } else { 1.0 };
    NodeEntry {
        key,
        page: PageRef {
            offset: 64,
            length: 100,
            crc: 0,
        },
        points: n,
        prefix: vec![n],
        spacing: vec![spacing],
        bounds: None,
        contour: None,
        detail: None,
        splats: None,
    }
}

/// Straight down on the square, which fills most of the view.
fn above() -> Camera {
    Camera {
        position: [32.0, 32.0, 80.0],
        target: [32.0, 32.0, 0.0],
        up: [0.0, 1.0, 0.0],
        fov_y: 60.0,
        width: 160,
        height: 160,
        near: 1.0,
        far: 200.0,
    }
}

/// Answers one read per permit.
struct Gated {
    permits: Mutex<Receiver<()>>,
}

impl PageReader for Gated {
    fn read(&self, node: &NodeEntry) -> Result<PointBatch, String> {
        self.permits
            .lock()
            .unwrap()
            .recv()
            .map_err(|_| "closed".to_string())?;
        let schema = Schema::new(vec![Attribute::Rgb]);
        let points = node_points(&node.key);
        let mut b = PointBatch::with_schema(&schema, points.len());
        for p in points {
            b.positions.push(p);
            b.rgb.as_mut().unwrap().push([255, 255, 255]);
        }
        Ok(b)
    }
}

#[test]
fn frames_keep_coming_while_pages_load_and_the_image_refines() {
    // On the CPU, and on the GPU where there is one (each draws every node in one pass).
    frames_refine_on(Gpu::cpu());
    match Gpu::headless() {
        Ok(gpu) => frames_refine_on(gpu),
        Err(e) => eprintln!("SKIPPED on the GPU: {e}"),
    }
}

fn frames_refine_on(gpu: Gpu) {
    let root = Aabb::new([0.0; 3], [64.0; 3]);
    let keys = std::iter::once(NodeKey::ROOT).chain((0..4).map(|o| NodeKey::ROOT.child(o)));
    let h = Hierarchy::new(root, keys.map(entry));
    let (permit, permits): (Sender<()>, _) = channel();
    let reader = Arc::new(Gated {
        permits: Mutex::new(permits),
    });
    let mut scene = Scene::new(reader, h, root, 1, usize::MAX, usize::MAX);
    // Declared after the scene, so dropped before it: a loader thread waiting for a permit
    // then ends (and a failing test does not hang).
    let permit = permit;
    scene.set_colour(ColorBy::Rgb);
    let raster = Rasterizer::new(&gpu);
    let cam = above();
    let options = SelectOptions {
        budget: 1_000_000,
        min_pixels: 0.5,
    };
    let style = Style {
        size: PointSize::Fixed(1.0),
        ..Style::default()
    };
    let lit = |img: &[u8]| img.chunks_exact(4).filter(|p| p[0] == 255).count();
    let frame = |scene: &mut Scene| {
        let t = Instant::now();
        let (img, stats) = scene.frame(&gpu, &raster, &cam, &options, &style);
        (lit(&img), stats, t.elapsed())
    };

    // Nothing has landed: frames come anyway, empty.
    for _ in 0..3 {
        let (pixels, stats, took) = frame(&mut scene);
        assert_eq!(pixels, 0);
        assert_eq!(stats.points, 0);
        assert!(!stats.complete);
        assert!(took < Duration::from_secs(5), "a frame took {took:?}");
    }
    // The root lands: its coarse grid is drawn; the children are still out.
    permit.send(()).unwrap();
    let mut coarse = (0, Default::default(), Duration::ZERO);
    let t = Instant::now();
    while coarse.0 == 0 && t.elapsed() < Duration::from_secs(30) {
        coarse = frame(&mut scene);
    }
    assert_eq!(coarse.0, 64, "the root's 8 x 8 grid");
    assert_eq!(coarse.1.points, 64);
    assert!(coarse.1.in_flight > 0 && !coarse.1.complete);
    // More frames while the children are blocked: the same image, no waiting.
    for _ in 0..3 {
        let (pixels, stats, _) = frame(&mut scene);
        assert_eq!((pixels, stats.points), (64, 64));
    }
    // The children land one by one: more points each time, then complete.
    let mut last = 64;
    for landed in 1..=4 {
        permit.send(()).unwrap();
        let t = Instant::now();
        let mut now = frame(&mut scene);
        let want = 64 + landed * 1024;
        while now.1.points < want && t.elapsed() < Duration::from_secs(30) {
            now = frame(&mut scene);
        }
        assert_eq!(now.1.points, want, "after {landed} children landed");
        assert!(now.0 > last, "the image refines: {} -> {}", last, now.0);
        last = now.0;
        if landed == 4 {
            assert!(now.1.complete && now.1.in_flight == 0);
        }
    }
}

/// Answers at once: a grid over the node's square at height `z`, in one colour.
struct Flat {
    z: f64,
    rgb: [u16; 3],
}

impl PageReader for Flat {
    fn read(&self, node: &NodeEntry) -> Result<PointBatch, String> {
        let schema = Schema::new(vec![Attribute::Rgb]);
        let points = node_points(&node.key);
        let mut b = PointBatch::with_schema(&schema, points.len());
        for p in points {
            b.positions.push([p[0], p[1], self.z]);
            b.rgb.as_mut().unwrap().push(self.rgb);
        }
        Ok(b)
    }
}

#[test]
fn several_datasets_share_the_budget_and_the_depth_buffer() {
    // Two copies of the square, one 10 units above the other; seen from above, the upper one
    // (red) hides the lower one (green) where both are drawn, whichever comes first.
    let keys = || std::iter::once(NodeKey::ROOT).chain((0..4).map(|o| NodeKey::ROOT.child(o)));
    let make = |z: f64, rgb: [u16; 3]| {
        let root = Aabb::new([0.0, 0.0, z], [64.0, 64.0, z + 64.0]);
        let h = Hierarchy::new(root, keys().map(entry));
        Scene::new(
            Arc::new(Flat { z, rgb }),
            h,
            root,
            1,
            usize::MAX,
            usize::MAX,
        )
    };
    for gpu in std::iter::once(Gpu::cpu()).chain(Gpu::headless().ok()) {
        let raster = Rasterizer::new(&gpu);
        let (mut low, mut high) = (make(0.0, [0, 255, 0]), make(10.0, [255, 0, 0]));
        let cam = above();
        let style = Style {
            size: PointSize::Fixed(3.0),
            ..Style::default()
        };
        let options = SelectOptions {
            budget: 1_000_000,
            min_pixels: 0.5,
        };
        let count = |img: &[u8], c: [u8; 3]| img.chunks_exact(4).filter(|p| p[..3] == c).count();
        let t = Instant::now();
        let (mut img, mut stats);
        loop {
            (img, stats) = myriad_render::frame_many(
                &mut [&mut low, &mut high],
                &gpu,
                &raster,
                &cam,
                &options,
                &style,
            );
            if stats.iter().all(|s| s.complete) || t.elapsed() > Duration::from_secs(30) {
                break;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(stats.iter().all(|s| s.complete), "{}", gpu.name);
        assert_eq!(stats[0].points + stats[1].points, 2 * (64 + 4 * 1024));
        let (red, green) = (count(&img, [255, 0, 0]), count(&img, [0, 255, 0]));
        assert!(red > 5000, "{}: {red} red pixels", gpu.name);
        // The lower square peeks out only around the upper one's edge (it is further, so it
        // looks smaller: none of it at all).
        assert!(green < red / 20, "{}: {green} green pixels", gpu.name);
        // A budget for about half: shared, and the nearer square gets more.
        let half = SelectOptions {
            budget: 4000,
            ..options
        };
        let (_, stats) = myriad_render::frame_many(
            &mut [&mut low, &mut high],
            &gpu,
            &raster,
            &cam,
            &half,
            &style,
        );
        assert_eq!(stats[0].selected_points + stats[1].selected_points, 4000);
        assert!(stats[1].selected_points > stats[0].selected_points);
    }
}

/// As `Gated`, with splats (normals up, radius 0.5), for an `mwkd` tree.
struct GatedSplats(Gated);

impl PageReader for GatedSplats {
    fn read(&self, node: &NodeEntry) -> Result<PointBatch, String> {
        self.0.read(node)
    }
    fn read_splats(
        &self,
        node: &NodeEntry,
    ) -> Result<Option<myriad_format::splat::Splats>, String> {
        let n = node.points as usize;
        Ok(Some(myriad_format::splat::Splats {
            normals: vec![[0.0, 0.0, 1.0]; n],
            radii: vec![0.5; n],
        }))
    }
}

/// An `mwkd` tree over the square (the root's aggregates, its four children's points), read
/// one node per permit sent.
fn gated_mwkd() -> (Scene, Sender<()>) {
    let root = Aabb::new([0.0; 3], [64.0; 3]);
    let splat_entry = |key: NodeKey| {
        let mut e = entry(key);
        e.bounds = Some(if key.level == 0 {
            Aabb::new([0.0; 3], [64.0, 64.0, 0.0])
        } else {
            let (x, y) = (key.cell[0] as f64 * 32.0, key.cell[1] as f64 * 32.0);
            Aabb::new([x, y, 0.0], [x + 32.0, y + 32.0, 0.0])
        });
        e.splats = Some(myriad_format::splat::SplatInfo {
            page: PageRef {
                offset: 64,
                length: 10,
                crc: 0,
            },
            radius: [0.5, 0.5],
            cone: [0.0, 0.0, 1.0, 1.0],
            aggregate: key.level == 0,
        });
        e
    };
    let keys = std::iter::once(NodeKey::ROOT).chain((0..4).map(|o| NodeKey::ROOT.child(o)));
    let h = Hierarchy::new(root, keys.map(splat_entry));
    assert!(h.splats());
    let (permit, permits): (Sender<()>, _) = channel();
    let reader = Arc::new(GatedSplats(Gated {
        permits: Mutex::new(permits),
    }));
    (
        Scene::new(reader, h, root, 1, usize::MAX, usize::MAX),
        permit,
    )
}

/// Goswami et al. 2010, section IV, for nodes that come into view: nothing was drawn in their
/// place, so their nearest ancestor on the GPU stands in until they land (without it, a hole), and
/// where none is, their parent is read first.
#[test]
fn nodes_coming_into_view_have_their_ancestor_in_their_place() {
    for gpu in std::iter::once(Gpu::cpu()).chain(Gpu::headless().ok()) {
        for on in [true, false] {
            let (mut scene, permit) = gated_mwkd();
            scene.ancestor_stand_ins = on;
            let raster = Rasterizer::new(&gpu);
            let style = Style {
                size: PointSize::Fixed(1.0),
                ..Style::default()
            };
            // Close above the first quarter: only child 0 is in view.
            let near = Camera {
                position: [16.0, 16.0, 20.0],
                target: [16.0, 16.0, 0.0],
                ..above()
            };
            let frame = |scene: &mut Scene, cam: &Camera, b: u64, want: u64| {
                let options = SelectOptions {
                    budget: b,
                    min_pixels: 0.0,
                };
                let t = Instant::now();
                loop {
                    let (_, stats) = scene.frame(&gpu, &raster, cam, &options, &style);
                    if stats.points == want || t.elapsed() > Duration::from_secs(30) {
                        return stats;
                    }
                    std::thread::sleep(Duration::from_millis(2));
                }
            };
            // Child 0 alone is wanted (its quarter fills the view). With stand-ins, its
            // parent, the root, is read first and drawn in its place; then child 0.
            permit.send(()).unwrap();
            let s = frame(&mut scene, &near, 5000, if on { 64 } else { 1024 });
            if on {
                assert_eq!((s.points, s.selected_nodes, s.holes), (64, 1, 0));
                permit.send(()).unwrap();
                let s = frame(&mut scene, &near, 5000, 1024);
                assert_eq!((s.points, s.selected_nodes, s.holes), (1024, 1, 0));
            } else {
                assert_eq!((s.points, s.holes), (1024, 0));
                // The root read (a small budget), then child 0 again.
                permit.send(()).unwrap();
                assert_eq!(frame(&mut scene, &near, 100, 64).points, 64);
                assert_eq!(frame(&mut scene, &near, 5000, 1024).points, 1024);
            }
            // Up to see the whole square: children 1-3 come into view and are not read (no
            // permits). The root, on the GPU but not drawn last frame, stands in for them.
            for _ in 0..3 {
                let s = frame(
                    &mut scene,
                    &above(),
                    5000,
                    if on { 1024 + 64 } else { 1024 },
                );
                assert_eq!(s.selected_nodes, 4);
                assert!(!s.complete);
                if on {
                    assert_eq!((s.points, s.holes), (1024 + 64, 0), "{}", gpu.name);
                } else {
                    assert_eq!((s.points, s.holes), (1024, 3), "{}", gpu.name);
                }
            }
        }
    }
}

/// Goswami et al. 2010, section IV: when the front moves, what was drawn before stays on screen
/// until the new nodes land: the root in place of its children while they load, the children in
/// place of the root when the front goes back up.
#[test]
fn the_front_moves_without_holes() {
    for gpu in std::iter::once(Gpu::cpu()).chain(Gpu::headless().ok()) {
        let (mut scene, permit) = gated_mwkd();
        // What was drawn stands in here; ancestors read first for nodes coming into view are
        // the next test's.
        scene.ancestor_stand_ins = false;
        let permit = permit;
        let raster = Rasterizer::new(&gpu);
        let cam = above();
        let style = Style {
            size: PointSize::Fixed(1.0),
            ..Style::default()
        };
        let budget = |b| SelectOptions {
            budget: b,
            min_pixels: 0.0,
        };
        let frame = |scene: &mut Scene, b: u64, want: u64| {
            let t = Instant::now();
            loop {
                let (_, stats) = scene.frame(&gpu, &raster, &cam, &budget(b), &style);
                if stats.points == want || t.elapsed() > Duration::from_secs(30) {
                    return stats;
                }
                std::thread::sleep(Duration::from_millis(2));
            }
        };
        // The children fill the budget: they load, and are all that is drawn.
        for _ in 0..4 {
            permit.send(()).unwrap();
        }
        let s = frame(&mut scene, 5000, 4096);
        assert_eq!((s.points, s.selected_nodes), (4096, 4));
        // The budget drops below them: the front is the root, which has not landed; the
        // children stay on screen meanwhile, frame after frame.
        for _ in 0..3 {
            let s = frame(&mut scene, 100, 4096);
            assert_eq!((s.points, s.selected_nodes), (4096, 1), "children stand in");
            assert!(!s.complete);
        }
        // The root lands: it alone is drawn.
        permit.send(()).unwrap();
        let s = frame(&mut scene, 100, 64);
        assert_eq!((s.points, s.nodes), (64, 1));
        assert!(s.complete);
        // And back down: the children are on the GPU still, drawn at once.
        let s = frame(&mut scene, 5000, 4096);
        assert_eq!(s.nodes, 4);
    }
}

/// Every cell of the bottom layer of a full octree over the square down to `depth`, each with a
/// few points at a spacing a fine threshold wants refined: a selection without a budget visits
/// them all (hundreds of thousands of nodes: a hierarchy too big to traverse within a frame).
fn huge(depth: u32) -> Hierarchy {
    let root = Aabb::new([0.0; 3], [64.0; 3]);
    let mut entries = Vec::new();
    for level in 0..=depth {
        let n = 1u32 << level;
        for x in 0..n {
            for y in 0..n {
                let mut e = entry(NodeKey::ROOT);
                e.key = NodeKey {
                    level,
                    cell: [x, y, 0],
                };
                e.points = 4;
                e.prefix = vec![4];
                e.spacing = vec![64.0 / n as f64 / 2.0];
                entries.push(e);
            }
        }
    }
    Hierarchy::new(root, entries)
}

#[test]
fn frames_keep_coming_while_a_huge_selection_runs_on_its_thread() {
    let gpu = Gpu::cpu();
    let (permit, permits): (Sender<()>, _) = channel();
    let reader = Arc::new(Gated {
        permits: Mutex::new(permits),
    });
    let mut scene = Scene::new(
        reader,
        huge(9),
        Aabb::new([0.0; 3], [64.0; 3]),
        1,
        usize::MAX,
        usize::MAX,
    );
    // Declared after the scene, so dropped before it: the loader thread waiting for a permit
    // then ends.
    let _permit = permit;
    let raster = Rasterizer::new(&gpu);
    let cam = above();
    let options = SelectOptions {
        budget: u64::MAX,
        min_pixels: 0.01,
    };
    let style = Style {
        size: PointSize::Fixed(1.0),
        ..Style::default()
    };
    // What a frame would wait for with the selection on the frame thread.
    let t = Instant::now();
    let alone = scene.select(&cam, &options, None);
    let traversal = t.elapsed();
    assert!(
        alone.nodes.len() > 300_000,
        "{} nodes selected",
        alone.nodes.len()
    );
    assert!(
        traversal > Duration::from_millis(100),
        "the traversal took only {traversal:?}"
    );

    // Threaded: frames come at their interval while the traversal runs (with the selection on
    // the frame thread, one frame would last the whole traversal); its answer is drawn when in.
    let start = Instant::now();
    let mut before_answer = 0;
    let mut slowest = Duration::ZERO;
    let mut answered = None;
    while start.elapsed() < traversal * 4 + Duration::from_secs(2) {
        let t = Instant::now();
        let (_, stats) = scene.frame_threaded(&gpu, &raster, &cam, &options, &style);
        if stats.select_thread == Duration::ZERO {
            // Not counted: the frame that takes the answer in, which then loads and draws
            // 350,000 nodes (work of the frame, not waiting).
            slowest = slowest.max(t.elapsed());
            before_answer += 1;
        } else {
            answered = Some(stats);
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let stats = answered.expect("the selection thread answered");
    eprintln!(
        "traversal {traversal:?}; {before_answer} frames meanwhile, the slowest {slowest:?}; on its thread {:?}",
        stats.select_thread
    );
    assert!(
        before_answer >= 3,
        "{before_answer} frames before the answer"
    );
    assert!(
        slowest < traversal / 3,
        "a frame took {slowest:?}, the traversal {traversal:?}"
    );
    assert_eq!(stats.selected_nodes, alone.nodes.len());
    assert!(
        stats.select_thread > traversal / 3,
        "{:?}",
        stats.select_thread
    );
    // Meanwhile the camera's newer requests wait: the drawn selection is behind by some.
    assert!(stats.select_lag >= 1, "lag {}", stats.select_lag);
    assert!(stats.select_current, "the camera did not move");
}

/// Answers at once: the node's grid in a colour of its own.
struct ByNode;

impl PageReader for ByNode {
    fn read(&self, node: &NodeEntry) -> Result<PointBatch, String> {
        let schema = Schema::new(vec![Attribute::Rgb]);
        let points = node_points(&node.key);
        let mut b = PointBatch::with_schema(&schema, points.len());
        let c = node.key.cell;
        let rgb = [
            20_000 + 15_000 * c[0] as u16,
            20_000 + 15_000 * c[1] as u16,
            65_535 - 30_000 * node.key.level as u16,
        ];
        for p in points {
            b.positions.push(p);
            b.rgb.as_mut().unwrap().push(rgb);
        }
        Ok(b)
    }
}

#[test]
fn the_quad_paths_node_order_changes_no_pixel() {
    // Front to back (Discher et al. 2018's reverse painter's order) or as selected, the depth test
    // keeps the nearest point: the order may change the time, not the picture.
    let gpu = match Gpu::headless() {
        Ok(g) => g,
        Err(e) => {
            eprintln!("SKIPPED: {e}");
            return;
        }
    };
    let root = Aabb::new([0.0; 3], [64.0; 3]);
    let keys = std::iter::once(NodeKey::ROOT).chain((0..4).map(|o| NodeKey::ROOT.child(o)));
    let h = Hierarchy::new(root, keys.map(entry));
    let mut scene = Scene::new(Arc::new(ByNode), h, root, 1, usize::MAX, usize::MAX);
    scene.set_colour(ColorBy::Rgb);
    let mut raster = Rasterizer::with_path(&gpu, myriad_render::Path::Quads);
    // Low over one side of the square: the nodes lie at different distances.
    let cam = Camera {
        position: [32.0, -30.0, 25.0],
        ..above()
    };
    let options = SelectOptions {
        budget: 1_000_000,
        min_pixels: 0.5,
    };
    let style = Style {
        size: PointSize::Fixed(3.0),
        ..Style::default()
    };
    scene.converge(&cam, &options, None);
    let mut images = Vec::new();
    for front_to_back in [true, false] {
        raster.front_to_back = front_to_back;
        let (img, stats) = scene.frame(&gpu, &raster, &cam, &options, &style);
        assert_eq!(stats.points, 64 + 4 * 1024);
        images.push(img);
    }
    let lit = images[0].chunks(4).filter(|p| p[..3] != [0, 0, 0]).count();
    assert!(lit > 160 * 160 / 4, "{lit}");
    let differ = images[0]
        .chunks(4)
        .zip(images[1].chunks(4))
        .filter(|(a, b)| a != b)
        .count();
    // Points at the same depth in one pixel (a tie) may go either way.
    assert!(differ * 500 <= 160 * 160, "{differ} pixels differ");
}

#[test]
fn the_loader_threads_make_the_gpu_words_and_frames_only_hand_them_over() {
    // Nodes read after the scene's settings are known come with their words: a frame uploads
    // them as they are, with the image of words made at the upload. A scheme changed later is
    // encoded at the upload for the nodes already in, and made by the loader threads for those
    // read after it.
    let root = Aabb::new([0.0; 3], [64.0; 3]);
    let keys = std::iter::once(NodeKey::ROOT).chain((0..4).map(|o| NodeKey::ROOT.child(o)));
    let h = Hierarchy::new(root, keys.map(entry));
    let cam = above();
    let options = SelectOptions {
        budget: 1_000_000,
        min_pixels: 0.5,
    };
    let style = Style {
        size: PointSize::Fixed(1.0),
        ..Style::default()
    };
    for (gpu, raster) in common::paths() {
        let scene = || {
            let reader = Arc::new(Flat {
                z: 3.0,
                rgb: [65535, 0, 0],
            });
            Scene::new(reader, h.clone(), root, 2, usize::MAX, usize::MAX)
        };
        let mut made = scene();
        made.converge(&cam, &options, None);
        let (image, stats) = made.frame(&gpu, &raster, &cam, &options, &style);
        assert_eq!(stats.points, 64 + 4 * 1024);
        assert_eq!((made.uploads_prepared, made.uploads_encoded), (5, 0));
        let mut at_upload = scene();
        at_upload.loader.set_prepare(None);
        at_upload.converge(&cam, &options, None);
        let (same, _) = at_upload.frame(&gpu, &raster, &cam, &options, &style);
        assert_eq!(
            (at_upload.uploads_prepared, at_upload.uploads_encoded),
            (0, 5)
        );
        assert!(image == same, "the same image either way");
        // Elevation: the resident nodes' words were made for their colours.
        made.set_colour(ColorBy::Elevation);
        let (ramp, _) = made.frame(&gpu, &raster, &cam, &options, &style);
        assert_eq!((made.uploads_prepared, made.uploads_encoded), (5, 5));
        assert!(ramp != image);
        let mut later = scene();
        later.set_colour(ColorBy::Elevation);
        later.converge(&cam, &options, None);
        let (read_after, _) = later.frame(&gpu, &raster, &cam, &options, &style);
        assert_eq!((later.uploads_prepared, later.uploads_encoded), (5, 0));
        assert!(read_after == ramp);
    }
}

/// A sparse node among fine ones, and a lone point: the root a grid of spacing 8 over the
/// square; child 0 (of the bottom layer) two points 16 apart with a spacing of 32 of its own (a
/// few points, separated at a coarse level of their node), just above the plane; child 2 a grid
/// of spacing 4 and a lone point 20 above it; children 1 and 3 fine grids (spacing 1).
struct Sparse;

const SPARSE: NodeKey = NodeKey {
    level: 1,
    cell: [0, 0, 0],
};

fn sparse_points(key: &NodeKey) -> (Vec<[f64; 3]>, [u16; 3]) {
    if *key == SPARSE {
        (vec![[8.0, 8.0, 0.5], [24.0, 24.0, 0.5]], [65_535, 0, 0])
    } else if *key == LONELY {
        let mut p: Vec<[f64; 3]> = (0..64)
            .map(|i| {
                [
                    (i % 8) as f64 * 4.0 + 2.0,
                    32.0 + (i / 8) as f64 * 4.0 + 2.0,
                    0.0,
                ]
            })
            .collect();
        p.push([16.0, 48.0, 20.0]);
        (p, [0, 0, 65_535])
    } else if key.level == 0 {
        (node_points(key), [65_535; 3])
    } else {
        (node_points(key), [0, 0, 65_535])
    }
}

const LONELY: NodeKey = NodeKey {
    level: 1,
    cell: [0, 1, 0],
};

fn sparse_entry(key: NodeKey) -> NodeEntry {
    let n = sparse_points(&key).0.len() as u32;
    let spacing = match key {
        SPARSE => 32.0,
        LONELY => 4.0,
        _ => entry(key).spacing[0],
    };
    NodeEntry {
        points: n,
        prefix: vec![n],
        spacing: vec![spacing],
        ..entry(key)
    }
}

impl PageReader for Sparse {
    fn read(&self, node: &NodeEntry) -> Result<PointBatch, String> {
        let (points, rgb) = sparse_points(&node.key);
        let schema = Schema::new(vec![Attribute::Rgb]);
        let mut b = PointBatch::with_schema(&schema, points.len());
        for (i, p) in points.into_iter().enumerate() {
            b.positions.push(p);
            // The lone point green.
            let last = node.key == LONELY && i as u32 == node.points - 1;
            b.rgb
                .as_mut()
                .unwrap()
                .push(if last { [0, 65_535, 0] } else { rgb });
        }
        Ok(b)
    }
}

#[test]
fn a_sparse_nodes_points_and_a_lone_point_are_drawn_no_wider_than_their_bounds() {
    // Adaptive sizes: a point takes the spacing of the finest drawn node around it, at most its
    // drawn ancestors' (the sparse node's two points and the root's in its quarter: the root's
    // 8, not the sparse node's 32); a point of a leaf with no other of its node within two of
    // the spacings its finest level is drawn at, at most LONE_PIXELS wide. On every path.
    let root = Aabb::new([0.0; 3], [64.0; 3]);
    for (gpu, raster) in common::paths() {
        let keys = std::iter::once(NodeKey::ROOT).chain((0..4).map(|o| NodeKey::ROOT.child(o)));
        let h = Hierarchy::new(root, keys.map(sparse_entry));
        let mut scene = Scene::new(Arc::new(Sparse), h, root, 1, usize::MAX, usize::MAX);
        scene.set_colour(ColorBy::Rgb);
        let cam = above();
        let options = SelectOptions {
            budget: 1_000_000,
            min_pixels: 0.5,
        };
        let scale = 1.0;
        let style = Style {
            size: PointSize::Adaptive { scale, max: 64.0 },
            ..Style::default()
        };
        scene.converge(&cam, &options, None);
        let (img, stats) = scene.frame(&gpu, &raster, &cam, &options, &style);
        assert_eq!(stats.points, 64 + 2 + 65 + 2 * 1024, "{:?}", raster.path);
        let count = |c: [u8; 3]| img.chunks(4).filter(|p| p[..3] == c).count();
        // The root's spacing at the plane: 8 x focal / 80 (and 79.5 for the sparse points).
        let focal = cam.focal();
        let root_px = (8.0 * scale as f64 * focal / 79.5).round();
        let sparse_px = (32.0 * scale as f64 * focal / 79.5).round();
        assert!(sparse_px > 3.0 * root_px, "{sparse_px} {root_px}");
        let red = count([255, 0, 0]) as f64;
        assert!(
            red > 0.0 && red <= 2.0 * root_px * root_px,
            "{:?}: the sparse node's points cover {red} pixels: two squares of {root_px} at \
             most (its own spacing would make them {sparse_px})",
            raster.path
        );
        let green = count([0, 255, 0]);
        assert!(
            (1..=9).contains(&green),
            "{:?}: the lone point covers {green} pixels (at most 3 x 3; its node's spacing \
             would make it {} wide)",
            raster.path,
            (4.0 * focal / 60.0).round()
        );
        // The fine grids are drawn as before: their quarters covered (child 2's shares its
        // quarter with the root's points, at the same depth).
        assert!(count([0, 0, 255]) > 2 * 55 * 55, "{}", count([0, 0, 255]));
    }
}
