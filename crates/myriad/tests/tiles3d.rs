//! `myriad export --to 3dtiles` as a user runs it, read back by the field's own readers:
//! py3dtiles (Python; `MYRIAD_PYTHON`, as `.ci/run` sets up) reads every tileset and tile and
//! finds every point where pyproj puts the input's; CesiumJS and 3d-tiles-renderer (npm, in
//! the folder `MYRIAD_NODE_MODULES` names, as `.ci/run` sets up) load the tiles in headless
//! Chromium from `myriad serve`, without an error, and CesiumJS picks a point at autzen's place
//! on the globe. Also the errors: no CRS, `--to-crs`, a folder that is not an export. Each
//! prints SKIPPED when its reader is missing.

mod common;
use common::{myriad, ok, ok_env, proj, pyprojs_proj, python_with, s, serve, shared_data, tempdir};
use myriad_serve::browser::{self, Browser};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

fn autzen() -> Option<PathBuf> {
    shared_data("PDAL__laz_autzen_trim.laz")
}

fn readers() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/readers")
}

/// What tiles3d_check.py reads of the tileset in `folder` (compared with `input` moved by
/// pyproj, when given).
fn py3dtiles(py: &str, folder: &Path, input: Option<&Path>) -> Value {
    let mut cmd = Command::new(py);
    cmd.arg(readers().join("tiles3d_check.py"))
        .arg(folder.join("tileset.json"));
    if let Some(i) = input {
        cmd.arg(i);
    }
    let r = cmd.output().unwrap();
    assert!(
        r.status.success(),
        "py3dtiles: {}",
        String::from_utf8_lossy(&r.stderr)
    );
    let v: Value = serde_json::from_slice(&r.stdout).unwrap();
    eprintln!("py3dtiles: {v}");
    v
}

#[test]
fn autzen_is_read_by_py3dtiles_where_pyproj_puts_it() {
    let Some(autzen) = autzen() else { return };
    if !proj() {
        return;
    }
    let Some(py) = python_with("py3dtiles, laspy, pyproj, numpy") else {
        eprintln!(
            "SKIPPED: no Python with py3dtiles, laspy and pyproj (MYRIAD_PYTHON); .ci/run installs them"
        );
        return;
    };
    // The same PROJ on both sides (pyproj's: Debian's older one picks another datum shift).
    let env = pyprojs_proj(&py);
    let d = tempdir("tiles3d-autzen");
    let myr = d.join("autzen.myr");
    ok(&["convert", s(&autzen), "-o", s(&myr)]);
    let ds = myriad_format::Dataset::open(&myr).unwrap();
    let (nodes, _) = ds.nodes();
    let with_points = nodes.iter().filter(|n| n.points > 0).count() as u64;
    for (version, ext) in [("1.1", "glb"), ("1.0", "pnts")] {
        let out = d.join(format!("tiles-{version}"));
        let printed = ok_env(
            &[
                "export",
                s(&myr),
                "-o",
                s(&out),
                "--to",
                "3dtiles",
                "--tiles-version",
                version,
            ],
            &env,
        );
        assert!(printed.contains("110,000 points"), "{printed}");
        let v = py3dtiles(&py, &out, Some(&autzen));
        // Every node a tile, every point in one, each where pyproj puts it (float32 offsets
        // from each tile's centre: well under a millimetre).
        assert_eq!(v["points"], 110_000, "{v}");
        assert_eq!(v["input_points"], 110_000, "{v}");
        assert_eq!(v["tiles"].as_u64(), Some(with_points), "{v}");
        assert!(v["worst"].as_f64().unwrap() < 1e-3, "{v}");
        assert!(v["versions"][0].as_str().unwrap().contains(version), "{v}");
        let tiles = std::fs::read_dir(out.join("tiles")).unwrap().count() as u64;
        assert_eq!(
            tiles + 1,
            with_points + v["tilesets"].as_u64().unwrap(),
            "{v}"
        );
        assert!(out.join("tiles/r.".to_string() + ext).is_file());
        if version == "1.1" {
            assert_eq!(
                v["fields"],
                serde_json::json!(["classification", "intensity"]),
                "{v}"
            );
        }
        // The root's geometric error is its spacing in metres (autzen's CRS is in feet).
        let ts: Value =
            serde_json::from_slice(&std::fs::read(out.join("tileset.json")).unwrap()).unwrap();
        let root_error = ts["root"]["geometricError"].as_f64().unwrap();
        let root = nodes.iter().find(|n| n.key.level == 0).unwrap();
        let spacing_m = root.spacing.last().unwrap() * 0.3048006096;
        assert!(
            (root_error - spacing_m).abs() < 1e-3 * spacing_m,
            "{root_error} {spacing_m}"
        );
    }
}

