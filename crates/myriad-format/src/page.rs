//! Node pages: one node's points, column by column, each column compressed on its own (so a
//! reader can later fetch only the columns it draws) and checked by its own CRC-32.
//!
//! Positions are integers on the dataset's grid (`round((x - offset) / scale)`), relative to the
//! node's smallest integer per axis, in as many bytes as the node's extent needs (the bit count
//! per axis is recorded; whole bytes are stored: on KY, byte planes through zstd take 5.78 bytes
//! per point for positions, the same deltas bit-packed 6.39, examples/position_coding.rs), each
//! axis as the zigzag difference to the previous point's. Every
//! column is byte-shuffled (all first bytes of the elements, then all second bytes, ...) before
//! zstd: neighbouring points share their high bytes. GPS time is delta coded on its bit pattern
//! first. Builders put the points of each level of detail in acquisition order where they can, so
//! that neighbours in a page are neighbours along a scan line. Byte layout: docs/format.md.

use myriad_core::{PointBatch, Schema};

pub const PAGE_MAGIC: &[u8; 4] = b"MYRN";
/// Bytes before the column directory.
pub const PAGE_HEAD: usize = 36;
/// Bytes per column directory entry.
pub const DIR_ENTRY: usize = 16;
/// Column id of positions; optional column `k` of [`PointBatch::column_le`] is `k + 1`; extra
/// bytes are [`EXTRA_COLUMN`].
pub const POSITION_COLUMN: u8 = 0;
pub const EXTRA_COLUMN: u8 = 16;
const GPS_TIME_COLUMN: u8 = 11;

/// Column encodings.
const ENC_PLANES: u8 = 0;
const ENC_DELTA_PLANES: u8 = 1;
/// Codecs.
const CODEC_ZSTD: u8 = 1;

/// zstd level for node columns (docs/format.md). On KY, level 1 stores 1.0 % more than level 3
/// (12.41 against 12.28 bytes per point) and encodes the pages in 0.50 s rather than 0.63 s on
/// one core: the build's speed is worth more than that percent (issue 19).
pub const ZSTD_LEVEL: i32 = 1;

/// The integer grid positions live on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantization {
    pub scale: [f64; 3],
    pub offset: [f64; 3],
}

impl Quantization {
    pub fn to_int(&self, p: [f64; 3]) -> [i64; 3] {
        std::array::from_fn(|a| round_to_i64((p[a] - self.offset[a]) / self.scale[a]))
    }
    pub fn to_world(&self, v: [i64; 3]) -> [f64; 3] {
        std::array::from_fn(|a| v[a] as f64 * self.scale[a] + self.offset[a])
    }
}

/// `v.round() as i64` (halves away from zero, saturating, NaN to 0), without the library call
/// that `round` is on baseline x86-64 and without a branch: the truncation is exact and so is
/// the fraction it leaves (below 2^52; above, `v` is whole and the fraction 0).
#[inline]
fn round_to_i64(v: f64) -> i64 {
    let t = v as i64;
    let fraction = v - t as f64;
    t.saturating_add((fraction >= 0.5) as i64 - (fraction <= -0.5) as i64)
}

/// Why a page could not be decoded.
#[derive(Debug, Clone, PartialEq)]
pub struct PageError {
    /// Byte offset inside the page.
    pub at: usize,
    pub message: String,
}

fn bad(at: usize, message: impl Into<String>) -> PageError {
    PageError {
        at,
        message: message.into(),
    }
}

fn shuffle(bytes: &[u8], width: usize) -> Vec<u8> {
    if width <= 1 {
        return bytes.to_vec();
    }
    let n = bytes.len() / width;
    let mut out = vec![0u8; bytes.len()];
    // Plane by plane: each written in order.
    for (b, plane) in out.chunks_exact_mut(n.max(1)).enumerate() {
        for (o, e) in plane.iter_mut().zip(bytes.chunks_exact(width)) {
            *o = e[b];
        }
    }
    out
}

