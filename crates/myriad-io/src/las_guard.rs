//! Checks on untrusted LAS/LAZ headers made before the `las` and `laz` crates see them. Those
//! crates size buffers from header fields without checking them against the file (las 0.11: EVLR
//! lengths; laz 0.13: chunk counts, layer sizes), which turns one flipped byte into a panic or
//! gigabytes of memory. Each check here was prompted by a fuzzing finding (`fuzz/`); each names
//! the byte offset of the field it rejects.

use myriad_core::{Error, Result};
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

/// The fixed LAS header fields this module checks, with their offsets (LAS 1.4 R15, table 3).
///
/// | offset | size | field |
/// |---|---|---|
/// | 24 | 2 | version major, minor |
/// | 94 | 2 | u16 header size |
/// | 96 | 4 | u32 offset to point data |
/// | 100 | 4 | u32 number of VLRs |
/// | 104 | 1 | u8 point data format (bits 6-7: LAZ) |
/// | 105 | 2 | u16 point data record length |
/// | 131 | 24 | f64 x3 scale factors |
/// | 155 | 24 | f64 x3 offsets |
/// | 179 | 48 | f64 max x, min x, max y, min y, max z, min z |
pub(crate) const HEADER_PREFIX: usize = 227;
const SCALE_AT: u64 = 131;
const OFFSET_AT: u64 = 155;

/// Record length of each point format's standard fields, formats 0-10.
const BASE_LEN: [u16; 11] = [20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67];

/// Checks the header fields that coordinates and record boundaries are computed from, where they
/// are: `head` holds the file's first [`HEADER_PREFIX`] bytes. A scale of zero or NaN would make
/// every coordinate meaningless (zero flattens the scan, NaN makes it unplaceable), and the `las`
/// crate's own errors about sizes carry no offset.
pub(crate) fn check_header(path: &Path, head: &[u8], file_size: u64) -> Result<()> {
    let bad = |at: u64, m: String| Error::at_byte(path, at, m);
    let u16_at = |o: usize| u16::from_le_bytes([head[o], head[o + 1]]);
    let u32_at = |o: usize| u32::from_le_bytes(head[o..o + 4].try_into().unwrap());
    let f64_at = |o: u64| f64::from_le_bytes(head[o as usize..o as usize + 8].try_into().unwrap());
    let (major, minor) = (head[24], head[25]);
    if major != 1 {
        return Err(bad(
            24,
            format!("LAS major version {major} (only 1.x exists)"),
        ));
    }
    // Each version's header holds at least its own fields.
    let minimum = match minor {
        0..=2 => 227,
        3 => 235,
        _ => 375,
    };
    let header_size = u16_at(94) as u64;
    if header_size < minimum {
        return Err(bad(
            94,
            format!("header size {header_size} is smaller than LAS 1.{minor}'s {minimum} bytes"),
        ));
    }
    if header_size > file_size {
        return Err(bad(
            94,
            format!("header size {header_size} is larger than the file ({file_size} bytes)"),
        ));
    }
    let data_at = u32_at(96) as u64;
    if data_at < header_size {
        return Err(bad(
            96,
            format!("offset to point data {data_at} lies inside the {header_size}-byte header"),
        ));
    }
    if data_at > file_size {
        return Err(bad(
            96,
            format!(
                "offset to point data {data_at} is past the end of the file ({file_size} bytes)"
            ),
        ));
    }
    let format = head[104] & 0x3F;
    if format > 10 {
        return Err(bad(104, format!("unknown point format {format}")));
    }
    let record_len = u16_at(105);
    if record_len < BASE_LEN[format as usize] {
        return Err(bad(
            105,
            format!(
                "point record length {record_len} is shorter than point format {format}'s {} bytes",
                BASE_LEN[format as usize]
            ),
        ));
    }
    for (a, axis) in ["X", "Y", "Z"].into_iter().enumerate() {
        let (s_at, o_at) = (SCALE_AT + 8 * a as u64, OFFSET_AT + 8 * a as u64);
        let (scale, offset) = (f64_at(s_at), f64_at(o_at));
        if !scale.is_finite() || scale == 0.0 {
            return Err(bad(
                s_at,
                format!("{axis} scale factor is {scale}: no coordinate can be computed from it"),
            ));
        }
        if !offset.is_finite() {
            return Err(bad(o_at, format!("{axis} offset is {offset}")));
        }
        // The largest record value must still give a finite coordinate.
        if !(scale.abs() * 2f64.powi(31) + offset.abs()).is_finite() {
            return Err(bad(
                s_at,
                format!("{axis} scale factor {scale:e} with offset {offset} overflows coordinates"),
            ));
        }
    }
    Ok(())
}

/// The header's bounds (min, max per axis), or `None` when they cannot be bounds: a value that is
/// not finite, or a minimum above its maximum. Nothing is computed from them but the first plan
/// of a build, which reads the points for their bounds when the header has none.
pub(crate) fn header_bounds(raw: &las::raw::Header) -> Option<([f64; 3], [f64; 3])> {
    let min = [raw.min_x, raw.min_y, raw.min_z];
    let max = [raw.max_x, raw.max_y, raw.max_z];
    (0..3)
        .all(|a| min[a].is_finite() && max[a].is_finite() && min[a] <= max[a])
        .then_some((min, max))
}

