//! Helpers shared by the integration tests of myriad-build.
#![allow(dead_code)]

use myriad_core::PointBatch;
use myriad_io::OpenOptions;
use std::path::{Path, PathBuf};

/// An empty folder of this test process, removed when the test passes (a failed one keeps it,
/// to look at).
pub fn tempdir(name: &str) -> TempDir {
    let d = std::env::temp_dir().join(format!("myriad-build-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    TempDir(d)
}

/// A test's folder ([`tempdir`]).
pub struct TempDir(PathBuf);

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// Every point of a file, read as a user's file is.
pub fn read_all(path: &Path) -> PointBatch {
    let mut src = myriad_io::open(path, &OpenOptions::default()).unwrap();
    let mut all = PointBatch::with_schema(&src.info().schema, 0);
    while let Some(b) = src.read_batch(1 << 16).unwrap() {
        all.append(&b);
    }
    all
}

/// Every point as the bytes of all its fields, sorted: a multiset.
pub fn records(b: &PointBatch) -> Vec<Vec<u8>> {
    let mut rows: Vec<Vec<u8>> = (0..b.len())
        .map(|i| {
            let mut r = Vec::new();
            b.put_row(i, &mut r);
            r
        })
        .collect();
    rows.sort_unstable();
    rows
}

/// A simulated city scan of `points` as `dir/city.las`.
pub fn synth(dir: &Path, points: u64, seed: u64) -> PathBuf {
    let las = dir.join("city.las");
    let opts = myriad_synth::SynthOptions {
        points,
        scene: myriad_synth::SceneKind::City,
        seed,
    };
    myriad_synth::write(&opts, &las, true, |_| {}).unwrap();
    las
}
