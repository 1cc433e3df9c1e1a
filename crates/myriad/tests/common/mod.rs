//! Helpers shared by the tests that run the `myriad` binary.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

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
