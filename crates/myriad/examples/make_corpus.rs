//! Writes the corpus of crafted inputs in `crates/myriad/tests/corpus/`: one small file per class
//! of damage and format, and `cases.tsv`, the outcome each command must give for each file (run
//! by `tests/corpus.rs`). Valid files are made first (by `myriad synth`, the e57 crate's writer,
//! `myriad convert`, or by hand for the text formats) and then damaged at the byte or line that
//! the class is about, so the expected error names that byte or line.
//!
//!     cargo run --release -p myriad --example make_corpus
//!
//! The files are committed; run this again after changing it (it replaces the folder).

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

fn las(c: &mut Corpus, tmp: &Path) {
    let b = synth(tmp, "base.las", 300);
    let len = b.len();
    let data = u32_at(&b, 96) as usize;
    let record = u16::from_le_bytes([b[105], b[106]]) as usize;
    let with = |at: usize, v: &[u8]| {
        let mut x = b.clone();
        put(&mut x, at, v);
        x
    };
    c.reads("las/valid.las", &b, INPUT, "\"points\":300");
    // Values that coordinates are computed from.
    c.fails(
        "las/scale-x-nan.las",
        &with(131, &f64le(f64::NAN)),
        INPUT,
        "byte 131: X scale factor is NaN",
    );
    c.fails(
        "las/scale-y-zero.las",
        &with(139, &f64le(0.0)),
        INPUT,
        "byte 139: Y scale factor is 0",
    );
    c.fails(
        "las/scale-z-inf.las",
        &with(147, &f64le(f64::INFINITY)),
        INPUT,
        "byte 147: Z scale factor is inf",
    );
    c.fails(
        "las/scale-x-overflows.las",
        &with(131, &f64le(1e300)),
        INPUT,
        "byte 131: X scale factor 1e300 with offset",
    );
    // A negative scale mirrors the records, not the coordinates: nothing is wrong.
    c.reads(
        "las/scale-x-negative.las",
        &with(131, &f64le(-0.001)),
        INPUT,
        "\"scale\":[-0.001,",
    );
    c.fails(
        "las/offset-x-nan.las",
        &with(155, &f64le(f64::NAN)),
        INPUT,
        "byte 155: X offset is NaN",
    );
    c.fails(
        "las/offset-z-neg-inf.las",
        &with(171, &f64le(f64::NEG_INFINITY)),
        INPUT,
        "byte 171: Z offset is -inf",
    );
    // Header bounds are not needed for coordinates: bad ones are replaced by the points' own.
    let mut nan_bounds = b.clone();
    for at in (179..227).step_by(8) {
        put(&mut nan_bounds, at, &f64le(f64::NAN));
    }
    c.reads("las/bounds-nan.las", &nan_bounds, INPUT, "\"points\":300");
    let mut huge_bounds = b.clone();
    for (i, at) in (179..227).step_by(8).enumerate() {
        put(
            &mut huge_bounds,
            at,
            &f64le(if i % 2 == 0 { 1e300 } else { -1e300 }),
        );
    }
    c.reads("las/bounds-huge.las", &huge_bounds, INPUT, "\"points\":300");
    // Sizes and offsets.
    c.fails(
        "las/header-size-past-end.las",
        &with(94, &65535u16.to_le_bytes()),
        INPUT,
        "byte 94: header size 65535 is larger than the file",
    );
    c.fails(
        "las/header-size-small.las",
        &with(94, &100u16.to_le_bytes()),
        INPUT,
        "byte 94: header size 100 is smaller than LAS 1.4's 375 bytes",
    );
    c.fails(
        "las/data-offset-past-end.las",
        &with(96, &u32::MAX.to_le_bytes()),
        INPUT,
        "byte 96: offset to point data 4294967295 is past the end of the file",
    );
    c.fails(
        "las/data-offset-in-header.las",
        &with(96, &200u32.to_le_bytes()),
        INPUT,
        "byte 96: offset to point data 200 lies inside the 375-byte header",
    );
    c.fails(
        "las/record-length-zero.las",
        &with(105, &0u16.to_le_bytes()),
        INPUT,
        "byte 105: point record length 0 is shorter than point format",
    );
    c.fails(
        "las/record-length-huge.las",
        &with(105, &u16::MAX.to_le_bytes()),
        INPUT,
        &format!("byte {len}: file ends after 0 of the 300 point records"),
    );
    c.fails(
        "las/point-format-42.las",
        &with(104, &[42]),
        INPUT,
        "byte 104: unknown point format 42",
    );
    c.fails(
        "las/version-9.las",
        &with(24, &[9]),
        INPUT,
        "byte 24: LAS major version 9",
    );
    c.fails(
        "las/vlr-count-huge.las",
        &with(100, &u32::MAX.to_le_bytes()),
        INPUT,
        "runs into the point data",
    );
    c.fails(
        "las/vlr-length-past-data.las",
        &with(375 + 20, &u16::MAX.to_le_bytes()),
        INPUT,
        "byte 395: VLR 0's length 65535 runs past the start of the point data",
    );
    let mut evlr = with(235, &f64le(0.0));
    put(&mut evlr, 235, &(u64::MAX - 10).to_le_bytes());
    put(&mut evlr, 243, &1u32.to_le_bytes());
    c.fails(
        "las/evlr-offset-past-end.las",
        &evlr,
        INPUT,
        "byte 235: first EVLR offset",
    );
    let mut evlr = b.clone();
    put(&mut evlr, 235, &(data as u64).to_le_bytes());
    put(&mut evlr, 243, &1u32.to_le_bytes());
    put(&mut evlr, data + 20, &(u64::MAX - 5).to_le_bytes());
    c.fails(
        "las/evlr-length-overflows.las",
        &evlr,
        INPUT,
        &format!("byte {}: EVLR length", data + 20),
    );
    // Counts that lie.
    let count = |n32: u32, n64: u64| {
        let mut x = b.clone();
        put(&mut x, 107, &n32.to_le_bytes());
        put(&mut x, 247, &n64.to_le_bytes());
        x
    };
    c.fails(
        "las/count-more.las",
        &count(5000, 5000),
        INPUT,
        &format!("byte {len}: file ends after 300 of the 5000 point records"),
    );
    c.reads(
        "las/count-fewer.las",
        &count(100, 100),
        INPUT,
        "\"points\":100",
    );
    c.fails(
        "las/count-u64-max.las",
        &count(0, u64::MAX),
        INPUT,
        &format!("byte {len}: file ends after 300 of the 18446744073709551615 point records"),
    );
    // Truncations at each structure's boundary.
    c.fails("las/empty.las", b"", INPUT, "byte 0: wrong magic number");
    c.fails(
        "las/magic-only.las",
        b"LASF",
        INPUT,
        "byte 4: file ends inside the 227-byte LAS header",
    );
    c.fails(
        "las/cut-in-header.las",
        &b[..300],
        INPUT,
        "byte 94: header size 375 is larger than the file (300 bytes)",
    );
    c.fails(
        "las/cut-in-vlr.las",
        &b[..380],
        INPUT,
        "byte 96: offset to point data",
    );
    c.fails(
        "las/cut-at-points.las",
        &b[..data],
        INPUT,
        &format!("byte {data}: file ends after 0 of the 300 point records"),
    );
    let cut = data + 10 * record + record / 2;
    c.fails(
        "las/cut-in-record.las",
        &b[..cut],
        INPUT,
        &format!("byte {cut}: file ends after 10 of the 300 point records"),
    );
    let mut g = b"LASF".to_vec();
    g.extend(garbage(2000, 1));
    c.fails("las/garbage-after-magic.las", &g, INPUT, "error");
}

