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

fn build_all(plan: &BuildPlan, parts: &Path) {
    for i in 0..plan.parts.len() {
        let s = partition::build_part(plan, i, parts, 2, &Silent).unwrap();
        if s.points > 0 {
            let ds = Dataset::open(&partition::part_paths(parts, i).0).unwrap();
            let r = myriad_build::extract::verify(&ds, |_| {});
            assert!(r.damage.is_empty(), "part {i}: {:?}", r.damage);
            assert_eq!(ds.meta.points, s.points);
        }
    }
}

fn same_as_one_machine(structure: Structure, name: &str) {
    let d = tempdir(name);
    let las = synth(&d, 250_000, 5);
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
    build_all(&plan, &parts);
    let merged = d.join("merged.myr");
    let m = partition::merge(&plan, &parts, &merged, false, 2, &Silent).unwrap();
    assert_eq!(m.points, 250_000);
    assert!(m.copied > 0 && m.built > 0, "{m:?}");

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
    let ds = Dataset::open(&merged).unwrap();
    assert_eq!(ds.meta.sources[0]["points"], 250_000);
    let r = myriad_build::extract::verify(&ds, |_| {});
    assert!(r.damage.is_empty());
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn octree_parts_merge_to_the_one_machine_build() {
    same_as_one_machine(Structure::Octree, "partition-octree");
}

#[test]
fn layered_parts_merge_to_the_one_machine_build() {
    same_as_one_machine(Structure::Layered, "partition-layered");
}

#[test]
fn merge_refuses_missing_and_foreign_parts() {
    let d = tempdir("partition-refuse");
    let las = synth(&d, 60_000, 2);
    let plan = partition::plan(std::slice::from_ref(&las), &options(3, Structure::Octree)).unwrap();
    let parts = d.join("parts");
    partition::build_part(&plan, 0, &parts, 1, &Silent).unwrap();
    partition::build_part(&plan, 2, &parts, 1, &Silent).unwrap();
    let out = d.join("out.myr");
    let e = partition::merge(&plan, &parts, &out, false, 1, &Silent)
        .unwrap_err()
        .to_string();
    assert!(e.contains("part-1.tops") && e.contains("--part 1"), "{e}");
    assert!(!out.exists());

    // Part 1 of another plan (other parameters) in its place.
    let mut o = options(3, Structure::Octree);
    o.params.capacity = 2000;
    let other = partition::plan(std::slice::from_ref(&las), &o).unwrap();
    assert_ne!(other.id, plan.id);
    partition::build_part(&other, 1, &parts, 1, &Silent).unwrap();
    let e = partition::merge(&plan, &parts, &out, false, 1, &Silent)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("part-1.tops") && e.contains("another plan"),
        "{e}"
    );
    assert!(!out.exists());

    // Rerun: it replaces the foreign part; then the merge works.
    partition::build_part(&plan, 1, &parts, 1, &Silent).unwrap();
    let m = partition::merge(&plan, &parts, &out, false, 1, &Silent).unwrap();
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
