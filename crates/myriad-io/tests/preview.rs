//! The preview of LAS/LAZ files (`LasSource::preview`): the samples are the file's own points at
//! the indices it names (the first of each LAZ chunk, LAS records at a stride), and a LAZ preview
//! reads a few bytes per chunk, no compressed data.

use myriad_core::{Attribute, PointBatch, Schema};
use myriad_io::las::{LasSink, LasSource, LasWriteOptions};
use myriad_io::{OpenOptions, open};
use std::path::{Path, PathBuf};

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("myriad-preview-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// Every point of a file, in its order.
fn all_points(path: &Path) -> PointBatch {
    let mut src = open(path, &OpenOptions::default()).unwrap();
    let mut all = PointBatch::default();
    let mut first = true;
    while let Some(b) = src.read_batch(myriad_io::MAX_BATCH).unwrap() {
        if first {
            all = b;
            first = false;
        } else {
            all.append(&b);
        }
    }
    all
}

/// A scan of `n` points with times, intensities, classes and colours that differ per point.
fn write_scan(path: &Path, n: usize, schema: &Schema) {
    let opts = LasWriteOptions::for_schema(schema, [0.001; 3], [1000.0, 2000.0, 0.0]).unwrap();
    let mut sink = LasSink::create(path, opts, true).unwrap();
    let mut b = PointBatch::with_schema(schema, n);
    for i in 0..n {
        let t = i as f64;
        b.positions.push([
            1000.0 + (t * 0.37) % 500.0,
            2000.0 + (t * 0.011) % 300.0,
            (t * 0.7) % 40.0,
        ]);
    }
    b.intensity = Some((0..n).map(|i| (i * 31 % 65536) as u16).collect());
    b.classification = Some((0..n).map(|i| (i % 7) as u8).collect());
    b.gps_time = Some((0..n).map(|i| i as f64 * 1e-4).collect());
    if schema.attributes.contains(&Attribute::Rgb) {
        b.rgb = Some(
            (0..n)
                .map(|i| {
                    [
                        (i % 65536) as u16,
                        (i * 3 % 65536) as u16,
                        (i * 7 % 65536) as u16,
                    ]
                })
                .collect(),
        );
    }
    if schema.attributes.contains(&Attribute::ScannerChannel) {
        b.scanner_channel = Some((0..n).map(|i| (i % 4) as u8).collect());
    }
    sink.write(&b).unwrap();
    sink.finish().unwrap();
}

/// The preview's samples are the file's points at its indices, column for column.
fn check_against_the_file(
    path: &Path,
    most: usize,
) -> (LasSource, myriad_io::las_preview::Preview) {
    let src = LasSource::open(path).unwrap();
    let p = src.preview(path, most).unwrap();
    let all = all_points(path);
    let idx: Vec<u32> = p.indices.iter().map(|&i| i as u32).collect();
    assert_eq!(p.points.len(), idx.len(), "{}", path.display());
    assert!(
        idx.windows(2).all(|w| w[0] < w[1]),
        "{}: indices ascend",
        path.display()
    );
    assert_eq!(
        p.points,
        all.gather(&idx),
        "{}: samples differ from the points",
        path.display()
    );
    (src, p)
}

#[test]
fn a_laz_preview_is_the_first_point_of_each_chunk_and_reads_no_compressed_bytes() {
    let n = 230_000;
    for (name, schema) in [
        // Point format 3: pointwise chunks.
        (
            "pf3.laz",
            Schema::new(vec![
                Attribute::Intensity,
                Attribute::Classification,
                Attribute::GpsTime,
                Attribute::Rgb,
            ]),
        ),
        // Point format 7: layered chunks.
        (
            "pf7.laz",
            Schema::new(vec![
                Attribute::Intensity,
                Attribute::Classification,
                Attribute::GpsTime,
                Attribute::Rgb,
                Attribute::ScannerChannel,
            ]),
        ),
    ] {
        let path = temp(name);
        write_scan(&path, n, &schema);
        let (src, p) = check_against_the_file(&path, usize::MAX);
        let chunk = src.header().laz_vlr().unwrap().chunk_size() as u64;
        let want: Vec<u64> = (0..n as u64).step_by(chunk as usize).collect();
        assert_eq!(p.indices, want, "{name}: one sample per chunk");
        // The chunk table (a few bytes a chunk) and one raw record a chunk: far below one
        // chunk's compressed bytes, let alone the file's.
        let record = src.header().point_format().len() as u64;
        let file = std::fs::metadata(&path).unwrap().len();
        assert!(
            p.bytes_read <= want.len() as u64 * (record + 16) + 64,
            "{name}: read {} bytes for {} chunks of {record}-byte records",
            p.bytes_read,
            want.len()
        );
        assert!(
            p.bytes_read * 1000 < file,
            "{name}: {} of {file} bytes",
            p.bytes_read
        );
        // At most `most`: every k-th chunk.
        let (_, few) = check_against_the_file(&path, 2);
        assert_eq!(few.indices.len(), 2);
    }
}

#[test]
fn a_las_preview_takes_records_at_a_stride() {
    let path = temp("pf1.las");
    let schema = Schema::new(vec![
        Attribute::Intensity,
        Attribute::Classification,
        Attribute::GpsTime,
    ]);
    write_scan(&path, 10_007, &schema);
    let (_, p) = check_against_the_file(&path, 1000);
    assert_eq!(p.indices.len(), 1000);
    assert_eq!(p.indices[0], 0);
    // Records ten apart: read in one pass through a buffer, at most the point records.
    let file = std::fs::metadata(&path).unwrap().len();
    assert!(
        p.bytes_read >= 1000 * 28 && p.bytes_read <= file,
        "{} bytes read",
        p.bytes_read
    );
    let (_, all) = check_against_the_file(&path, usize::MAX);
    assert_eq!(all.indices.len(), 10_007);
}

/// Every LAS and LAZ scan in ../shared/data (COPC among them): the preview's samples are the
/// decoded points at its indices.
#[test]
fn previews_of_the_real_scans_are_their_points() {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if !d.is_dir() {
        use std::io::Write;
        let _ = writeln!(std::io::stderr(), "SKIPPED: {} not found", d.display());
        return;
    }
    let mut files: Vec<PathBuf> = std::fs::read_dir(&d)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "las" || e == "laz"))
        .collect();
    files.sort();
    let mut laz = 0;
    for f in &files {
        let Ok(src) = LasSource::open(f) else {
            continue;
        };
        let compressed = src.header().point_format().is_compressed;
        let (_, p) = check_against_the_file(f, 100_000);
        assert!(!p.indices.is_empty(), "{}", f.display());
        if compressed {
            laz += 1;
            let file = std::fs::metadata(f).unwrap().len();
            assert!(
                p.bytes_read * 20 < file,
                "{}: {} of {file} bytes",
                f.display(),
                p.bytes_read
            );
        }
    }
    assert!(laz >= 5, "the corpus has LAZ files ({laz})");
}

