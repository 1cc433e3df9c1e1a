//! The web viewer's core, natively: what the browser runs (tests/web.rs in the myriad crate
//! drives it there). Its selection, hierarchy pages read as needed, comes to the selection of
//! the whole hierarchy; decoded nodes put every point back where it is stored and colour it as
//! `myriad render` does; a damaged page is an error naming the file and byte offset; and the
//! committed WebAssembly is that of the current sources.

use myriad_build::convert::{ConvertOptions, Silent, convert};
use myriad_core::NodeKey;
use myriad_core::colour::{ColorBy, colours};
use myriad_format::{ByteSource, Dataset, FileBytes};
use myriad_lod::{Hierarchy, SelectOptions, select};
use myriad_web::{Ask, Viewer, decode};
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn dataset(name: &str) -> PathBuf {
    dataset_of(name, myriad_build::convert::Structure::Octree)
}

fn dataset_of(name: &str, structure: myriad_build::convert::Structure) -> PathBuf {
    let d = std::env::temp_dir().join(format!("myriad-web-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let las = d.join("city.las");
    let opts = myriad_synth::SynthOptions {
        points: 200_000,
        scene: myriad_synth::SceneKind::City,
        seed: 3,
    };
    myriad_synth::write(&opts, &las, true, |_| {}).unwrap();
    let out = d.join("city.myr");
    let mut o = ConvertOptions::new(&out);
    o.open = myriad_io::OpenOptions::default();
    // Small nodes: a deep tree, several hierarchy pages.
    o.params.capacity = 300;
    o.structure = structure;
    convert(std::slice::from_ref(&las), &o, &Silent).unwrap();
    out
}

fn source(p: &Path) -> Arc<dyn ByteSource> {
    Arc::new(FileBytes::open(p).unwrap())
}

/// The viewer's selection, hierarchy pages read as it asks for them, against the selection of
/// the whole hierarchy: the same nodes and prefixes. Returns what the viewer was asked.
fn same_selection(v: &mut Viewer, ds: &Dataset, entries: &[myriad_format::NodeEntry]) -> Ask {
    let whole = Hierarchy::new(ds.meta.root, entries.to_vec());
    let mut camera = v.default_camera(800, 600, 60.0);
    camera.position[2] -= 0.6 * (camera.position[2] - camera.target[2]);
    let options = SelectOptions {
        budget: 150_000,
        min_pixels: 1.0,
    };
    let ask = Ask {
        camera,
        options,
        clip: None,
        drawn: HashSet::new(),
    };
    // Asked again while pages are missing, as the viewer does.
    let mut answer = v.select(&ask);
    let mut calls = 1;
    while answer["pages_missing"].as_u64() != Some(0) {
        answer = v.select(&ask);
        calls += 1;
        assert!(calls < 100, "{answer}");
    }
    assert!(
        answer["pages"].as_u64().unwrap() > 1,
        "several hierarchy pages read: {}",
        answer["pages"]
    );
    let mut cam = camera;
    cam.fit_depth(&ds.meta.bounds);
    let want = select(&whole, &cam, &options);
    let got: Vec<(Vec<u32>, u32)> = answer["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| {
            let k = n["key"]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_u64().unwrap() as u32);
            (k.collect(), n["points"].as_u64().unwrap() as u32)
        })
        .collect();
    let want: Vec<(Vec<u32>, u32)> = want
        .nodes
        .iter()
        .map(|n| {
            let k = n.key;
            (vec![k.level, k.cell[0], k.cell[1], k.cell[2]], n.points)
        })
        .collect();
    assert!(want.len() > 10);
    assert_eq!(
        got, want,
        "the same nodes and prefixes as the whole hierarchy gives"
    );
    ask
}