/// A LAZ file holding the records of the LAS file `las` in chunks of `chunk` points: its header
/// and VLRs, a laszip VLR added, the point format's compression bit set.
fn laz_of(las: &[u8], chunk: u32) -> Vec<u8> {
    let data = u32_at(las, 96) as usize;
    let format = las[104];
    let record = u16::from_le_bytes([las[105], las[106]]);
    let base = [20u16, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67][format as usize];
    let vlr = laz::LazVlrBuilder::default()
        .with_point_format(format, record - base)
        .unwrap()
        .with_fixed_chunk_size(chunk)
        .build();
    let mut payload = Vec::new();
    vlr.write_to(&mut payload).unwrap();
    let mut out = las[..data].to_vec();
    out.extend_from_slice(&[0, 0]);
    let mut user = [0u8; 16];
    user[..14].copy_from_slice(b"laszip encoded");
    out.extend_from_slice(&user);
    out.extend_from_slice(&22204u16.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u16).to_le_bytes());
    out.extend_from_slice(&[0u8; 32]);
    out.extend_from_slice(&payload);
    let new_data = out.len() as u32;
    put(&mut out, 96, &new_data.to_le_bytes());
    let vlrs = u32_at(&out, 100) + 1;
    put(&mut out, 100, &vlrs.to_le_bytes());
    out[104] = format | 0x80;
    let mut cursor = std::io::Cursor::new(out);
    cursor.set_position(new_data as u64);
    let mut z = laz::LasZipCompressor::new(cursor, vlr).unwrap();
    z.compress_many(&las[data..]).unwrap();
    z.done().unwrap();
    z.into_inner().into_inner()
}

