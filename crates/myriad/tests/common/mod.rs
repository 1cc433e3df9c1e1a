//! Helpers shared by the tests that run the `myriad` binary.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

pub struct Run {
    pub code: i32,
    pub stdout: String,
    pub stderr: String,
}

/// Runs the binary with `args` to the end.
pub fn myriad(args: &[&str]) -> Run {
    let out = Command::new(env!("CARGO_BIN_EXE_myriad"))
        .args(args)
        .output()
        .expect("run myriad");
    Run {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// Every record of a LAS/LAZ file as comparable integers: position in thousandths (the synthetic
/// scans' scale), GPS time bits, intensity, classification, returns, colour.
pub fn records(path: &Path) -> Vec<Vec<i64>> {
    let mut src = myriad_io::open(path, &myriad_io::OpenOptions::default()).unwrap();
    let mut out = Vec::new();
    while let Some(b) = src.read_batch(myriad_io::DEFAULT_BATCH).unwrap() {
        for i in 0..b.len() {
            let p = b.positions[i];
            let rgb = b.rgb.as_ref().unwrap()[i];
            out.push(vec![
                (p[0] * 1000.0).round() as i64,
                (p[1] * 1000.0).round() as i64,
                (p[2] * 1000.0).round() as i64,
                b.gps_time.as_ref().unwrap()[i].to_bits() as i64,
                b.intensity.as_ref().unwrap()[i] as i64,
                b.classification.as_ref().unwrap()[i] as i64,
                b.return_number.as_ref().unwrap()[i] as i64,
                rgb[0] as i64,
                rgb[1] as i64,
                rgb[2] as i64,
            ]);
        }
    }
    out.sort();
    out
}

/// Runs the binary, which must succeed; its output.
pub fn ok(args: &[&str]) -> String {
    let r = myriad(args);
    assert_eq!(r.code, 0, "{args:?}: {}", r.stderr);
    r.stdout
}

/// An empty folder of this test process.
pub fn tempdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("myriad-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

pub fn synth(dir: &Path, name: &str, points: u64) -> PathBuf {
    let p = dir.join(name);
    let r = myriad(&[
        "synth",
        "-o",
        s(&p),
        "--points",
        &points.to_string(),
        "--seed",
        "5",
    ]);
    assert_eq!(r.code, 0, "synth failed: {}", r.stderr);
    p
}

/// `myriad serve` on a free port; its base URL. Killed when dropped.
pub struct Serving {
    child: Child,
    pub base: String,
}

impl Drop for Serving {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `myriad serve ARGS --bind 127.0.0.1:0`, its stderr going to `stderr`.
pub fn serve(args: &[&str], stderr: Stdio) -> Serving {
    let mut child = Command::new(env!("CARGO_BIN_EXE_myriad"))
        .arg("serve")
        .args(args)
        .args(["--bind", "127.0.0.1:0"])
        .stdout(Stdio::piped())
        .stderr(stderr)
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let first = lines.next().expect("serve prints its address").unwrap();
    let base = first
        .split(" on ")
        .nth(1)
        .expect("serving N files on URL")
        .trim_end_matches('/')
        .to_string();
    // Keep reading its output so that it never blocks on a full pipe.
    std::thread::spawn(move || for _ in lines {});
    Serving { child, base }
}
