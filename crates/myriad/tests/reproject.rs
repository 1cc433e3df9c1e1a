//! Reprojection as a user runs it (`convert --to-crs`, `export --to-crs`): autzen (Oregon
//! Lambert, feet) into UTM 10N metres and earth-centred coordinates, every point within 1 mm of
//! pyproj's transform of the same input; lidR's plots into longitude and latitude and back within
//! 1 mm; a compound CRS keeping its vertical part; a file without a CRS refused in one line;
//! points that do not transform counted, never moved to 0,0.

mod common;
use common::shared_data as data;
use common::{myriad, ok, ok_env, proj, pyprojs_proj, python_with, s, tempdir};
use std::collections::HashMap;
use std::path::Path;
use std::process::Command;

/// A point's attributes (what reprojection leaves alone) and its position.
type Points = Vec<([u64; 6], [f64; 3])>;

fn points(path: &Path) -> Points {
    let mut src = myriad_io::open(path, &myriad_io::OpenOptions::default()).unwrap();
    let mut out = Vec::new();
    while let Some(b) = src.read_batch(myriad_io::DEFAULT_BATCH).unwrap() {
        for i in 0..b.len() {
            let key = [
                b.gps_time.as_ref().map_or(0, |g| g[i].to_bits()),
                b.intensity.as_ref().map_or(0, |v| v[i] as u64),
                b.return_number.as_ref().map_or(0, |v| v[i] as u64),
                b.classification.as_ref().map_or(0, |v| v[i] as u64),
                b.point_source_id.as_ref().map_or(0, |v| v[i] as u64),
                // Not the scan angle: COPC's point formats store it in other steps.
                b.user_data.as_ref().map_or(0, |v| v[i] as u64),
            ];
            out.push((key, b.positions[i]));
        }
    }
    out
}

/// Every point of `got` lies within `tolerance` of a point of `want` with the same attributes
/// (and both have as many); the largest distance.
fn matches(got: &Points, want: &Points, tolerance: f64) -> f64 {
    assert_eq!(got.len(), want.len());
    let mut by_key: HashMap<[u64; 6], Vec<[f64; 3]>> = HashMap::new();
    for (k, p) in want {
        by_key.entry(*k).or_default().push(*p);
    }
    let mut worst = 0.0f64;
    for (k, p) in got {
        let near = by_key[k]
            .iter()
            .map(|q| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt())
            .fold(f64::INFINITY, f64::min);
        assert!(
            near <= tolerance,
            "{p:?}: {near} from the nearest expected point"
        );
        worst = worst.max(near);
    }
    worst
}

/// The input's points as pyproj moves them (`always_xy`, from the CRS laspy reads in the file).
fn pyproj(py: &str, input: &Path, to: &str, out: &Path) -> Points {
    let script = r#"
import sys, laspy, numpy as np
from pyproj import Transformer
las = laspy.read(sys.argv[1])
t = Transformer.from_crs(las.header.parse_crs(), sys.argv[2], always_xy=True)
x, y, z = t.transform(np.asarray(las.x), np.asarray(las.y), np.asarray(las.z))
np.stack([x, y, z], axis=1).astype("<f8").tofile(sys.argv[3])
"#;
    let r = Command::new(py)
        .args(["-c", script, s(input), to, s(out)])
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let bytes = std::fs::read(out).unwrap();
    let moved: Vec<[f64; 3]> = bytes
        .chunks_exact(24)
        .map(|c| {
            std::array::from_fn(|a| f64::from_le_bytes(c[8 * a..8 * a + 8].try_into().unwrap()))
        })
        .collect();
    // The input's points in file order, as myriad-io reads them, with pyproj's positions.
    let mut mine = points(input);
    assert_eq!(mine.len(), moved.len());
    for (m, p) in mine.iter_mut().zip(moved) {
        m.1 = p;
    }
    mine
}