/// Walks the VLR headers between the file header and the point data, so that a record length
/// that runs past the point data is named at its own offset (the `las` crate reports it as an
/// offset to point data that is too small, without a position).
///
/// | offset in the VLR | size | field |
/// |---|---|---|
/// | 0 | 2 | reserved |
/// | 2 | 16 | user id |
/// | 18 | 2 | record id |
/// | 20 | 2 | u16 record length after header |
/// | 22 | 32 | description |
pub(crate) fn check_vlrs(path: &Path, raw: &las::raw::Header) -> Result<()> {
    let f = File::open(path).map_err(|e| Error::io(path, e))?;
    check_vlrs_in(path, raw, f)
}

/// [`check_vlrs`] on the file's bytes read by `f` (a file, or bytes in memory named `path`).
pub(crate) fn check_vlrs_in(
    path: &Path,
    raw: &las::raw::Header,
    mut f: impl Read + Seek,
) -> Result<()> {
    let data_at = raw.offset_to_point_data as u64;
    let mut at = raw.header_size as u64;
    for i in 0..raw.number_of_variable_length_records {
        if at + 54 > data_at {
            return Err(Error::at_byte(
                path,
                at,
                format!(
                    "VLR {i} of {} starts at byte {at}, where its 54-byte header runs into the point data at byte {data_at}",
                    raw.number_of_variable_length_records
                ),
            ));
        }
        let mut len = [0u8; 2];
        f.seek(SeekFrom::Start(at + 20))
            .and_then(|_| f.read_exact(&mut len))
            .map_err(|e| Error::io(path, e))?;
        let len = u16::from_le_bytes(len) as u64;
        if at + 54 + len > data_at {
            return Err(Error::at_byte(
                path,
                at + 20,
                format!(
                    "VLR {i}'s length {len} runs past the start of the point data at byte {data_at}"
                ),
            ));
        }
        at += 54 + len;
    }
    Ok(())
}

/// Checks that the first EVLR lies inside the file before the `las` crate reads it: las 0.11
/// sizes a vector from its u64 length unchecked (a panic or gigabytes of memory; found by fuzzing).
///
/// | offset in the EVLR | size | field |
/// |---|---|---|
/// | 0 | 2 | reserved |
/// | 2 | 16 | user id |
/// | 18 | 2 | record id |
/// | 20 | 8 | u64 record length after header |
/// | 28 | 32 | description |
pub(crate) fn check_evlr(path: &Path, raw: &las::raw::Header, file_size: u64) -> Result<()> {
    let Some(evlr) = raw.evlr.filter(|e| e.number_of_evlrs > 0) else {
        return Ok(());
    };
    let start = evlr.start_of_first_evlr;
    if start.checked_add(60).is_none_or(|end| end > file_size) {
        return Err(Error::at_byte(
            path,
            235,
            format!("first EVLR offset {start} lies outside the file"),
        ));
    }
    let mut f = File::open(path).map_err(|e| Error::io(path, e))?;
    let mut len = [0u8; 8];
    f.seek(SeekFrom::Start(start + 20))
        .map_err(|e| Error::io(path, e))?;
    f.read_exact(&mut len).map_err(|e| Error::io(path, e))?;
    let len = u64::from_le_bytes(len);
    if (start + 60)
        .checked_add(len)
        .is_none_or(|end| end > file_size)
    {
        return Err(Error::at_byte(
            path,
            start + 20,
            format!("EVLR length {len} runs past the end of the file"),
        ));
    }
    Ok(())
}

/// Checks the LAZ chunk table's header before the `laz` crate sizes a vector from it (laz 0.13
/// allocates `number_of_chunks` entries unchecked: a flipped byte asked for 68 GB in fuzzing).
///
/// | where | size | field |
/// |---|---|---|
/// | offset to point data | 8 | i64: offset of the chunk table (-1: not written) |
/// | chunk table offset | 4 | u32 version (0) |
/// | + 4 | 4 | u32 number of chunks |
pub(crate) fn check_laz_chunk_table(
    path: &Path,
    raw: &las::raw::Header,
    file_size: u64,
) -> Result<()> {
    let mut f = File::open(path).map_err(|e| Error::io(path, e))?;
    let at = raw.offset_to_point_data as u64;
    let mut b = [0u8; 8];
    let read_at = |f: &mut File, at: u64, b: &mut [u8]| -> Result<()> {
        f.seek(SeekFrom::Start(at))
            .map_err(|e| Error::io(path, e))?;
        f.read_exact(b)
            .map_err(|_| Error::at_byte(path, at, "unexpected end of file in the LAZ chunk table"))
    };
    read_at(&mut f, at, &mut b)?;
    let table = i64::from_le_bytes(b);
    if table == -1 {
        return Ok(()); // written by a streaming writer; laz finds the chunks by scanning
    }
    if table < at as i64 + 8 || table as u64 + 8 > file_size {
        return Err(Error::at_byte(
            path,
            at,
            format!("LAZ chunk table offset {table} lies outside the file"),
        ));
    }
    read_at(&mut f, table as u64, &mut b)?;
    let chunks = u32::from_le_bytes(b[4..8].try_into().unwrap()) as u64;
    let points = raw
        .large_file
        .map_or(raw.number_of_point_records as u64, |l| {
            l.number_of_point_records
                .max(raw.number_of_point_records as u64)
        });
    if chunks > points.max(1) || chunks > file_size {
        return Err(Error::at_byte(
            path,
            table as u64 + 4,
            format!(
                "LAZ chunk table declares {chunks} chunks for {points} points in a {file_size}-byte file"
            ),
        ));
    }
    Ok(())
}

