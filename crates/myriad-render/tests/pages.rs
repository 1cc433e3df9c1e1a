//! Hierarchy pages loaded on demand (issue 22): a scene starts from the root page alone, asks
//! for the pages below the nodes it refines through the loader threads, never waits for them,
//! refines when they land, and keeps them within a byte budget; what it selects once they are
//! in is what the whole hierarchy selects.

use myriad_core::{Aabb, Attribute, NodeKey, PointBatch, Schema};
use myriad_format::hierarchy::PAGE_LEVELS;
use myriad_format::{
    ChildPage, Dataset, DatasetWriter, HierarchyPage, Metadata, NodeEntry, NodeShape, PageRef,
    Quantization,
};
use myriad_lod::{Camera, Hierarchy, Occlusion, PageReader, SelectOptions, select_where};
use myriad_render::{ColorBy, Gpu, PointSize, Rasterizer, Scene, Style};
use std::collections::HashMap;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// An 8 x 8 grid over the bottom face of a node's cube (z = 0) in a root cube of side 32.
fn grid(key: &NodeKey) -> Vec<[f64; 3]> {
    let side = 32.0 / (1u64 << key.level) as f64;
    let step = side / 8.0;
    (0..64)
        .map(|i| {
            [
                key.cell[0] as f64 * side + ((i % 8) as f64 + 0.5) * step,
                key.cell[1] as f64 * side + ((i / 8) as f64 + 0.5) * step,
                0.0,
            ]
        })
        .collect()
}

fn entry(key: NodeKey) -> NodeEntry {
    NodeEntry::new(
        key,
        PageRef {
            offset: 64,
            length: 100,
            crc: 0,
        },
        64,
        vec![64],
        vec![32.0 / (1u64 << key.level) as f64 / 8.0],
    )
}

/// Nodes answer at once; hierarchy pages one per permit.
struct PagesGated {
    pages: HashMap<NodeKey, HierarchyPage>,
    permits: Mutex<Receiver<()>>,
}

impl PageReader for PagesGated {
    fn read(&self, node: &NodeEntry) -> Result<PointBatch, String> {
        let schema = Schema::new(vec![Attribute::Rgb]);
        let points = grid(&node.key);
        let mut b = PointBatch::with_schema(&schema, points.len());
        for p in points {
            b.positions.push(p);
            b.rgb.as_mut().unwrap().push([255, 255, 255]);
        }
        Ok(b)
    }
    fn read_hierarchy(&self, page: &ChildPage) -> Result<HierarchyPage, String> {
        self.permits
            .lock()
            .unwrap()
            .recv()
            .map_err(|_| "closed".to_string())?;
        Ok(self.pages[&page.key].clone())
    }
}