fn unshuffle(bytes: &[u8], width: usize) -> Vec<u8> {
    /// A value's bytes gathered from its planes, the width known to the compiler (the node
    /// pages' columns are 2, 4, 6 and 8 bytes wide, extra bytes often 3), so that the loop over
    /// the planes unrolls.
    fn fixed<const W: usize>(bytes: &[u8]) -> Vec<u8> {
        let n = bytes.len() / W;
        let mut out = vec![0u8; bytes.len()];
        let planes: [&[u8]; W] = std::array::from_fn(|b| &bytes[b * n..(b + 1) * n]);
        for (i, e) in out.chunks_exact_mut(W).enumerate() {
            for (v, plane) in e.iter_mut().zip(&planes) {
                *v = plane[i];
            }
        }
        out
    }
    match width {
        0 | 1 => bytes.to_vec(),
        2 => fixed::<2>(bytes),
        3 => fixed::<3>(bytes),
        4 => fixed::<4>(bytes),
        6 => fixed::<6>(bytes),
        8 => fixed::<8>(bytes),
        _ => {
            let n = bytes.len() / width;
            let mut out = vec![0u8; bytes.len()];
            for (i, e) in out.chunks_exact_mut(width).enumerate() {
                for (b, v) in e.iter_mut().enumerate() {
                    *v = bytes[b * n + i];
                }
            }
            out
        }
    }
}

/// The `n` values of `width` bytes in byte planes, as integers: plane by plane, each shifted
/// into place (no element copied through a buffer of its width).
fn plane_values(planes: &[u8], n: usize, width: usize) -> Vec<u64> {
    let mut values = vec![0u64; n];
    for (b, plane) in planes.chunks_exact(n.max(1)).take(width).enumerate() {
        for (v, &byte) in values.iter_mut().zip(plane) {
            *v |= (byte as u64) << (8 * b);
        }
    }
    values
}

/// Replaces little-endian u64 elements by their wrapping difference to the previous one.
fn delta_u64(bytes: &mut [u8]) {
    let mut prev = 0u64;
    for e in bytes.chunks_exact_mut(8) {
        let v = u64::from_le_bytes(e.try_into().unwrap());
        e.copy_from_slice(&v.wrapping_sub(prev).to_le_bytes());
        prev = v;
    }
}

fn undelta_u64(bytes: &mut [u8]) {
    let mut prev = 0u64;
    for e in bytes.chunks_exact_mut(8) {
        let v = u64::from_le_bytes(e.try_into().unwrap()).wrapping_add(prev);
        e.copy_from_slice(&v.to_le_bytes());
        prev = v;
    }
}

struct Column {
    id: u8,
    encoding: u8,
    width: u8,
    raw_len: usize,
    stored: Vec<u8>,
}

#[cfg(not(target_arch = "wasm32"))]
fn compress_column(id: u8, encoding: u8, width: usize, planes: Vec<u8>) -> Column {
    Column {
        id,
        encoding,
        width: width as u8,
        raw_len: planes.len(),
        stored: crate::codec::compress(&planes, ZSTD_LEVEL),
    }
}

/// The difference `d` (modulo 2^(8w)) as a zigzag number of `w` bytes: small differences of
/// either sign become small numbers.
fn zigzag(d: u64, w: usize) -> u64 {
    if w == 0 {
        return 0;
    }
    let bits = 8 * w as u32;
    let signed = ((d << (64 - bits)) as i64) >> (64 - bits);
    let z = ((signed << 1) ^ (signed >> 63)) as u64;
    if bits == 64 {
        z
    } else {
        z & ((1u64 << bits) - 1)
    }
}

/// Inverse of [`zigzag`]: the difference (to be taken modulo 2^(8w)).
fn unzigzag(z: u64) -> u64 {
    ((z >> 1) as i64 ^ -((z & 1) as i64)) as u64
}

/// Bits needed for values `0..=range`.
fn bits_for(range: u64) -> u8 {
    (64 - range.leading_zeros()) as u8
}

#[cfg(not(target_arch = "wasm32"))]
/// Encodes `batch` as a node page. Positions are rounded to `q`'s grid.
pub fn encode(batch: &PointBatch, q: &Quantization) -> Vec<u8> {
    let ints: Vec<[i64; 3]> = batch.positions.iter().map(|&p| q.to_int(p)).collect();
    encode_ints(batch, &ints)
}

#[cfg(not(target_arch = "wasm32"))]
/// [`encode`], when every position lies on `q`'s grid: decoding gives back each coordinate's
/// bits (`None` otherwise). What a build spills its points as (myriad-build's `spill.rs`).
pub fn encode_on_grid(batch: &PointBatch, q: &Quantization) -> Option<Vec<u8>> {
    let mut ints = Vec::with_capacity(batch.len());
    for &p in &batch.positions {
        let v = q.to_int(p);
        if q.to_world(v).map(f64::to_bits) != p.map(f64::to_bits) {
            return None;
        }
        ints.push(v);
    }
    Some(encode_ints(batch, &ints))
}