fn laz(c: &mut Corpus, tmp: &Path) {
    // 3000 points in six chunks of 500 (LAS 1.4 without EVLRs).
    let b = laz_of(&synth(tmp, "base-for-laz.las", 3000), 500);
    let data = u32_at(&b, 96) as usize;
    let table = u64_at(&b, data) as usize;
    let with = |at: usize, v: &[u8]| {
        let mut x = b.clone();
        put(&mut x, at, v);
        x
    };
    c.reads("laz/valid.laz", &b, INPUT, "\"points\":3000");
    c.fails(
        "laz/scale-x-nan.laz",
        &with(131, &f64le(f64::NAN)),
        INPUT,
        "byte 131: X scale factor is NaN",
    );
    c.fails(
        "laz/chunk-table-past-end.laz",
        &with(data, &(u64::MAX / 2).to_le_bytes()),
        INPUT,
        &format!("byte {data}: LAZ chunk table offset"),
    );
    c.fails(
        "laz/chunk-count-huge.laz",
        &with(table + 4, &0x8480_0000u32.to_le_bytes()),
        INPUT,
        &format!("byte {}: LAZ chunk table declares", table + 4),
    );
    let vlr = b
        .windows(14)
        .position(|w| w == b"laszip encoded")
        .expect("laszip VLR")
        - 2;
    c.fails(
        "laz/items-zero-bytes.laz",
        &with(vlr + 54 + 32, &0u16.to_le_bytes()),
        INPUT,
        "byte 105: laszip VLR describes 0-byte records",
    );
    let mut more = with(107, &6000u32.to_le_bytes());
    put(&mut more, 247, &6000u64.to_le_bytes());
    c.fails("laz/count-more.laz", &more, INPUT, "the last LAZ chunk (5) does not hold the 3500 points the header's count of 6000 leaves for it");
    let mut fewer = with(107, &1000u32.to_le_bytes());
    put(&mut fewer, 247, &1000u64.to_le_bytes());
    c.reads("laz/count-fewer.laz", &fewer, INPUT, "\"points\":1000");
    c.fails(
        "laz/cut-in-chunk.laz",
        &b[..data + 8 + 500],
        INPUT,
        &format!("byte {data}: LAZ chunk table offset"),
    );
    // The third chunk's bytes replaced by others: the decoder fails inside it. The chunk table
    // (u32 version, u32 count, then the chunks' byte counts, arithmetic-coded) is read through
    // the laz crate to find where the chunk starts.
    let mut f = std::io::Cursor::new(b.clone());
    std::io::Seek::seek(&mut f, std::io::SeekFrom::Start(data as u64)).unwrap();
    let vlr = laz::LazVlrBuilder::default()
        .with_point_format(3, 0)
        .unwrap()
        .with_fixed_chunk_size(500)
        .build();
    let t = laz::laszip::ChunkTable::read_from(&mut f, &vlr).unwrap();
    let third = data
        + 8
        + t.as_ref()[..2]
            .iter()
            .map(|e| e.byte_count as usize)
            .sum::<usize>();
    // A chunk table whose second chunk claims 2^50 bytes (the table rewritten in place; its
    // 32-bit coding keeps the low bits, so the chunk comes out short of its points).
    let mut huge = laz::laszip::ChunkTable::with_capacity(t.len());
    for (i, e) in t.as_ref().iter().enumerate() {
        let byte_count = if i == 1 { 1 << 50 } else { e.byte_count };
        huge.push(laz::laszip::ChunkTableEntry {
            point_count: e.point_count,
            byte_count,
        });
    }
    let mut h = b[..table].to_vec();
    huge.write_to(&mut h, &vlr).unwrap();
    let second = data + 8 + t.as_ref()[0].byte_count as usize;
    c.fails(
        "laz/chunk-bytes-huge.laz",
        &h,
        INPUT,
        &format!("byte {second}: LAZ chunk 1 (points 500..1000) does not decompress"),
    );
    let mut chunk = b.clone();
    chunk[third + 40..third + 440].copy_from_slice(&garbage(400, 2));
    c.fails(
        "laz/chunk-garbage.laz",
        &chunk,
        INPUT,
        &format!("byte {third}: LAZ chunk 2 (points 1000..1500) does not decompress"),
    );
}

/// An E57 file of one scan with a pose and scaled-integer coordinates (1 mm), then its XML
/// section rewritten by `xml` (the writer recomputes the page checksums).
fn e57_file(tmp: &Path, name: &str, nan_points: bool, xml: impl Fn(String) -> String) -> Vec<u8> {
    use e57::{
        E57Writer, Quaternion, Record, RecordDataType, RecordName, RecordValue, Transform,
        Translation,
    };
    let p = tmp.join(name);
    let coord = |name| Record {
        name,
        data_type: if nan_points {
            RecordDataType::Double {
                min: None,
                max: None,
            }
        } else {
            RecordDataType::ScaledInteger {
                min: -1_000_000,
                max: 1_000_000,
                scale: 0.001,
                offset: 0.0,
            }
        },
    };
    let proto = vec![
        coord(RecordName::CartesianX),
        coord(RecordName::CartesianY),
        coord(RecordName::CartesianZ),
    ];
    let mut w = E57Writer::from_file(&p, "corpus").unwrap();
    let mut pc = w.add_pointcloud("scan", proto).unwrap();
    pc.set_transform(Some(Transform {
        rotation: Quaternion {
            w: 1.0,
            x: 0.0,
            y: 0.0,
            z: 0.0,
        },
        translation: Translation {
            x: 10.0,
            y: 20.0,
            z: 30.0,
        },
    }));
    for i in 0..20 {
        let v = |k: i64| {
            if nan_points {
                RecordValue::Double(if i % 10 == 3 {
                    f64::NAN
                } else {
                    (i * k) as f64 * 0.01
                })
            } else {
                RecordValue::ScaledInteger(i * k * 10)
            }
        };
        pc.add_point(vec![v(1), v(2), v(3)]).unwrap();
    }
    pc.finalize().unwrap();
    w.finalize_customized_xml(|s| Ok(xml(s))).unwrap();
    drop(w);
    std::fs::read(p).unwrap()
}