/// A chain of nodes at the corner of the root cube, levels 0 to 4 on the root page, and two
/// level-5 nodes, each the root of a page of its own, below the last.
#[test]
fn frames_keep_coming_while_a_hierarchy_page_is_out_and_the_view_refines_when_it_lands() {
    let chain = |l: u32| NodeKey {
        level: l,
        cell: [0; 3],
    };
    let below = [chain(PAGE_LEVELS), chain(PAGE_LEVELS - 1).child(1)];
    let reference = |key: NodeKey| ChildPage {
        key,
        page: PageRef {
            offset: 1000 + key.cell[0] as u64,
            length: 10,
            crc: 0,
        },
    };
    let root_page = HierarchyPage {
        nodes: (0..PAGE_LEVELS).map(|l| entry(chain(l))).collect(),
        children: below.iter().map(|&k| reference(k)).collect(),
    };
    let pages = below
        .iter()
        .map(|&k| {
            (
                k,
                HierarchyPage {
                    nodes: vec![entry(k)],
                    children: vec![],
                },
            )
        })
        .collect();
    let (permit, permits): (Sender<()>, _) = channel();
    let reader = Arc::new(PagesGated {
        pages,
        permits: Mutex::new(permits),
    });
    let root = Aabb::new([0.0; 3], [32.0; 3]);
    let h = Hierarchy::from_root_page(root, root_page, PAGE_LEVELS);
    assert_eq!((h.len(), h.pages()), (5, 1));
    // Three loader threads: the two pages hold two of them.
    let mut scene = Scene::new(reader, h, root, 3, usize::MAX, usize::MAX);
    let permit = permit;
    scene.set_colour(ColorBy::Rgb);
    let gpu = Gpu::cpu();
    let raster = Rasterizer::new(&gpu);
    // Close above the two level-5 nodes ([0, 2] x [0, 1]).
    let cam = Camera {
        position: [1.0, 0.5, 3.0],
        target: [1.0, 0.5, 0.0],
        up: [0.0, 1.0, 0.0],
        fov_y: 60.0,
        width: 160,
        height: 160,
        near: 0.1,
        far: 100.0,
    };
    let options = SelectOptions {
        budget: 1_000_000,
        min_pixels: 0.0,
    };
    let style = Style {
        size: PointSize::Fixed(1.0),
        ..Style::default()
    };
    let lit = |img: &[u8]| img.chunks_exact(4).filter(|p| p[0] == 255).count();
    let mut frame = || {
        let t = Instant::now();
        let (img, stats) = scene.frame(&gpu, &raster, &cam, &options, &style);
        (lit(&img), stats, t.elapsed())
    };
    // Until a frame draws the chain: its nodes are read at once.
    let t = Instant::now();
    let mut now = frame();
    while now.1.points < 5 * 64 && t.elapsed() < Duration::from_secs(30) {
        now = frame();
    }
    // Both pages are out: frames keep coming with the chain alone.
    for _ in 0..5 {
        let (pixels, stats, took) = frame();
        assert_eq!(stats.points, 5 * 64);
        assert_eq!(stats.pages_wanted, 2);
        assert_eq!(stats.hierarchy_pages, 1);
        assert!(!stats.complete && stats.in_flight > 0);
        assert!(took < Duration::from_secs(5), "a frame took {took:?}");
        assert_eq!(pixels, now.0);
    }
    // One page lands, then the other: the view refines each time, then is complete.
    let mut last = now.0;
    for landed in 1..=2u64 {
        permit.send(()).unwrap();
        let t = Instant::now();
        let want = (5 + landed) * 64;
        let mut now = frame();
        while now.1.points < want && t.elapsed() < Duration::from_secs(30) {
            now = frame();
        }
        assert_eq!(now.1.points, want, "after {landed} pages landed");
        assert_eq!(now.1.hierarchy_pages, 1 + landed as usize);
        assert!(now.0 > last, "the image refines: {last} -> {}", now.0);
        last = now.0;
    }
    let (_, stats, _) = frame();
    assert!(stats.complete && stats.in_flight == 0 && stats.pages_wanted == 0);
}

/// A quadtree over the bottom of the root cube, `depth` levels deep: every level-5 node is the
/// root of a page of its own.
fn write_quadtree(path: &std::path::Path, depth: u32) -> Vec<NodeKey> {
    let quant = Quantization {
        scale: [0.001; 3],
        offset: [0.0; 3],
    };
    let w = DatasetWriter::create(path, true, quant).unwrap();
    let schema = Schema::new(vec![]);
    let mut keys = Vec::new();
    let mut level = vec![NodeKey::ROOT];
    for _ in 0..=depth {
        let mut next = Vec::new();
        for &k in &level {
            let mut b = PointBatch::with_schema(&schema, 64);
            b.positions = grid(&k);
            let e = entry(k);
            w.write_node(k, &b, &[64], &e.spacing, NodeShape::default())
                .unwrap();
            keys.push(k);
            next.extend((0..4).map(|o| k.child(o)));
        }
        level = next;
    }
    let root = Aabb::new([0.0; 3], [32.0; 3]);
    w.finish(Metadata {
        structure: "nested-octree".into(),
        parameters: serde_json::json!({}),
        points: 0,
        nodes: 0,
        depth: 0,
        bounds: Aabb::new([0.0; 3], [32.0, 32.0, 0.0]),
        root,
        quantization: quant,
        crs: None,
        schema,
        sources: vec![],
        las_header: None,
        software: "test".into(),
        levels: vec![],
        files: vec![],
    })
    .unwrap();
    keys
}

