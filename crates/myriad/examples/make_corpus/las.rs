//! LAS and LAZ files: header fields, VLRs, counts, truncations; LAZ chunks.

use super::*;

pub(super) fn las(c: &mut Corpus, tmp: &Path) {
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
    // A scale so fine that the dataset's integer grid cannot number the data's extent: the file
    // reads (every X is its offset), the build refuses it.
    let tiny = c.file("las/scale-x-tiny.las", &with(131, &f64le(1e-300)));
    c.expect(&tiny, "info", 0, "\"points\":300");
    c.expect(
        &tiny,
        "convert",
        1,
        "its X scale is too fine for the data's extent",
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
pub(super) fn laz_of(las: &[u8], chunk: u32) -> Vec<u8> {
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

pub(super) fn laz(c: &mut Corpus, tmp: &Path) {
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
