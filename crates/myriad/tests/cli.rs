//! The `myriad` binary as a user runs it: exit codes, one-line errors naming the file and the
//! byte offset or line, and the synth -> info path. Needs no shared data.

mod common;
use common::{myriad, s, synth, tempdir};
use std::path::{Path, PathBuf};
use std::process::Command;

/// `info` on `path` must fail with exit code 1 and one line `error: <path>: <where>...`
/// containing `expect`.
fn bad(path: &Path, expect: &str) {
    let r = myriad(&["info", s(path)]);
    assert_eq!(
        r.code,
        1,
        "{}: exit code; stderr: {}",
        path.display(),
        r.stderr
    );
    assert!(!r.stderr.contains("panicked"), "panic: {}", r.stderr);
    let lines: Vec<&str> = r
        .stderr
        .lines()
        .filter(|l| !l.starts_with("warning:"))
        .collect();
    assert_eq!(lines.len(), 1, "one error line expected: {:?}", r.stderr);
    let line = lines[0];
    assert!(
        line.starts_with(&format!("error: {}", path.display())),
        "names the file: {line}"
    );
    assert!(line.contains(expect), "expected {expect:?} in {line:?}");
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn las_and_laz_faults() {
    let d = tempdir("las");
    let las = std::fs::read(synth(&d, "ok.las", 3000)).unwrap();
    let laz = std::fs::read(synth(&d, "ok.laz", 50_000)).unwrap();

    bad(
        &write(&d, "short-header.las", &las[..100]),
        "byte 100: file ends inside the 227-byte LAS header",
    );
    bad(
        &write(&d, "truncated.las", &las[..las.len() - 1000]),
        "of the 3000 point records its header declares",
    );
    let mut magic = las.clone();
    magic[..4].copy_from_slice(b"LASX");
    bad(
        &write(&d, "magic.las", &magic),
        "byte 0: wrong magic number",
    );
    // Header counts that lie: the legacy count (byte 107) and the LAS 1.4 count (byte 247).
    let mut lie = las.clone();
    lie[107..111].copy_from_slice(&5000u32.to_le_bytes());
    lie[247..255].copy_from_slice(&5000u64.to_le_bytes());
    bad(
        &write(&d, "lie.las", &lie),
        "file ends after 3000 of the 5000 point records",
    );
    // Cut in half: the chunk table at the end is gone.
    bad(
        &write(&d, "truncated.laz", &laz[..laz.len() / 2]),
        "LAZ chunk table offset",
    );
    let mut lie = laz.clone();
    lie[107..111].copy_from_slice(&60_000u32.to_le_bytes());
    lie[247..255].copy_from_slice(&60_000u64.to_le_bytes());
    bad(
        &write(&d, "lie.laz", &lie),
        "the last LAZ chunk (0) does not hold the 60000 points the header's count of 60000 leaves for it",
    );
    // A chunk count that would make the laz crate allocate tens of gigabytes (found by fuzzing).
    let mut chunks = laz.clone();
    let data = u32::from_le_bytes(laz[96..100].try_into().unwrap()) as usize;
    let table = i64::from_le_bytes(laz[data..data + 8].try_into().unwrap()) as usize;
    chunks[table + 4..table + 8].copy_from_slice(&0x8480_0000u32.to_le_bytes());
    bad(
        &write(&d, "chunks.laz", &chunks),
        &format!("byte {}: LAZ chunk table declares", table + 4),
    );
    // An EVLR whose u64 length runs past the file (found by fuzzing: the las crate would try to
    // allocate it). Synth writes LAS 1.4, whose header holds the EVLR offset (235) and count (243).
    let mut evlr = las.clone();
    evlr[235..243].copy_from_slice(&1000u64.to_le_bytes());
    evlr[243..247].copy_from_slice(&1u32.to_le_bytes());
    evlr[1020..1028].copy_from_slice(&(u64::MAX - 5).to_le_bytes());
    bad(&write(&d, "evlr.las", &evlr), "byte 1020: EVLR length");
    // A laszip VLR whose items describe 0-byte records: laz divides by that (found by fuzzing).
    // Its data: compressor, coder, version, options, chunk size, special EVLRs (32 bytes), then the
    // u16 item count.
    let mut items = laz.clone();
    let vlr = laz
        .windows(14)
        .position(|w| w == b"laszip encoded")
        .expect("laszip VLR")
        - 2;
    items[vlr + 54 + 32..vlr + 54 + 34].copy_from_slice(&0u16.to_le_bytes());
    bad(
        &write(&d, "items.laz", &items),
        "byte 105: laszip VLR describes 0-byte records",
    );
    let mut offset = las.clone();
    offset[96..100].copy_from_slice(&u32::MAX.to_le_bytes());
    bad(
        &write(&d, "offset.las", &offset),
        "byte 96: offset to point data",
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn text_formats_name_the_line() {
    let d = tempdir("text");
    bad(
        &write(&d, "nan.xyz", b"1 2 3\n4 5 6\n7 8 abc\n"),
        "line 3: not a number: \"abc\"",
    );
    bad(
        &write(&d, "short.csv", b"x,y,z,intensity\n1,2,3,4\n5,6\n"),
        "line 3: expected 4 values",
    );
    bad(
        &write(&d, "binary.txt", &[0xFF, 0xFE, 0x00, 0x41, b'\n']),
        "line 1",
    );
    bad(&write(&d, "ascii.ply", b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n4 five 6\n"), "line 9: not a number: \"five\"");
    bad(&write(&d, "lie.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n4 5 6\n"), "line 10: file ends after 2 of 3 vertices");
    bad(
        &write(
            &d,
            "noheader.ply",
            b"ply\nformat ascii 1.0\nelement vertex 3\n",
        ),
        "file ends before \"end_header\"",
    );
    bad(&write(&d, "bad.pcd", b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n1 2 3\n4 x 6\n"), "line 11: not a number: \"x\"");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn binary_formats_name_the_byte() {
    let d = tempdir("bin");
    let mut ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
    let header_len = ply.len();
    ply.extend_from_slice(&[0u8; 12 * 3]);
    bad(
        &write(&d, "lie.ply", &ply),
        &format!("byte {}: file ends before the 4 vertices", header_len + 36),
    );
    bad(
        &write(&d, "magic.ply", b"plx\nformat ascii 1.0\n"),
        "byte 0: wrong magic number",
    );
    let mut pcd = b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 5\nHEIGHT 1\nPOINTS 5\nDATA binary\n".to_vec();
    pcd.extend_from_slice(&[0u8; 12 * 2]);
    bad(&write(&d, "lie.pcd", &pcd), "file ends before the 5 points");
    let mut pcdc = b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary_compressed\n".to_vec();
    let at = pcdc.len();
    pcdc.extend_from_slice(&5u32.to_le_bytes());
    pcdc.extend_from_slice(&12u32.to_le_bytes());
    pcdc.extend_from_slice(&[0xE0, 0xFF, 0xFF, 0x00, 0x00]); // a back reference before any output
    bad(
        &write(&d, "lzf.pcd", &pcdc),
        &format!("byte {}: corrupt LZF data", at + 8),
    );
    // A field of COUNT 0 occupies no bytes (found by fuzzing).
    bad(
        &write(&d, "count0.pcd", b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 0\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary\n12345678"),
        "line 5: a field has COUNT 0",
    );
    bad(
        &write(&d, "garbage.pcd", b"\x00\x01\x02garbage\n"),
        "byte 0: wrong magic number",
    );
    bad(
        &write(&d, "magic.e57", b"ASTM-E58 and then nothing of use"),
        "byte 0: wrong magic number",
    );
    let mut e57 = b"ASTM-E57".to_vec();
    e57.extend_from_slice(&[1, 0, 0, 0, 0, 0, 0, 0]);
    e57.extend_from_slice(&1_000_000u64.to_le_bytes());
    e57.resize(48, 0);
    bad(
        &write(&d, "truncated.e57", &e57),
        "byte 48: file is truncated",
    );
    bad(
        &write(&d, "short.e57", b"ASTM-E57\x01\x00"),
        "byte 10: file ends inside the 48-byte E57 header",
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn paths_that_are_not_point_clouds() {
    let d = tempdir("paths");
    let r = myriad(&["info", s(&d)]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("is a directory"), "{}", r.stderr);
    let odd = write(&d, "scan.abc", b"1 2 3\n");
    let r = myriad(&["info", s(&odd)]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("unknown extension \".abc\""),
        "{}",
        r.stderr
    );
    let r = myriad(&["info", s(&d.join("missing.las"))]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.starts_with("error: ") && r.stderr.contains("missing.las"),
        "{}",
        r.stderr
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn usage_errors_exit_2() {
    assert_eq!(myriad(&[]).code, 2);
    assert_eq!(myriad(&["info"]).code, 2);
    assert_eq!(
        myriad(&["synth", "-o", "x.las", "--points", "many"]).code,
        2
    );
    assert_eq!(myriad(&["frobnicate"]).code, 2);
    let help = myriad(&["synth", "--help"]);
    assert_eq!(help.code, 0);
    assert!(help.stdout.contains("--points"));
}

/// `synth --point-format N` writes LAS/LAZ in each point format without waveforms (issue 43's
/// corpus), every point read back; others, and a format for E57, are one-line errors.
#[test]
fn synth_writes_each_point_format() {
    let d = tempdir("synth-formats");
    let synth = |p: &std::path::Path, format: &str| {
        myriad(&[
            "synth",
            "-o",
            s(p),
            "--points",
            "5000",
            "--point-format",
            format,
        ])
    };
    for format in ["0", "1", "2", "3", "6", "7", "8"] {
        let p = d.join(format!("pf{format}.laz"));
        let r = synth(&p, format);
        assert_eq!(r.code, 0, "{format}: {}", r.stderr);
        let r = myriad(&["info", "--json", s(&p)]);
        let v: serde_json::Value = serde_json::from_str(r.stdout.trim()).unwrap();
        assert_eq!(v["points"], 5000, "{format}");
        assert!(
            v["version"]
                .as_str()
                .unwrap()
                .ends_with(&format!("point format {format}")),
            "{v}"
        );
    }
    let p = d.join("pf4.laz");
    let r = synth(&p, "4");
    assert_eq!(r.code, 1);
    assert_eq!(
        r.stderr.trim(),
        "error: point format 4: synth writes formats 0-3 and 6-8"
    );
    assert!(!p.exists());
    let e = d.join("x.e57");
    let r = myriad(&[
        "synth",
        "-o",
        s(&e),
        "--points",
        "5000",
        "--scene",
        "indoor",
        "--point-format",
        "6",
    ]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert_eq!(r.stderr.trim().lines().count(), 1, "{}", r.stderr);
}

#[test]
fn synth_then_info_json() {
    let d = tempdir("synth");
    for (name, scene) in [
        ("city.laz", "city"),
        ("terrain.las", "terrain"),
        ("indoor.laz", "indoor"),
    ] {
        let p = d.join(name);
        let r = myriad(&["synth", "-o", s(&p), "--points", "20000", "--scene", scene]);
        assert_eq!(r.code, 0, "{}", r.stderr);
        let r = myriad(&["info", "--json", s(&p)]);
        assert_eq!(r.code, 0, "{}", r.stderr);
        let v: serde_json::Value = serde_json::from_str(r.stdout.trim()).unwrap();
        assert_eq!(v["points"], 20000, "{name}");
        assert_eq!(
            v["format"],
            if name.ends_with("laz") { "LAZ" } else { "LAS" }
        );
        // The header states the bounds of the coordinates as stored (rounded to the scale).
        assert_eq!(v["bounds"], v["header_bounds"], "{name}: header bounds");
        let min = v["bounds"]["min"].as_array().unwrap();
        let max = v["bounds"]["max"].as_array().unwrap();
        for a in 0..3 {
            assert!(
                min[a].as_f64().unwrap() < max[a].as_f64().unwrap(),
                "{name}: flat bounds"
            );
        }
        assert!(
            v["crs"].as_str().unwrap().contains("UTM zone 33N"),
            "{name}: crs {}",
            v["crs"]
        );
        // What the CRS names: its name, code, kind and units.
        let c = &v["crs_info"];
        assert_eq!(
            (
                c["name"].as_str(),
                c["epsg"].as_u64(),
                c["kind"].as_str(),
                c["units"].as_str()
            ),
            (
                Some("WGS 84 / UTM zone 33N"),
                Some(32633),
                Some("projected"),
                Some("m")
            ),
            "{name}: {c}"
        );
        let attrs: Vec<&str> = v["attributes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_str().unwrap())
            .collect();
        for a in [
            "x",
            "intensity",
            "classification",
            "gps_time",
            "rgb",
            "return_number",
        ] {
            assert!(attrs.contains(&a), "{name}: missing {a}");
        }
    }
    // An existing output is not replaced without --force, and is left as it was.
    let p = d.join("city.laz");
    let before = std::fs::read(&p).unwrap();
    let r = myriad(&["synth", "-o", s(&p), "--points", "10"]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("--force"), "{}", r.stderr);
    assert_eq!(std::fs::read(&p).unwrap(), before);
    let r = myriad(&["synth", "-o", s(&p), "--points", "10", "--force"]);
    assert_eq!(r.code, 0);
    let r = myriad(&["synth", "-o", s(&d.join("x.ply")), "--points", "10"]);
    assert_eq!(r.code, 1);
    // Nothing but the outputs is left in the folder (no temporary files).
    let mut names: Vec<String> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["city.laz", "indoor.laz", "terrain.las"]);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn info_applies_sidecar_placements() {
    let d = tempdir("placement");
    let scan = write(&d, "scan.xyz", b"0 0 0\n1 0 0\n5 0 0\n");
    write(
        &d,
        "scan.xyz.placement",
        b"TRANSLATE 1000 0 0\nOBB-ANGLES SOCS 0 0 0 2 2 2 0 0 0\n",
    );
    let r = myriad(&["info", "--json", s(&scan)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let v: serde_json::Value = serde_json::from_str(r.stdout.trim()).unwrap();
    assert_eq!(v["points"], 2);
    assert_eq!(v["trimmed"], 1);
    assert_eq!(v["bounds"]["min"][0], 1000.0);
    assert!(
        v["placement"]
            .as_str()
            .unwrap()
            .ends_with("scan.xyz.placement")
    );
    let r = myriad(&["info", "--json", "--no-placement", s(&scan)]);
    let v: serde_json::Value = serde_json::from_str(r.stdout.trim()).unwrap();
    assert_eq!(
        (v["points"].as_u64(), v["trimmed"].as_u64()),
        (Some(3), Some(0))
    );
    let bad_placement = write(&d, "bad.placement", b"TRANSLATE 1 2 3\nROTATE-DEG 1 2\n");
    let r = myriad(&["info", "--placement", s(&bad_placement), s(&scan)]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr
            .contains("bad.placement: line 2: ROTATE-DEG takes 3 numbers"),
        "{}",
        r.stderr
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn convert_info_verify_extract() {
    let d = tempdir("convert");
    let las = synth(&d, "c.las", 300_000);
    let out = d.join("c.myr");
    let r = myriad(&["convert", s(&las), "-o", s(&out), "--memory", "512MB"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    for want in ["300,000", "bytes per point", "points/s"] {
        assert!(
            r.stdout.contains(want),
            "summary lacks {want}: {}",
            r.stdout
        );
    }
    let r = myriad(&["info", "--json", s(&out)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let v: serde_json::Value = serde_json::from_str(r.stdout.trim()).unwrap();
    assert_eq!(v["points"], 300_000);
    assert_eq!(v["structure"], "nested-octree");
    let levels = v["levels"].as_array().unwrap();
    let per_level: u64 = levels.iter().map(|l| l["points"].as_u64().unwrap()).sum();
    assert_eq!(per_level, 300_000);
    assert_eq!(levels[0]["nodes"], 1);
    assert!(v["bytes_per_point"].as_f64().unwrap() < 30.0);
    let r = myriad(&["info", s(&out)]);
    assert!(r.stdout.contains("level") && r.stdout.contains("nested-octree"));
    let r = myriad(&["verify", s(&out)]);
    assert_eq!(r.code, 0, "{}{}", r.stdout, r.stderr);
    assert!(r.stdout.contains("ok"));
    let back = d.join("back.laz");
    let r = myriad(&[
        "extract",
        s(&out),
        "-o",
        s(&back),
        "--box=-1e9,-1e9,-1e9,1e9,1e9,1e9",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let r = myriad(&["info", "--json", s(&back)]);
    let v: serde_json::Value = serde_json::from_str(r.stdout.trim()).unwrap();
    assert_eq!(v["points"], 300_000);

    // Usage errors and bad values.
    let r = myriad(&["convert", s(&las), "-o", s(&out)]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("--force"), "{}", r.stderr);
    let r = myriad(&[
        "convert",
        s(&las),
        "-o",
        s(&out),
        "--force",
        "--memory",
        "lots",
    ]);
    assert_eq!(r.code, 2, "{}", r.stderr);
    let r = myriad(&[
        "convert",
        s(&las),
        "-o",
        s(&out),
        "--force",
        "--memory",
        "10MB",
    ]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    let r = myriad(&[
        "extract",
        s(&out),
        "-o",
        s(&back),
        "--force",
        "--box",
        "1,2,3",
    ]);
    assert_eq!(r.code, 2, "{}", r.stderr);

    // A bad input names the file and the byte; nothing is written.
    let junk = write(&d, "junk.las", b"LASF but not really a header at all");
    let o2 = d.join("j.myr");
    let r = myriad(&["convert", s(&junk), "-o", s(&o2)]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr
            .starts_with(&format!("error: {}: byte", junk.display())),
        "{}",
        r.stderr
    );
    assert!(!o2.exists());

    // A flipped byte in a node page: verify names the node and exits 1; extract reports it
    // and exits 1 after writing the rest.
    let mut bytes = std::fs::read(&out).unwrap();
    bytes[64 + 200] ^= 0x55;
    std::fs::write(&out, &bytes).unwrap();
    let r = myriad(&["verify", s(&out)]);
    assert_eq!(r.code, 1, "{}", r.stdout);
    assert!(
        r.stdout.contains("damaged: ") && r.stdout.contains("node "),
        "{}",
        r.stdout
    );
    let r = myriad(&["extract", s(&out), "-o", s(&back), "--force"]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("warning: ") && r.stderr.contains("node "),
        "{}",
        r.stderr
    );
    assert!(!r.stderr.contains("panicked"));
    // Not a dataset.
    let r = myriad(&["verify", s(&las)]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("byte 0"), "{}", r.stderr);
}

#[test]
fn a_killed_build_leaves_nothing_that_opens() {
    let d = tempdir("kill");
    let las = synth(&d, "k.las", 1_500_000);
    let out = d.join("k.myr");
    // Kill at moments spread over the build (reading, building, merging, writing).
    for delay_ms in [30u64, 150, 400, 700, 1000, 1400, 2000] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_myriad"))
            .args([
                "convert",
                s(&las),
                "-o",
                s(&out),
                "--force",
                "--memory",
                "300MB",
            ])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        let killed = child.kill().is_ok();
        let status = child.wait().unwrap();
        if killed && !status.success() {
            assert!(
                !out.exists(),
                "killed at {delay_ms} ms, yet {} exists",
                out.display()
            );
        }
        // Whatever was left (temporary files) does not open as a dataset.
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p != las && p.is_file() && p != out {
                let r = myriad(&["info", s(&p)]);
                assert_ne!(
                    r.code,
                    0,
                    "{} opens after a kill at {delay_ms} ms",
                    p.display()
                );
            }
        }
        let _ = std::fs::remove_file(&out);
    }
    // The next build clears what the killed ones left, and succeeds.
    let r = myriad(&["convert", s(&las), "-o", s(&out)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let left: Vec<String> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
    let r = myriad(&["verify", s(&out)]);
    assert_eq!(r.code, 0);
}

#[test]
fn render_a_converted_scan_to_png() {
    let d = tempdir("render");
    let las = synth(&d, "r.las", 200_000);
    let out = d.join("r.myr");
    assert_eq!(myriad(&["convert", s(&las), "-o", s(&out)]).code, 0);
    let png_path = d.join("r.png");
    let r = myriad(&[
        "render",
        s(&out),
        "-o",
        s(&png_path),
        "--width",
        "320",
        "--height",
        "200",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        r.stdout.contains("points in") && r.stdout.contains("frame"),
        "{}",
        r.stdout
    );
    // Positions quantized per node: 8 to 16 bytes a point with colour (f32 took 16), fewer read.
    let number_before = |what: &str| -> f64 {
        let at = r.stdout.find(what).expect(what);
        let head = r.stdout[..at].trim_end();
        head[head.rfind([' ', '(']).unwrap() + 1..].parse().unwrap()
    };
    let (stored, read) = (
        number_before(" bytes a point"),
        number_before(" read per drawn point"),
    );
    assert!((8.0..16.0).contains(&stored), "{}", r.stdout);
    assert!((8.0..=16.0).contains(&read), "{}", r.stdout);
    // A PNG of the asked size, and the scan is in it: a good part of the pixels are not black.
    let bytes = std::fs::read(&png_path).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    assert_eq!((w, h), (320, 200));
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut img = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut img).unwrap();
    let lit = img.chunks_exact(4).filter(|p| p[..3] != [0, 0, 0]).count();
    assert!(lit > 320 * 200 / 20, "{lit} pixels show the scan");
    // An existing image is not replaced without --force; bad values are refused.
    let r = myriad(&["render", s(&out), "-o", s(&png_path)]);
    assert_eq!(r.code, 1);
    let r = myriad(&[
        "render",
        s(&out),
        "-o",
        s(&png_path),
        "--force",
        "--camera",
        "1,2,3",
    ]);
    assert_eq!(r.code, 2);
    for bad in [
        &["--shape", "hexagon"][..],
        &["--occlusion", "sometimes"],
        &["--point-size", "adaptive:0"],
        &["--view", "sideways"],
        &["--raster", "rays"],
    ] {
        let mut args = vec!["render", s(&out), "-o", s(&png_path), "--force"];
        args.extend_from_slice(bad);
        assert_eq!(myriad(&args).code, 2, "{bad:?}");
    }
    let r = myriad(&[
        "render",
        s(&out),
        "-o",
        s(&png_path),
        "--force",
        "--camera",
        "5,5,5,5,5,5",
    ]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("the eye and the target"), "{}", r.stderr);

    // Every option a user has: both paths, shapes, eye-dome lighting, the standard views, a
    // colour scheme; each image shows the scan.
    let decode = |path: &std::path::Path| {
        let decoder =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut img = vec![0; reader.output_buffer_size().unwrap()];
        reader.next_frame(&mut img).unwrap();
        img
    };
    // The GPU paths need an adapter (lavapipe in CI); the CPU path runs anywhere.
    let probe = myriad(&[
        "render",
        s(&out),
        "-o",
        s(&png_path),
        "--force",
        "--raster",
        "quads",
    ]);
    let gpu = probe.code == 0;
    if !gpu {
        assert!(probe.stderr.contains("no GPU adapter"), "{}", probe.stderr);
        eprintln!("SKIPPED: render --raster quads/compute (no GPU adapter)");
    }
    for extra in [
        &["--raster", "cpu"][..],
        &["--raster", if gpu { "quads" } else { "cpu" }],
        &["--raster", if gpu { "compute" } else { "cpu" }],
        &["--shape", "round", "--edl"],
        &["--occlusion", "queries", "--raster", "cpu"],
        &[
            "--occlusion",
            "queries",
            "--raster",
            if gpu { "compute" } else { "cpu" },
        ],
        &["--shape", "paraboloid", "--point-size", "fixed:3"],
        &["--view", "top", "--color", "classification"],
        &[
            "--view",
            "close",
            "--point-size",
            "adaptive:1",
            "--budget",
            "50k",
        ],
    ] {
        let mut args = vec![
            "render",
            s(&out),
            "-o",
            s(&png_path),
            "--force",
            "--width",
            "320",
            "--height",
            "200",
        ];
        args.extend_from_slice(extra);
        let r = myriad(&args);
        assert_eq!(r.code, 0, "{extra:?}: {}", r.stderr);
        let img = decode(&png_path);
        let lit = img.chunks_exact(4).filter(|p| p[..3] != [0, 0, 0]).count();
        assert!(
            lit > 320 * 200 / 20,
            "{extra:?}: {lit} pixels show the scan"
        );
    }

    // Post passes: one uniform grey shows nothing of the shape without shading, and its shape in
    // many shades with it; an unknown pass is a usage error naming it.
    let greys = |passes: &str| {
        let r = myriad(&[
            "render",
            s(&out),
            "-o",
            s(&png_path),
            "--force",
            "--width",
            "320",
            "--height",
            "200",
            "--raster",
            "cpu",
            "--color",
            "uniform",
            "--passes",
            passes,
        ]);
        assert_eq!(r.code, 0, "{passes}: {}", r.stderr);
        let img = decode(&png_path);
        let mut levels: Vec<u8> = img
            .chunks_exact(4)
            .filter(|p| p[..3] != [0, 0, 0])
            .map(|p| p[0])
            .collect();
        levels.sort();
        levels.dedup();
        levels.len()
    };
    assert_eq!(greys("none"), 1, "one colour without shading");
    assert!(greys("shade") > 20, "shading shows the shape");
    let r = myriad(&[
        "render",
        s(&out),
        "-o",
        s(&png_path),
        "--passes",
        "fill,glow",
    ]);
    assert_eq!(r.code, 2);
    assert!(r.stderr.contains("glow"), "{}", r.stderr);
}

/// `convert --structure` builds each hierarchy; each verifies, gives every point back, shows in
/// `info`, and renders an image of the scan (mwkd's with splats).
#[test]
fn every_structure_converts_verifies_extracts_and_renders() {
    let d = tempdir("structures");
    let las = synth(&d, "c.las", 150_000);
    for structure in ["octree", "layered", "kd", "mwkd"] {
        let out = d.join(format!("{structure}.myr"));
        let mut args = vec![
            "convert",
            s(&las),
            "-o",
            s(&out),
            "--structure",
            structure,
            "--capacity",
            "8192",
        ];
        // Goswami et al. 2010's parameters, for mwkd alone: one line and nothing written for the
        // others.
        let tuned = ["--fanout", "4", "--grid", "35"];
        if structure != "mwkd" {
            let r = myriad(&[&args[..], &tuned[..]].concat());
            assert_eq!(r.code, 1, "{structure}: {}", r.stderr);
            assert_eq!(
                r.stderr.trim(),
                "error: --fanout and --grid are for --structure mwkd"
            );
            assert!(!out.exists());
        } else {
            args.extend(tuned);
        }
        let r = myriad(&args);
        assert_eq!(r.code, 0, "{structure}: {}", r.stderr);
        let r = myriad(&["info", s(&out)]);
        let name = if structure == "octree" {
            "nested-octree"
        } else {
            structure
        };
        if structure == "mwkd" {
            assert!(
                r.stdout.contains("\"fanout\":4,\"grid\":35"),
                "{}",
                r.stdout
            );
        }
        assert!(
            r.stdout.contains(&format!("structure   {name}")),
            "{structure}: {}",
            r.stdout
        );
        let r = myriad(&["verify", s(&out)]);
        assert_eq!(r.code, 0, "{structure}: {}", r.stderr);
        assert!(r.stdout.contains("150,000 points"), "{}", r.stdout);
        let back = d.join(format!("{structure}.las"));
        let r = myriad(&["extract", s(&out), "-o", s(&back)]);
        assert_eq!(r.code, 0, "{structure}: {}", r.stderr);
        // Every original point, no aggregate (the record-by-record check is in myriad-build's
        // tests): the LAS header counts the input's points.
        let r = myriad(&["info", s(&back)]);
        assert!(r.stdout.contains("150,000"), "{structure}: {}", r.stdout);
        let png_path = d.join(format!("{structure}.png"));
        let r = myriad(&[
            "render",
            s(&out),
            "-o",
            s(&png_path),
            "--width",
            "240",
            "--height",
            "160",
            "--raster",
            "cpu",
        ]);
        assert_eq!(r.code, 0, "{structure}: {}", r.stderr);
        let decoder = png::Decoder::new(std::io::Cursor::new(std::fs::read(&png_path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut img = vec![0; reader.output_buffer_size().unwrap()];
        reader.next_frame(&mut img).unwrap();
        let lit = img.chunks_exact(4).filter(|p| p[..3] != [0, 0, 0]).count();
        assert!(
            lit > 240 * 160 / 10,
            "{structure}: {lit} pixels show the scan"
        );
    }
    let r = myriad(&[
        "convert",
        s(&las),
        "-o",
        s(&d.join("x.myr")),
        "--structure",
        "bsp",
    ]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("unknown structure"), "{}", r.stderr);
    assert!(!d.join("x.myr").exists());
}