#[test]
fn autzen_to_utm_and_earth_centred_within_a_millimetre_of_pyproj() {
    let (Some(autzen), true) = (data("PDAL__laz_autzen_trim.laz"), proj()) else {
        return;
    };
    let Some(py) = python_with("laspy, pyproj, numpy") else {
        eprintln!(
            "SKIPPED: no Python with laspy and pyproj (MYRIAD_PYTHON); .ci/run installs them"
        );
        return;
    };
    let d = tempdir("reproject-autzen");
    let same = pyprojs_proj(&py);
    // With pyproj's own PROJ, both targets within 1 mm; with Debian's, the UTM zone within 1 mm
    // and the earth-centred coordinates within the 2 m of the operation PROJ 9.1 chooses.
    for (to, env, tolerance) in [
        ("EPSG:32610", &same, 1e-3),
        ("EPSG:4978", &same, 1e-3),
        ("EPSG:32610", &vec![], 1e-3),
        ("EPSG:4978", &vec![], 2.0),
    ] {
        let name = format!("{}-{}", to.replace(':', ""), env.len());
        let myr = d.join(format!("{name}.myr"));
        let out = ok_env(&["convert", s(&autzen), "-o", s(&myr), "--to-crs", to], env);
        assert!(out.contains("110,000"), "{out}");
        let info = ok(&["info", s(&myr)]);
        let code = format!("({to})");
        assert!(
            info.lines()
                .any(|l| l.contains("crs name") && l.contains(&code)),
            "{info}"
        );
        let las = d.join(format!("{name}.las"));
        ok(&["extract", s(&myr), "-o", s(&las)]);
        let want = pyproj(&py, &autzen, to, &d.join(format!("{name}.f64")));
        let worst = matches(&points(&las), &want, tolerance);
        let whose = if env.is_empty() {
            "the system's"
        } else {
            "pyproj's"
        };
        eprintln!("autzen to {to} with {whose} PROJ: every point within {worst:.6} m of pyproj's");
        // The LAS written back says the new CRS (laspy reads it).
        let check = Command::new(&py)
            .args([
                "-c",
                "import sys, laspy; c = laspy.read(sys.argv[1]).header.parse_crs(); print(c.to_epsg())",
                s(&las),
            ])
            .output()
            .unwrap();
        assert_eq!(String::from_utf8_lossy(&check.stdout).trim(), &to[5..]);
    }
    // export --to-crs: the same points, re-placed, to COPC.
    let myr = d.join("autzen.myr");
    ok(&["convert", s(&autzen), "-o", s(&myr)]);
    let copc = d.join("utm.copc.laz");
    let out = ok(&["export", s(&myr), "-o", s(&copc), "--to-crs", "EPSG:32610"]);
    assert!(out.contains("moved into EPSG:32610"), "{out}");
    let want = pyproj(&py, &autzen, "EPSG:32610", &d.join("copc.f64"));
    matches(&points(&copc), &want, 1e-3);
}

#[test]
fn lidr_plots_to_longitude_latitude_and_back() {
    if !proj() {
        return;
    }
    for (file, code) in [
        ("lidR__Megaplot.laz", "EPSG:26917"),
        ("lidR__Topography.laz", "EPSG:2949"),
    ] {
        let Some(input) = data(file) else { return };
        let d = tempdir(&format!("reproject-{code}").replace(':', ""));
        let (geo, back) = (d.join("geo.myr"), d.join("back.myr"));
        ok(&["convert", s(&input), "-o", s(&geo), "--to-crs", "EPSG:4326"]);
        let info = ok(&["info", s(&geo)]);
        assert!(info.contains("geographic, units degrees"), "{info}");
        // Longitude and latitude in x and y, on a grid of 1e-9 degrees (0.1 mm).
        let ds = myriad_format::Dataset::open(&geo).unwrap();
        assert!(
            ds.meta.quantization.scale[0] <= 1e-8,
            "{:?}",
            ds.meta.quantization
        );
        assert!(ds.meta.bounds.min[0] > -180.0 && ds.meta.bounds.max[1] < 90.0);
        // Measurements in longitude and latitude are geodesic, in metres: the plot's diagonal
        // as long as in the projected CRS (within 0.1 %: the projection's scale factor).
        let info_in = myriad_io::open(&input, &myriad_io::OpenOptions::default()).unwrap();
        let ib = info_in.info().bounds.unwrap();
        let projected = ((ib.max[0] - ib.min[0]).powi(2) + (ib.max[1] - ib.min[1]).powi(2)).sqrt();
        let mut t = myriad_io::proj::Transform::new(code, "EPSG:4326").unwrap();
        let (a, b) = (
            t.point([ib.min[0], ib.min[1], 0.0]).unwrap(),
            t.point([ib.max[0], ib.max[1], 0.0]).unwrap(),
        );
        let m = format!("distance:{},{},0,{},{},0", a[0], a[1], b[0], b[1]);
        let listed = ok(&["annotate", s(&geo), "--measure", &m]);
        let line = listed.lines().find(|l| l.contains("distance")).unwrap();
        let metres: f64 = line
            .split(": ")
            .nth(1)
            .unwrap()
            .split(' ')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!(line.contains(" m ("), "{line}");
        assert!(
            (metres - projected).abs() < 1e-3 * projected,
            "{metres} against {projected}"
        );
        let geo_las = d.join("geo.las");
        ok(&["extract", s(&geo), "-o", s(&geo_las)]);
        ok(&["convert", s(&geo_las), "-o", s(&back), "--to-crs", code]);
        let las = d.join("back.las");
        ok(&["extract", s(&back), "-o", s(&las)]);
        let worst = matches(&points(&las), &points(&input), 1e-3);
        eprintln!("{file}: {code} -> EPSG:4326 -> {code}: within {worst:.6} m");
    }
}

