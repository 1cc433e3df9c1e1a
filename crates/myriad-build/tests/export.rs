//! `export` end to end: COPC and Potree hold exactly the records `extract` gives (every field),
//! with boxes and spacings, for every structure; every point lies in its node's cube; the
//! hierarchies reach every node as their readers walk them; damaged nodes are left out and named.

mod common;
use common::{read_all, records, synth, tempdir};

use myriad_build::convert::{ConvertOptions, Silent, Structure, convert};
use myriad_build::export::{ExportOptions, ExportSummary, Target, export};
use myriad_build::extract::{ExtractOptions, extract};
use myriad_core::{Aabb, Attribute, NodeKey, PointBatch, Schema};
use myriad_format::Dataset;
use myriad_io::OpenOptions;
use std::path::Path;

/// The columns of `schema` only (a COPC file is LAS 1.4 format 6-8: it reads back with a
/// scanner channel a legacy input did not have), without wave packets (COPC cannot hold them).
/// A legacy scan angle rank (whole degrees) is stored in 0.006-degree steps: it reads back within
/// 0.003 degrees, the same whole degree once rounded.
fn project(mut b: PointBatch, schema: &Schema) -> PointBatch {
    if !schema.has(&Attribute::ScannerChannel) {
        b.scanner_channel = None;
        whole_degrees(&mut b);
    }
    if !schema.has(&Attribute::GpsTime) {
        b.gps_time = None;
    }
    b.wave_packet = None;
    b
}

fn whole_degrees(b: &mut PointBatch) {
    for a in b.scan_angle.iter_mut().flatten() {
        *a = a.round();
    }
}

fn build(input: &Path, out: &Path, structure: Structure, capacity: usize) -> Dataset {
    let mut o = ConvertOptions::new(out);
    o.structure = structure;
    o.params.capacity = capacity;
    o.force = true;
    convert(&[input.to_path_buf()], &o, &Silent).unwrap();
    Dataset::open(out).unwrap()
}

fn export_to(
    ds: &Dataset,
    out: &Path,
    target: Target,
    bbox: Option<Aabb>,
    spacing: Option<f64>,
) -> ExportSummary {
    export_with(ds, out, target, bbox, spacing, None)
}

/// [`export_to`], COPC's leaves joining their parents' chunks up to `join` points (`Some(0)`:
/// node for node).
fn export_with(
    ds: &Dataset,
    out: &Path,
    target: Target,
    bbox: Option<Aabb>,
    spacing: Option<f64>,
    join: Option<u64>,
) -> ExportSummary {
    let mut o = ExportOptions::new(target);
    o.copc_node_points = join;
    o.bbox = bbox;
    o.spacing = spacing;
    o.force = true;
    o.copc_page_levels = 2;
    o.memory = 512 << 20;
    export(ds, out, &o, &Silent).unwrap()
}

fn extracted(ds: &Dataset, dir: &Path, bbox: Option<Aabb>, spacing: Option<f64>) -> PointBatch {
    let las = dir.join("extract.las");
    extract(
        ds,
        &las,
        &ExtractOptions {
            bbox,
            spacing,
            force: true,
            ..Default::default()
        },
    )
    .unwrap();
    read_all(&las)
}

/// The COPC file's nodes as a reader walks its pages, each with its points (chunks lie in file
/// order, so the k-th chunk is the next run of points read from the file).
fn copc_nodes(path: &Path) -> Vec<(NodeKey, PointBatch)> {
    let bytes = std::fs::read(path).unwrap();
    let mut entries = myriad_io::copc::read_hierarchy(&bytes).unwrap();
    let all = read_all(path);
    entries.retain(|e| e.3 > 0);
    entries.sort_by_key(|e| e.1);
    let mut at = 0;
    let mut out = Vec::new();
    for (key, _, _, count) in entries {
        out.push((key, all.slice(at..at + count as usize)));
        at += count as usize;
    }
    assert_eq!(
        at,
        all.len(),
        "the hierarchy's counts add up to the file's points"
    );
    out
}

fn assert_in_cubes(nodes: &[(NodeKey, PointBatch)], root: &Aabb, slack: f64) {
    for (key, b) in nodes {
        let c = key.bounds(root);
        for p in &b.positions {
            assert!(
                (0..3).all(|a| p[a] >= c.min[a] - slack && p[a] <= c.max[a] + slack),
                "{p:?} outside node {key:?} {c:?}"
            );
        }
    }
}

/// A node's name and its points' positions.
type Named = (String, Vec<[f64; 3]>);

