//! Replays the fuzz targets' committed corpora (`fuzz/seeds/TARGET.tar.zst`, kept by
//! `fuzz/run-all.sh`: the inputs that reached new code, findings included; packed, as they are
//! thousands of near-identical files) and the crafted corpus (`tests/corpus/`) through the fuzz
//! targets' own code (`fuzz/support.rs`), so that a finding stays fixed without cargo fuzz: every
//! input must give points or a clean error, never a panic.

use std::path::{Path, PathBuf};

mod support {
    include!("../../../fuzz/support.rs");
}

#[allow(dead_code)]
mod parsers {
    include!("../../../fuzz/parsers.rs");
}

/// The fuzz targets and the crafted corpus folders that seed each.
const TARGETS: &[(&str, &[&str])] = &[
    ("las", &["las", "laz"]),
    ("ply", &["ply"]),
    ("pcd", &["pcd"]),
    ("e57", &["e57"]),
    ("dataset", &["myr"]),
    // The parsers (`fuzz/parsers.rs`): seeds only.
    ("filter", &[]),
    ("shape", &[]),
    ("import", &[]),
    ("query", &[]),
    ("cloud", &[]),
    ("edits", &[]),
];

/// The inputs packed in `fuzz/seeds/TARGET.tar.zst` (none when the target has no packed corpus).
fn packed(path: &Path) -> Vec<(String, Vec<u8>)> {
    let Ok(file) = std::fs::File::open(path) else {
        return Vec::new();
    };
    let mut archive = tar::Archive::new(zstd::Decoder::new(file).expect("zstd stream"));
    let mut out = Vec::new();
    for entry in archive.entries().expect("tar entries") {
        let mut entry = entry.expect("tar entry");
        if !entry.header().entry_type().is_file() {
            continue;
        }
        let name = format!("{}:{}", path.display(), entry.path().unwrap().display());
        let mut data = Vec::new();
        std::io::Read::read_to_end(&mut entry, &mut data).unwrap();
        out.push((name, data));
    }
    out
}

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
        let mut inputs = packed(&seeds.join(format!("{target}.tar.zst")));
        let from_seeds = inputs.len();
        assert!(
            from_seeds > 0,
            "{target}: fuzz/seeds/{target}.tar.zst is missing or empty"
        );
        for c in *crafted {
            for f in files(&root.join("tests/corpus").join(c)) {
                inputs.push((f.display().to_string(), std::fs::read(&f).unwrap()));
            }
        }
        assert!(
            crafted.is_empty() || inputs.len() > from_seeds,
            "{target}: no crafted inputs found"
        );
        for (name, data) in &inputs {
            let run = std::panic::catch_unwind(|| match *target {
                "dataset" => support::read_dataset(data),
                "filter" => parsers::filter(data),
                "shape" => parsers::shape(data),
                "import" => parsers::import(data),
                "edits" => parsers::edits(data),
                "query" => parsers::query(data),
                "cloud" => parsers::cloud(data),
                ext => support::read_all(data, ext),
            });
            if run.is_err() {
                failures.push(name.clone());
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