/// Replaces the text of the first `<tag ...>TEXT</tag>` after `after` with `value`.
fn set_xml(s: &str, after: &str, tag: &str, value: &str) -> String {
    let from = s
        .find(after)
        .unwrap_or_else(|| panic!("{after} in the XML"));
    let open = from
        + s[from..]
            .find(&format!("<{tag}"))
            .unwrap_or_else(|| panic!("<{tag}"));
    let text = open + s[open..].find('>').unwrap() + 1;
    let end = text + s[text..].find('<').unwrap();
    format!("{}{value}{}", &s[..text], &s[end..])
}

/// The byte offset of the first `<tag` after `after` in the file's XML section: the offset the
/// reader must name, found in the file itself.
fn xml_at(file: &[u8], after: &str, tag: &str) -> usize {
    let from = file
        .windows(after.len())
        .position(|w| w == after.as_bytes())
        .unwrap();
    from + file[from..]
        .windows(tag.len() + 1)
        .position(|w| w == format!("<{tag}").as_bytes())
        .unwrap()
}

fn e57(c: &mut Corpus, tmp: &Path) {
    let b = e57_file(tmp, "base.e57", false, |s| s);
    c.reads("e57/valid.e57", &b, INPUT, "\"points\":20");
    let cases: [(&str, &str, &str, &str, &str); 6] = [
        (
            "pose-translation-nan",
            "<translation",
            "x",
            "NaN",
            "pose translation [NaN, 20, 30] is not finite",
        ),
        (
            "pose-rotation-not-unit",
            "<rotation",
            "w",
            "2",
            "pose rotation quaternion has length 2, not 1",
        ),
        (
            "pose-rotation-inf",
            "<rotation",
            "x",
            "inf",
            "pose rotation [1.0, inf, 0.0, 0.0] is not finite",
        ),
        (
            "scale-x-zero",
            "<cartesianX",
            "cartesianX",
            "",
            "cartesianX scale is 0",
        ),
        (
            "scale-y-nan",
            "<cartesianY",
            "cartesianY",
            "",
            "cartesianY scale is NaN",
        ),
        (
            "offset-z-inf",
            "<cartesianZ",
            "cartesianZ",
            "",
            "cartesianZ offset is inf",
        ),
    ];
    for (name, after, tag, value, message) in cases {
        let f = e57_file(tmp, &format!("{name}.e57"), false, |s| {
            if value.is_empty() {
                // The scale or offset attribute of a scaled-integer coordinate.
                let (attr, v) = match name {
                    "scale-x-zero" => ("scale", "0"),
                    "scale-y-nan" => ("scale", "NaN"),
                    _ => ("offset", "inf"),
                };
                let from = s.find(after).unwrap();
                let a = from + s[from..].find(&format!("{attr}=\"")).unwrap() + attr.len() + 2;
                let e = a + s[a..].find('"').unwrap();
                format!("{}{v}{}", &s[..a], &s[e..])
            } else {
                set_xml(&s, after, tag, value)
            }
        });
        // The element named: the pose's rotation/translation, or the prototype's coordinate.
        let element = if value.is_empty() { tag } else { &after[1..] };
        let at = xml_at(
            &f,
            if value.is_empty() {
                "<prototype"
            } else {
                "<pose"
            },
            element,
        );
        c.fails(
            &format!("e57/{name}.e57"),
            &f,
            INPUT,
            &format!("byte {at}: scan 0: {message}"),
        );
    }
    let len = b.len() as u64;
    let with = |at: usize, v: u64| {
        let mut x = b.clone();
        put(&mut x, at, &v.to_le_bytes());
        x
    };
    c.fails(
        "e57/xml-offset-past-end.e57",
        &with(24, len + 10),
        INPUT,
        "byte 24: XML section offset",
    );
    c.fails(
        "e57/xml-length-overflows.e57",
        &with(32, u64::MAX),
        INPUT,
        "byte 32: XML section length",
    );
    c.fails(
        "e57/length-lies.e57",
        &with(16, len + 1000),
        INPUT,
        &format!(
            "byte {len}: file is truncated: header declares {}",
            len + 1000
        ),
    );
    c.fails(
        "e57/page-size-zero.e57",
        &with(40, 0),
        INPUT,
        "byte 40: page size 0",
    );
    c.fails(
        "e57/page-size-huge.e57",
        &with(40, u64::MAX),
        INPUT,
        "byte 40: page size",
    );
    let half = b.len() / 2;
    c.fails(
        "e57/cut-in-half.e57",
        &b[..half],
        INPUT,
        &format!("byte {half}: file is truncated"),
    );
    c.fails(
        "e57/cut-in-header.e57",
        &b[..20],
        INPUT,
        "byte 20: file ends inside the 48-byte E57 header",
    );
    let mut g = b"ASTM-E57".to_vec();
    g.extend(garbage(1000, 3));
    c.fails("e57/garbage-after-magic.e57", &g, INPUT, "error");
    let records = e57_file(tmp, "records-lie.e57", false, |s| {
        s.replace("recordCount=\"20\"", "recordCount=\"5000\"")
    });
    c.fails(
        "e57/record-count-more.e57",
        &records,
        INPUT,
        "invalid E57 data",
    );
    let fewer = e57_file(tmp, "records-fewer.e57", false, |s| {
        s.replace("recordCount=\"20\"", "recordCount=\"10\"")
    });
    c.reads("e57/record-count-fewer.e57", &fewer, INPUT, "\"points\":10");
    let nan = e57_file(tmp, "nan.e57", true, |s| s);
    c.reads("e57/nan-points.e57", &nan, INPUT, "\"points\":18");
}

