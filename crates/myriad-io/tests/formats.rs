//! Reader behaviour on small files made here: PLY (ascii and both binary byte orders), PCD
//! (ascii, binary, binary_compressed), text layouts, NaN skipping, and the PLY writer.

use myriad_core::{Attribute, PointBatch, Schema};
use myriad_io::las::{LasSink, LasWriteOptions};
use myriad_io::ply::PlySink;
use myriad_io::{OpenOptions, PointSource, open};
use std::path::PathBuf;

fn tmp(name: &str, bytes: &[u8]) -> PathBuf {
    let d = std::env::temp_dir().join(format!("myriad-formats-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn read(path: &std::path::Path, columns: Option<&str>) -> (Box<dyn PointSource>, PointBatch) {
    let mut src = open(
        path,
        &OpenOptions {
            columns: columns.map(str::to_string),
            ..Default::default()
        },
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut all: Option<PointBatch> = None;
    while let Some(b) = src.read_batch(2).unwrap_or_else(|e| panic!("{e}")) {
        match &mut all {
            Some(a) => a.append(&b),
            None => all = Some(b),
        }
    }
    (src, all.unwrap_or_default())
}

fn ply_binary(big: bool) -> Vec<u8> {
    let order = if big {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut v = format!(
        "ply\nformat {order} 1.0\ncomment two points\nelement face 1\nproperty list uchar int vertex_indices\n\
         element vertex 2\nproperty double x\nproperty float y\nproperty float z\nproperty uchar red\n\
         property uchar green\nproperty uchar blue\nproperty float nx\nproperty float ny\nproperty float nz\n\
         property ushort scalar_intensity\nend_header\n"
    )
    .into_bytes();
    // The face element comes first and must be skipped: a 3-item list.
    v.push(3);
    for i in [0i32, 1, 0] {
        v.extend(if big {
            i.to_be_bytes()
        } else {
            i.to_le_bytes()
        });
    }
    for (x, y, z, c, n, i) in [
        (1.5f64, 2.0f32, 3.0f32, [255u8, 0, 10], 1.0f32, 100u16),
        (-4.25, 5.0, 6.0, [0, 128, 255], 0.0, 65535),
    ] {
        v.extend(if big {
            x.to_be_bytes()
        } else {
            x.to_le_bytes()
        });
        for f in [y, z] {
            v.extend(if big {
                f.to_be_bytes()
            } else {
                f.to_le_bytes()
            });
        }
        v.extend(c);
        for f in [n, 0.0, 1.0 - n] {
            v.extend(if big {
                f.to_be_bytes()
            } else {
                f.to_le_bytes()
            });
        }
        v.extend(if big {
            i.to_be_bytes()
        } else {
            i.to_le_bytes()
        });
    }
    v
}

#[test]
fn ply_binary_both_byte_orders() {
    for big in [false, true] {
        let (src, b) = read(&tmp(&format!("b{big}.ply"), &ply_binary(big)), None);
        assert_eq!(src.info().points, Some(2));
        assert_eq!(
            b.positions,
            vec![[1.5, 2.0, 3.0], [-4.25, 5.0, 6.0]],
            "big endian: {big}"
        );
        assert_eq!(
            b.rgb.as_ref().unwrap(),
            &vec![[65535, 0, 2570], [0, 32896, 65535]]
        );
        assert_eq!(b.normal.as_ref().unwrap()[0], [1.0, 0.0, 0.0]);
        assert_eq!(b.intensity.as_ref().unwrap(), &vec![100, 65535]);
    }
}

#[test]
fn ply_ascii_with_faces_and_nan() {
    let text = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
property float confidence\nproperty float intensity\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0 1 0.5\nnan 1 1 1 0.5\n2 2 2 1 1.0\n3 0 1 2\n";
    let (src, b) = read(&tmp("a.ply", text), None);
    assert_eq!(b.positions, vec![[0.0, 0.0, 0.0], [2.0, 2.0, 2.0]]);
    assert_eq!(src.skipped_non_finite(), 1);
    assert_eq!(b.intensity.unwrap(), vec![32768, 65535]);
}

#[test]
fn ply_writer_round_trip() {
    let schema = Schema::new(vec![
        Attribute::Intensity,
        Attribute::Classification,
        Attribute::Rgb,
        Attribute::Normal,
    ]);
    let mut b = PointBatch::with_schema(&schema, 3);
    for i in 0..3u16 {
        b.positions
            .push([500000.123456789 + i as f64, 4e6 - 0.001 * i as f64, -12.5]);
        b.intensity.as_mut().unwrap().push(i * 1000);
        b.classification.as_mut().unwrap().push(i as u8 + 2);
        b.rgb.as_mut().unwrap().push([i * 257 * 50, 65535, 0]);
        b.normal.as_mut().unwrap().push([0.0, i as f32 * 0.5, 1.0]);
    }
    let d = std::env::temp_dir().join(format!("myriad-plyw-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join("out.ply");
    let mut sink = PlySink::create(&p, &schema, true).unwrap();
    sink.write(&b).unwrap();
    assert_eq!(sink.finish().unwrap(), 3);
    let (_, back) = read(&p, None);
    assert_eq!(
        back.positions, b.positions,
        "double positions survive exactly"
    );
    assert_eq!(back.intensity, b.intensity);
    assert_eq!(back.classification, b.classification);
    assert_eq!(back.normal, b.normal);
    assert_eq!(
        back.rgb, b.rgb,
        "8-bit colours widened back to the same 16-bit values"
    );
}

fn pcd_header(data: &str, n: usize) -> String {
    format!(
        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb intensity\nSIZE 4 4 4 4 2\nTYPE F F F F U\nCOUNT 1 1 1 1 1\n\
         WIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {data}\n"
    )
}

fn packed(r: u8, g: u8, b: u8) -> f32 {
    f32::from_bits((r as u32) << 16 | (g as u32) << 8 | b as u32)
}

#[test]
fn pcd_ascii_binary_and_compressed_agree() {
    let pts = [
        (1.0f32, 2.0f32, 3.0f32, packed(255, 0, 0), 7u16),
        (f32::NAN, 0.0, 0.0, packed(0, 0, 0), 0),
        (4.0, 5.0, 6.5, packed(0, 255, 1), 9),
    ];
    let mut ascii = pcd_header("ascii", 3).into_bytes();
    let mut binary = pcd_header("binary", 3).into_bytes();
    let mut columns: Vec<u8> = Vec::new();
    for (x, y, z, c, i) in pts {
        ascii.extend(format!("{x} {y} {z} {:e} {i}\n", c).into_bytes());
        for f in [x, y, z, c] {
            binary.extend(f.to_le_bytes());
        }
        binary.extend(i.to_le_bytes());
    }
    for field in 0..5 {
        for p in pts {
            match field {
                0 => columns.extend(p.0.to_le_bytes()),
                1 => columns.extend(p.1.to_le_bytes()),
                2 => columns.extend(p.2.to_le_bytes()),
                3 => columns.extend(p.3.to_le_bytes()),
                _ => columns.extend(p.4.to_le_bytes()),
            }
        }
    }
    // An LZF block of literal runs (at most 32 bytes each).
    let mut lzf = Vec::new();
    for chunk in columns.chunks(32) {
        lzf.push(chunk.len() as u8 - 1);
        lzf.extend_from_slice(chunk);
    }
    let mut comp = pcd_header("binary_compressed", 3).into_bytes();
    comp.extend((lzf.len() as u32).to_le_bytes());
    comp.extend((columns.len() as u32).to_le_bytes());
    comp.extend(&lzf);
    for (name, bytes) in [("a.pcd", ascii), ("b.pcd", binary), ("c.pcd", comp)] {
        let (src, b) = read(&tmp(name, &bytes), None);
        assert_eq!(
            b.positions,
            vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.5]],
            "{name}"
        );
        assert_eq!(src.skipped_non_finite(), 1, "{name}");
        assert_eq!(
            b.rgb.as_ref().unwrap(),
            &vec![[65535, 0, 0], [0, 65535, 257]],
            "{name}"
        );
        assert_eq!(b.intensity.as_ref().unwrap(), &vec![7, 9], "{name}");
    }
}

#[test]
fn text_layouts() {
    // (file name, content, --columns, expected positions, intensity, rgb)
    type Case<'a> = (
        &'a str,
        &'a str,
        Option<&'a str>,
        Vec<[f64; 3]>,
        Option<Vec<u16>>,
        Option<Vec<[u16; 3]>>,
    );
    let cases: Vec<Case> = vec![
        (
            "plain.xyz",
            "1 2 3\n4 5 6\n",
            None,
            vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]],
            None,
            None,
        ),
        (
            "comma.csv",
            "# comment\n1,2,3\n\n4,5,6\n",
            None,
            vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]],
            None,
            None,
        ),
        (
            "named.csv",
            "X;Y;Z;Intensity\n1;2;3;0.5\n",
            None,
            vec![[1.0, 2.0, 3.0]],
            Some(vec![32768]),
            None,
        ),
        (
            "rgb.txt",
            "1 2 3 255 0 128\n",
            None,
            vec![[1.0, 2.0, 3.0]],
            None,
            Some(vec![[65535, 0, 32896]]),
        ),
        (
            "scan.pts",
            "2\n1 2 3 -2048 10 20 30\n4 5 6 2047 0 0 0\n",
            None,
            vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]],
            Some(vec![0, 65535]),
            Some(vec![[2570, 5140, 7710], [0, 0, 0]]),
        ),
        (
            "swapped.txt",
            "7 1 2 3\n",
            Some("intensity,x,y,z"),
            vec![[1.0, 2.0, 3.0]],
            Some(vec![7]),
            None,
        ),
        (
            "extra.txt",
            "1 2 3 9 9\n",
            None,
            vec![[1.0, 2.0, 3.0]],
            None,
            None,
        ),
    ];
    for (name, content, cols, pos, intensity, rgb) in cases {
        let (src, b) = read(&tmp(name, content.as_bytes()), cols);
        assert_eq!(b.positions, pos, "{name}");
        assert_eq!(b.intensity, intensity, "{name}");
        assert_eq!(b.rgb, rgb, "{name}");
        if name.ends_with(".pts") {
            assert_eq!(src.info().points, Some(2), "PTS count line");
        }
    }
}

