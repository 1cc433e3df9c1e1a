//! LAS and LAZ from bytes already in memory rather than from a file: a header read from a
//! file's first bytes, one LAZ chunk decoded on its own, a whole small LAS/LAZ file decoded.
//! This is what the readers of the field's cloud formats need (a COPC node is one LAZ chunk
//! fetched by a range request; an EPT node of `dataType` laszip is a whole LAZ file), whose bytes
//! come from a URL as often as from a disk. The same checks as [`crate::las::LasSource::open`]
//! run before the `las` and `laz` crates see the bytes (they size buffers from header fields).

use crate::las_guard::{HEADER_PREFIX, check_header, check_vlrs_in};
use crate::las_records::{self, Layout, Quantization};
use myriad_core::{Aabb, Attribute, Error, PointBatch, Result, Schema};
use std::path::Path;

/// What decoding a LAS/LAZ file's points needs, read from its header and VLRs.
#[derive(Clone)]
pub struct LasLayout {
    pub header: las::Header,
    layout: Layout,
    quant: Quantization,
    record_len: usize,
    /// The point columns (the format's fields and the extra dimensions).
    pub schema: Schema,
    pub crs: Option<String>,
    laz: Option<laz::LazVlr>,
    /// Where the point data start.
    pub data_at: u64,
    pub points: u64,
    /// The header's bounds (`None`: not finite).
    pub bounds: Option<Aabb>,
}

/// How many bytes from a file's start hold its header and VLRs, from its first
/// [`HEADER_PREFIX`] bytes (`head`): the offset to its point data.
pub fn data_offset(name: &Path, head: &[u8]) -> Result<u64> {
    if head.len() < HEADER_PREFIX || &head[..4] != b"LASF" {
        return Err(Error::at_byte(
            name,
            0,
            "not a LAS file (LAS files start with \"LASF\" and a 227-byte header)",
        ));
    }
    Ok(u32::from_le_bytes(head[96..100].try_into().unwrap()) as u64)
}

impl LasLayout {
    /// Reads the header and VLRs in `head` (the file's first bytes, up to its point data at
    /// least) of a file of `file_size` bytes; EVLRs are left out (they lie at the end).
    pub fn parse(name: &Path, head: &[u8], file_size: u64) -> Result<LasLayout> {
        let data_at = data_offset(name, head)?;
        if (head.len() as u64) < data_at {
            return Err(Error::at_byte(
                name,
                head.len() as u64,
                format!("the header and VLRs end at byte {data_at}, past the bytes read"),
            ));
        }
        check_header(name, &head[..HEADER_PREFIX], file_size)?;
        let mut bytes = head[..data_at as usize].to_vec();
        // LAS 1.4: no EVLRs here (the hierarchy and other records at the end of the file are
        // read by whoever needs them).
        if bytes[25] >= 4 && bytes.len() >= 247 {
            bytes[235..247].fill(0);
        }
        let raw = las::raw::Header::read_from(std::io::Cursor::new(&bytes))
            .map_err(|e| Error::at_byte(name, 0, format!("invalid LAS header: {e}")))?;
        check_vlrs_in(name, &raw, std::io::Cursor::new(&bytes))?;
        let header = las::Header::new(std::io::Cursor::new(&bytes))
            .map_err(|e| Error::at_byte(name, 0, format!("invalid LAS header or VLRs: {e}")))?;
        let fmt = header.point_format();
        let format = fmt
            .to_u8()
            .map_err(|e| Error::at_byte(name, 104, e.to_string()))?;
        let layout = Layout::new(format)
            .ok_or_else(|| Error::at_byte(name, 104, format!("unknown point format {format}")))?;
        let record_len = fmt.len() as usize;
        let laz = match fmt.is_compressed {
            true => {
                let vlr = header
                    .laz_vlr()
                    .map_err(|e| Error::at_byte(name, 0, format!("invalid laszip VLR: {e}")))?;
                if vlr.items_size() != record_len as u64 {
                    return Err(Error::at_byte(
                        name,
                        105,
                        format!(
                            "laszip VLR describes {}-byte records, the header {record_len}-byte ones",
                            vlr.items_size()
                        ),
                    ));
                }
                Some(vlr)
            }
            false => None,
        };
        let mut schema = Schema::for_las_format(format);
        schema.extra_bytes = fmt.extra_bytes as usize;
        let extra = crate::las_extra::extra_dims(&header);
        schema
            .attributes
            .extend(extra.into_iter().map(Attribute::Extra));
        let bounds = crate::las_guard::header_bounds(&raw).map(|(min, max)| Aabb::new(min, max));
        Ok(LasLayout {
            crs: crate::las::crs_of(&header),
            quant: Quantization::of(&header),
            points: header.number_of_points(),
            header,
            layout,
            record_len,
            schema,
            laz,
            data_at,
            bounds,
        })
    }