#[test]
fn a_compound_crs_keeps_its_vertical_part() {
    let (Some(input), true) = (data("lasrs__32-1-472-150-76.laz"), proj()) else {
        return;
    };
    let d = tempdir("reproject-compound");
    let myr = d.join("geo.myr");
    ok(&["convert", s(&input), "-o", s(&myr), "--to-crs", "EPSG:4258"]);
    let info = ok(&["info", s(&myr)]);
    let line = info.lines().find(|l| l.contains("crs name")).unwrap();
    assert!(
        line.contains("geographic") && line.contains("vertical NN2000 height (EPSG:5941), m"),
        "{line}"
    );
    // Heights unchanged: the same vertical datum.
    let (a, b) = (points(&input), {
        let las = d.join("geo.las");
        ok(&["extract", s(&myr), "-o", s(&las)]);
        points(&las)
    });
    let mut za: Vec<i64> = a.iter().map(|p| (p.1[2] * 1000.0).round() as i64).collect();
    let mut zb: Vec<i64> = b.iter().map(|p| (p.1[2] * 1000.0).round() as i64).collect();
    za.sort();
    zb.sort();
    assert_eq!(za, zb);
}

#[test]
fn no_crs_is_refused_and_points_that_do_not_transform_are_counted() {
    if !proj() {
        return;
    }
    let d = tempdir("reproject-errors");
    let text = d.join("pts.xyz");
    std::fs::write(&text, "-123.0 44.0 1.0\n-123.1 44.1 2.0\n-123.0 95.0 3.0\n").unwrap();
    let myr = d.join("a.myr");
    let r = myriad(&["convert", s(&text), "-o", s(&myr), "--to-crs", "EPSG:32610"]);
    assert_eq!(r.code, 1);
    let line = r.stderr.trim();
    assert_eq!(line.lines().count(), 1, "{line}");
    assert!(
        line.contains("pts.xyz") && line.contains("--from-crs"),
        "{line}"
    );
    assert!(!myr.exists());
    let out = ok(&[
        "convert",
        s(&text),
        "-o",
        s(&myr),
        "--to-crs",
        "EPSG:32610",
        "--from-crs",
        "EPSG:4326",
    ]);
    assert!(out.contains("points      2"), "{out}");
    assert!(
        out.contains("dropped     1 that do not transform into EPSG:32610"),
        "{out}"
    );
    let ds = myriad_format::Dataset::open(&myr).unwrap();
    // Nothing at 0,0: both points near zone 10's central meridian.
    assert!(
        ds.meta.bounds.min[0] > 490_000.0 && ds.meta.bounds.max[0] < 510_000.0,
        "{:?}",
        ds.meta.bounds
    );
    // A CRS PROJ does not know: one line naming it.
    let r = myriad(&[
        "convert",
        s(&text),
        "-o",
        s(&myr),
        "--force",
        "--to-crs",
        "EPSG:99999999",
        "--from-crs",
        "EPSG:4326",
    ]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.trim().lines().count() == 1 && r.stderr.contains("EPSG:99999999"),
        "{}",
        r.stderr
    );
    // export of a dataset without a CRS.
    let plain = d.join("plain.myr");
    ok(&["convert", s(&text), "-o", s(&plain)]);
    let r = myriad(&[
        "export",
        s(&plain),
        "-o",
        s(&d.join("x.copc.laz")),
        "--to-crs",
        "EPSG:32610",
    ]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("--from-crs") && r.stderr.trim().lines().count() == 1,
        "{}",
        r.stderr
    );
}