/// A synthetic scan deep enough for external tilesets, cut by `--box` and thinned by
/// `--spacing`, and the errors a user meets.
#[test]
fn deep_trees_split_into_tilesets_and_errors_are_one_line() {
    if !proj() {
        return;
    }
    let d = tempdir("tiles3d-synth");
    let las = d.join("scan.laz");
    let myr = d.join("scan.myr");
    ok(&["synth", "-o", s(&las), "--points", "400k", "--force"]);
    ok(&[
        "convert",
        s(&las),
        "-o",
        s(&myr),
        "--capacity",
        "64",
        "--force",
    ]);
    let ds = myriad_format::Dataset::open(&myr).unwrap();
    let out = d.join("tiles");
    let r = myriad(&["export", s(&myr), "-o", s(&out), "--to", "3dtiles"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stdout.contains("400,000 points"), "{}", r.stdout);
    // Every tileset file names only files that are there, and every tile is named once.
    let mut named = std::collections::BTreeSet::new();
    let mut files = 0;
    let mut stack = vec![out.join("tileset.json")];
    while let Some(f) = stack.pop() {
        files += 1;
        let v: Value = serde_json::from_slice(&std::fs::read(&f).unwrap()).unwrap();
        let mut tiles = vec![&v["root"]];
        while let Some(t) = tiles.pop() {
            if let Some(uri) = t["content"]["uri"].as_str() {
                let p = f.parent().unwrap().join(uri);
                assert!(p.is_file(), "{} names {uri}", f.display());
                assert!(named.insert(p.clone()), "{uri} named twice");
                if uri.ends_with(".json") {
                    stack.push(p);
                }
            }
            // A child's error is below its parent's; boxes are 12 numbers.
            assert_eq!(t["boundingVolume"]["box"].as_array().unwrap().len(), 12);
            for c in t["children"].as_array().into_iter().flatten() {
                assert!(c["geometricError"].as_f64() < t["geometricError"].as_f64());
                tiles.push(c);
            }
        }
    }
    assert!(
        files > 1,
        "a tree deeper than 6 levels has external tilesets"
    );
    assert!(
        r.stdout.contains(&format!("({files} tileset files")),
        "{}",
        r.stdout
    );
    let on_disk = std::fs::read_dir(out.join("tiles")).unwrap().count();
    assert_eq!(named.len(), on_disk, "every file in tiles/ is named once");

    // --box and --spacing as the other exports: the same points as extract writes.
    let b = ds.meta.bounds;
    let cut = format!(
        "{},{},{},{},{},{}",
        b.min[0],
        b.min[1],
        b.min[2],
        (b.min[0] + b.max[0]) / 2.0,
        (b.min[1] + b.max[1]) / 2.0,
        b.max[2]
    );
    let part = d.join("part");
    let r = myriad(&[
        "export",
        s(&myr),
        "-o",
        s(&part),
        "--to",
        "3dtiles",
        "--box",
        &cut,
        "--spacing",
        "1",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let laz = d.join("part.laz");
    let e = myriad(&[
        "extract",
        s(&myr),
        "-o",
        s(&laz),
        "--box",
        &cut,
        "--spacing",
        "1",
    ]);
    assert_eq!(e.code, 0, "{}", e.stderr);
    let want = e
        .stdout
        .split(" points")
        .next()
        .unwrap()
        .rsplit(' ')
        .next()
        .unwrap();
    assert!(
        r.stdout.contains(&format!("{want} points")),
        "{} / {}",
        r.stdout,
        e.stdout
    );

    // Replacing: only with --force, and never a folder that is not an export.
    let r = myriad(&["export", s(&myr), "-o", s(&out), "--to", "3dtiles"]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("--force"), "{}", r.stderr);
    let mine = d.join("mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("notes.txt"), "mine").unwrap();
    let r = myriad(&[
        "export",
        s(&myr),
        "-o",
        s(&mine),
        "--to",
        "3dtiles",
        "--force",
    ]);
    assert_eq!(r.code, 1);
    assert_eq!(r.stderr.trim().lines().count(), 1, "{}", r.stderr);
    assert_eq!(
        std::fs::read_to_string(mine.join("notes.txt")).unwrap(),
        "mine"
    );
    let r = myriad(&[
        "export",
        s(&myr),
        "-o",
        s(&out),
        "--to",
        "3dtiles",
        "--force",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);

    // Neither --to-crs (3D Tiles are always Earth-centred) nor a dataset without a CRS.
    let r = myriad(&[
        "export",
        s(&myr),
        "-o",
        s(&d.join("x")),
        "--to",
        "3dtiles",
        "--to-crs",
        "EPSG:4326",
    ]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("--to-crs"), "{}", r.stderr);
    let txt = d.join("plain.xyz");
    std::fs::write(&txt, "0 0 0\n1 1 1\n2 0 1\n").unwrap();
    let plain = d.join("plain.myr");
    ok(&["convert", s(&txt), "-o", s(&plain)]);
    let r = myriad(&[
        "export",
        s(&plain),
        "-o",
        s(&d.join("p")),
        "--to",
        "3dtiles",
    ]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("--from-crs"), "{}", r.stderr);
    assert_eq!(r.stderr.trim().lines().count(), 1, "{}", r.stderr);
    assert!(!d.join("p").exists(), "no output on failure");
    let r = myriad(&[
        "export",
        s(&plain),
        "-o",
        s(&d.join("p")),
        "--to",
        "3dtiles",
        "--from-crs",
        "EPSG:32633",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stdout.contains("3 points"), "{}", r.stdout);
    // A point that does not move into Earth-centred coordinates (latitude 95) is left out and
    // counted, the others written.
    let geo = d.join("geo.xyz");
    std::fs::write(&geo, "10 45 0\n10.001 45.001 1\n10 95 2\n").unwrap();
    let geo_myr = d.join("geo.myr");
    ok(&["convert", s(&geo), "-o", s(&geo_myr)]);
    let r = myriad(&[
        "export",
        s(&geo_myr),
        "-o",
        s(&d.join("g")),
        "--to",
        "3dtiles",
        "--from-crs",
        "EPSG:4326",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stdout.contains("2 points"), "{}", r.stdout);
    assert!(
        r.stderr.contains("warning: 1 points do not transform"),
        "{}",
        r.stderr
    );
    // Nothing left behind: no hidden temporary folders.
    let hidden: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with('.'))
        .collect();
    assert!(hidden.is_empty(), "{hidden:?}");
}

/// The npm packages the browser test loads: `MYRIAD_NODE_MODULES` (a node_modules folder with
/// cesium, three and 3d-tiles-renderer).
fn node_modules() -> Option<PathBuf> {
    let m = PathBuf::from(std::env::var_os("MYRIAD_NODE_MODULES")?);
    [
        "cesium/Build/Cesium/Cesium.js",
        "three/build/three.module.js",
        "3d-tiles-renderer/build/index.js",
    ]
    .iter()
    .all(|f| m.join(f).is_file())
    .then_some(m)
}

#[test]
fn autzen_opens_in_cesium_and_3d_tiles_renderer() {
    let Some(autzen) = autzen() else { return };
    if !proj() {
        return;
    }
    let Some(modules) = node_modules() else {
        eprintln!(
            "SKIPPED: no MYRIAD_NODE_MODULES with cesium, three and 3d-tiles-renderer (npm; .ci/run installs them)"
        );
        return;
    };
    let Some(exe) = browser::find() else {
        eprintln!("SKIPPED: no Chromium (apt-get install chromium; .ci/run installs it)");
        return;
    };
    let Some(py) = python_with("laspy, pyproj, numpy") else {
        eprintln!(
            "SKIPPED: no Python with laspy and pyproj (MYRIAD_PYTHON); .ci/run installs them"
        );
        return;
    };
    let d = tempdir("tiles3d-browsers");
    let myr = d.join("autzen.myr");
    ok(&["convert", s(&autzen), "-o", s(&myr)]);
    let tiles = d.join("autzen");
    ok(&["export", s(&myr), "-o", s(&tiles), "--to", "3dtiles"]);
    let page = d.join("page");
    std::fs::create_dir_all(&page).unwrap();
    for f in ["cesium_check.html", "tiles_renderer_check.html"] {
        std::fs::copy(readers().join(f), page.join(f)).unwrap();
    }
    let server = serve(
        &[
            s(&modules.join("cesium/Build/Cesium")),
            s(&modules.join("three")),
            s(&modules.join("3d-tiles-renderer")),
            s(&page),
            s(&tiles),
        ],
        Stdio::null(),
    );
    let mut b = Browser::launch(&exe).unwrap();
    let report = |b: &mut Browser, page: &str| -> Value {
        b.open(
            &format!(
                "{}/d/page/{page}?tileset=/d/autzen/tileset.json&sse=1",
                server.base
            ),
            800,
            600,
        )
        .unwrap();
        let v = b
            .wait_for("window.report", Duration::from_secs(240))
            .unwrap();
        eprintln!("{page}: {v}");
        v
    };

    // CesiumJS, asked for every level (a screen-space error of 1 pixel): every tile loads
    // without an error, and a point picked in the middle of the view lies where pyproj puts
    // one of autzen's.
    let all = std::fs::read_dir(tiles.join("tiles")).unwrap().count();
    assert!(all >= 3, "{all} tiles");
    let v = report(&mut b, "cesium_check.html");
    assert_eq!(v["errors"], serde_json::json!([]), "{v}");
    assert_eq!(v["failed"], serde_json::json!([]), "{v}");
    assert_eq!(v["loaded"].as_array().unwrap().len(), all, "{v}");
    let pick = &v["pick"];
    assert!(pick.is_object(), "nothing picked: {v}");
    let (lon, lat, h) = (
        pick["lon"].as_f64().unwrap(),
        pick["lat"].as_f64().unwrap(),
        pick["height"].as_f64().unwrap(),
    );
    // Autzen stadium, Eugene, Oregon.
    assert!(
        (lon + 123.07).abs() < 0.01 && (lat - 44.06).abs() < 0.01,
        "{v}"
    );
    let script = r#"
import sys, laspy, numpy as np
from pyproj import Transformer
las = laspy.read(sys.argv[1])
t = Transformer.from_crs(las.header.parse_crs(), "EPSG:4979", always_xy=True)
lon, lat, h = t.transform(np.asarray(las.x), np.asarray(las.y), np.asarray(las.z))
plon, plat, ph = map(float, sys.argv[2:5])
east = (lon - plon) * 111320.0 * np.cos(np.radians(plat))
north = (lat - plat) * 110540.0
d = np.hypot(east, north)
i = int(np.argmin(d))
print(d[i], h[i] - ph)
"#;
    let r = Command::new(&py)
        .args(["-c", script, s(&autzen)])
        .args([lon, lat, h].map(|x| x.to_string()))
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let out = String::from_utf8_lossy(&r.stdout).into_owned();
    let near: Vec<f64> = out.split_whitespace().map(|x| x.parse().unwrap()).collect();
    eprintln!("CesiumJS's pick: {lon}, {lat}, {h} m; the nearest point by pyproj {near:?} m away");
    // Here 0.13 m across and 1.6 m in height (a 4-pixel sprite's depth at about 0.6 m a
    // pixel); Debian's PROJ puts autzen 1.3 m from where pyproj's does (see reproject.rs).
    assert!(near[0] < 3.0 && near[1].abs() < 5.0, "{out}");

    // 3d-tiles-renderer (three.js): every tile loads, points drawn.
    let v = report(&mut b, "tiles_renderer_check.html");
    assert_eq!(v["errors"], serde_json::json!([]), "{v}");
    assert_eq!(v["failed"], serde_json::json!([]), "{v}");
    assert_eq!(v["loaded"].as_array().unwrap().len(), all, "{v}");
    assert!(v["points"].as_u64().unwrap() >= 1000, "{v}");
    assert!(v["lit"].as_u64().unwrap() >= 1000, "{v}");
}
