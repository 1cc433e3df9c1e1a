//! LAS point records <-> [`PointBatch`] columns, for point formats 0-10 (LAS 1.4 R15, tables 7-17).
//!
//! Legacy formats 0-5 share this 20-byte core:
//!
//! | offset | size | type | field |
//! |---|---|---|---|
//! | 0 | 12 | i32 x3 | X, Y, Z (scaled integers) |
//! | 12 | 2 | u16 | intensity |
//! | 14 | 1 | bits | return number (0-2), number of returns (3-5), scan direction (6), edge (7) |
//! | 15 | 1 | bits | classification (0-4), synthetic (5), key point (6), withheld (7) |
//! | 16 | 1 | i8 | scan angle rank, degrees |
//! | 17 | 1 | u8 | user data |
//! | 18 | 2 | u16 | point source id |
//!
//! then GPS time f64 (1, 3, 4, 5 at 20), RGB 3 x u16 (2 at 20; 3, 5 at 28), wave packet (4 at 28,
//! 5 at 34). Extended formats 6-10 share a 30-byte core:
//!
//! | offset | size | type | field |
//! |---|---|---|---|
//! | 0 | 12 | i32 x3 | X, Y, Z |
//! | 12 | 2 | u16 | intensity |
//! | 14 | 1 | bits | return number (0-3), number of returns (4-7) |
//! | 15 | 1 | bits | synthetic, key point, withheld, overlap (0-3), scanner channel (4-5), scan direction (6), edge (7) |
//! | 16 | 1 | u8 | classification |
//! | 17 | 1 | u8 | user data |
//! | 18 | 2 | i16 | scan angle, 0.006 degree units |
//! | 20 | 2 | u16 | point source id |
//! | 22 | 8 | f64 | GPS time |
//!
//! then RGB (7, 8, 10 at 30), NIR u16 (8, 10 at 36), wave packet (9 at 30, 10 at 38). A wave packet
//! is u8 descriptor index, u64 byte offset, u32 size, f32 return location, f32 x3 x(t): 29 bytes.
//! Extra bytes follow the standard fields, up to the header's record length.

use myriad_core::{PointBatch, Schema, WavePacket};

/// Byte offsets of the optional fields of one point format.
#[derive(Debug, Clone, Copy)]
pub struct Layout {
    pub format: u8,
    pub extended: bool,
    pub gps: Option<usize>,
    pub rgb: Option<usize>,
    pub nir: Option<usize>,
    pub wave: Option<usize>,
    /// Length of the standard fields; extra bytes start here.
    pub base_len: usize,
}

impl Layout {
    pub fn new(format: u8) -> Option<Layout> {
        let (gps, rgb, nir, wave, base_len) = match format {
            0 => (None, None, None, None, 20),
            1 => (Some(20), None, None, None, 28),
            2 => (None, Some(20), None, None, 26),
            3 => (Some(20), Some(28), None, None, 34),
            4 => (Some(20), None, None, Some(28), 57),
            5 => (Some(20), Some(28), None, Some(34), 63),
            6 => (Some(22), None, None, None, 30),
            7 => (Some(22), Some(30), None, None, 36),
            8 => (Some(22), Some(30), Some(36), None, 38),
            9 => (Some(22), None, None, Some(30), 59),
            10 => (Some(22), Some(30), Some(36), Some(38), 67),
            _ => return None,
        };
        Some(Layout {
            format,
            extended: format >= 6,
            gps,
            rgb,
            nir,
            wave,
            base_len,
        })
    }
}

/// Scale and offset per axis: world = raw * scale + offset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantization {
    pub scale: [f64; 3],
    pub offset: [f64; 3],
}

impl Quantization {
    /// A LAS header's scales and offsets.
    pub fn of(header: &las::Header) -> Quantization {
        let t = header.transforms();
        Quantization {
            scale: [t.x.scale, t.y.scale, t.z.scale],
            offset: [t.x.offset, t.y.offset, t.z.offset],
        }
    }
}

fn u16_at(r: &[u8], o: usize) -> u16 {
    u16::from_le_bytes([r[o], r[o + 1]])
}
fn i32_at(r: &[u8], o: usize) -> i32 {
    i32::from_le_bytes(r[o..o + 4].try_into().unwrap())
}
fn f32_at(r: &[u8], o: usize) -> f32 {
    f32::from_le_bytes(r[o..o + 4].try_into().unwrap())
}
fn f64_at(r: &[u8], o: usize) -> f64 {
    f64::from_le_bytes(r[o..o + 8].try_into().unwrap())
}