/// A large LAZ scan's preview (more than the 2 M points decoded whole): its chunks' first points,
/// then whole chunks spread over the file decoded until the deadline, each sample the file's own
/// point at its index; a deadline already past gives the chunk starts alone.
#[test]
fn a_large_laz_previews_its_chunk_starts_then_decoded_chunks_spread_over_it() {
    let path = temp("large.laz");
    let schema = Schema::new(vec![
        Attribute::Intensity,
        Attribute::Classification,
        Attribute::GpsTime,
    ]);
    write_scan(&path, 2_100_000, &schema);
    let src = LasSource::open(&path).unwrap();
    let chunks = src.chunks().unwrap().unwrap().len();
    let past = std::time::Instant::now();
    let starts = src.preview_shown(&path, 200_000, past).unwrap();
    assert_eq!(
        starts.points.len(),
        chunks,
        "a deadline past: the chunk starts alone"
    );
    let later = std::time::Instant::now() + std::time::Duration::from_secs(30);
    let p = src.preview_shown(&path, 200_000, later).unwrap();
    assert!(p.how.contains("decoded"), "{}", p.how);
    assert!(
        p.points.len() > 20 * chunks && p.points.len() <= 200_000,
        "{} points",
        p.points.len()
    );
    assert_eq!(p.points.len(), p.indices.len());
    let all = all_points(&path);
    let mut seen = std::collections::HashSet::new();
    for (k, &i) in p.indices.iter().enumerate() {
        assert!(seen.insert(i), "point {i} twice");
        assert_eq!(
            p.points.positions[k], all.positions[i as usize],
            "point {i}"
        );
        assert_eq!(
            p.points.gps_time.as_ref().unwrap()[k],
            all.gps_time.as_ref().unwrap()[i as usize]
        );
    }
    // Spread: samples in every tenth of the file.
    for tenth in 0..10u64 {
        let n = p
            .indices
            .iter()
            .filter(|&&i| i * 10 / 2_100_000 == tenth)
            .count();
        assert!(n > 1000, "tenth {tenth}: {n} samples");
    }
}