    /// Scale and offset per axis.
    pub fn scale_offset(&self) -> ([f64; 3], [f64; 3]) {
        (self.quant.scale, self.quant.offset)
    }

    /// The length of a point record.
    pub fn record_len(&self) -> usize {
        self.record_len
    }

    /// Decodes uncompressed records (whole records; a trailing part is left out).
    pub fn decode_records(&self, bytes: &[u8]) -> PointBatch {
        let n = bytes.len() / self.record_len;
        let extra = self.record_len - self.layout.base_len;
        let mut batch = las_records::batch_for(&self.layout, extra, n);
        let bytes = &bytes[..n * self.record_len];
        las_records::decode(
            bytes,
            self.record_len,
            &self.layout,
            &self.quant,
            &mut batch,
        );
        batch
    }

    /// Decodes one LAZ chunk of `points` points on its own (a COPC node), `at` its byte offset
    /// in `name` for errors. The layer sizes are checked against the chunk before `laz` sizes
    /// buffers from them.
    pub fn decode_chunk(
        &self,
        name: &Path,
        at: u64,
        chunk: &[u8],
        points: u64,
    ) -> Result<PointBatch> {
        let Some(vlr) = &self.laz else {
            return Err(Error::at_byte(
                name,
                at,
                "not a LAZ file: no chunks to decode",
            ));
        };
        let bad = |off: u64, m: String| Error::at_byte(name, at + off, m);
        let out_len = points
            .checked_mul(self.record_len as u64)
            .filter(|&n| points <= chunk.len() as u64 * 64 && n < 1 << 34)
            .and_then(|n| usize::try_from(n).ok())
            .ok_or_else(|| {
                bad(
                    0,
                    format!("{points} points cannot be in a {}-byte chunk", chunk.len()),
                )
            })?;
        check_layers(vlr, chunk).map_err(|(off, m)| bad(off, m))?;
        let mut out = vec![0u8; out_len];
        let entry = laz::laszip::ChunkTableEntry {
            point_count: points,
            byte_count: chunk.len() as u64,
        };
        // The laz crate panics on some damaged chunks (its decoder's tables indexed by what it
        // read: found by fuzzing): an error like any other.
        let decoded = myriad_core::guard::catching(|| {
            laz::par_decompress_selective(
                chunk,
                &mut out,
                vlr,
                std::slice::from_ref(&entry),
                laz::DecompressionSelection::all(),
            )
        });
        match decoded {
            Ok(Ok(())) => Ok(()),
            Ok(Err(e)) => Err(e.to_string()),
            Err(m) => Err(m),
        }
        .map_err(|e| {
            bad(
                0,
                format!("LAZ chunk of {points} points does not decompress: {e}"),
            )
        })?;
        Ok(self.decode_records(&out))
    }

