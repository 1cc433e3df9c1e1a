//! Replays the fuzz targets' committed corpora (`fuzz/seeds/TARGET/`, kept by `fuzz/run-all.sh`:
//! the inputs that reached new code, findings included) and the crafted corpus
//! (`tests/corpus/`) through the fuzz targets' own code (`fuzz/support.rs`), so that a finding
//! stays fixed without cargo fuzz: every input must give points or a clean error, never a panic.

use std::path::{Path, PathBuf};

mod support {
    include!("../../../fuzz/support.rs");
}

/// The fuzz targets and the crafted corpus folders that seed each.
const TARGETS: &[(&str, &[&str])] = &[
    ("las", &["las", "laz"]),
    ("ply", &["ply"]),
    ("pcd", &["pcd"]),
    ("e57", &["e57"]),
    ("dataset", &["myr"]),
];

fn files(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| {
            d.map(|e| e.unwrap().path())
                .filter(|p| p.is_file())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

#[test]
fn fuzz_corpora_replay_without_a_panic() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let seeds = root.join("../../fuzz/seeds");
    let mut failures = Vec::new();
    let mut counts = Vec::new();
    for (target, crafted) in TARGETS {
        let mut inputs = files(&seeds.join(target));
        let from_seeds = inputs.len();
        for c in *crafted {
            inputs.extend(files(&root.join("tests/corpus").join(c)));
        }
        assert!(
            inputs.len() > from_seeds,
            "{target}: no crafted inputs found"
        );
        for input in &inputs {
            let data = std::fs::read(input).unwrap();
            let run = std::panic::catch_unwind(|| match *target {
                "dataset" => support::read_dataset(&data),
                ext => support::read_all(&data, ext),
            });
            if run.is_err() {
                failures.push(input.display().to_string());
            }
        }
        counts.push(format!(
            "{target}: {from_seeds} seeds + {} crafted",
            inputs.len() - from_seeds
        ));
    }
    println!("replayed {}", counts.join(", "));
    assert!(failures.is_empty(), "panicked on:\n{}", failures.join("\n"));
}