#[test]
fn selection_decoding_and_damage() {
    let path = dataset("core");
    let mut v = Viewer::open(source(&path), "city.myr").unwrap();
    assert_eq!(v.info()["points"], 200_000);
    let ds = Dataset::open(&path).unwrap();
    let (entries, damage) = ds.nodes();
    assert!(damage.is_empty());
    let ask = same_selection(&mut v, &ds, &entries);
    // The drawn nodes' tree: every drawn node has its entry.
    let drawn: HashSet<NodeKey> = entries.iter().take(5).map(|e| e.key).collect();
    let a = v.select(&Ask { drawn, ..ask });
    assert!(!a["tree"].as_array().unwrap().is_empty());

    // Decoding a node as fetched: every point back to within f32 rounding of its node, the
    // colours those `myriad render` gives.
    let e = entries.iter().max_by_key(|e| e.points).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let page = &bytes[e.page.offset as usize..][..e.page.length as usize];
    let origin = e.key.bounds(&ds.meta.root).min;
    let z = (0.0, 40.0);
    let got = decode(
        &v.dataset,
        e,
        page,
        origin,
        ColorBy::Elevation,
        z,
        &myriad_measure::Bound::all(),
    )
    .unwrap();
    let stored = ds.read_node(e).unwrap();
    assert_eq!(
        got.colours,
        colours(&stored, stored.len(), ColorBy::Elevation, z, e.key.level)
    );
    let side = e.key.bounds(&ds.meta.root).size()[0];
    for (i, p) in stored.positions.iter().enumerate() {
        for a in 0..3 {
            let back = origin[a] + got.positions[3 * i + a] as f64;
            assert!((back - p[a]).abs() <= side * 1e-6, "{back} vs {}", p[a]);
        }
    }
    // A damaged page: the error names the file and the byte.
    let mut bad = page.to_vec();
    bad[40] ^= 0x55;
    let err = decode(
        &v.dataset,
        e,
        &bad,
        origin,
        ColorBy::Rgb,
        z,
        &myriad_measure::Bound::all(),
    )
    .err()
    .unwrap();
    assert!(
        err.contains("city.myr") && err.contains(&format!("byte {}", e.page.offset)),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(path.parent().unwrap());
}

/// A layered dataset (contours of subtrees and of nodes' own points in its hierarchy entries):
/// the viewer reads them and selects as the whole hierarchy does (it did not while a contour
/// reaching out of its node's cube put the node in view: the viewer never read the page of a
/// node whose cube is out of view).
#[test]
fn layered_selection() {
    let path = dataset_of("layered", myriad_build::convert::Structure::Layered);
    let mut v = Viewer::open(source(&path), "city.myr").unwrap();
    let ds = Dataset::open(&path).unwrap();
    let (entries, damage) = ds.nodes();
    assert!(damage.is_empty());
    assert!(entries.iter().any(|e| e.detail.is_some()));
    same_selection(&mut v, &ds, &entries);
    let _ = std::fs::remove_dir_all(path.parent().unwrap());
}

#[test]
fn the_committed_webassembly_is_built_from_these_sources() {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("build.sh");
    let out = std::process::Command::new("sh")
        .arg(&script)
        .arg("--check")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The web viewer's measurements are `myriad_measure`'s: the figure, the label in the units
/// asked for (converted from the CRS's), whether enough points are in.
#[test]
fn measurements_are_the_measure_crates() {
    let utm = r#"PROJCS["WGS 84 / UTM zone 33N",UNIT["metre",1,AUTHORITY["EPSG","9001"]]]"#;
    let area = [0.0, 0.0, 5.0, 1524.0, 0.0, 9.0, 1524.0, 1524.0, 1.0];
    let m = myriad_web::measure_json(3, &area, 2, Some(utm));
    assert_eq!(m["kind"], "area");
    assert_eq!(m["complete"], true);
    assert_eq!(m["label"], "12500000.00 ft² area");
    let m = myriad_web::measure_json(3, &area[..6], 1, Some(utm));
    assert_eq!(
        (m["complete"].clone(), m["label"].clone()),
        (false.into(), serde_json::Value::Null)
    );
    let m = myriad_web::measure_json(1, &[0.0, 0.0, 0.0, 3.0, 4.0, 0.0], 0, None);
    assert_eq!(
        (m["value"].as_f64(), m["label"].as_str()),
        (Some(5.0), Some("5.000"))
    );
    assert!(myriad_web::measure_json(9, &[], 0, None)["error"].is_string());
}