/// A LAS 1.4 LAZ chunk whose layer sizes claim more than the chunk holds must be an error before
/// the laz crate allocates them (found by fuzzing: 4 GiB zero-filled per layer).
#[test]
fn laz_layer_sizes_are_checked() {
    let schema = Schema::new(vec![
        Attribute::Intensity,
        Attribute::ScannerChannel,
        Attribute::GpsTime,
    ]);
    let d = std::env::temp_dir().join(format!("myriad-lazlayers-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join("pf6.laz");
    let opts = LasWriteOptions::for_schema(&schema, [0.01; 3], [0.0; 3]).unwrap();
    assert_eq!(opts.header.point_format().to_u8().unwrap(), 6);
    let mut sink = LasSink::create(&p, opts, true).unwrap();
    let mut b = PointBatch::default();
    let mut inconsistent = PointBatch::with_schema(&schema, 1);
    inconsistent.positions.push([0.0; 3]);
    assert!(
        sink.write(&inconsistent).is_err(),
        "a batch with short columns is refused"
    );
    for i in 0..1000 {
        b.positions
            .push([i as f64, (i * 7 % 13) as f64, 0.5 * i as f64]);
    }
    b.intensity = Some((0..1000).map(|i| i as u16).collect());
    b.gps_time = Some((0..1000).map(|i| i as f64 * 0.1).collect());
    sink.write(&b).unwrap();
    sink.finish().unwrap();
    let (_, back) = read(&p, None);
    assert_eq!(back.positions, b.positions);
    // First chunk: 8-byte table offset, first point (30 bytes), u32 count, then 9 layer sizes.
    let mut bytes = std::fs::read(&p).unwrap();
    let data = u32::from_le_bytes(bytes[96..100].try_into().unwrap()) as usize;
    let z_layer = data + 8 + 30 + 4 + 4;
    bytes[z_layer..z_layer + 4].copy_from_slice(&0xF000_0000u32.to_le_bytes());
    let bad = tmp("bad-layers.laz", &bytes);
    let err = open(&bad, &OpenOptions::default())
        .err()
        .expect("corrupt layer size must be an error")
        .to_string();
    assert!(
        err.contains(&format!(
            "byte {}: LAZ chunk 0: its layers claim",
            data + 8 + 30 + 4
        )),
        "{err}"
    );
}

/// A LAZ file of several blocks (read by two producers in turn) gives every point once, in
/// order; a header that declares more points than the chunks hold is an error, not a hang.
/// `read_raw_records` (the `bench` baseline, the same producers) counts the same records and
/// fails the same way.
#[test]
fn laz_of_many_blocks_reads_in_order() {
    let schema = Schema::new(vec![Attribute::Intensity, Attribute::GpsTime]);
    let d = std::env::temp_dir().join(format!("myriad-lazblocks-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join("blocks.laz");
    let opts = LasWriteOptions::for_schema(&schema, [0.01; 3], [0.0; 3]).unwrap();
    let mut sink = LasSink::create(&p, opts, true).unwrap();
    let n = 1_500_000usize;
    for start in (0..n).step_by(100_000) {
        let mut b = PointBatch::with_schema(&schema, 100_000);
        for i in start..start + 100_000 {
            b.positions
                .push([(i % 1000) as f64, (i / 1000) as f64 * 0.5, (i % 7) as f64]);
        }
        b.intensity = Some((start..start + 100_000).map(|i| i as u16).collect());
        b.gps_time = Some((start..start + 100_000).map(|i| i as f64).collect());
        sink.write(&b).unwrap();
    }
    assert_eq!(sink.finish().unwrap(), n as u64);
    let read_all = |path: &PathBuf| -> myriad_core::Result<usize> {
        let mut src = open(path, &OpenOptions::default())?;
        let mut next = 0usize;
        while let Some(b) = src.read_batch(1 << 16)? {
            let gps = b.gps_time.as_ref().unwrap();
            for (k, &t) in gps.iter().enumerate() {
                let i = next + k;
                assert_eq!(t, i as f64, "point {i} out of order");
                assert_eq!(
                    b.positions[k],
                    [(i % 1000) as f64, (i / 1000) as f64 * 0.5, (i % 7) as f64]
                );
                assert_eq!(b.intensity.as_ref().unwrap()[k], i as u16);
            }
            next += b.len();
        }
        Ok(next)
    };
    assert_eq!(read_all(&p).unwrap(), n);
    assert_eq!(myriad_io::las::read_raw_records(&p).unwrap(), n as u64);
    // The header says 2.5 M points: the error names the file and comes after the points that
    // are there, from whichever producer meets it first in file order.
    let mut bytes = std::fs::read(&p).unwrap();
    bytes[107..111].copy_from_slice(&2_500_000u32.to_le_bytes());
    if bytes[25] >= 4 {
        bytes[247..255].copy_from_slice(&2_500_000u64.to_le_bytes());
    }
    let lie = tmp("blocks-lie.laz", &bytes);
    let err = read_all(&lie)
        .expect_err("more points declared than held")
        .to_string();
    assert!(
        err.contains("blocks-lie.laz") && err.contains("2500000"),
        "{err}"
    );
    let err = myriad_io::las::read_raw_records(&lie)
        .expect_err("more points declared than held")
        .to_string();
    assert!(
        err.contains("blocks-lie.laz") && err.contains("2500000"),
        "{err}"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// A LAZ file's chunks: each one's bounds from a pass over its coordinates, and a source that
/// reads only some of them gives exactly their points, in order; asking for a chunk the file
/// does not have, or out of order, is a one-line error. Both a layered format (6: only X, Y
/// and Z decompressed for the bounds) and a legacy one (1: decompressed whole).
#[test]
fn laz_chunks_bound_and_read_alone() {
    let d = std::env::temp_dir().join(format!("myriad-lazchunks-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    for (name, schema) in [
        (
            "pf6.laz",
            Schema::new(vec![
                Attribute::Intensity,
                Attribute::ScannerChannel,
                Attribute::GpsTime,
            ]),
        ),
        (
            "pf1.laz",
            Schema::new(vec![Attribute::Intensity, Attribute::GpsTime]),
        ),
    ] {
        let p = d.join(name);
        let opts = LasWriteOptions::for_schema(&schema, [0.01; 3], [0.0; 3]).unwrap();
        let mut sink = LasSink::create(&p, opts, true).unwrap();
        let n = 280_000usize; // 50,000-point chunks: 5 whole and one of 30,000
        let at = |i: usize| {
            let c = (i / 50_000) as f64;
            [
                c * 100.0 + (i % 97) as f64,
                -c - (i % 13) as f64 * 0.25,
                (i % 5) as f64,
            ]
        };
        let mut b = PointBatch::with_schema(&schema, n);
        b.positions.extend((0..n).map(at));
        b.intensity = Some((0..n).map(|i| i as u16).collect());
        b.gps_time = Some((0..n).map(|i| i as f64).collect());
        if let Some(c) = &mut b.scanner_channel {
            c.extend((0..n).map(|i| (i % 4) as u8));
        }
        sink.write(&b).unwrap();
        sink.finish().unwrap();

        let bounds = myriad_io::las::chunk_bounds(&p)
            .unwrap()
            .expect("a chunk table");
        assert_eq!(bounds.len(), 6, "{name}");
        for (k, (c, b)) in bounds.iter().enumerate() {
            let first = k * 50_000;
            let count = if k == 5 { 30_000 } else { 50_000 };
            assert_eq!((c.index as usize, c.points), (k, count as u64), "{name}");
            let want = (first..first + count).fold(myriad_core::Aabb::EMPTY, |a, i| {
                let mut a = a;
                a.extend(at(i));
                a
            });
            assert_eq!(b.min, want.min, "{name} chunk {k}");
            assert_eq!(b.max, want.max, "{name} chunk {k}");
        }

        let kept = |chunks: Vec<u32>| OpenOptions {
            laz_chunks: Some(std::sync::Arc::new(
                [(p.clone(), chunks)].into_iter().collect(),
            )),
            ..Default::default()
        };
        let mut src = open(&p, &kept(vec![1, 4, 5])).unwrap();
        assert_eq!(src.info().points, Some(130_000));
        let mut got = Vec::new();
        while let Some(b) = src.read_batch(1 << 16).unwrap() {
            for (k, &t) in b.gps_time.as_ref().unwrap().iter().enumerate() {
                assert_eq!(b.positions[k], at(t as usize));
                assert_eq!(b.intensity.as_ref().unwrap()[k], t as usize as u16);
                got.push(t as usize);
            }
        }
        let want: Vec<usize> = (50_000..100_000).chain(200_000..280_000).collect();
        assert!(
            got == want,
            "{name}: the points of chunks 1, 4 and 5, in order"
        );
        for bad in [vec![6], vec![4, 1]] {
            let err = open(&p, &kept(bad.clone()))
                .err()
                .expect("refused")
                .to_string();
            assert!(
                err.contains(name) && err.contains("plan again") && !err.contains('\n'),
                "{bad:?}: {err}"
            );
        }
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// Every scan of an E57 file is read, each with its own pose (rotation and translation) applied,
/// and points without valid coordinates are skipped and counted.
#[test]
fn e57_reads_every_scan_with_its_pose() {
    // Cartesian scans without a grid: where the scanner stood is not known.
    let (src, b) = e57_two_scans(false);
    assert!(src.info().origins.is_empty() && b.point_source_id.is_none());
    // With a row/column grid (a stationary scanner's structured scans): each point's scan
    // number as its source ID, and where each scan was taken from (its pose's translation).
    let (src, b) = e57_two_scans(true);
    assert_eq!(src.info().origins, vec![[0.0; 3], [10.0, 0.0, 0.0]]);
    assert_eq!(b.point_source_id.unwrap(), vec![1, 1, 2, 2]);
    // A placement moves where the scanners stood with the points.
    let placement = myriad_io::placement::Placement::parse(
        std::path::Path::new("scan.e57.placement"),
        "ROTATE-DEG 0 0 90\nTRANSLATE 100 0 0",
    )
    .unwrap();
    let placed = myriad_io::placement::Placed::new(src, placement);
    let o = &placed.info().origins;
    let rounded: Vec<[i64; 3]> = o.iter().map(|p| p.map(|c| c.round() as i64)).collect();
    assert_eq!(rounded, vec![[100, 0, 0], [100, 10, 0]]);
}

/// Two scans, the second posed, one NaN point; with `grid`, row and column indices.
fn e57_two_scans(grid: bool) -> (Box<dyn PointSource>, PointBatch) {
    use e57::{
        E57Writer, Quaternion, Record, RecordDataType, RecordName, RecordValue, Transform,
        Translation,
    };
    let d = std::env::temp_dir().join(format!("myriad-e57-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join(format!("two-scans-{grid}.e57"));
    let xyz = |name| Record {
        name,
        data_type: RecordDataType::Double {
            min: None,
            max: None,
        },
    };
    let mut proto = vec![
        xyz(RecordName::CartesianX),
        xyz(RecordName::CartesianY),
        xyz(RecordName::CartesianZ),
        Record {
            name: RecordName::Intensity,
            data_type: RecordDataType::Single {
                min: Some(0.0),
                max: Some(1.0),
            },
        },
    ];
    let index = |name| Record {
        name,
        data_type: RecordDataType::Integer { min: 0, max: 10 },
    };
    if grid {
        proto.push(index(RecordName::RowIndex));
        proto.push(index(RecordName::ColumnIndex));
    }
    let mut w = E57Writer::from_file(&p, "file-guid").unwrap();
    type Scan<'a> = (&'a str, Option<Transform>, Vec<[f64; 4]>);
    let scans: [Scan; 2] = [
        (
            "a",
            None,
            vec![
                [0.0, 0.0, 0.0, 0.5],
                [1.0, 0.0, 0.0, 1.0],
                [f64::NAN, 0.0, 0.0, 0.0],
            ],
        ),
        (
            "b",
            // A quarter turn about z, then 10 m along x.
            Some(Transform {
                rotation: Quaternion {
                    w: std::f64::consts::FRAC_1_SQRT_2,
                    x: 0.0,
                    y: 0.0,
                    z: std::f64::consts::FRAC_1_SQRT_2,
                },
                translation: Translation {
                    x: 10.0,
                    y: 0.0,
                    z: 0.0,
                },
            }),
            vec![[1.0, 0.0, 0.0, 0.25], [2.0, 0.0, 5.0, 0.0]],
        ),
    ];
    for (guid, pose, points) in scans {
        let mut pc = w.add_pointcloud(guid, proto.clone()).unwrap();
        pc.set_transform(pose);
        for q in points {
            let mut v = vec![
                RecordValue::Double(q[0]),
                RecordValue::Double(q[1]),
                RecordValue::Double(q[2]),
                RecordValue::Single(q[3] as f32),
            ];
            if grid {
                v.extend([RecordValue::Integer(0), RecordValue::Integer(1)]);
            }
            pc.add_point(v).unwrap();
        }
        pc.finalize().unwrap();
    }
    w.finalize().unwrap();
    drop(w);
    let (src, b) = read(&p, None);
    assert_eq!(src.info().points, Some(5), "header count covers both scans");
    assert_eq!(src.skipped_non_finite(), 1);
    let got: Vec<[i64; 3]> = b
        .positions
        .iter()
        .map(|p| p.map(|c| (c * 1000.0).round() as i64))
        .collect();
    assert_eq!(
        got,
        vec![
            [0, 0, 0],
            [1000, 0, 0],
            [10000, 1000, 0],
            [10000, 2000, 5000]
        ]
    );
    assert_eq!(b.intensity.as_ref().unwrap(), &vec![32768, 65535, 16384, 0]);
    (src, b)
}