/// A hierarchy of 1,025 pages walked with room for a few dozen: the pages unused longest go,
/// the memory stays within the budget (beyond it only by what one frame uses), and every view
/// selects exactly what the whole hierarchy selects once its pages are in.
#[test]
fn a_hierarchy_larger_than_its_budget_is_walked_within_it() {
    let dir = std::env::temp_dir().join(format!("myriad-pages-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("quadtree.myr");
    let keys = write_quadtree(&path, 6);
    let ds = Arc::new(Dataset::open(&path).unwrap());
    assert_eq!(ds.meta.levels.len(), 7);
    assert_eq!(ds.meta.levels[6].nodes, 4096);
    let (all, damage) = ds.nodes();
    assert!(damage.is_empty());
    assert_eq!(all.len(), keys.len());
    let whole = Hierarchy::new(ds.meta.root, all);
    let mut scene = Scene::open(ds.clone(), usize::MAX, usize::MAX);
    scene.occlusion = Occlusion::Off;
    assert_eq!(scene.hierarchy.pages(), 1);
    assert_eq!(scene.hierarchy.len(), 341);
    // Room for the root page and about 40 pages of five nodes.
    let page = {
        let mut h = scene.hierarchy.as_ref().clone();
        let before = h.bytes();
        let c = h.unloaded()[0];
        h.insert_page(c.key, ds.hierarchy_page(&c).unwrap());
        h.bytes() - before
    };
    let budget = scene.hierarchy.bytes() + 40 * page;
    scene.pages.budget = budget;
    // Low over the plane, along a diagonal: each view wants a few dozen pages; every other
    // view with a point budget that stops the traversal (pages below where it stops are not
    // needed, and not asked for).
    let mut most = 0;
    let mut read = 0;
    for step in 0..12 {
        let options = SelectOptions {
            budget: if step % 2 == 0 { 1_000_000 } else { 1_000 },
            min_pixels: 1.0,
        };
        let x = 1.0 + step as f64 * 2.7;
        let cam = Camera {
            position: [x, x, 1.5],
            target: [x + 1.0, x + 1.0, 0.0],
            up: [0.0, 0.0, 1.0],
            fov_y: 60.0,
            width: 320,
            height: 240,
            near: 0.05,
            far: 100.0,
        };
        let got = scene.converge(&cam, &options, None);
        let want = select_where(&whole, &cam, &options, &|_| true);
        let nodes = |s: &myriad_lod::Selection| {
            s.nodes
                .iter()
                .map(|n| (n.key, n.points))
                .collect::<Vec<_>>()
        };
        assert_eq!(nodes(&got), nodes(&want), "view {step}");
        assert_eq!(got.budget_reached, step % 2 == 1, "view {step}");
        assert!(got.pages.iter().all(|p| scene.hierarchy.has_page(&p.key)));
        let used = got.used_pages.len();
        assert!(
            scene.hierarchy.bytes() <= budget + used * page,
            "view {step}: {} bytes of hierarchy, budget {budget}, {used} pages in use",
            scene.hierarchy.bytes()
        );
        most = most.max(scene.hierarchy.pages());
        read = scene.loader.pages_read;
    }
    eprintln!(
        "most {most} pages held, {read} read, {} dropped",
        scene.pages.evicted
    );
    assert!(scene.pages.evicted > 0, "nothing was dropped");
    assert!(most < 1025, "{most} pages held at once");
    assert!(read > most, "{read} pages read");
    std::fs::remove_dir_all(&dir).unwrap();
}