#[cfg(not(target_arch = "wasm32"))]
/// [`encode`] of positions already on the grid (`ints`, one per point).
fn encode_ints(batch: &PointBatch, ints: &[[i64; 3]]) -> Vec<u8> {
    let n = batch.len();
    let mut origin = [0i64; 3];
    let mut bits = [0u8; 3];
    if n > 0 {
        for a in 0..3 {
            let lo = ints.iter().map(|v| v[a]).min().unwrap();
            let hi = ints.iter().map(|v| v[a]).max().unwrap();
            origin[a] = lo;
            bits[a] = bits_for(hi.wrapping_sub(lo) as u64);
        }
    }
    let widths = bits.map(|b| (b as usize).div_ceil(8));
    let mut columns = Vec::new();
    // Positions: the three axes one after the other, each in its own byte planes. An axis's
    // differences first, then its planes one by one, each a loop the compiler vectorizes
    // (writing each value's bytes to its planes at once took 35.3 ns a point for a whole
    // 65,536-point page, against 33.4).
    let mut planes = vec![0u8; n * widths.iter().sum::<usize>()];
    let mut differences = vec![0u64; n];
    let mut rest = &mut planes[..];
    for a in 0..3 {
        let mut prev = 0u64;
        for (d, v) in differences.iter_mut().zip(ints) {
            let rel = v[a].wrapping_sub(origin[a]) as u64;
            *d = zigzag(rel.wrapping_sub(prev), widths[a]);
            prev = rel;
        }
        let (axis, after) = rest.split_at_mut(n * widths[a]);
        for (b, plane) in axis.chunks_exact_mut(n.max(1)).enumerate() {
            for (o, d) in plane.iter_mut().zip(&differences) {
                *o = (d >> (8 * b)) as u8;
            }
        }
        rest = after;
    }
    columns.push(Column {
        id: POSITION_COLUMN,
        encoding: ENC_DELTA_PLANES,
        width: 0,
        raw_len: planes.len(),
        stored: crate::codec::compress(&planes, ZSTD_LEVEL),
    });
    for k in 0..PointBatch::COLUMNS {
        let id = k as u8 + 1;
        if id == GPS_TIME_COLUMN {
            if let Some((width, mut raw)) = batch.column_le(k) {
                delta_u64(&mut raw);
                let planes = shuffle(&raw, width);
                columns.push(compress_column(id, ENC_DELTA_PLANES, width, planes));
            }
        } else if let Some((width, planes)) = batch.column_planes(k) {
            columns.push(compress_column(id, ENC_PLANES, width, planes));
        }
    }
    if let Some(e) = &batch.extra_bytes {
        let planes = shuffle(e, batch.extra_stride);
        columns.push(compress_column(
            EXTRA_COLUMN,
            ENC_PLANES,
            batch.extra_stride,
            planes,
        ));
    }

    let body: usize = columns.iter().map(|c| c.stored.len()).sum();
    let mut out = Vec::with_capacity(PAGE_HEAD + columns.len() * DIR_ENTRY + 4 + body);
    out.extend_from_slice(PAGE_MAGIC);
    out.extend_from_slice(&(n as u32).to_le_bytes());
    for o in origin {
        out.extend_from_slice(&o.to_le_bytes());
    }
    out.extend_from_slice(&bits);
    out.push(columns.len() as u8);
    for c in &columns {
        out.extend_from_slice(&[c.id, c.encoding, c.width, CODEC_ZSTD]);
        out.extend_from_slice(&(c.stored.len() as u32).to_le_bytes());
        out.extend_from_slice(&(c.raw_len as u32).to_le_bytes());
        out.extend_from_slice(&crc32fast::hash(&c.stored).to_le_bytes());
    }
    let head_crc = crc32fast::hash(&out);
    out.extend_from_slice(&head_crc.to_le_bytes());
    for c in &columns {
        out.extend_from_slice(&c.stored);
    }
    out
}