/// A record's position.
#[inline]
pub fn position(r: &[u8], q: &Quantization) -> [f64; 3] {
    [
        i32_at(r, 0) as f64 * q.scale[0] + q.offset[0],
        i32_at(r, 4) as f64 * q.scale[1] + q.offset[1],
        i32_at(r, 8) as f64 * q.scale[2] + q.offset[2],
    ]
}

/// Appends the records in `bytes` (each `record_len` long) to `batch`, which must have the columns
/// of `Schema::for_las_format(layout.format)` plus extra bytes of `record_len - base_len`.
pub fn decode(
    bytes: &[u8],
    record_len: usize,
    layout: &Layout,
    q: &Quantization,
    batch: &mut PointBatch,
) {
    // A few thousand records at a time, so that the passes over them (one a field) find them in
    // the core's cache rather than in memory.
    for block in bytes.chunks(record_len * DECODE_BLOCK) {
        decode_block(block, record_len, layout, q, batch);
    }
}

/// Records [`decode`] decodes at once (8192 of 30-70 bytes: 240-570 KB).
const DECODE_BLOCK: usize = 8192;

fn decode_block(
    bytes: &[u8],
    record_len: usize,
    layout: &Layout,
    q: &Quantization,
    batch: &mut PointBatch,
) {
    // Column by column: one tight loop over the records per field, each extending its column
    // by an iterator of known length (no per-point capacity checks).
    let records = || bytes.chunks_exact(record_len);
    batch.positions.extend(records().map(|r| position(r, q)));
    macro_rules! col {
        ($f:ident, $r:ident => $v:expr) => {
            batch
                .$f
                .as_mut()
                .expect(concat!("batch lacks ", stringify!($f)))
                .extend(records().map(|$r| $v))
        };
    }
    col!(intensity, r => u16_at(r, 12));
    if layout.extended {
        col!(return_number, r => r[14] & 0x0F);
        col!(number_of_returns, r => r[14] >> 4);
        col!(classification_flags, r => r[15] & 0x0F);
        col!(scanner_channel, r => (r[15] >> 4) & 0x03);
        col!(scan_flags, r => r[15] >> 6);
        col!(classification, r => r[16]);
        col!(user_data, r => r[17]);
        col!(scan_angle, r => (i16::from_le_bytes([r[18], r[19]]) as f64 * 0.006) as f32);
        col!(point_source_id, r => u16_at(r, 20));
    } else {
        col!(return_number, r => r[14] & 0x07);
        col!(number_of_returns, r => (r[14] >> 3) & 0x07);
        col!(scan_flags, r => r[14] >> 6);
        col!(classification, r => r[15] & 0x1F);
        col!(classification_flags, r => r[15] >> 5);
        col!(scan_angle, r => r[16] as i8 as f32);
        col!(user_data, r => r[17]);
        col!(point_source_id, r => u16_at(r, 18));
    }
    if let Some(o) = layout.gps {
        col!(gps_time, r => f64_at(r, o));
    }
    if let Some(o) = layout.rgb {
        col!(rgb, r => [u16_at(r, o), u16_at(r, o + 2), u16_at(r, o + 4)]);
    }
    if let Some(o) = layout.nir {
        col!(nir, r => u16_at(r, o));
    }
    if let Some(o) = layout.wave {
        col!(wave_packet, r => WavePacket {
            descriptor_index: r[o],
            byte_offset: u64::from_le_bytes(r[o + 1..o + 9].try_into().unwrap()),
            size: u32::from_le_bytes(r[o + 9..o + 13].try_into().unwrap()),
            return_point_location: f32_at(r, o + 13),
            x_t: f32_at(r, o + 17),
            y_t: f32_at(r, o + 21),
            z_t: f32_at(r, o + 25),
        });
    }
    if record_len > layout.base_len {
        let extra = batch.extra_bytes.as_mut().expect("batch lacks extra_bytes");
        for r in records() {
            extra.extend_from_slice(&r[layout.base_len..]);
        }
    }
}

/// The column layout [`decode`] fills for a format with `extra` extra bytes.
pub fn batch_for(layout: &Layout, extra: usize, capacity: usize) -> PointBatch {
    let mut s = Schema::for_las_format(layout.format);
    s.extra_bytes = extra;
    PointBatch::with_schema(&s, capacity)
}

