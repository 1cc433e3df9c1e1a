//! Distribution: nothing lost or duplicated, chunks within their cells and under the size limit,
//! inputs of different formats merged, spill files removed.

use myriad_build::distribute::{DistributeOptions, distribute};
use myriad_core::{Attribute, PointBatch, Schema};
use myriad_io::las::{LasSink, LasWriteOptions};
use myriad_io::{OpenOptions, scan};
use std::path::{Path, PathBuf};

fn tempdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("myriad-distribute-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// (x, y, z, gps time) of every point, as exact bit patterns, sorted: a multiset to compare.
fn keys(b: &PointBatch) -> Vec<[u64; 4]> {
    let gps = b.gps_time.as_ref();
    (0..b.len())
        .map(|i| {
            let p = b.positions[i];
            [
                p[0].to_bits(),
                p[1].to_bits(),
                p[2].to_bits(),
                gps.map_or(0, |g| g[i].to_bits()),
            ]
        })
        .collect()
}

fn read_all(path: &Path) -> PointBatch {
    let mut src = myriad_io::open(path, &OpenOptions::default()).unwrap();
    let mut all: Option<PointBatch> = None;
    while let Some(b) = src.read_batch(1 << 16).unwrap() {
        match &mut all {
            Some(a) => a.append(&b),
            None => all = Some(b),
        }
    }
    all.unwrap()
}

#[test]
fn nothing_lost_chunks_fit_and_spill_files_go() {
    let d = tempdir("city");
    let las = d.join("city.las");
    let opts = myriad_synth::SynthOptions {
        points: 200_000,
        scene: myriad_synth::SceneKind::City,
        seed: 3,
    };
    myriad_synth::write(&opts, &las, true, |_| {}).unwrap();
    // A few text points inside the same area: another format, fewer attributes.
    let (_, b) = scan(
        myriad_io::open(&las, &OpenOptions::default())
            .unwrap()
            .as_mut(),
    )
    .unwrap();
    let xyz = d.join("extra.xyz");
    let text: String = (0..100)
        .map(|i| {
            format!(
                "{} {} {}\n",
                b.min[0] + i as f64,
                b.min[1] + 2.0 * i as f64,
                b.min[2]
            )
        })
        .collect();
    std::fs::write(&xyz, text).unwrap();

    let spill = d.join("spill");
    std::fs::create_dir_all(&spill).unwrap();
    let options = DistributeOptions {
        chunk_points: 20_000,
        buffer_bytes: 256 << 10,
        resident_bytes: 0,
        compress_above: 0,
        min_chunks: 1,
        temp_dir: spill.clone(),
        grid: None,
    };
    let dist = distribute(
        &[las.clone(), xyz.clone()],
        &OpenOptions::default(),
        &options,
    )
    .unwrap();
    assert_eq!(dist.points, 200_100);
    assert_eq!(dist.chunks.iter().map(|c| c.points).sum::<u64>(), 200_100);
    assert_eq!(dist.clamped, 0);
    assert!(dist.chunks.len() > 10, "{} chunks", dist.chunks.len());
    assert!(dist.schema.has(&Attribute::Rgb) && dist.schema.has(&Attribute::GpsTime));
    let mut got = Vec::new();
    let mut zero_intensity = 0;
    for c in &dist.chunks {
        assert!(c.points <= 20_000, "chunk {c:?} too large");
        let b = dist.load(c).unwrap();
        assert!(b.is_consistent());
        assert_eq!(b.len() as u64, c.points);
        let cell = dist.cell_bounds(c);
        assert!(
            b.positions.iter().all(|p| cell.contains(*p)),
            "a point outside its chunk's cell"
        );
        zero_intensity += b
            .intensity
            .as_ref()
            .unwrap()
            .iter()
            .filter(|&&i| i == 0)
            .count();
        got.extend(keys(&b));
    }
    assert!(zero_intensity >= 100, "text points get zero intensity");
    let mut want = keys(&read_all(&las));
    let text = read_all(&xyz);
    want.extend((0..text.len()).map(|i| {
        let p = text.positions[i];
        [
            p[0].to_bits(),
            p[1].to_bits(),
            p[2].to_bits(),
            0f64.to_bits(),
        ]
    }));
    got.sort_unstable();
    want.sort_unstable();
    assert!(
        got == want,
        "the chunks do not hold exactly the input points"
    );
    drop(dist);
    assert_eq!(
        std::fs::read_dir(&spill).unwrap().count(),
        0,
        "spill files left behind"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn inputs_with_different_extra_bytes_are_refused() {
    let d = tempdir("extra");
    let mut s = Schema::new(vec![Attribute::Intensity]);
    s.extra_bytes = 2;
    let las = d.join("eb.las");
    let mut sink = LasSink::create(
        &las,
        LasWriteOptions::for_schema(&s, [0.01; 3], [0.0; 3]).unwrap(),
        true,
    )
    .unwrap();
    let mut b = PointBatch::with_schema(
        &myriad_core::Schema {
            extra_bytes: 2,
            ..Schema::for_las_format(1)
        },
        1,
    );
    b.push_record(&myriad_core::PointRecord {
        position: [1.0, 2.0, 3.0],
        ..Default::default()
    });
    sink.write(&b).unwrap();
    sink.finish().unwrap();
    let xyz = d.join("p.xyz");
    std::fs::write(&xyz, "1 2 3\n").unwrap();
    let options = DistributeOptions {
        chunk_points: 10,
        buffer_bytes: 1 << 16,
        resident_bytes: 0,
        compress_above: u64::MAX,
        min_chunks: 1,
        temp_dir: d.clone(),
        grid: None,
    };
    let err = distribute(&[las, xyz], &OpenOptions::default(), &options)
        .unwrap_err()
        .to_string();
    assert!(err.contains("extra bytes differ"), "{err}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// The whole hierarchy of a scan: distribute, a nested octree per chunk, then the levels above the
/// chunks. Every point is in exactly one node, inside the node's cube; nodes respect the capacity;
/// every node's parent exists; every node's points are a MOSPT (one point per occupied cell at
/// each full level).
#[test]
fn chunks_and_tops_form_one_nested_octree() {
    use myriad_build::nested::{NestedParams, NodeKey, build_subtree, build_tops};
    use std::collections::HashSet;
    let d = tempdir("tree");
    let las = d.join("terrain.las");
    let opts = myriad_synth::SynthOptions {
        points: 150_000,
        scene: myriad_synth::SceneKind::Terrain,
        seed: 4,
    };
    myriad_synth::write(&opts, &las, true, |_| {}).unwrap();
    let dist = distribute(
        std::slice::from_ref(&las),
        &OpenOptions::default(),
        &DistributeOptions {
            chunk_points: 15_000,
            buffer_bytes: 1 << 20,
            resident_bytes: 0,
            compress_above: u64::MAX,
            min_chunks: 1,
            temp_dir: d.clone(),
            grid: None,
        },
    )
    .unwrap();
    assert_eq!(dist.clamped, 0);
    let params = NestedParams {
        capacity: 4000,
        inner_depth: 6,
        max_level: 16,
        ntree: false,
    };
    let mut nodes = Vec::new();
    let mut chunk_roots = Vec::new();
    for c in &dist.chunks {
        let key = NodeKey {
            level: c.level,
            cell: c.cell,
        };
        for n in build_subtree(dist.load(c).unwrap(), &dist.root, key, &params) {
            if n.key == key {
                chunk_roots.push(n)
            } else {
                nodes.push(n)
            }
        }
    }
    nodes.extend(build_tops(chunk_roots, &dist.root, &params));
    let keys: HashSet<NodeKey> = nodes.iter().map(|n| n.key).collect();
    assert_eq!(keys.len(), nodes.len(), "a node built twice");
    assert!(keys.contains(&NodeKey::ROOT));
    let mut times: Vec<u64> = Vec::new();
    for n in &nodes {
        assert!(
            n.points.len() <= params.capacity,
            "{:?} holds {}",
            n.key,
            n.points.len()
        );
        let cube = n.key.bounds(&dist.root);
        if let Some(p) = n.points.positions.iter().find(|p| !cube.contains(**p)) {
            panic!("{:?}: point {p:?} outside {cube:?}", n.key);
        }
        if n.key.level > 0 {
            assert!(
                keys.contains(&NodeKey {
                    level: n.key.level - 1,
                    cell: n.key.cell.map(|c| c / 2)
                }),
                "{:?} orphan",
                n.key
            );
        }
        for l in 0..n.prefix.len().saturating_sub(1) {
            let k = 1u64 << l;
            let cell = |p: &[f64; 3]| {
                (0..3)
                    .map(|a| (((p[a] - cube.min[a]) / cube.size()[a] * k as f64) as u64).min(k - 1))
                    .collect::<Vec<_>>()
            };
            let prefix: HashSet<_> = n.points.positions[..n.prefix[l] as usize]
                .iter()
                .map(cell)
                .collect();
            assert_eq!(
                prefix.len(),
                n.prefix[l] as usize,
                "{:?} level {l}: shared cell",
                n.key
            );
            assert_eq!(
                prefix,
                n.points.positions.iter().map(cell).collect::<HashSet<_>>(),
                "{:?} level {l}",
                n.key
            );
        }
        times.extend(
            n.points
                .gps_time
                .as_ref()
                .unwrap()
                .iter()
                .map(|t| t.to_bits()),
        );
    }
    let mut want: Vec<u64> = read_all(&las)
        .gps_time
        .unwrap()
        .iter()
        .map(|t| t.to_bits())
        .collect();
    times.sort_unstable();
    want.sort_unstable();
    assert!(
        times == want,
        "points lost or duplicated: {} vs {}",
        times.len(),
        want.len()
    );
    let root = nodes.iter().find(|n| n.key == NodeKey::ROOT).unwrap();
    assert!(
        root.points.len() > 100,
        "the root holds a coarse sample of everything"
    );
    drop(dist);
    std::fs::remove_dir_all(&d).unwrap();
}

/// A `synth` city of `points` points as `d/city.las`.
fn synth_city(d: &Path, points: u64, seed: u64) -> PathBuf {
    let las = d.join("city.las");
    let opts = myriad_synth::SynthOptions {
        points,
        scene: myriad_synth::SceneKind::City,
        seed,
    };
    myriad_synth::write(&opts, &las, true, |_| {}).unwrap();
    las
}

/// Chunks of one level and cell, and their points in order.
type Chunked = Vec<(u32, [u32; 3], Vec<[u64; 4]>)>;

/// `las` distributed with write buffers of `buffer_bytes` and chunks of at most `chunk_points`,
/// spilling into `spill`: the spill files written, and the chunks.
fn chunks_of(las: &Path, spill: &Path, buffer_bytes: usize, chunk_points: u64) -> (usize, Chunked) {
    let options = DistributeOptions {
        chunk_points,
        buffer_bytes,
        resident_bytes: 0,
        compress_above: u64::MAX,
        min_chunks: 8,
        temp_dir: spill.to_path_buf(),
        grid: None,
    };
    let dist = distribute(&[las.to_path_buf()], &OpenOptions::default(), &options).unwrap();
    // Spill files: everything in the folder but the lock that holds it.
    let files = std::fs::read_dir(dist.spill_dir())
        .unwrap()
        .filter(|e| e.as_ref().unwrap().file_name() != myriad_io::claim::LOCK_FILE)
        .count();
    let chunks: Chunked = dist
        .chunks
        .iter()
        .map(|c| {
            let b = dist.load(c).unwrap();
            assert_eq!(b.len() as u64, c.points);
            (c.level, c.cell, keys(&b))
        })
        .collect();
    (files, chunks)
}

/// Rows that all fit the write buffers are never written to disk: the chunks come from memory,
/// the same as from spill files.
#[test]
fn chunks_that_fit_in_memory_are_not_spilled() {
    let d = tempdir("resident");
    let las = synth_city(&d, 100_000, 4);
    let spill = d.join("spill");
    std::fs::create_dir_all(&spill).unwrap();
    let (in_memory, a) = chunks_of(&las, &spill, 256 << 20, 1_000_000);
    let (on_disk, b) = chunks_of(&las, &spill, 64 << 10, 1_000_000);
    assert_eq!(
        in_memory, 0,
        "spill files written for rows that fit in memory"
    );
    assert!(on_disk > 0);
    assert!(a.len() > 1);
    assert_eq!(a, b, "the same chunks, the same points in the same order");
    std::fs::remove_dir_all(&d).unwrap();
}

/// Where the points do not all fit, the largest write buffers go to disk when they fill and the
/// rest stay in memory; a chunk too large whose points all stayed is split in memory. Either
/// way: the same chunks, the same points in the same order as when everything is spilled.
#[test]
fn chunks_kept_in_part_or_split_in_memory_are_those_spilled() {
    let d = tempdir("partly");
    let las = synth_city(&d, 100_000, 5);
    let spill = d.join("spill");
    std::fs::create_dir_all(&spill).unwrap();
    // 16 KB of buffers: nearly every point goes through the spill files.
    let (spilled_files, spilled) = chunks_of(&las, &spill, 16 << 10, 15_000);
    // Everything fits: chunks over 15,000 points are split without a file written.
    let (files, in_memory) = chunks_of(&las, &spill, 256 << 20, 15_000);
    // A megabyte: some points written, the rest kept.
    let (partly_files, partly) = chunks_of(&las, &spill, 1 << 20, 15_000);
    let (_, whole) = chunks_of(&las, &spill, 256 << 20, 1_000_000);
    for c in [&spilled, &in_memory, &partly, &whole] {
        assert_eq!(c.iter().map(|c| c.2.len()).sum::<usize>(), 100_000);
    }
    assert!(spilled_files > 0 && partly_files > 0);
    assert_eq!(
        files, 0,
        "spill files written for points that fit in memory"
    );
    assert!(
        in_memory.len() > whole.len(),
        "no chunk was split: {} chunks",
        whole.len()
    );
    assert!(in_memory.iter().all(|c| c.2.len() <= 15_000));
    assert!(
        in_memory == spilled,
        "split in memory: other chunks or order"
    );
    assert!(partly == spilled, "kept in part: other chunks or order");
    std::fs::remove_dir_all(&d).unwrap();
}