    /// Decodes every point of a whole LAS or LAZ file held in `bytes` (an EPT node).
    pub fn decode_file(name: &Path, bytes: &[u8]) -> Result<(LasLayout, PointBatch)> {
        let l = LasLayout::parse(name, bytes, bytes.len() as u64)?;
        let data = &bytes[l.data_at as usize..];
        let Some(vlr) = &l.laz else {
            let need = l.points.saturating_mul(l.record_len as u64);
            if need > data.len() as u64 {
                return Err(Error::at_byte(
                    name,
                    bytes.len() as u64,
                    format!("file ends before its {} points' records", l.points),
                ));
            }
            let b = l.decode_records(&data[..need as usize]);
            return Ok((l, b));
        };
        // The chunk table: an i64 offset, then (version u32, count u32, ...) at that offset.
        if data.len() < 8 {
            return Err(Error::at_byte(
                name,
                l.data_at,
                "file ends before its LAZ chunk table offset",
            ));
        }
        let table_at = i64::from_le_bytes(data[..8].try_into().unwrap());
        let chunks: Vec<(u64, u64)> = match table_at {
            -1 => return Err(Error::at_byte(name, l.data_at, "LAZ without a chunk table")),
            t if t < l.data_at as i64 + 8 || t as u64 + 8 > bytes.len() as u64 => {
                return Err(Error::at_byte(
                    name,
                    l.data_at,
                    format!("LAZ chunk table offset {t} lies outside the file"),
                ));
            }
            t => {
                let count =
                    u32::from_le_bytes(bytes[t as usize + 4..t as usize + 8].try_into().unwrap());
                // Each chunk holds a point and a byte at least (the laz crate sizes the table
                // from the count: 5 GB for a count of 2^28, found by fuzzing).
                let data = (t as u64).saturating_sub(l.data_at + 8);
                if count as u64 > l.points.max(1) || count as u64 > data.max(1) {
                    return Err(Error::at_byte(
                        name,
                        t as u64 + 4,
                        format!("{count} LAZ chunks for {} points in {data} bytes", l.points),
                    ));
                }
                let mut cur = std::io::Cursor::new(bytes);
                cur.set_position(l.data_at);
                let table = laz::laszip::ChunkTable::read_from(&mut cur, vlr).map_err(|e| {
                    Error::at_byte(
                        name,
                        t as u64,
                        format!("cannot read the LAZ chunk table: {e}"),
                    )
                })?;
                let fixed = (!vlr.uses_variable_size_chunks()).then(|| vlr.chunk_size() as u64);
                let mut left = l.points;
                table
                    .as_ref()
                    .iter()
                    .map(|c| {
                        let n = fixed.map_or(c.point_count, |f| f.min(left));
                        left -= n.min(left);
                        (c.byte_count, n)
                    })
                    .collect()
            }
        };
        // Room for the points the bytes can plausibly hold, not the header's count: a header
        // claiming 2^40 points over a few kilobytes asked for 16 GB (found by fuzzing); a scan
        // that compresses better than this only grows the batch.
        let room = l.points.min(bytes.len() as u64 * 16);
        let mut batch =
            las_records::batch_for(&l.layout, l.record_len - l.layout.base_len, room as usize);
        let mut at = l.data_at + 8;
        for (bytes_n, n) in chunks {
            let end = at.saturating_add(bytes_n);
            if end > bytes.len() as u64 {
                return Err(Error::at_byte(
                    name,
                    at,
                    format!("LAZ chunk of {bytes_n} bytes runs past the end"),
                ));
            }
            let b = l.decode_chunk(name, at, &bytes[at as usize..end as usize], n)?;
            batch.append(&b);
            at = end;
        }
        if batch.len() as u64 != l.points {
            return Err(Error::at_byte(
                name,
                l.data_at,
                format!(
                    "{} points decoded, the header says {}",
                    batch.len(),
                    l.points
                ),
            ));
        }
        Ok((l, batch))
    }

    /// The header, as bytes of an empty LAS file (what a dataset stores to write extracts in the
    /// input's point format).
    pub fn header_bytes(&self) -> Result<Vec<u8>> {
        crate::las::header_to_bytes(&self.header)
    }
}

/// Checks a layered chunk's layer byte counts against its length (LAS 1.4 formats 6-10; older
/// formats have no counts): the offset in the chunk and what is wrong.
fn check_layers(vlr: &laz::LazVlr, chunk: &[u8]) -> std::result::Result<(), (u64, String)> {
    let Some((first_point, layers)) = crate::las_guard::layered(vlr) else {
        return Ok(());
    };
    let head = first_point + 4 + 4 * layers;
    if (chunk.len() as u64) < head {
        return Err((
            0,
            format!(
                "a {}-byte LAZ chunk is shorter than its {head}-byte head",
                chunk.len()
            ),
        ));
    }
    let total = crate::las_guard::layer_bytes(&chunk[first_point as usize + 4..head as usize]);
    if head + total > chunk.len() as u64 {
        return Err((
            first_point + 4,
            format!(
                "LAZ chunk: its layers claim {total} bytes of a {}-byte chunk",
                chunk.len()
            ),
        ));
    }
    Ok(())
}