/// Potree's nodes from its folder: name, points, positions decoded from octree.bin.
fn potree_nodes(dir: &Path) -> (serde_json::Value, Vec<Named>) {
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("metadata.json")).unwrap()).unwrap();
    let hierarchy = std::fs::read(dir.join("hierarchy.bin")).unwrap();
    let octree = std::fs::read(dir.join("octree.bin")).unwrap();
    let first = meta["hierarchy"]["firstChunkSize"].as_u64().unwrap();
    let nodes = myriad_io::potree::read_hierarchy(&hierarchy, first).unwrap();
    let record: u64 = meta["attributes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["size"].as_u64().unwrap())
        .sum();
    let f = |v: &serde_json::Value, i: usize| v[i].as_f64().unwrap();
    let mut out = Vec::new();
    for (name, _, points, offset, size) in nodes {
        assert_eq!(size, points as u64 * record, "{name}: byte size");
        let mut pos = Vec::new();
        for i in 0..points as u64 {
            let r = (offset + i * record) as usize;
            let c =
                |k: usize| i32::from_le_bytes(octree[r + 4 * k..r + 4 * k + 4].try_into().unwrap());
            pos.push(std::array::from_fn(|k| {
                c(k) as f64 * f(&meta["scale"], k) + f(&meta["offset"], k)
            }));
        }
        out.push((name, pos));
    }
    (meta, out)
}

/// A Potree node name (r, then child digits 4x + 2y + z) as a key.
fn potree_key(name: &str) -> NodeKey {
    let mut k = NodeKey::ROOT;
    for d in name[1..].bytes().map(|b| (b - b'0') as usize) {
        k = k.child((d >> 2 & 1) | (d >> 1 & 1) << 1 | (d & 1) << 2);
    }
    k
}

fn sorted_positions(p: &[[f64; 3]], scale: [f64; 3]) -> Vec<[i64; 3]> {
    let mut v: Vec<[i64; 3]> = p
        .iter()
        .map(|x| std::array::from_fn(|a| (x[a] / scale[a]).round() as i64))
        .collect();
    v.sort_unstable();
    v
}

#[test]
fn copc_and_potree_hold_what_extract_gives() {
    let d = tempdir("export-octree");
    let las = synth(&d, 150_000, 7);
    let ds = build(&las, &d.join("c.myr"), Structure::Octree, 250);
    let root = ds.meta.root;
    let q = ds.meta.quantization;
    let b = ds.meta.bounds;
    let mid: [f64; 3] = std::array::from_fn(|a| (b.min[a] + b.max[a]) / 2.0);
    let quarter = Aabb::new(
        std::array::from_fn(|a| b.min[a] + (b.max[a] - b.min[a]) * 0.2),
        [mid[0], mid[1], b.max[2]],
    );
    let coarse = ds.nodes().0[0].spacing.last().unwrap() / 4.0;
    for (bbox, spacing) in [
        (None, None),
        (Some(quarter), None),
        (None, Some(coarse)),
        (Some(quarter), Some(coarse)),
    ] {
        let mut want = extracted(&ds, &d, bbox, spacing);
        whole_degrees(&mut want);
        assert!(
            want.len() > 100,
            "{bbox:?} {spacing:?}: {} points",
            want.len()
        );

        let copc = d.join("c.copc.laz");
        let s = export_to(&ds, &copc, Target::Copc, bbox, spacing);
        assert!(s.damage.is_empty() && !s.replaced);
        assert_eq!(s.points as usize, want.len());
        let got = project(read_all(&copc), &ds.meta.schema);
        assert_eq!(got.schema(), want.schema());
        assert!(
            records(&got) == records(&want),
            "{bbox:?} {spacing:?}: COPC records differ from extract's"
        );
        let nodes = copc_nodes(&copc);
        // A box or a coarse spacing leaves few points: their nodes may all join one chunk.
        let least = if bbox.is_none() && spacing.is_none() {
            100
        } else {
            1
        };
        assert!(
            nodes.len() >= least,
            "{bbox:?} {spacing:?}: {} of {} nodes",
            nodes.len(),
            ds.meta.nodes
        );
        assert_in_cubes(&nodes, &root, q.scale[0]);
        let info = myriad_io::open(&copc, &OpenOptions::default()).unwrap();
        assert!(
            info.info().version.contains("COPC"),
            "{}",
            info.info().version
        );

        let pot = d.join("potree");
        let s = export_to(&ds, &pot, Target::Potree, bbox, spacing);
        assert_eq!(s.points as usize, want.len());
        let (meta, nodes) = potree_nodes(&pot);
        assert_eq!(meta["points"].as_u64().unwrap() as usize, want.len());
        let side = root.size()[0];
        let bb = &meta["boundingBox"];
        for a in 0..3 {
            assert_eq!(bb["min"][a].as_f64().unwrap(), root.min[a]);
            assert!((bb["max"][a].as_f64().unwrap() - root.min[a] - side).abs() < 1e-9);
        }
        let mut all = Vec::new();
        for (name, pos) in &nodes {
            let key = potree_key(name);
            assert_in_cubes(
                &[(
                    key,
                    PointBatch {
                        positions: pos.clone(),
                        ..Default::default()
                    },
                )],
                &root,
                q.scale[0],
            );
            all.extend_from_slice(pos);
        }
        assert_eq!(
            sorted_positions(&all, q.scale),
            sorted_positions(&want.positions, q.scale)
        );
    }
    // Deep enough that the Potree hierarchy has proxies (chunks of 4 levels).
    assert!(ds.meta.depth > 4, "depth {}", ds.meta.depth);
}