/// Decodes a node page into a batch with the columns of `schema`. Every column's checksum and
/// length is checked; an error names the byte inside the page.
pub fn decode(page: &[u8], schema: &Schema, q: &Quantization) -> Result<PointBatch, PageError> {
    let u32_at = |o: usize| u32::from_le_bytes(page[o..o + 4].try_into().unwrap());
    if page.len() < PAGE_HEAD {
        return Err(bad(page.len(), "page shorter than its 36-byte head"));
    }
    if &page[..4] != PAGE_MAGIC {
        return Err(bad(0, "not a node page (wrong magic)"));
    }
    let n = u32_at(4) as usize;
    let origin: [i64; 3] = std::array::from_fn(|a| {
        i64::from_le_bytes(page[8 + 8 * a..16 + 8 * a].try_into().unwrap())
    });
    let bits: [u8; 3] = page[32..35].try_into().unwrap();
    if let Some(a) = (0..3).find(|&a| bits[a] > 64) {
        return Err(bad(32 + a, format!("{} bits per coordinate", bits[a])));
    }
    let widths = bits.map(|b| (b as usize).div_ceil(8));
    let count = page[35] as usize;
    let dir_end = PAGE_HEAD + count * DIR_ENTRY;
    if page.len() < dir_end + 4 {
        return Err(bad(page.len(), "page ends inside its column directory"));
    }
    if crc32fast::hash(&page[..dir_end]) != u32_at(dir_end) {
        return Err(bad(dir_end, "head checksum mismatch"));
    }
    let mut batch = PointBatch::with_schema(schema, 0);
    let mut at = dir_end + 4;
    let mut have_positions = false;
    for c in 0..count {
        let d = PAGE_HEAD + c * DIR_ENTRY;
        let (id, encoding, width, codec) =
            (page[d], page[d + 1], page[d + 2] as usize, page[d + 3]);
        let stored_len = u32_at(d + 4) as usize;
        let raw_len = u32_at(d + 8) as usize;
        let crc = u32_at(d + 12);
        if page.len() - at < stored_len {
            return Err(bad(
                d + 4,
                format!("column {id} runs past the end of the page"),
            ));
        }
        let stored = &page[at..at + stored_len];
        if crc32fast::hash(stored) != crc {
            return Err(bad(at, format!("column {id}: checksum mismatch")));
        }
        if codec != CODEC_ZSTD {
            return Err(bad(d + 3, format!("column {id}: unknown codec {codec}")));
        }
        let expected = match id {
            POSITION_COLUMN => n * widths.iter().sum::<usize>(),
            EXTRA_COLUMN => n * width,
            k if (k as usize) <= PointBatch::COLUMNS => {
                let size = PointBatch::column_size(k as usize - 1);
                if width != size {
                    return Err(bad(
                        d + 2,
                        format!("column {id}: width {width}, not {size}"),
                    ));
                }
                n * size
            }
            _ => return Err(bad(d, format!("unknown column {id}"))),
        };
        if raw_len != expected {
            return Err(bad(
                d + 8,
                format!("column {id}: {raw_len} bytes for {n} points"),
            ));
        }
        let planes = crate::codec::decompress(stored, raw_len)
            .map_err(|e| bad(at, format!("column {id}: {e}")))?;
        let got = planes.len();
        if got != raw_len {
            return Err(bad(at, format!("column {id}: {got} bytes, not {raw_len}")));
        }
        match id {
            POSITION_COLUMN => {
                if encoding != ENC_DELTA_PLANES {
                    return Err(bad(
                        d + 1,
                        format!("positions: unknown encoding {encoding}"),
                    ));
                }
                let mut axes: [Vec<i64>; 3] = Default::default();
                let mut p = 0;
                for a in 0..3 {
                    let w = widths[a];
                    let raw = plane_values(&planes[p..p + n * w], n, w);
                    p += n * w;
                    axes[a] = if w == 0 {
                        vec![origin[a]; n]
                    } else {
                        let mask = if w == 8 {
                            u64::MAX
                        } else {
                            (1u64 << (8 * w)) - 1
                        };
                        let mut prev = 0u64;
                        raw.into_iter()
                            .map(|z| {
                                let rel = prev.wrapping_add(unzigzag(z)) & mask;
                                prev = rel;
                                origin[a].wrapping_add(rel as i64)
                            })
                            .collect()
                    };
                }
                batch.positions = (0..n)
                    .map(|i| q.to_world([axes[0][i], axes[1][i], axes[2][i]]))
                    .collect();
                have_positions = true;
            }
            _ => {
                let mut raw = unshuffle(&planes, width);
                if encoding == ENC_DELTA_PLANES {
                    undelta_u64(&mut raw);
                } else if encoding != ENC_PLANES {
                    return Err(bad(
                        d + 1,
                        format!("column {id}: unknown encoding {encoding}"),
                    ));
                }
                if id == EXTRA_COLUMN {
                    if schema.extra_bytes > 0 && width == schema.extra_bytes {
                        batch.extra_bytes = Some(raw);
                    }
                } else {
                    let k = id as usize - 1;
                    let wanted =
                        PointBatch::column_attribute(k).is_some_and(|attr| schema.has(&attr));
                    if wanted {
                        batch.set_column_le(k, &raw);
                    }
                }
            }
        }
        at += stored_len;
    }
    if !have_positions {
        return Err(bad(PAGE_HEAD, "page has no positions"));
    }
    if !batch.is_consistent() {
        return Err(bad(
            PAGE_HEAD,
            "a column the dataset has is missing from the page",
        ));
    }
    Ok(batch)
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_core::{Attribute, Schema};

    #[test]
    fn rounding_is_the_librarys() {
        let mut values = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            -2.5,
            0.49999999999999994,
            -0.49999999999999994,
            4503599627370495.5,
            4503599627370497.0,
            -4503599627370495.5,
            9.223372036854775e18,
            9.223372036854776e18,
            -9.223372036854776e18,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MIN_POSITIVE,
        ];
        // Coordinates as a LAS reader makes them, re-quantized, and values between.
        let mut x = 0x2545f4914f6cdd1du64;
        for _ in 0..100_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let raw = (x % 2_000_000_000) as f64 - 1e9;
            values.push((raw * 0.001 + 500_000.0 - 500_000.0) / 0.001);
            values.push(raw / 2.0);
            values.push(raw / 7.0);
            values.push(f64::from_bits(x));
        }
        for v in values {
            assert_eq!(round_to_i64(v), v.round() as i64, "{v:e}");
        }
    }

    fn sample(n: usize) -> PointBatch {
        let mut schema = Schema::for_las_format(3);
        schema.extra_bytes = 3;
        let mut b = PointBatch::with_schema(&schema, n);
        for i in 0..n {
            let f = i as f64;
            b.positions
                .push([1000.0 + f * 0.01, 2000.0 - f * 0.02, 5.0 + (f * 0.1).sin()]);
            b.intensity.as_mut().unwrap().push(i as u16 * 7);
            b.return_number.as_mut().unwrap().push((i % 5) as u8 + 1);
            b.number_of_returns.as_mut().unwrap().push(5);
            b.classification.as_mut().unwrap().push((i % 7) as u8);
            b.classification_flags
                .as_mut()
                .unwrap()
                .push((i % 16) as u8);
            b.scan_flags.as_mut().unwrap().push((i % 4) as u8);
            b.scan_angle.as_mut().unwrap().push(i as f32 * 0.006 - 10.0);
            b.user_data.as_mut().unwrap().push(i as u8);
            b.point_source_id.as_mut().unwrap().push(3);
            b.gps_time.as_mut().unwrap().push(3.0e8 + f * 1e-5);
            b.rgb
                .as_mut()
                .unwrap()
                .push([i as u16, 65535 - i as u16, 256]);
            b.extra_bytes.as_mut().unwrap().extend([i as u8, 1, 2]);
        }
        b
    }

    const Q: Quantization = Quantization {
        scale: [0.001; 3],
        offset: [1000.0, 2000.0, 0.0],
    };

    #[test]
    fn round_trip_every_column() {
        let b = sample(5000);
        let page = encode(&b, &Q);
        let back = decode(&page, &b.schema(), &Q).unwrap();
        assert_eq!(back.len(), 5000);
        for (p, q) in b.positions.iter().zip(&back.positions) {
            for a in 0..3 {
                assert!((p[a] - q[a]).abs() <= 0.0005 + 1e-9, "{p:?} {q:?}");
            }
        }
        let mut expected = b.clone();
        expected.positions = back.positions.clone();
        assert_eq!(back, expected);
        // Positions on the grid survive exactly.
        let again = decode(&encode(&back, &Q), &b.schema(), &Q).unwrap();
        assert_eq!(again, back);
    }

    #[test]
    fn a_subset_of_columns_and_empty_pages() {
        let b = sample(100);
        let page = encode(&b, &Q);
        let only = Schema::new(vec![Attribute::Rgb]);
        let back = decode(&page, &only, &Q).unwrap();
        assert_eq!(back.rgb, b.rgb);
        assert!(back.intensity.is_none() && back.extra_bytes.is_none());
        let empty = PointBatch::with_schema(&b.schema(), 0);
        assert_eq!(
            decode(&encode(&empty, &Q), &b.schema(), &Q).unwrap().len(),
            0
        );
    }

    #[test]
    fn every_flipped_byte_is_caught_or_harmless() {
        let b = sample(300);
        let schema = b.schema();
        let page = encode(&b, &Q);
        let good = decode(&page, &schema, &Q).unwrap();
        for i in 0..page.len() {
            let mut p = page.clone();
            p[i] ^= 0x40;
            // Either an error, or (a flip in a field the decoder does not need, such as the
            // encoding of a column that is not requested) the same points: never garbage.
            if let Ok(d) = decode(&p, &schema, &Q) {
                assert_eq!(d, good, "flip at {i} gave other points");
            }
        }
    }
}
