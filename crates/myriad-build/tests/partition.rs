//! A plan's parts, built one by one and merged, make the dataset a one-machine build of the
//! plan makes: the same nodes, page for page.

mod common;

use common::{synth, tempdir};
use myriad_build::convert::{self, Silent, Structure};
use myriad_build::nested::NestedParams;
use myriad_build::partition::{self, BuildPlan, PlanOptions};
use myriad_format::Dataset;
use std::path::Path;

fn options(parts: usize, structure: Structure) -> PlanOptions {
    PlanOptions {
        parts,
        structure,
        params: NestedParams {
            capacity: 3000,
            inner_depth: convert::DEFAULT_INNER_DEPTH,
            max_level: convert::DEFAULT_MAX_LEVEL,
            ntree: false,
        },
        memory: 1 << 30,
        threads: 2,
        precision: 1e-4,
        open: Default::default(),
        chunk_points: Some(15_000),
        chunks: true,
        chunk_cache: None,
    }
}

/// Every node of `path`: key, counts, levels, outline, and its page's bytes.
fn pages(path: &Path) -> Vec<(String, Vec<u8>)> {
    let ds = Dataset::open(path).unwrap();
    let (mut nodes, damage) = ds.nodes();
    assert!(damage.is_empty(), "{damage:?}");
    nodes.sort_by_key(|e| e.key);
    nodes
        .iter()
        .map(|e| {
            let what = format!(
                "{:?} {} {:?} {:?} {:?} {:?}",
                e.key, e.points, e.prefix, e.spacing, e.bounds, e.contour
            );
            (what, ds.node_page(e).unwrap())
        })
        .collect()
}

fn build_all(plan: &BuildPlan, parts: &Path, exchanged: bool) -> Vec<partition::PartSummary> {
    let mut out = Vec::new();
    for i in 0..plan.parts.len() {
        let s = partition::build_part(plan, i, parts, 2, exchanged, &Silent).unwrap();
        if s.points > 0 {
            let ds = Dataset::open(&partition::part_paths(parts, i).0).unwrap();
            let r = myriad_build::extract::verify(&ds, |_| {});
            assert!(r.damage.is_empty(), "part {i}: {:?}", r.damage);
            assert_eq!(ds.meta.points, s.points);
        }
        out.push(s);
    }
    out
}

/// The points of `las` as LAZ (50,000-point chunks) in the order of their cells of level 3 (x
/// most significant, as the plans order cells):
/// a tile's points sorted as a spatial index would leave them, so that chunks are compact.
fn sorted_laz(las: &Path) -> std::path::PathBuf {
    let src = myriad_io::las::LasSource::open(las).unwrap();
    let opts = myriad_io::las::LasWriteOptions::like(src.header());
    let all = common::read_all(las);
    let b = all
        .positions
        .iter()
        .fold(myriad_core::Aabb::EMPTY, |mut b, &p| {
            b.extend(p);
            b
        });
    let cell = |p: [f64; 3]| -> [u32; 3] {
        std::array::from_fn(|a| {
            let f = (p[a] - b.min[a]) / (b.max[a] - b.min[a]).max(1e-9);
            (f * 8.0).clamp(0.0, 7.0) as u32
        })
    };
    let mut order: Vec<u32> = (0..all.len() as u32).collect();
    order.sort_by_key(|&i| {
        let c = cell(all.positions[i as usize]);
        myriad_core::geometry::morton(c[2], c[1], c[0])
    });
    let laz = las.with_extension("laz");
    let mut sink = myriad_io::las::LasSink::create(&laz, opts, true).unwrap();
    sink.write(&all.gather(&order)).unwrap();
    sink.finish().unwrap();
    laz
}

