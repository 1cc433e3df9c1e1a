//! Nothing the user gave is lost (issue 40): an output that is one of the inputs (however it is
//! spelled, `--force` included) or has another format's extension is refused, a mistyped output
//! folder is not made, an input given twice is refused instead of counted twice, a line of any
//! length cannot take the machine's memory, and `render --full` of a damaged dataset fails.

mod common;
use common::{myriad, s, synth, tempdir};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Exit code 1 with one error line containing `expect`, and no panic.
fn refused(args: &[&str], expect: &str) {
    let r = myriad(args);
    assert_eq!(r.code, 1, "{args:?}: {}", r.stderr);
    let errors: Vec<&str> = r
        .stderr
        .lines()
        .filter(|l| l.starts_with("error:"))
        .collect();
    assert_eq!(errors.len(), 1, "{args:?}: {}", r.stderr);
    assert!(
        errors[0].contains(expect),
        "{args:?}: {expect:?} not in {}",
        errors[0]
    );
    assert!(!r.stderr.contains("panicked"), "{}", r.stderr);
}

#[test]
fn outputs_never_replace_inputs_and_inputs_count_once() {
    let d = tempdir("careless-io");
    let las = synth(&d, "a.las", 20_000);
    let bytes = std::fs::read(&las).unwrap();
    std::fs::create_dir_all(d.join("sub")).unwrap();
    let spelled = d.join("sub").join("..").join("a.las");
    // convert onto its input, as itself or spelled otherwise; a dataset under a LAS name.
    refused(&["convert", s(&las), "-o", s(&las), "--force"], "not .las");
    refused(
        &["convert", s(&las), "-o", s(&spelled), "--force"],
        "not .las",
    );
    refused(&["convert", s(&las), "-o", s(&d.join("x.las"))], "not .las");
    assert!(!d.join("x.las").exists());
    assert_eq!(std::fs::read(&las).unwrap(), bytes, "the input was changed");
    // A folder that does not exist is not made up to the root.
    refused(
        &["convert", s(&las), "-o", s(&d.join("no/such/x.myr"))],
        "does not exist",
    );
    assert!(!d.join("no").exists());
    // The same input twice: refused, not 40,000 points.
    refused(
        &[
            "convert",
            s(&las),
            s(&spelled),
            "-o",
            s(&d.join("twice.myr")),
        ],
        "given twice",
    );
    refused(
        &[
            "plan",
            s(&las),
            s(&las),
            "-o",
            s(&d.join("p.json")),
            "--parts",
            "2",
        ],
        "given twice",
    );
    assert!(!d.join("twice.myr").exists());

    let myr = d.join("a.myr");
    let r = myriad(&["convert", s(&las), "-o", s(&myr)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let dataset = std::fs::read(&myr).unwrap();
    refused(
        &["convert", s(&las), "--append", s(&myr), s(&las)],
        "given twice",
    );
    // render, extract, export, mesh onto the dataset: refused, the dataset as it was.
    refused(&["render", s(&myr), "-o", s(&myr), "--force"], "PNG");
    let png_named = d.join("b.png");
    std::fs::copy(&myr, &png_named).unwrap();
    refused(
        &["render", s(&png_named), "-o", s(&png_named), "--force"],
        "is the input",
    );
    refused(&["extract", s(&myr), "-o", s(&myr), "--force"], "");
    refused(
        &["export", s(&myr), "--to", "potree", "-o", s(&d), "--force"],
        "is the input",
    );
    assert_eq!(
        std::fs::read(&myr).unwrap(),
        dataset,
        "the dataset was changed"
    );
    let r = myriad(&["verify", s(&myr)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
}

/// `info` on `path`, which must fail within 20 s (killed otherwise: a reader that grows one
/// line without end) with one short error line containing `expect`.
fn refused_quickly(path: &Path, expect: &str) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_myriad"))
        .args(["info", s(path)])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t.elapsed() > Duration::from_secs(20) {
            let _ = child.kill();
            panic!("{}: info still reading after 20 s", path.display());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{}: {err}", path.display());
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.len() < 400, "a {}-byte error line", err.len());
    assert!(err.contains(expect), "{expect:?} not in {err}");
    assert!(err.contains(s(path)), "{err}");
}

#[test]
fn a_line_of_any_length_is_refused_with_the_limit() {
    let d = tempdir("careless-lines");
    // A sparse gigabyte of NUL bytes named as text: no line end anywhere.
    let zeros = d.join("zeros.xyz");
    std::fs::File::create(&zeros)
        .unwrap()
        .set_len(1 << 30)
        .unwrap();
    refused_quickly(&zeros, "longer than 65536 bytes");
    // /dev/zero named as text never ends at all.
    let endless = d.join("endless.xyz");
    std::os::unix::fs::symlink("/dev/zero", &endless).unwrap();
    refused_quickly(&endless, "longer than 65536 bytes");
    // Headers of PLY and PCD with a line past the limit.
    let mut ply = b"ply\nformat ascii 1.0\ncomment ".to_vec();
    ply.extend(std::iter::repeat_n(b'x', 100_000));
    ply.extend(b"\nend_header\n");
    std::fs::write(d.join("long.ply"), &ply).unwrap();
    refused_quickly(&d.join("long.ply"), "longer than 65536 bytes");
    let mut pcd = b"# .PCD v0.7\nFIELDS ".to_vec();
    pcd.extend(std::iter::repeat_n(b'x', 100_000));
    std::fs::write(d.join("long.pcd"), &pcd).unwrap();
    refused_quickly(&d.join("long.pcd"), "longer than 65536 bytes");
    // A long bad token is quoted in part.
    let mut text = b"1 2 3\n4 5 ".to_vec();
    text.extend(std::iter::repeat_n(b'y', 10_000));
    text.push(b'\n');
    std::fs::write(d.join("token.xyz"), &text).unwrap();
    let r = myriad(&[
        "convert",
        s(&d.join("token.xyz")),
        "-o",
        s(&d.join("t.myr")),
    ]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(
        r.stderr.contains("line 2") && r.stderr.contains("not a number"),
        "{}",
        r.stderr
    );
    assert!(r.stderr.len() < 400, "{}", r.stderr);
}

#[test]
fn render_full_of_a_damaged_dataset_names_the_damage_and_fails() {
    let d = tempdir("careless-damage");
    let las = synth(&d, "s.las", 100_000);
    let myr = d.join("s.myr");
    let r = myriad(&["convert", s(&las), "-o", s(&myr), "--capacity", "2000"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    // Flip a byte in the middle of three node pages below the root.
    let ds = myriad_format::Dataset::open(&myr).unwrap();
    let (nodes, _) = ds.nodes();
    let hit: Vec<_> = nodes
        .iter()
        .filter(|n| n.key.level >= 2 && n.page.length > 100)
        .take(3)
        .collect();
    assert_eq!(hit.len(), 3);
    let mut bytes = std::fs::read(&myr).unwrap();
    for n in &hit {
        bytes[(n.page.offset + n.page.length as u64 / 2) as usize] ^= 0x5a;
    }
    drop(ds);
    std::fs::write(&myr, &bytes).unwrap();
    let png = d.join("s.png");
    let mut args = common::render_cpu(s(&myr), s(&png), ("160", "120"));
    args.push("--full");
    let r = myriad(&args);
    assert_eq!(r.code, 1, "{}", r.stderr);
    let warnings = r
        .stderr
        .lines()
        .filter(|l| l.starts_with("warning:"))
        .count();
    assert!(warnings >= 3, "{}", r.stderr);
    for n in &hit {
        assert!(
            r.stderr.contains(&format!("node {}", n.key)),
            "{} not named: {}",
            n.key,
            r.stderr
        );
    }
    assert!(r.stderr.contains("error: 3 damaged pages"), "{}", r.stderr);
}

/// Numbers a user gives that reached allocations, loop bounds, casts and saved plans unchecked
/// (issue 67 item 3, found by a search of the code): each a one-line error now, or a result,
/// never a panic, an abort or terabytes asked for.
#[test]
fn numbers_out_of_range_are_refused_in_one_line() {
    let d = tempdir("careless-numbers");
    let las = synth(&d, "n.las", 20_000);
    let myr = d.join("n.myr");
    let r = myriad(&["convert", s(&las), "-o", s(&myr)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let out = |n: &str| d.join(n).to_string_lossy().to_string();
    let (plan, csv, x, y) = (out("p.json"), out("a.csv"), out("x.las"), out("y.myr"));
    let cases: Vec<(Vec<&str>, &str)> = vec![
        // A corridor and a polygon of 1e300 (their edge index asked for terabytes).
        (
            vec![
                "profile",
                s(&myr),
                "--line",
                "0,0,1e300,0",
                "--width",
                "2e12",
                "-o",
                &csv,
            ],
            "",
        ),
        (
            vec!["volume", s(&myr), "--polygon", "0,0,1e300,0,0,2e12"],
            "",
        ),
        (
            vec!["plan", s(&las), "-o", &plan, "--parts", "10000000000"],
            "--parts 10000000000",
        ),
        (
            vec!["plan", s(&las), "-o", &plan, "--precision", "nan"],
            "--precision",
        ),
        (
            vec![
                "convert",
                s(&las),
                "-o",
                &y,
                "--capacity",
                "10000000000000000",
            ],
            "--capacity",
        ),
        (
            vec!["convert", s(&las), "-o", &y, "--memory", "6000000TB"],
            "--memory",
        ),
        (
            vec!["convert", s(&las), "-o", &y, "--threads", "1000000"],
            "threads",
        ),
        (
            vec!["extract", s(&myr), "-o", &x, "--box", "nan,0,0,1,1,1"],
            "finite",
        ),
        (
            vec![
                "synth",
                "--scene",
                "stockpiles",
                "--points",
                "1e15",
                "-o",
                &x,
            ],
            "at most 10G",
        ),
        (
            vec!["serve", s(&myr), "--max-connections", "3000000000000000000"],
            "max-connections",
        ),
    ];
    for (args, says) in cases {
        let r = myriad(&args);
        assert!(!r.stderr.contains("panicked"), "{args:?}: {}", r.stderr);
        if says.is_empty() {
            // A result, or an error of one line.
            assert!(
                r.code == 0 || r.code == 1,
                "{args:?}: {} {}",
                r.code,
                r.stderr
            );
            if r.code == 1 {
                assert_eq!(r.stderr.trim().lines().count(), 1, "{args:?}: {}", r.stderr);
            }
        } else {
            assert_ne!(r.code, 0, "{args:?} should fail: {}", r.stdout);
            assert!(
                r.stderr.contains(says),
                "{args:?}: {says:?} not in {}",
                r.stderr
            );
        }
    }
    assert!(!Path::new(&x).exists() && !Path::new(&y).exists() && !Path::new(&plan).exists());
    let _ = std::fs::remove_dir_all(&d);
}