/// Checks the laszip VLR against the header, then every chunk of a layered (LAS 1.4, point
/// formats 6-10) LAZ file: the layer byte counts
/// must fit inside the chunk. laz 0.13 resizes a buffer to each count and fills it with zeros
/// before reading, so one corrupt u32 costs up to 4 GiB of memory per layer (found by fuzzing).
///
/// A layered chunk: the first point uncompressed (the sum of the item sizes), u32 point count,
/// one u32 byte count per layer (Point14: 9, RGB14: 1, RGBNIR14: 2, WavePacket14: 1,
/// Byte14(n): n), then the layers. Chunks follow the 8-byte chunk table offset, in table order.
pub(crate) fn check_laz_layers(
    path: &Path,
    header: &las::Header,
    data_start: u64,
    file_size: u64,
) -> Result<()> {
    let bad = |at: u64, m: String| Error::at_byte(path, at, m);
    let vlr = header
        .laz_vlr()
        .map_err(|e| bad(0, format!("invalid laszip VLR: {e}")))?;
    // The items must describe exactly the header's record (laz divides by their size), and fixed
    // chunks must hold at least one point.
    let record_len = header.point_format().len() as u64;
    if vlr.items_size() != record_len {
        return Err(bad(
            105,
            format!(
                "laszip VLR describes {}-byte records, the header {record_len}-byte ones",
                vlr.items_size()
            ),
        ));
    }
    if !vlr.uses_variable_size_chunks() && vlr.chunk_size() == 0 {
        return Err(bad(0, "laszip VLR declares chunks of 0 points".into()));
    }
    let Some((first_point, layers)) = layered(&vlr) else {
        return Ok(()); // not layered: no per-layer sizes to check
    };
    let mut f = BufReader::new(File::open(path).map_err(|e| Error::io(path, e))?);
    f.seek(SeekFrom::Start(data_start))
        .map_err(|e| Error::io(path, e))?;
    let table = match laz::laszip::ChunkTable::read_from(&mut f, &vlr) {
        Ok(t) => t,
        Err(e) => {
            return Err(bad(
                data_start,
                format!("cannot read the LAZ chunk table: {e}"),
            ));
        }
    };
    let mut start = data_start + 8;
    let mut sizes = vec![0u8; 4 * layers as usize];
    for (i, chunk) in table.as_ref().iter().enumerate() {
        let head = first_point + 4 + 4 * layers;
        if start.saturating_add(chunk.byte_count) > file_size || chunk.byte_count < head {
            if chunk.byte_count == 0 {
                break; // an empty trailing chunk
            }
            return Err(bad(
                start,
                format!(
                    "LAZ chunk {i} ({} bytes) does not fit the file",
                    chunk.byte_count
                ),
            ));
        }
        f.seek(SeekFrom::Start(start + first_point + 4))
            .map_err(|e| Error::io(path, e))?;
        f.read_exact(&mut sizes).map_err(|e| Error::io(path, e))?;
        let total = layer_bytes(&sizes);
        if head + total > chunk.byte_count {
            return Err(bad(
                start + first_point + 4,
                format!(
                    "LAZ chunk {i}: its layers claim {total} bytes of a {}-byte chunk",
                    chunk.byte_count
                ),
            ));
        }
        start += chunk.byte_count;
    }
    Ok(())
}

/// A layered chunk's (LAS 1.4, point formats 6-10) first point's bytes and its number of
/// layers, from the laszip VLR's items; `None` for formats that are not layered.
pub(crate) fn layered(vlr: &laz::LazVlr) -> Option<(u64, u64)> {
    use laz::LazItemType as T;
    let mut first_point = 0u64;
    let mut layers = 0u64;
    for item in vlr.items() {
        first_point += item.size() as u64;
        layers += match item.item_type() {
            T::Point14 => 9,
            T::RGB14 | T::WavePacket14 => 1,
            T::RGBNIR14 => 2,
            T::Byte14(n) => n as u64,
            _ => return None,
        };
    }
    Some((first_point, layers))
}

/// The bytes a chunk's layers claim: the sum of its u32 layer byte counts.
pub(crate) fn layer_bytes(sizes: &[u8]) -> u64 {
    sizes
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes(b.try_into().unwrap()) as u64)
        .sum()
}
