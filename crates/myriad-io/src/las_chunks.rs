//! LAZ read chunk by chunk (issue 43): where each chunk lies in the file and how many points
//! it holds, blocks of whole chunks, and their decompression (whole, or only the coordinates
//! where the point format allows, for the bounds of each chunk's points that
//! [`chunk_bounds`](crate::las::chunk_bounds) finds): what reading only the chunks a
//! [`LasSource`](crate::las::LasSource) is restricted to needs, so that a part of a partitioned
//! build decompresses only the chunks that meet its cells.
//!
//! A LAZ chunk decompresses on its own from its bytes and its point count (the chunk table
//! gives both, or the byte counts and the fixed chunk size of the laszip VLR), so chunks are
//! read here straight from the file and decompressed with `laz::par_decompress_selective`,
//! which also takes the variable-size chunks of COPC files.

use myriad_core::{Error, Result};
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

/// One LAZ chunk: its bytes in the file and its points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LazChunk {
    /// The chunk's index in the chunk table.
    pub index: u32,
    /// Where its bytes start in the file, and how many.
    pub byte_at: u64,
    pub bytes: u64,
    /// The points it holds.
    pub points: u64,
}

/// The chunks of a LAZ file whose point data start at `data_at`, with their points adding up
/// to the header's count (the last chunk of a table of fixed-size chunks holds what is left).
/// `None` when the file is not LAZ or was written without a chunk table.
pub(crate) fn table(
    path: &Path,
    header: &las::Header,
    data_at: u64,
    file_size: u64,
) -> Result<Option<Vec<LazChunk>>> {
    if !header.point_format().is_compressed {
        return Ok(None);
    }
    let vlr = header
        .laz_vlr()
        .map_err(|e| Error::at_byte(path, 0, format!("invalid laszip VLR: {e}")))?;
    let mut f = BufReader::new(File::open(path).map_err(|e| Error::io(path, e))?);
    f.seek(SeekFrom::Start(data_at))
        .map_err(|e| Error::io(path, e))?;
    let mut offset = [0u8; 8];
    f.read_exact(&mut offset).map_err(|e| Error::io(path, e))?;
    if i64::from_le_bytes(offset) == -1 {
        return Ok(None); // written by a streaming writer: no table
    }
    f.seek(SeekFrom::Start(data_at))
        .map_err(|e| Error::io(path, e))?;
    let t = laz::laszip::ChunkTable::read_from(&mut f, &vlr).map_err(|e| {
        Error::at_byte(
            path,
            data_at,
            format!("cannot read the LAZ chunk table: {e}"),
        )
    })?;
    let total = header.number_of_points();
    let n = t.as_ref().len();
    let (mut point, mut byte) = (0u64, data_at + 8);
    let mut out = Vec::with_capacity(n);
    for (i, c) in t.as_ref().iter().enumerate() {
        let points = if i + 1 == n {
            total - point
        } else {
            c.point_count.min(total - point)
        };
        if byte.saturating_add(c.byte_count) > file_size {
            return Err(Error::at_byte(
                path,
                byte,
                format!(
                    "LAZ chunk {i} ({} bytes) runs past the end of the file",
                    c.byte_count
                ),
            ));
        }
        out.push(LazChunk {
            index: i as u32,
            byte_at: byte,
            bytes: c.byte_count,
            points,
        });
        point += points;
        byte += c.byte_count;
    }
    Ok(Some(out))
}

/// Decompresses `chunks` of `path` into `out` (their records one after another; `out` holds
/// exactly their points' records), only the fields `selection` names where the point format is
/// layered (LAS 1.4 formats 6 to 10; older formats decompress whole). A chunk that does not
/// decompress is named with its byte offset.
pub(crate) fn decompress(
    path: &Path,
    file: &mut File,
    vlr: &laz::LazVlr,
    chunks: &[LazChunk],
    selection: laz::DecompressionSelection,
    compressed: &mut Vec<u8>,
    out: &mut [u8],
) -> Result<()> {
    compressed.clear();
    let mut entries = Vec::with_capacity(chunks.len());
    for c in chunks {
        let len = usize::try_from(c.bytes)
            .map_err(|_| Error::at_byte(path, c.byte_at, "LAZ chunk too large"))?;
        let start = compressed.len();
        compressed.resize(start + len, 0);
        file.seek(SeekFrom::Start(c.byte_at))
            .and_then(|_| file.read_exact(&mut compressed[start..]))
            .map_err(|e| {
                Error::at_byte(
                    path,
                    c.byte_at,
                    format!("cannot read LAZ chunk {}: {e}", c.index),
                )
            })?;
        entries.push(laz::laszip::ChunkTableEntry {
            point_count: c.points,
            byte_count: c.bytes,
        });
    }
    // The laz crate panics on some damaged chunks (found by fuzzing): an error like any other.
    let decode = |from: &[u8], to: &mut [u8], e: &[laz::laszip::ChunkTableEntry]| {
        match myriad_core::guard::catching(|| {
            laz::par_decompress_selective(from, to, vlr, e, selection)
        }) {
            Ok(r) => r.map_err(|e| e.to_string()),
            Err(m) => Err(m),
        }
    };
    if decode(compressed, out, &entries).is_ok() {
        return Ok(());
    }
    // Which chunk: each alone.
    let record = vlr.items_size() as usize;
    let (mut at, mut rec) = (0usize, 0usize);
    for (c, e) in chunks.iter().zip(&entries) {
        let (len, n) = (c.bytes as usize, c.points as usize * record);
        if let Err(err) = decode(
            &compressed[at..at + len],
            &mut out[rec..rec + n],
            std::slice::from_ref(e),
        ) {
            return Err(Error::at_byte(
                path,
                c.byte_at,
                format!(
                    "LAZ chunk {} ({} points) does not decompress: {err}",
                    c.index, c.points
                ),
            ));
        }
        at += len;
        rec += n;
    }
    Err(Error::at_byte(
        path,
        chunks.first().map_or(0, |c| c.byte_at),
        "LAZ chunks do not decompress together",
    ))
}

/// Groups `chunks` into blocks of about `block` points (whole chunks, at least one each).
pub(crate) fn blocks(chunks: &[LazChunk], block: u64) -> Vec<Vec<LazChunk>> {
    let mut out: Vec<Vec<LazChunk>> = Vec::new();
    let mut points = 0;
    for &c in chunks {
        match out.last_mut() {
            Some(b) if points + c.points <= block => b.push(c),
            _ => {
                out.push(vec![c]);
                points = 0;
            }
        }
        points += c.points;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chunk(index: u32, points: u64) -> LazChunk {
        LazChunk {
            index,
            byte_at: 0,
            bytes: 1,
            points,
        }
    }

    #[test]
    fn blocks_hold_whole_chunks_up_to_the_size() {
        let c: Vec<_> = [3, 3, 3, 10, 1]
            .iter()
            .enumerate()
            .map(|(i, &n)| chunk(i as u32, n))
            .collect();
        let b = blocks(&c, 6);
        let sizes: Vec<Vec<u32>> = b
            .iter()
            .map(|b| b.iter().map(|c| c.index).collect())
            .collect();
        assert_eq!(sizes, vec![vec![0, 1], vec![2], vec![3], vec![4]]);
        assert!(blocks(&[], 6).is_empty());
    }
}