/// Same result as `f64::round` for |v| < 2^52, without the library call that `round` is on
/// baseline x86-64; NaN and huge values pass through for the caller's range check.
#[inline]
fn round_half_away(v: f64) -> f64 {
    if v.abs() < 4.0e15 {
        let t = v as i64 as f64; // truncates toward zero; v - t is exact
        if (v - t).abs() >= 0.5 {
            t + 1.0f64.copysign(v)
        } else {
            t
        }
    } else {
        v
    }
}

/// Why a point cannot be encoded in the target format.
#[derive(Debug)]
pub struct EncodeError {
    pub point: usize,
    pub message: String,
}

/// Encodes `batch` as records of `layout` with `record_len` bytes each, appending to `out`, and
/// extends `bounds` by the coordinates as stored (after rounding to the scale), which is what a
/// header's bounds must describe. Columns the batch lacks are written as zero; extra bytes are
/// copied up to the record's room. Works column by column: one tight loop per field.
pub fn encode(
    batch: &PointBatch,
    record_len: usize,
    layout: &Layout,
    q: &Quantization,
    out: &mut Vec<u8>,
    bounds: &mut myriad_core::Aabb,
) -> Result<(), EncodeError> {
    let start = out.len();
    out.resize(start + batch.len() * record_len, 0);
    let records = &mut out[start..];
    // Writes one column into every record at byte `offset` via `put`.
    fn column<T: Copy>(records: &mut [u8], len: usize, col: &[T], put: impl Fn(&mut [u8], T)) {
        for (r, &v) in records.chunks_exact_mut(len).zip(col) {
            put(r, v);
        }
    }
    // Multiplying by the inverse scale instead of dividing: for coordinates that came from LAS
    // integers the product is within a few ulp of the integer, far from any rounding boundary.
    let inv = q.scale.map(|s| 1.0 / s);
    let mut stored = [0.0; 3];
    for (i, (r, p)) in records
        .chunks_exact_mut(record_len)
        .zip(&batch.positions)
        .enumerate()
    {
        for a in 0..3 {
            let v = round_half_away((p[a] - q.offset[a]) * inv[a]);
            if !(v >= i32::MIN as f64 && v <= i32::MAX as f64) {
                return Err(EncodeError {
                    point: i,
                    message: format!("coordinate {} does not fit the LAS scale/offset", p[a]),
                });
            }
            r[a * 4..a * 4 + 4].copy_from_slice(&(v as i32).to_le_bytes());
            stored[a] = v * q.scale[a] + q.offset[a];
        }
        bounds.extend(stored);
    }
    let n = record_len;
    if let Some(c) = &batch.intensity {
        column(records, n, c, |r, v| {
            r[12..14].copy_from_slice(&v.to_le_bytes())
        });
    }
    // Bit fields are OR-ed into bytes 14 and 15 (and the class byte of legacy formats).
    let or_bits = |records: &mut [u8], col: &Option<Vec<u8>>, byte: usize, mask: u8, shift: u32| {
        if let Some(c) = col {
            column(records, n, c, |r, v| r[byte] |= (v & mask) << shift);
        }
    };
    if layout.extended {
        or_bits(records, &batch.return_number, 14, 0x0F, 0);
        or_bits(records, &batch.number_of_returns, 14, 0x0F, 4);
        or_bits(records, &batch.classification_flags, 15, 0x0F, 0);
        or_bits(records, &batch.scanner_channel, 15, 0x03, 4);
        or_bits(records, &batch.scan_flags, 15, 0x03, 6);
        if let Some(c) = &batch.classification {
            column(records, n, c, |r, v| r[16] = v);
        }
        if let Some(c) = &batch.user_data {
            column(records, n, c, |r, v| r[17] = v);
        }
        if let Some(c) = &batch.scan_angle {
            column(records, n, c, |r, v| {
                let a = round_half_away(v as f64 / 0.006).clamp(i16::MIN as f64, i16::MAX as f64)
                    as i16;
                r[18..20].copy_from_slice(&a.to_le_bytes())
            });
        }
        if let Some(c) = &batch.point_source_id {
            column(records, n, c, |r, v| {
                r[20..22].copy_from_slice(&v.to_le_bytes())
            });
        }
    } else {
        or_bits(records, &batch.return_number, 14, 0x07, 0);
        or_bits(records, &batch.number_of_returns, 14, 0x07, 3);
        or_bits(records, &batch.scan_flags, 14, 0x03, 6);
        if let Some(c) = &batch.classification {
            column(records, n, c, |r, v| r[15] |= v.min(31));
        }
        or_bits(records, &batch.classification_flags, 15, 0x07, 5);
        if let Some(c) = &batch.scan_angle {
            column(records, n, c, |r, v| {
                r[16] = round_half_away(v as f64).clamp(-128.0, 127.0) as i8 as u8
            });
        }
        if let Some(c) = &batch.user_data {
            column(records, n, c, |r, v| r[17] = v);
        }
        if let Some(c) = &batch.point_source_id {
            column(records, n, c, |r, v| {
                r[18..20].copy_from_slice(&v.to_le_bytes())
            });
        }
    }
    if let (Some(o), Some(c)) = (layout.gps, &batch.gps_time) {
        column(records, n, c, |r, v| {
            r[o..o + 8].copy_from_slice(&v.to_le_bytes())
        });
    }
    if let (Some(o), Some(c)) = (layout.rgb, &batch.rgb) {
        column(records, n, c, |r, v| {
            for k in 0..3 {
                r[o + 2 * k..o + 2 * k + 2].copy_from_slice(&v[k].to_le_bytes());
            }
        });
    }
    if let (Some(o), Some(c)) = (layout.nir, &batch.nir) {
        column(records, n, c, |r, v| {
            r[o..o + 2].copy_from_slice(&v.to_le_bytes())
        });
    }
    if let (Some(o), Some(c)) = (layout.wave, &batch.wave_packet) {
        column(records, n, c, |r, w| {
            r[o] = w.descriptor_index;
            r[o + 1..o + 9].copy_from_slice(&w.byte_offset.to_le_bytes());
            r[o + 9..o + 13].copy_from_slice(&w.size.to_le_bytes());
            r[o + 13..o + 17].copy_from_slice(&w.return_point_location.to_le_bytes());
            r[o + 17..o + 21].copy_from_slice(&w.x_t.to_le_bytes());
            r[o + 21..o + 25].copy_from_slice(&w.y_t.to_le_bytes());
            r[o + 25..o + 29].copy_from_slice(&w.z_t.to_le_bytes());
        });
    }
    if let Some(e) = &batch.extra_bytes {
        let s = batch.extra_stride;
        let k = s.min(record_len - layout.base_len);
        if s > 0 {
            for (r, src) in records.chunks_exact_mut(record_len).zip(e.chunks_exact(s)) {
                r[layout.base_len..layout.base_len + k].copy_from_slice(&src[..k]);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_rounding_matches_std() {
        for v in [
            0.0,
            0.49999999999999994,
            0.5,
            1.5,
            2.5,
            -0.5,
            -1.5,
            -2.4999,
            1e9 + 0.5,
            -3e12 - 0.5,
            7.2e15,
        ] {
            assert_eq!(round_half_away(v), v.round(), "{v}");
        }
        assert!(round_half_away(f64::NAN).is_nan());
    }

    #[test]
    fn layouts_match_spec_lengths() {
        let lens = [20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67];
        for (f, len) in lens.iter().enumerate() {
            assert_eq!(Layout::new(f as u8).unwrap().base_len, *len, "format {f}");
        }
        assert!(Layout::new(11).is_none());
    }

    #[test]
    fn every_format_round_trips_bytes() {
        let q = Quantization {
            scale: [0.01, 0.01, 0.001],
            offset: [1000.0, -50.0, 3.0],
        };
        for f in 0..=10u8 {
            let layout = Layout::new(f).unwrap();
            let record_len = layout.base_len + 3;
            let mut bytes = vec![0u8; record_len * 5];
            let mut seed = 0x9E3779B97F4A7C15u64 ^ f as u64;
            for b in bytes.iter_mut() {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                *b = seed as u8;
            }
            // Legacy scan angle ranks are -90..90 by spec; keep them in i8 range that round trips.
            let mut batch = batch_for(&layout, 3, 5);
            decode(&bytes, record_len, &layout, &q, &mut batch);
            assert!(batch.is_consistent());
            let mut out = Vec::new();
            let mut bounds = myriad_core::Aabb::EMPTY;
            encode(&batch, record_len, &layout, &q, &mut out, &mut bounds).unwrap();
            assert!(batch.positions.iter().all(|p| bounds.contains(*p)));
            assert_eq!(out, bytes, "format {f}");
        }
    }
}