#[test]
fn kd_and_mwkd_export_their_original_points() {
    let d = tempdir("export-kd");
    let las = synth(&d, 60_000, 7);
    for structure in [Structure::Kd, Structure::Mwkd, Structure::Layered] {
        let ds = build(&las, &d.join("k.myr"), structure, 2000);
        let mut want = extracted(&ds, &d, None, None);
        whole_degrees(&mut want);
        assert_eq!(want.len(), 60_000);
        let copc = d.join("k.copc.laz");
        // Node for node: the re-placing build's tree as it is.
        let s = export_with(&ds, &copc, Target::Copc, None, None, Some(0));
        assert_eq!(s.replaced, structure != Structure::Layered, "{structure:?}");
        let got = project(read_all(&copc), &want.schema());
        assert!(
            records(&got) == records(&want),
            "{structure:?}: COPC records differ"
        );
        let root = myriad_io::copc::read_hierarchy(&std::fs::read(&copc).unwrap()).unwrap();
        assert!(root.len() > 5);
        // Nothing of the re-placing build is left behind.
        let left: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with('.'))
            .map(|e| e.file_name())
            .collect();
        assert!(left.is_empty(), "{left:?}");
    }
}

#[test]
fn a_damaged_node_is_left_out_and_named() {
    let d = tempdir("export-damage");
    let las = synth(&d, 60_000, 7);
    let out = d.join("d.myr");
    let ds = build(&las, &out, Structure::Octree, 2000);
    let (nodes, _) = ds.nodes();
    let victim = nodes
        .iter()
        .filter(|n| n.points > 100)
        .nth(2)
        .unwrap()
        .clone();
    drop(ds);
    let mut bytes = std::fs::read(&out).unwrap();
    bytes[(victim.page.offset + victim.page.length as u64 / 2) as usize] ^= 0x10;
    std::fs::write(&out, &bytes).unwrap();
    let ds = Dataset::open(&out).unwrap();
    for (target, name) in [(Target::Copc, "d.copc.laz"), (Target::Potree, "pot")] {
        let s = export_with(&ds, &d.join(name), target, None, None, Some(0));
        assert_eq!(s.damage.len(), 1);
        assert_eq!(s.damage[0].key, victim.key);
        assert_eq!(s.points, 60_000 - victim.points as u64);
    }
    // Leaves joining their parents' chunks: the victim's points alone are left out, wherever
    // it (or the leaves that joined it) went.
    let s = export_with(
        &ds,
        &d.join("j.copc.laz"),
        Target::Copc,
        None,
        None,
        Some(1 << 30),
    );
    assert!(s.nodes < nodes.len() as u64, "{} nodes", s.nodes);
    assert_eq!(s.damage.len(), 1);
    assert_eq!(s.damage[0].key, victim.key);
    assert_eq!(s.points, 60_000 - victim.points as u64);
    assert_eq!(
        copc_nodes(&d.join("j.copc.laz"))
            .iter()
            .map(|(_, b)| b.len())
            .sum::<usize>() as u64,
        s.points
    );
    // The hierarchy still reaches the victim's children.
    let copc = copc_nodes(&d.join("d.copc.laz"));
    let children = nodes
        .iter()
        .filter(|n| n.key.level > victim.key.level && n.key.parent() == victim.key)
        .count();
    let reached = copc
        .iter()
        .filter(|(k, _)| k.level > victim.key.level && k.parent() == victim.key)
        .count();
    assert_eq!(reached, children);
}

#[test]
fn outputs_are_atomic_and_never_clobber_a_folder() {
    let d = tempdir("export-atomic");
    let las = synth(&d, 20_000, 7);
    let ds = build(&las, &d.join("a.myr"), Structure::Octree, 2000);
    let pot = d.join("pot");
    std::fs::create_dir_all(&pot).unwrap();
    std::fs::write(pot.join("notes.txt"), "mine").unwrap();
    let mut o = ExportOptions::new(Target::Potree);
    o.force = true;
    let e = export(&ds, &pot, &o, &Silent).unwrap_err().to_string();
    assert!(e.contains("not a Potree folder"), "{e}");
    assert_eq!(
        std::fs::read_to_string(pot.join("notes.txt")).unwrap(),
        "mine"
    );
    o.force = false;
    let copc = d.join("x.copc.laz");
    std::fs::write(&copc, "keep").unwrap();
    let mut c = ExportOptions::new(Target::Copc);
    c.force = false;
    assert!(
        export(&ds, &copc, &c, &Silent)
            .unwrap_err()
            .to_string()
            .contains("--force")
    );
    assert_eq!(std::fs::read_to_string(&copc).unwrap(), "keep");
    // A Potree folder is replaced whole with --force.
    let pot2 = d.join("pot2");
    o.force = true;
    export(&ds, &pot2, &o, &Silent).unwrap();
    export(&ds, &pot2, &o, &Silent).unwrap();
    let names: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert!(
        !names
            .iter()
            .any(|n| n.to_string_lossy().contains("partial")),
        "{names:?}"
    );
}
