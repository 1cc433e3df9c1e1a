//! Placements: parsing (errors name the line), trimming in the scanner's or the project's frame,
//! the transform into project coordinates, and sidecar discovery by `open`.

use myriad_io::placement::Placement;
use myriad_io::{OpenOptions, open, scan};
use std::path::{Path, PathBuf};

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("myriad-placement-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn parse_err(text: &str) -> String {
    Placement::parse(Path::new("p.placement"), text)
        .unwrap_err()
        .to_string()
}

#[test]
fn parse_errors_name_the_line() {
    let check = |text: &str, expect: &str| {
        let e = parse_err(text);
        assert!(e.contains(expect), "{text:?}: expected {expect:?} in {e:?}");
    };
    check(
        "# comment\nTRANSLATE 1 2\n",
        "p.placement: line 2: TRANSLATE takes 3 numbers, found 2",
    );
    check("ROTATE-DEG 0 0 x\n", "line 1: not a number: \"x\"");
    check("\n\nSPIN 1 2 3\n", "line 3: unknown keyword \"SPIN\"");
    check(
        "OBB-ANGLES 0 0 0 1 1 1 0 0 0\n",
        "line 1: OBB-ANGLES needs SOCS or PRCS first",
    );
    check(
        "OBB-NORMALS SOCS 0 0 0 1 1 1 1 0 0 2 0 0 0 0 1\n",
        "line 1: OBB-NORMALS directions are coplanar",
    );
    check(
        "OBB-ANGLES SOCS 0 0 0 1 1 1 0 0 0\nOBB-ANGLES PRCS 0 0 0 1 1 1 0 0 0\n",
        "line 2: only one trimming box",
    );
    check(
        "TRANSFORM 1 0 0 0 0 1 0 0 0 0 1 0\nTRANSLATE 1 1 1\n",
        "cannot be combined",
    );
}

fn xyz(d: &Path, name: &str) -> PathBuf {
    // A row of points along x in the scanner's frame: -3 .. 3.
    let p = d.join(name);
    let text: String = (-3..=3).map(|i| format!("{i} 0 0\n")).collect();
    std::fs::write(&p, text).unwrap();
    p
}

fn read_positions(path: &Path, placement: Option<&Path>, sidecar: bool) -> (Vec<[i64; 3]>, u64) {
    let options = OpenOptions {
        placement: placement.map(Path::to_path_buf),
        sidecar_placements: sidecar,
        ..Default::default()
    };
    let mut src = open(path, &options).unwrap_or_else(|e| panic!("{e}"));
    let mut out = Vec::new();
    while let Some(b) = src.read_batch(3).unwrap() {
        out.extend(
            b.positions
                .iter()
                .map(|p| p.map(|c| (c * 1000.0).round() as i64)),
        );
    }
    (out, src.trimmed())
}

#[test]
fn trims_in_either_frame_then_transforms() {
    let d = dir();
    let scan_file = xyz(&d, "row.xyz");
    // A quarter turn about z, then 100 m east: scanner x becomes project y.
    let socs = d.join("socs.placement");
    std::fs::write(&socs, "ROTATE-DEG 0 0 90\nTRANSLATE 100 0 0\nOBB-ANGLES SOCS 0 0 0  1.5 1 1  0 0 0  # |x| <= 1.5\n").unwrap();
    let (pts, trimmed) = read_positions(&scan_file, Some(&socs), false);
    assert_eq!(
        pts,
        vec![[100_000, -1000, 0], [100_000, 0, 0], [100_000, 1000, 0]]
    );
    assert_eq!(trimmed, 4);
    // The same box given in project coordinates, turned with the scan: the same points survive.
    let prcs = d.join("prcs.placement");
    std::fs::write(&prcs, "ROTATE-DEG 0 0 90\nTRANSLATE 100 0 0\nOBB-NORMALS PRCS 100 0 0  1 1.5 1  1 0 0  0 1 0  0 0 1\n").unwrap();
    assert_eq!(
        read_positions(&scan_file, Some(&prcs), false),
        (pts.clone(), 4)
    );
    // TRANSFORM gives the same matrix by rows.
    let m = d.join("m.placement");
    std::fs::write(&m, "TRANSFORM 0 -1 0 100  1 0 0 0  0 0 1 0\n").unwrap();
    let (all, trimmed) = read_positions(&scan_file, Some(&m), false);
    assert_eq!((all.len(), trimmed), (7, 0));
    assert_eq!(all[0], [100_000, -3000, 0]);
}

#[test]
fn sidecar_placement_is_found_next_to_the_scan() {
    let d = dir();
    let scan_file = xyz(&d, "side.xyz");
    std::fs::write(d.join("side.xyz.placement"), "TRANSLATE 0 0 10\n").unwrap();
    let (pts, _) = read_positions(&scan_file, None, true);
    assert!(pts.iter().all(|p| p[2] == 10_000));
    let (pts, _) = read_positions(&scan_file, None, false);
    assert!(
        pts.iter().all(|p| p[2] == 0),
        "sidecars only when asked for"
    );
    let mut src = open(
        &scan_file,
        &OpenOptions {
            sidecar_placements: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(scan(src.as_mut()).unwrap().0, 7);
    assert!(
        src.placement_path()
            .unwrap()
            .ends_with("side.xyz.placement")
    );
}

/// Local scanner coordinates are often negative: every number of a placement takes a sign.
#[test]
fn negative_numbers_are_read() {
    let p = Placement::parse(
        Path::new("p.placement"),
        "TRANSLATE -10 -2.5 -1e3\nOBB-ANGLES SOCS -1 -2 -3  0.5 0.5 0.5  -90 0 -45\n",
    )
    .unwrap();
    let t = p.project_from_scanner.rows.map(|r| r[3]);
    assert_eq!(t, [-10.0, -2.5, -1000.0]);
    let (obb, _) = p.trim.unwrap();
    assert_eq!(obb.center, [-1.0, -2.0, -3.0]);
}
