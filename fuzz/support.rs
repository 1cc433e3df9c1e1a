// What each fuzz target does with its input, shared by the targets (`fuzz_targets/`) and by
// `crates/myriad/tests/fuzz_replay.rs`, which replays the committed corpora (`fuzz/seeds/`) in
// `cargo test`, so that a fuzzing finding stays fixed. Included with `include!`; needs the
// `myriad_io`, `myriad_format` and `crc32fast` crates.

/// A file in RAM for this process and thread (replay runs in test threads).
fn scratch_path(ext: &str) -> std::path::PathBuf {
    let dir = if std::path::Path::new("/dev/shm").is_dir() { "/dev/shm" } else { "/tmp" };
    let thread = format!("{:?}", std::thread::current().id()).replace(|c: char| !c.is_ascii_digit(), "");
    std::path::PathBuf::from(format!("{dir}/myriad-fuzz-{}-{thread}.{ext}", std::process::id()))
}

/// Writes `data` to a file in RAM with extension `ext`, opens it with myriad-io and reads every
/// point (capped, so a header that claims billions of points in a tiny file stays cheap).
pub fn read_all(data: &[u8], ext: &str) {
    let path = scratch_path(ext);
    std::fs::write(&path, data).unwrap();
    if let Ok(mut src) = myriad_io::open(&path, &myriad_io::OpenOptions::default()) {
        let mut n = 0usize;
        while let Ok(Some(b)) = src.read_batch(1 << 14) {
            assert!(b.is_consistent());
            n += b.len();
            if n > 2_000_000 {
                break;
            }
        }
    }
    let _ = std::fs::remove_file(&path);
}

fn crc(b: &[u8]) -> u32 {
    crc32fast::hash(b)
}
fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}
fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}
fn range(b: &[u8], offset: u64, len: u32) -> Option<std::ops::Range<usize>> {
    let s = usize::try_from(offset).ok()?;
    let e = s.checked_add(len as usize)?;
    (e <= b.len()).then_some(s..e)
}
fn put(b: &mut [u8], at: usize, v: u32) {
    if let Some(d) = b.get_mut(at..at + 4) {
        d.copy_from_slice(&v.to_le_bytes());
    }
}

/// Fixes a node page's head and column CRCs in place.
fn fix_node_page(b: &mut [u8], r: std::ops::Range<usize>) {
    let p = &mut b[r];
    if p.len() < 36 {
        return;
    }
    let count = p[35] as usize;
    let dir_end = 36 + 16 * count;
    if p.len() < dir_end + 4 {
        return;
    }
    let mut at = dir_end + 4;
    for c in 0..count {
        let d = 36 + 16 * c;
        let len = u32_at(p, d + 4).unwrap() as usize;
        let Some(end) = at.checked_add(len).filter(|&e| e <= p.len()) else { break };
        let v = crc(&p[at..end]);
        put(p, d + 12, v);
        at = end;
    }
    let v = crc(&p[..dir_end]);
    put(p, dir_end, v);
}

/// Fixes the CRCs the root hierarchy page holds (node pages, child pages) in place.
fn fix_root_page(b: &mut [u8], r: std::ops::Range<usize>) {
    let Some(e) = u32_at(b, r.start + 4) else { return };
    let Some(c) = u32_at(b, r.start + 8) else { return };
    let mut at = r.start + 12;
    for k in 0..(e as usize + c as usize).min(100_000) {
        let node = k < e as usize;
        let (Some(off), Some(len)) = (u64_at(b, at + 13), u32_at(b, at + 21)) else { return };
        if at + 29 > r.end {
            return;
        }
        if let Some(pr) = range(b, off, len) {
            if node {
                fix_node_page(b, pr.clone());
            }
            let v = crc(&b[pr]);
            put(b, at + 25, v);
        }
        if node {
            let Some(&levels) = b.get(at + 33) else { return };
            at += 34 + 12 * levels as usize;
            // Format 2: a flags byte, then bounds (48 bytes), contour (120), splats (41, whose
            // page's CRC is fixed too).
            let Some(&flags) = b.get(at) else { return };
            at += 1 + if flags & 1 != 0 { 48 } else { 0 } + if flags & 2 != 0 { 120 } else { 0 };
            if flags & 4 != 0 {
                let (Some(off), Some(len)) = (u64_at(b, at), u32_at(b, at + 8)) else { return };
                if let Some(pr) = range(b, off, len) {
                    let v = crc(&b[pr]);
                    put(b, at + 12, v);
                }
                at += 41;
            }
        } else {
            at += 29;
        }
    }
}

fn fix(mut b: Vec<u8>) -> Vec<u8> {
    if b.len() < 64 {
        return b;
    }
    let len = b.len() as u64;
    b[48..56].copy_from_slice(&len.to_le_bytes());
    if let Some(r) = range(&b, u64_at(&b, 32).unwrap(), u32_at(&b, 40).unwrap()) {
        fix_root_page(&mut b, r.clone());
        let v = crc(&b[r]);
        put(&mut b, 44, v);
    }
    if let Some(r) = range(&b, u64_at(&b, 16).unwrap(), u32_at(&b, 24).unwrap()) {
        let v = crc(&b[r]);
        put(&mut b, 28, v);
    }
    put(&mut b, 12, 0);
    let v = crc(&b[..64]);
    put(&mut b, 12, v);
    b
}

/// The dataset target: any bytes must open as a dataset and read node by node, or give clean
/// errors and damage reports, never a panic. Random bytes rarely pass a CRC-32, so before
/// reading, the checksums the mutated file claims are recomputed (`fix`: header, metadata, root
/// hierarchy page, the node pages it lists and their heads and columns, child page references):
/// the decoders behind the checksums get fuzzed too.
pub fn read_dataset(data: &[u8]) {
    let path = scratch_path("myr");
    std::fs::write(&path, fix(data.to_vec())).unwrap();
    read_dataset_at(&path);
    let _ = std::fs::remove_file(&path);
}

fn read_dataset_at(path: &std::path::Path) {
    let Ok(ds) = myriad_format::Dataset::open(path) else { return };
    if let Some(h) = &ds.meta.las_header {
        let _ = myriad_io::las::header_from_bytes(h);
    }
    let (nodes, _damage) = ds.nodes();
    let mut points = 0usize;
    for n in nodes.iter().take(64) {
        let _ = ds.read_splats(n);
        if let Ok(b) = ds.read_node(n) {
            assert!(b.is_consistent());
            assert_eq!(b.len(), n.points as usize);
            points += b.len();
        }
        if points > 2_000_000 {
            break;
        }
    }
}