const PLY_HEAD: &str = "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nend_header\n";

fn ply_binary(head: &str, points: &[[f32; 3]]) -> Vec<u8> {
    let mut b = head.as_bytes().to_vec();
    for p in points {
        for v in p {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    b
}

fn ply(c: &mut Corpus) {
    let pts = [
        [1.0, 2.0, 3.0],
        [4.0, 5.0, 6.0],
        [7.0, 8.0, 9.0],
        [1.5, 2.5, 3.5],
    ];
    let ok = ply_binary(PLY_HEAD, &pts);
    c.reads("ply/valid.ply", &ok, INPUT, "\"points\":4");
    let end = PLY_HEAD.len() + 36;
    c.fails(
        "ply/count-more.ply",
        &ply_binary(PLY_HEAD, &pts[..3]),
        INPUT,
        &format!("byte {end}: file ends before the 4 vertices"),
    );
    c.reads(
        "ply/count-fewer.ply",
        &ply_binary(&PLY_HEAD.replace("vertex 4", "vertex 2"), &pts),
        INPUT,
        "\"points\":2",
    );
    c.fails(
        "ply/count-u64-max.ply",
        &ply_binary(
            &PLY_HEAD.replace("vertex 4", "vertex 18446744073709551615"),
            &pts,
        ),
        INPUT,
        "byte 182: file ends before the 18446744073709551615 vertices its header declares",
    );
    c.fails(
        "ply/count-overflows-u64.ply",
        &ply_binary(
            &PLY_HEAD.replace("vertex 4", "vertex 99999999999999999999"),
            &pts,
        ),
        INPUT,
        "line 3: ",
    );
    c.fails(
        "ply/count-negative.ply",
        &ply_binary(&PLY_HEAD.replace("vertex 4", "vertex -1"), &pts),
        INPUT,
        "line 3: ",
    );
    let mut nan = pts;
    nan[1][0] = f32::NAN;
    nan[2][2] = f32::INFINITY;
    c.reads(
        "ply/nan-inf-binary.ply",
        &ply_binary(PLY_HEAD, &nan),
        INPUT,
        "\"points\":2",
    );
    let ascii = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    c.reads(
        "ply/nan-inf-ascii.ply",
        format!("{ascii}1 2 3\nnan 5 6\n7 8 inf\n").as_bytes(),
        INPUT,
        "\"points\":1",
    );
    c.fails(
        "ply/not-a-number.ply",
        format!("{ascii}1 2 3\n4 five 6\n7 8 9\n").as_bytes(),
        INPUT,
        "line 9: not a number: \"five\"",
    );
    c.reads(
        "ply/huge-number.ply",
        format!("{ascii}1 2 3\n4 1e999999999999 6\n7 8 9\n").as_bytes(),
        INPUT,
        "\"points\":2",
    );
    c.fails(
        "ply/no-end-header.ply",
        b"ply\nformat ascii 1.0\nelement vertex 3\n",
        INPUT,
        "file ends before \"end_header\"",
    );
    c.fails(
        "ply/unknown-type.ply",
        PLY_HEAD
            .replace("property float x", "property float128 x")
            .as_bytes(),
        INPUT,
        "line 4: ",
    );
    c.fails(
        "ply/no-z.ply",
        &ply_binary(&PLY_HEAD.replace("property float z\n", ""), &pts),
        INPUT,
        "line ",
    );
    c.fails(
        "ply/list-coordinate.ply",
        &ply_binary(
            &PLY_HEAD.replace("property float x", "property list uchar float x"),
            &pts,
        ),
        INPUT,
        "line 4: list property in a binary PLY vertex element",
    );
    // Elements before the vertices are skipped: one of no properties takes no bytes however
    // many it declares (found by fuzzing: counting 1.7e15 of them took minutes); one whose
    // records run past the end is an error.
    let empty = PLY_HEAD.replace(
        "element vertex 4",
        "element nothing 1744073709551616\nelement vertex 4",
    );
    c.reads(
        "ply/empty-element-huge-count.ply",
        &ply_binary(&empty, &pts),
        INPUT,
        "\"points\":4",
    );
    let before = PLY_HEAD.replace(
        "element vertex 4",
        "element face 1000000\nproperty int a\nelement vertex 4",
    );
    let end = before.len() + 48;
    c.fails(
        "ply/element-past-end.ply",
        &ply_binary(&before, &pts),
        INPUT,
        &format!("byte {end}: file ends inside element \"face\" (1000000 declared)"),
    );
    let cut = PLY_HEAD.len() + 12 + 5;
    c.fails(
        "ply/cut-in-record.ply",
        &ok[..cut],
        INPUT,
        &format!("byte {cut}: file ends before the 4 vertices"),
    );
    c.fails("ply/empty.ply", b"", INPUT, "byte 0: wrong magic number");
    let mut g = b"ply\n".to_vec();
    g.extend(garbage(500, 4));
    c.fails("ply/garbage-after-magic.ply", &g, INPUT, "line 2: ");
}

const PCD_HEAD: &str = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 4\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA binary\n";

fn pcd(c: &mut Corpus) {
    let pts = [
        [1.0f32, 2.0, 3.0],
        [4.0, 5.0, 6.0],
        [7.0, 8.0, 9.0],
        [1.5, 2.5, 3.5],
    ];
    let bin = |head: &str, pts: &[[f32; 3]]| ply_binary(head, pts);
    c.reads("pcd/valid.pcd", &bin(PCD_HEAD, &pts), INPUT, "\"points\":4");
    c.fails(
        "pcd/points-more.pcd",
        &bin(PCD_HEAD, &pts[..2]),
        INPUT,
        &format!(
            "byte {}: file ends before the 4 points",
            PCD_HEAD.len() + 24
        ),
    );
    let fewer = PCD_HEAD
        .replace("WIDTH 4", "WIDTH 2")
        .replace("POINTS 4", "POINTS 2");
    c.reads(
        "pcd/points-fewer.pcd",
        &bin(&fewer, &pts),
        INPUT,
        "\"points\":2",
    );
    let max = PCD_HEAD
        .replace("WIDTH 4", "WIDTH 18446744073709551615")
        .replace("POINTS 4", "POINTS 18446744073709551615");
    c.fails(
        "pcd/points-u64-max.pcd",
        &bin(&max, &pts),
        INPUT,
        "byte 207: file ends before the 18446744073709551615 points its header declares",
    );
    let over = PCD_HEAD.replace("POINTS 4", "POINTS 99999999999999999999");
    c.fails(
        "pcd/points-overflow-u64.pcd",
        &bin(&over, &pts),
        INPUT,
        "line 9: ",
    );
    let wh = PCD_HEAD.replace("HEIGHT 1", "HEIGHT 3");
    // WIDTH x HEIGHT is only the organization: POINTS counts.
    c.reads(
        "pcd/width-height-lie.pcd",
        &bin(&wh, &pts),
        INPUT,
        "\"points\":4",
    );
    let count = PCD_HEAD.replace("COUNT 1 1 1", "COUNT 1 1 4294967295");
    c.fails(
        "pcd/count-huge.pcd",
        &bin(&count, &pts),
        INPUT,
        "line 5: SIZE and COUNT make a point larger than the whole file",
    );
    // Found by fuzzing: an ascii file whose COUNT asked for a 222-billion-value row buffer.
    let ascii_count = PCD_HEAD
        .replace("COUNT 1 1 1", "COUNT 1 222222222221 1")
        .replace("DATA binary", "DATA ascii");
    c.fails(
        "pcd/count-huge-ascii.pcd",
        format!("{ascii_count}1 2 3\n4 5 6\n7 8 9\n1 1 1\n").as_bytes(),
        INPUT,
        "line 5: SIZE and COUNT make a point larger than the whole file",
    );
    let size = PCD_HEAD.replace("SIZE 4 4 4", "SIZE 4 4 3");
    c.fails(
        "pcd/size-3.pcd",
        &bin(&size, &pts),
        INPUT,
        "line 3: unsupported field type F of size 3",
    );
    let wh = PCD_HEAD
        .replace("WIDTH 4", "WIDTH 4294967296")
        .replace("HEIGHT 1", "HEIGHT 8589934592")
        .replace("POINTS 4\n", "");
    c.fails(
        "pcd/width-height-overflow.pcd",
        &bin(&wh, &pts),
        INPUT,
        "line 7: WIDTH x HEIGHT overflows 64 bits",
    );
    let mut nan = pts;
    nan[0][1] = f32::NAN;
    c.reads(
        "pcd/nan-binary.pcd",
        &bin(PCD_HEAD, &nan),
        INPUT,
        "\"points\":3",
    );
    let ascii = PCD_HEAD.replace("DATA binary", "DATA ascii");
    c.reads(
        "pcd/nan-ascii.pcd",
        format!("{ascii}1 2 3\nnan nan nan\n4 inf 6\n7 8 9\n").as_bytes(),
        INPUT,
        "\"points\":2",
    );
    c.fails(
        "pcd/not-a-number.pcd",
        format!("{ascii}1 2 3\n4 x 6\n7 8 9\n1 1 1\n").as_bytes(),
        INPUT,
        "line 12: not a number: \"x\"",
    );
    // binary_compressed: u32 compressed size, u32 uncompressed size, then LZF data.
    let comp = PCD_HEAD.replace("DATA binary", "DATA binary_compressed");
    let at = comp.len();
    let lzf = |csize: u32, usize_: u32| {
        let mut b = comp.as_bytes().to_vec();
        b.extend_from_slice(&csize.to_le_bytes());
        b.extend_from_slice(&usize_.to_le_bytes());
        b.extend_from_slice(&[0x02, 1, 2, 3]);
        b
    };
    c.fails(
        "pcd/compressed-size-past-end.pcd",
        &lzf(1_000_000_000, 48),
        INPUT,
        &format!("byte {at}: "),
    );
    c.fails(
        "pcd/uncompressed-size-lies.pcd",
        &lzf(4, u32::MAX),
        INPUT,
        &format!("byte {}: ", at + 4),
    );
    let mut bad = comp.as_bytes().to_vec();
    bad.extend_from_slice(&5u32.to_le_bytes());
    bad.extend_from_slice(&48u32.to_le_bytes());
    bad.extend_from_slice(&[0xE0, 0xFF, 0xFF, 0x00, 0x00]);
    c.fails(
        "pcd/lzf-corrupt.pcd",
        &bad,
        INPUT,
        &format!("byte {}: corrupt LZF data", at + 8),
    );
    c.fails(
        "pcd/no-data-line.pcd",
        PCD_HEAD.replace("DATA binary\n", "").as_bytes(),
        INPUT,
        "",
    );
    c.fails(
        "pcd/cut-in-header.pcd",
        &PCD_HEAD.as_bytes()[..40],
        INPUT,
        "",
    );
    c.fails(
        "pcd/garbage.pcd",
        &garbage(300, 5),
        INPUT,
        "byte 0: wrong magic number",
    );
}

fn text(c: &mut Corpus) {
    c.reads(
        "text/valid.xyz",
        b"1 2 3\n4 5 6\n7 8 9\n",
        INPUT,
        "\"points\":3",
    );
    c.fails(
        "text/not-a-number.xyz",
        b"1 2 3\n4 5 6\n7 8 abc\n",
        INPUT,
        "line 3: not a number: \"abc\"",
    );
    c.reads(
        "text/nan-inf.xyz",
        b"1 2 3\nnan 5 6\n7 inf 9\n1e999 1 1\n4 4 4\n",
        INPUT,
        "\"points\":2",
    );
    c.fails(
        "text/short-row.csv",
        b"x,y,z,intensity\n1,2,3,4\n5,6\n",
        INPUT,
        "line 3: expected 4 values",
    );
    c.reads(
        "text/count-lies.pts",
        b"1000\n1 2 3 10 1 2 3\n4 5 6 20 4 5 6\n",
        INPUT,
        "\"points\":2",
    );
    c.fails(
        "text/binary.txt",
        &[0xFF, 0xFE, 0x00, 0x41, b'\n'],
        INPUT,
        "line 1",
    );
    c.fails("text/garbage.xyz", &garbage(300, 6), INPUT, "line 1");
}

fn placement(c: &mut Corpus) {
    let scan = b"1 2 3\n4 5 6\n7 8 9\n";
    let mut case = |name: &str, text: &str, line: &str| {
        c.file(&format!("placement/{name}.xyz"), scan);
        let p = format!("placement/{name}.xyz.placement");
        c.file(&p, text.as_bytes());
        for cmd in INPUT {
            let file = format!("placement/{name}.xyz");
            c.expect(&file, cmd, 1, &format!("{p}: {line}"));
        }
    };
    case(
        "not-invertible",
        "# flattens z\nTRANSFORM 1 0 0 0  0 1 0 0  0 0 0 0\n",
        "line 2: TRANSFORM is not invertible",
    );
    case(
        "nan",
        "TRANSLATE nan 0 0\n",
        "line 1: not a number: \"nan\"",
    );
    case(
        "inf",
        "ROTATE-DEG 0 0 inf\n",
        "line 1: not a number: \"inf\"",
    );
    case(
        "combined",
        "TRANSLATE 1 2 3\nTRANSFORM 1 0 0 0 0 1 0 0 0 0 1 0\n",
        "line 2: TRANSFORM cannot be combined",
    );
    case(
        "overflows",
        "TRANSFORM 1e300 0 0 0  0 1e300 0 0  0 0 1e300 0\n",
        "line 1: TRANSFORM is not invertible (determinant inf",
    );
    case(
        "negative-box",
        "OBB-ANGLES SOCS 0 0 0 -1 1 1 0 0 0\n",
        "line 1: half lengths must not be negative",
    );
}

/// Fixes the dataset header's checksum (bytes 12..16 over the 64 bytes with them zeroed).
fn fix_header_crc(b: &mut [u8]) {
    put(b, 12, &[0; 4]);
    let crc = crc32fast::hash(&b[..64]);
    put(b, 12, &crc.to_le_bytes());
}

fn dataset(c: &mut Corpus, tmp: &Path) {
    let src = tmp.join("base-for-myr.las");
    std::fs::write(&src, synth(tmp, "base-myr.las", 2000)).unwrap();
    let out = tmp.join("base.myr");
    let mut options = myriad_build::convert::ConvertOptions::new(&out);
    options.force = true;
    options.params.capacity = 500;
    myriad_build::convert::convert(&[src], &options, &myriad_build::convert::Silent)
        .expect("convert");
    let b = std::fs::read(&out).unwrap();
    let len = b.len();
    c.reads("myr/valid.myr", &b, DATASET, "\"points\":2000");
    let with = |at: usize, v: &[u8]| {
        let mut x = b.clone();
        put(&mut x, at, v);
        x
    };
    c.fails(
        "myr/empty.myr",
        b"",
        DATASET,
        "byte 0: file ends inside the 64-byte dataset header",
    );
    c.fails(
        "myr/cut-in-header.myr",
        &b[..40],
        DATASET,
        "byte 40: file ends inside the 64-byte dataset header",
    );
    c.fails(
        "myr/cut-in-half.myr",
        &b[..len / 2],
        DATASET,
        &format!(
            "byte {}: file has {} bytes, its header says {len}",
            len / 2,
            len / 2
        ),
    );
    c.fails(
        "myr/header-checksum.myr",
        &with(56, &1u64.to_le_bytes()),
        DATASET,
        "byte 12: header checksum mismatch",
    );
    let mut v = with(8, &99u32.to_le_bytes());
    fix_header_crc(&mut v);
    c.fails(
        "myr/version-99.myr",
        &v,
        DATASET,
        "byte 8: format version 99",
    );
    let mut m = with(16, &(u64::MAX - 3).to_le_bytes());
    fix_header_crc(&mut m);
    c.fails(
        "myr/metadata-past-end.myr",
        &m,
        DATASET,
        "byte 16: metadata lies past the end of the file",
    );
    let mut m = with(24, &u32::MAX.to_le_bytes());
    fix_header_crc(&mut m);
    c.fails(
        "myr/metadata-length-huge.myr",
        &m,
        DATASET,
        "byte 16: metadata lies past the end of the file",
    );
    // A metadata number replaced by null (what serde_json writes for NaN), checksums fixed.
    let (moff, mlen) = (u64_at(&b, 16) as usize, u32_at(&b, 24) as usize);
    let json = String::from_utf8(b[moff..moff + mlen].to_vec()).unwrap();
    let key = json.find("\"bounds\"").unwrap();
    let num = key
        + json[key..]
            .find(|ch: char| ch.is_ascii_digit() || ch == '-')
            .unwrap();
    let num_end = num + json[num..].find([',', '\n', ']']).unwrap();
    let mut nulled = json.clone();
    nulled.replace_range(num..num_end, &format!("{:<w$}", "null", w = num_end - num));
    let mut m = b.clone();
    put(&mut m, moff, nulled.as_bytes());
    put(
        &mut m,
        28,
        &crc32fast::hash(nulled.as_bytes()).to_le_bytes(),
    );
    fix_header_crc(&mut m);
    c.fails(
        "myr/metadata-null-number.myr",
        &m,
        DATASET,
        &format!("byte {moff}: metadata: expected a number"),
    );
    // Damage inside the file that only some commands read: the root hierarchy page and the
    // first node page (the point data starts after the header).
    let (hoff, hlen) = (u64_at(&b, 32) as usize, u32_at(&b, 40) as usize);
    let mut h = b.clone();
    h[hoff + hlen / 2] ^= 0x55;
    let name = c.file("myr/hierarchy-damaged.myr", &h);
    c.expect(&name, "info", 0, "\"points\":2000");
    c.expect(&name, "verify", 1, &format!("byte {hoff}: "));
    c.expect(&name, "extract", 1, &format!("byte {hoff}: "));
    c.expect(&name, "render", 1, &format!("byte {hoff}: "));
    let mut n = b.clone();
    n[64 + 100] ^= 0x55;
    let name = c.file("myr/node-damaged.myr", &n);
    c.expect(&name, "info", 0, "\"points\":2000");
    c.expect(&name, "verify", 1, "byte 64: ");
    c.expect(&name, "extract", 1, "byte 64: ");
    c.expect(&name, "render", 0, "");
    let mut g = b"MYRIAD\x00\x1a".to_vec();
    g.extend(garbage(500, 7));
    c.fails(
        "myr/garbage-after-magic.myr",
        &g,
        DATASET,
        "byte 12: header checksum mismatch",
    );
    c.fails(
        "myr/wrong-magic.myr",
        &garbage(500, 8),
        DATASET,
        "byte 0: not a Myriad dataset",
    );
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    let tmp = std::env::temp_dir().join(format!("myriad-make-corpus-{}", std::process::id()));
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
    las(&mut c, &tmp);
    laz(&mut c, &tmp);
    e57(&mut c, &tmp);
    ply(&mut c);
    pcd(&mut c);
    text(&mut c);
    placement(&mut c);
    dataset(&mut c, &tmp);
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