fn same_as_one_machine(structure: Structure, name: &str, laz: bool) {
    let d = tempdir(name);
    let mut las = synth(&d, 250_000, 5);
    if laz {
        las = sorted_laz(&las);
    }
    let plan = partition::plan(std::slice::from_ref(&las), &options(4, structure)).unwrap();
    assert!(plan.partition_level >= 1 && plan.partition_level <= plan.chunk_level);
    assert_eq!(plan.parts.len(), 4);
    assert!(
        plan.parts
            .iter()
            .all(|(cells, n)| !cells.is_empty() && *n > 0)
    );
    // Through its file, as the parts on other machines read it.
    let plan_path = d.join("plan.json");
    std::fs::write(&plan_path, plan.to_json().to_string()).unwrap();
    let plan = BuildPlan::load(&plan_path).unwrap();

    let parts = d.join("parts");
    let summaries = build_all(&plan, &parts, false);
    let read: u64 = summaries
        .iter()
        .flat_map(|s| &s.inputs)
        .flatten()
        .map(|i| i.1)
        .sum();
    if laz {
        // Each part decompressed only its chunks: fewer points than a whole file each, and
        // exactly its chunks' points.
        assert_eq!(plan.chunked.len(), 1, "the LAZ input meets several parts");
        let c = &plan.chunked[0];
        assert_eq!(c.chunks, 5);
        let chunks = myriad_io::las::chunk_bounds(&las).unwrap().unwrap();
        for (i, s) in summaries.iter().enumerate() {
            let want: u64 = c.of(i).iter().map(|&k| chunks[k as usize].0.points).sum();
            assert_eq!(s.inputs[0].map_or(0, |x| x.1), want, "part {i}");
            assert!(want < 250_000, "part {i} reads {:?} of 5 chunks", c.of(i));
        }
        assert!(
            read < 3 * 250_000,
            "the parts read {read} points of 250,000 (whole: 1,000,000)"
        );
    } else {
        assert_eq!(read, 4 * 250_000, "a LAS input is read whole by every part");
    }
    let merged = d.join("merged.myr");
    let m = partition::merge(&plan, &parts, &merged, false, true, 2, &Silent).unwrap();
    assert_eq!(m.points, 250_000);
    assert!(m.copied > 0 && m.built > 0 && m.linked == 0, "{m:?}");
    // By default the parts' pages stay where they are: the same nodes and pages, read through
    // the links, in a file that holds only the levels above the parts.
    let linked = d.join("linked.myr");
    let l = partition::merge(&plan, &parts, &linked, false, false, 2, &Silent).unwrap();
    let with_points = summaries.iter().filter(|s| s.points > 0).count() as u64;
    assert_eq!(
        (l.points, l.copied, l.linked),
        (250_000, m.copied, with_points)
    );
    assert!(l.bytes < m.bytes, "{} of {} bytes", l.bytes, m.bytes);
    assert_eq!(pages(&linked), pages(&merged));
    // Every page below the partition level is in a part's file; the levels above in its own.
    let ds = Dataset::open(&linked).unwrap();
    let (nodes, _) = ds.nodes();
    for n in nodes.iter().filter(|n| n.page.length > 0) {
        let (file, _) = ds.locate(n.page);
        assert_eq!(
            file.is_some(),
            n.key.level > plan.partition_level,
            "{}",
            n.key
        );
    }
    let own: u64 = (nodes.iter())
        .filter(|n| ds.locate(n.page).0.is_none())
        .map(|n| n.page.length as u64)
        .sum();
    assert!(own < l.bytes);

    let one = d.join("one.myr");
    let s = convert::convert(
        std::slice::from_ref(&las),
        &plan.convert_options(None, &one, 2),
        &Silent,
    )
    .unwrap();
    assert_eq!(s.points, 250_000);
    let (a, b) = (pages(&merged), pages(&one));
    assert_eq!(a.len(), b.len(), "node counts");
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.0, y.0);
        assert!(x.1 == y.1, "{}: page bytes differ", x.0);
    }
    for path in [&merged, &linked] {
        let ds = Dataset::open(path).unwrap();
        assert_eq!(ds.meta.sources[0]["points"], 250_000);
        let r = myriad_build::extract::verify(&ds, |_| {});
        assert!(r.damage.is_empty());
        assert_eq!(r.points, 250_000);
    }
    if laz {
        same_with_the_exchange(&plan, &d, &las, &b);
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// The exchange: the scatter tasks decompress each chunk that some part reads once and sort
/// its records by part; the parts built from them read exactly their points and merge to the
/// one-machine build (`one`'s pages).
fn same_with_the_exchange(plan: &BuildPlan, d: &Path, las: &Path, one: &[(String, Vec<u8>)]) {
    let dir = d.join("exchanged");
    // A part before the scatter tasks have run is refused, naming the missing manifest.
    let e = partition::build_part(plan, 0, &dir, 2, true, &Silent).unwrap_err();
    assert!(
        e.to_string().contains("t0.json") && e.to_string().contains("--scatter 0"),
        "{e}"
    );
    let tasks = plan.scatter_tasks();
    assert_eq!(tasks.len(), plan.parts.len());
    let chunks = myriad_io::las::chunk_bounds(las).unwrap().unwrap();
    let c = &plan.chunked[0];
    let mut shared: Vec<u32> = (0..plan.parts.len()).flat_map(|i| c.of(i)).collect();
    shared.sort_unstable();
    shared.dedup();
    // The tasks take those chunks once each, in order.
    let taken: Vec<u32> = tasks
        .iter()
        .flatten()
        .flat_map(|(_, v)| v.clone())
        .collect();
    assert_eq!(taken, shared);
    let (mut read, mut routed) = (0, vec![0u64; plan.parts.len()]);
    for t in 0..tasks.len() {
        let s = partition::scatter(plan, t, &dir, &Silent).unwrap();
        assert_eq!(s.outside, 0);
        read += s.read;
        for (r, n) in routed.iter_mut().zip(&s.routed) {
            *r += n;
        }
    }
    let want: u64 = shared.iter().map(|&k| chunks[k as usize].0.points).sum();
    assert_eq!(read, want, "every chunk a part reads decompressed once");
    assert_eq!(routed.iter().sum::<u64>(), 250_000);
    let summaries = build_all(plan, &dir, true);
    for (i, s) in summaries.iter().enumerate() {
        // Each part read its own points and no other.
        assert_eq!(s.inputs[0].map_or(0, |x| x.1), s.points, "part {i}");
        assert_eq!(s.points, routed[i], "part {i}");
    }
    let merged = d.join("exchanged.myr");
    partition::merge(plan, &dir, &merged, false, true, 2, &Silent).unwrap();
    let a = pages(&merged);
    assert_eq!(a.len(), one.len(), "node counts");
    for (x, y) in a.iter().zip(one) {
        assert_eq!(x.0, y.0);
        assert!(x.1 == y.1, "{}: page bytes differ", x.0);
    }
    assert!(
        !partition::exchange_dir(&dir).exists(),
        "the merge removes the records"
    );
}

/// A merged dataset links its parts' files: they are found relative to it (the folders moved
/// together), and a part missing, built again or damaged is named in one line.
#[test]
fn a_linked_part_missing_or_changed_is_named() {
    let d = tempdir("partition-linked");
    let las = synth(&d, 80_000, 6);
    let plan = partition::plan(std::slice::from_ref(&las), &options(3, Structure::Octree)).unwrap();
    let parts = d.join("job").join("parts");
    build_all(&plan, &parts, false);
    let out = d.join("job").join("city.myr");
    let m = partition::merge(&plan, &parts, &out, false, false, 1, &Silent).unwrap();
    assert!(m.linked >= 2, "{m:?}");
    let ds = Dataset::open(&out).unwrap();
    assert_eq!(ds.files()[0].path, "parts/part-0.myr");
    ds.check_files().unwrap();
    drop(ds);

    // The dataset and its parts moved together: still whole.
    let moved = d.join("moved");
    std::fs::rename(d.join("job"), &moved).unwrap();
    let ds = Dataset::open(&moved.join("city.myr")).unwrap();
    assert!(myriad_build::extract::verify(&ds, |_| {}).damage.is_empty());
    drop(ds);

    // A byte of a part's page changed: the damage names the part's file and its byte.
    let part = moved.join("parts").join("part-1.myr");
    let original = std::fs::read(&part).unwrap();
    let mut bytes = original.clone();
    bytes[100] ^= 0xff;
    std::fs::write(&part, &bytes).unwrap();
    let ds = Dataset::open(&moved.join("city.myr")).unwrap();
    let r = myriad_build::extract::verify(&ds, |_| {});
    assert!(!r.damage.is_empty());
    let e = ds.damage_error(&r.damage[0]).to_string();
    assert!(e.contains("part-1.myr") && e.contains("checksum"), "{e}");

    // Built again (another file under its name): its header differs, named before any page.
    let mut other = original.clone();
    other[56] ^= 1; // the point count, so the header's CRC changes
    let crc = {
        let mut h = other[..64].to_vec();
        h[12..16].fill(0);
        crc32fast::hash(&h)
    };
    other[12..16].copy_from_slice(&crc.to_le_bytes());
    std::fs::write(&part, &other).unwrap();
    let ds = Dataset::open(&moved.join("city.myr")).unwrap();
    let e = ds.check_files().unwrap_err().to_string();
    assert!(e.contains("part-1.myr") && e.contains("merge again"), "{e}");
    assert_eq!(e.lines().count(), 1);

    // Missing: named, in one line, by the check and by a page read.
    std::fs::remove_file(&part).unwrap();
    let ds = Dataset::open(&moved.join("city.myr")).unwrap();
    let e = ds.check_files().unwrap_err().to_string();
    assert!(e.contains("part-1.myr") && e.contains("city.myr"), "{e}");
    let (nodes, _) = ds.nodes();
    let n = nodes
        .iter()
        .find(|n| ds.locate(n.page).0 == Some(1))
        .unwrap();
    let e = ds.damage_error(&ds.read_node(n).unwrap_err()).to_string();
    assert!(e.contains("part-1.myr"), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn octree_parts_merge_to_the_one_machine_build() {
    same_as_one_machine(Structure::Octree, "partition-octree", false);
}

#[test]
fn layered_parts_merge_to_the_one_machine_build() {
    same_as_one_machine(Structure::Layered, "partition-layered", false);
}

/// A LAZ input that several parts meet: each part decompresses only the chunks whose points
/// meet its cells, and the merge is still the one-machine build, page for page.
#[test]
fn parts_decompress_only_their_laz_chunks() {
    same_as_one_machine(Structure::Octree, "partition-chunks", true);
}

/// The chunks' bounds are kept beside the plan and used by the next plan while the input is
/// unchanged (same size and time); a changed input is passed over again.
#[test]
fn chunk_bounds_are_kept_for_the_next_plan() {
    let d = tempdir("partition-chunk-cache");
    let laz = sorted_laz(&synth(&d, 120_000, 7));
    let cache = d.join("plan.chunks.json");
    let mut o = options(3, Structure::Octree);
    o.chunk_cache = Some(cache.clone());
    let first = partition::plan(std::slice::from_ref(&laz), &o).unwrap();
    assert_eq!(first.chunked.len(), 1);
    let text = std::fs::read_to_string(&cache).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let key = laz.display().to_string();
    assert_eq!(v["inputs"][&key]["chunks"].as_array().unwrap().len(), 3);
    assert_eq!(
        partition::plan(std::slice::from_ref(&laz), &o)
            .unwrap()
            .chunked,
        first.chunked
    );
    // Bounds far from the scan, in the cache: the next plan believes them (every chunk in the
    // corner cell's part at most), which shows that it read the cache instead of the input.
    let mut v = v;
    for c in v["inputs"][&key]["chunks"].as_array_mut().unwrap() {
        for k in 1..7 {
            c[k] = serde_json::json!(-1e9);
        }
    }
    std::fs::write(&cache, v.to_string()).unwrap();
    let fooled = partition::plan(std::slice::from_ref(&laz), &o).unwrap();
    assert_ne!(fooled.chunked, first.chunked);
    assert!(
        fooled.chunked[0]
            .parts
            .iter()
            .filter(|p| !p.is_empty())
            .count()
            <= 1
    );
    // The input touched: passed over again.
    let f = std::fs::File::options().append(true).open(&laz).unwrap();
    f.set_modified(std::time::SystemTime::now() + std::time::Duration::from_secs(5))
        .unwrap();
    drop(f);
    assert_eq!(
        partition::plan(std::slice::from_ref(&laz), &o)
            .unwrap()
            .chunked,
        first.chunked
    );
    // A cache that is not JSON is made anew.
    std::fs::write(&cache, "not json").unwrap();
    assert_eq!(
        partition::plan(std::slice::from_ref(&laz), &o)
            .unwrap()
            .chunked,
        first.chunked
    );
    assert!(std::fs::read_to_string(&cache).unwrap().starts_with('{'));
}

/// A tile with no points (as cutting a scan into a grid leaves at its corners) has no bounds:
/// its plan still loads, and the parts and the merge skip it.
#[test]
fn an_empty_input_is_planned_and_merged() {
    let d = tempdir("partition-empty-input");
    let las = synth(&d, 30_000, 4);
    let src = myriad_io::las::LasSource::open(&las).unwrap();
    let empty = d.join("empty.las");
    let sink = myriad_io::las::LasSink::create(
        &empty,
        myriad_io::las::LasWriteOptions::like(src.header()),
        true,
    )
    .unwrap();
    assert_eq!(sink.finish().unwrap(), 0);
    let inputs = [las, empty];
    let plan = partition::plan(&inputs, &options(2, Structure::Octree)).unwrap();
    let p = d.join("plan.json");
    std::fs::write(&p, plan.to_json().to_string()).unwrap();
    let plan = BuildPlan::load(&p).unwrap();
    assert_eq!(plan.inputs[1].points, 0);
    let parts = d.join("parts");
    build_all(&plan, &parts, false);
    let m = partition::merge(&plan, &parts, &d.join("m.myr"), false, false, 1, &Silent).unwrap();
    assert_eq!(m.points, 30_000);
}

#[test]
fn merge_refuses_missing_and_foreign_parts() {
    let d = tempdir("partition-refuse");
    let las = synth(&d, 60_000, 2);
    let plan = partition::plan(std::slice::from_ref(&las), &options(3, Structure::Octree)).unwrap();
    let parts = d.join("parts");
    partition::build_part(&plan, 0, &parts, 1, false, &Silent).unwrap();
    partition::build_part(&plan, 2, &parts, 1, false, &Silent).unwrap();
    let out = d.join("out.myr");
    let e = partition::merge(&plan, &parts, &out, false, false, 1, &Silent)
        .unwrap_err()
        .to_string();
    assert!(e.contains("part-1.tops") && e.contains("--part 1"), "{e}");
    assert!(!out.exists());

    // Part 1 of another plan (other parameters) in its place.
    let mut o = options(3, Structure::Octree);
    o.params.capacity = 2000;
    let other = partition::plan(std::slice::from_ref(&las), &o).unwrap();
    assert_ne!(other.id, plan.id);
    partition::build_part(&other, 1, &parts, 1, false, &Silent).unwrap();
    let e = partition::merge(&plan, &parts, &out, false, false, 1, &Silent)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("part-1.tops") && e.contains("another plan"),
        "{e}"
    );
    assert!(!out.exists());

    // Rerun: it replaces the foreign part; then the merge works.
    partition::build_part(&plan, 1, &parts, 1, false, &Silent).unwrap();
    let m = partition::merge(&plan, &parts, &out, false, false, 1, &Silent).unwrap();
    assert_eq!(m.points, 60_000);

    // An edited plan is refused.
    let p = d.join("plan.json");
    let text = plan
        .to_json()
        .to_string()
        .replace("\"capacity\":3000", "\"capacity\":3001");
    std::fs::write(&p, text).unwrap();
    let e = BuildPlan::load(&p).unwrap_err().to_string();
    assert!(e.contains("edited"), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_point_outside_the_planned_cube_names_its_input() {
    let d = tempdir("partition-outside");
    let las = synth(&d, 20_000, 3);
    let mut plan =
        partition::plan(std::slice::from_ref(&las), &options(2, Structure::Octree)).unwrap();
    // A plan whose root misses part of the scan (as from a header that understates its bounds).
    let r = &mut plan.dataset.root;
    let half = r.size()[0] / 2.0;
    r.max = r.min.map(|v| v + half);
    let e = convert::convert(
        std::slice::from_ref(&las),
        &plan.convert_options(None, &d.join("x.myr"), 1),
        &Silent,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("city.las") && e.contains("outside the planned root cube"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&d);
}
