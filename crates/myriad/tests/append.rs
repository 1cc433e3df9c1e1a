//! `convert --append` (issue 19): scans added to a dataset hold exactly the records of all the
//! inputs (a neighbouring scan, which grows the root, then one inside, which rebuilds only the
//! cells it falls in), the dataset verifies, a killed append leaves the old dataset whole, and
//! one over the memory budget is refused.

mod common;
use common::{halves, myriad, ok, records, s, tempdir};
use myriad_format::Dataset;
use std::process::{Command, Stdio};
use std::time::Duration;

#[test]
fn appended_scans_hold_every_record_and_a_kill_loses_nothing() {
    let d = tempdir("append");
    let scan = d.join("scan.laz");
    ok(&["synth", "-o", s(&scan), "--points", "400k", "--seed", "3"]);
    let whole = d.join("whole.myr");
    ok(&["convert", s(&scan), "-o", s(&whole), "--capacity", "2000"]);
    // West and east of the middle: two neighbouring scans.
    let (west, east) = halves(&d, &whole);
    let b = Dataset::open(&whole).unwrap().meta.bounds;
    let site = d.join("site.myr");
    ok(&["convert", s(&west), "-o", s(&site), "--capacity", "2000"]);
    let before = Dataset::open(&site).unwrap().meta.points;

    // The east half lies partly outside the west half's root cube: the root grows.
    let out = ok(&["convert", s(&east), "--append", s(&site)]);
    eprintln!("{out}");
    assert!(out.contains("verified"), "{out}");
    let ds = Dataset::open(&site).unwrap();
    let (w, e) = (records(&west), records(&east));
    assert_eq!(ds.meta.points as usize, w.len() + e.len());
    assert!(ds.meta.points > before);
    let all = d.join("all.las");
    ok(&["extract", s(&site), "-o", s(&all)]);
    let mut want: Vec<Vec<i64>> = w.iter().chain(&e).cloned().collect();
    want.sort();
    assert_eq!(records(&all), want, "the records of both scans, each once");

    // A scan inside: only the cells it falls in are rebuilt, the other pages are copied.
    let small = d.join("small.laz");
    let c = ds.meta.bounds.center();
    ok(&[
        "extract",
        s(&whole),
        "-o",
        s(&small),
        "--box",
        &format!(
            "{},{},{},{},{},{}",
            c[0] - 10.0,
            c[1] - 10.0,
            b.min[2] - 1.0,
            c[0] + 10.0,
            c[1] + 10.0,
            b.max[2] + 1.0
        ),
    ]);
    let out = ok(&["convert", s(&small), "--append", s(&site), "--json"]);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    eprintln!("{v}");
    assert_eq!(v["levels_grown"], 0);
    assert!(v["nodes_copied"].as_u64().unwrap() > 0, "{v}");
    assert!(v["cells_rebuilt"].as_u64() < v["cells"].as_u64(), "{v}");
    ok(&["extract", s(&site), "-o", s(&all), "--force"]);
    want.extend(records(&small));
    want.sort();
    assert_eq!(records(&all), want);
    ok(&["verify", s(&site)]);

    // Killed at any moment: the dataset is the old one or the new one, whole.
    let n0 = Dataset::open(&site).unwrap().meta.points;
    let added = records(&east).len() as u64;
    let mut killed_midway = 0;
    for ms in [5u64, 40, 120, 300] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_myriad"))
            .args(["convert", s(&east), "--append", s(&site)])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(ms));
        if child.try_wait().unwrap().is_none() {
            killed_midway += 1;
        }
        let _ = child.kill();
        let _ = child.wait();
        let n = Dataset::open(&site).unwrap().meta.points;
        let r = myriad(&["verify", s(&site)]);
        assert_eq!(r.code, 0, "after a kill at {ms} ms: {}", r.stderr);
        assert!(
            n == n0 || n == n0 + added,
            "{n} points after a kill at {ms} ms"
        );
    }
    assert!(killed_midway > 0, "no append was killed while it ran");

    // What append refuses: more than the memory budget (before touching anything), a kd dataset.
    let n = Dataset::open(&site).unwrap().meta.points;
    let r = myriad(&["convert", s(&east), "--append", s(&site), "--memory", "1MB"]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("--memory") && r.stderr.lines().count() == 1,
        "{}",
        r.stderr
    );
    assert_eq!(Dataset::open(&site).unwrap().meta.points, n);
    let kd = d.join("kd.myr");
    ok(&["convert", s(&west), "-o", s(&kd), "--structure", "kd"]);
    let r = myriad(&["convert", s(&east), "--append", s(&kd)]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("kd") && r.stderr.lines().count() == 1,
        "{}",
        r.stderr
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// Scans added to a layered dataset: the cells kept take back the points the levels above held,
/// and their contours (and their own points') grow to hold them; the dataset is checked whole
/// before it replaces the old one, and holds every record of both scans.
#[test]
fn appended_to_a_layered_dataset_every_point_lies_in_its_contours() {
    let d = tempdir("append-layered");
    let (a, b) = (d.join("a.las"), d.join("b.las"));
    for (f, seed, n) in [(&a, "1", "300k"), (&b, "2", "200k")] {
        let args = [
            "synth",
            "-o",
            s(f),
            "--points",
            n,
            "--scene",
            "city",
            "--seed",
            seed,
        ];
        ok(&args);
    }
    let site = d.join("site.myr");
    ok(&[
        "convert",
        s(&a),
        "-o",
        s(&site),
        "--structure",
        "layered",
        "--capacity",
        "5000",
    ]);
    let out = ok(&["convert", s(&b), "--append", s(&site), "--json"]);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    // Some cells kept: their top nodes took back points from the levels above.
    assert!(v["cells_rebuilt"].as_u64() < v["cells"].as_u64(), "{v}");
    ok(&["verify", s(&site)]);
    let ds = Dataset::open(&site).unwrap();
    assert_eq!(ds.meta.structure, "layered");
    let all = d.join("all.las");
    ok(&["extract", s(&site), "-o", s(&all)]);
    let mut want: Vec<Vec<i64>> = records(&a).into_iter().chain(records(&b)).collect();
    want.sort();
    assert_eq!(records(&all), want, "the records of both scans, each once");
    let _ = std::fs::remove_dir_all(&d);
}
