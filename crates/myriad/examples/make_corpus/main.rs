//! Writes the corpus of crafted inputs in `crates/myriad/tests/corpus/`: one small file per class
//! of damage and format, and `cases.tsv`, the outcome each command must give for each file (run
//! by `tests/corpus.rs`). Valid files are made first (by `myriad synth`, the e57 crate's writer,
//! `myriad convert`, or by hand for the text formats) and then damaged at the byte or line that
//! the class is about, so the expected error names that byte or line.
//!
//!     cargo run --release -p myriad --example make_corpus
//!
//! The files are committed; run this again after changing it (it replaces the folder). One
//! module per family of formats: `las.rs` (LAS, LAZ), `e57.rs`, `ply_pcd.rs`, `text.rs` (text
//! scans and placements), `dataset.rs` (.myr).

mod dataset;
mod e57;
mod las;
mod ply_pcd;
mod text;

use std::path::{Path, PathBuf};

/// Commands each kind of input is run through.
const INPUT: &[&str] = &["info", "convert"];
const DATASET: &[&str] = &["info", "verify", "extract", "render"];

struct Corpus {
    dir: PathBuf,
    lines: Vec<String>,
}

impl Corpus {
    /// Writes `bytes` as `name` (a path below the corpus folder).
    fn file(&mut self, name: &str, bytes: &[u8]) -> String {
        let p = self.dir.join(name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, bytes).unwrap();
        name.to_string()
    }
    /// Every command in `commands` must fail on `name` with exit code 1 and one error line that
    /// names the file and contains `message`.
    fn fails(&mut self, name: &str, bytes: &[u8], commands: &[&str], message: &str) {
        let f = self.file(name, bytes);
        for c in commands {
            self.lines.push(format!("{f}\t{c}\t1\t{message}"));
        }
    }
    /// Every command in `commands` must succeed on `name`, `info`'s output containing `info`.
    fn reads(&mut self, name: &str, bytes: &[u8], commands: &[&str], info: &str) {
        let f = self.file(name, bytes);
        for c in commands {
            let expect = if *c == "info" { info } else { "" };
            self.lines.push(format!("{f}\t{c}\t0\t{expect}"));
        }
    }
    /// One command's outcome on a file written before.
    fn expect(&mut self, name: &str, command: &str, exit: i32, text: &str) {
        self.lines
            .push(format!("{name}\t{command}\t{exit}\t{text}"));
    }
}

fn put(b: &mut [u8], at: usize, v: &[u8]) {
    b[at..at + v.len()].copy_from_slice(v);
}
fn f64le(v: f64) -> [u8; 8] {
    v.to_le_bytes()
}
fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}
fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().unwrap())
}

/// Deterministic bytes that are no format's structure.
fn garbage(n: usize, seed: u64) -> Vec<u8> {
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 24) as u8
        })
        .collect()
}

fn synth(tmp: &Path, name: &str, points: u64) -> Vec<u8> {
    let p = tmp.join(name);
    let options = myriad_synth::SynthOptions {
        points,
        scene: myriad_synth::SceneKind::City,
        seed: 3,
    };
    myriad_synth::write(&options, &p, true, |_| {}).expect("synth");
    std::fs::read(p).unwrap()
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    // A fixed folder: the dataset records its input's path, so the corpus comes out the same.
    let tmp = std::env::temp_dir().join("myriad-make-corpus");
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).unwrap();
    for sub in [
        "las",
        "laz",
        "e57",
        "ply",
        "pcd",
        "text",
        "placement",
        "myr",
    ] {
        let _ = std::fs::remove_dir_all(root.join(sub));
    }
    let mut c = Corpus {
        dir: root.clone(),
        lines: Vec::new(),
    };
    las::las(&mut c, &tmp);
    las::laz(&mut c, &tmp);
    e57::e57(&mut c, &tmp);
    ply_pcd::ply(&mut c);
    ply_pcd::pcd(&mut c);
    text::text(&mut c);
    text::placement(&mut c);
    dataset::dataset(&mut c, &tmp);
    let mut tsv = String::from(
        "# file\tcommand\texit code\ttext the output must contain (errors: the one stderr line)\n",
    );
    for l in &c.lines {
        tsv.push_str(l);
        tsv.push('\n');
    }
    std::fs::write(root.join("cases.tsv"), tsv).unwrap();
    std::fs::remove_dir_all(&tmp).unwrap();
    let files: std::collections::BTreeSet<&str> = c
        .lines
        .iter()
        .map(|l| l.split('\t').next().unwrap())
        .collect();
    println!(
        "{} files, {} cases in {}",
        files.len(),
        c.lines.len(),
        root.display()
    );
}
