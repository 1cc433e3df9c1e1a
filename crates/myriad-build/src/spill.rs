//! Spill files: the points of a chunk written during distribution and read back when it is
//! built, as frames appended one flush at a time.
//!
//! A frame is a kind, a raw length and a stored length (u32 each), then its body. Points that all
//! lie on a LAS input's grid (its own points always do) are written as a node page
//! ([`myriad_format::page`], preceded by the grid's scale and offset): integer position deltas
//! and byte planes through zstd, checked to give back every coordinate's bits. Others are rows
//! of [`PointBatch::put_row`], through zstd when the build's spill would be large.

use myriad_core::{Error, PointBatch, Result, Schema};
use myriad_format::Quantization;
use std::io::Read;
use std::path::{Path, PathBuf};

/// How spill frames are written ([`encode_frame`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Codec {
    /// Rows through zstd.
    pub compress: bool,
    /// The grid of the first input with one (a LAS input's scale and offset): frames whose every
    /// position lies on it are node pages.
    pub grid: Option<Quantization>,
}

/// Frame kinds: rows as they are, rows through zstd, a node page.
const FRAME_ROWS: u32 = 0;
const FRAME_ROWS_ZSTD: u32 = 1;
const FRAME_PAGE: u32 = 2;
/// Bytes before a frame's body: kind, raw length, stored length (u32 each).
const FRAME_HEAD: usize = 12;
/// Bytes of the grid before a page frame's page: scale and offset (f64 each).
const GRID_BYTES: usize = 48;

/// A spill frame of `batch`'s points: its kind, its raw length (bytes of rows; points of a
/// page) and its stored length, then the body.
///
/// When every position lies on `codec.grid` (a LAS input's own scale and offset: always, for its
/// points), the frame is a node page ([`myriad_format::page`]: the grid's scale and offset, then
/// the page): positions as integer deltas and every column in byte planes through zstd level 1,
/// lossless because each coordinate is checked to come back with the same bits (on a 200 M point
/// city the reading phase fell from 82 to 64 s against zstd'd rows). Other frames are rows of
/// [`PointBatch::put_row`], through zstd at level 1 when `codec.compress` (and it helps).
pub(crate) fn encode_frame(batch: &PointBatch, codec: Codec) -> Vec<u8> {
    let frame = |kind: u32, raw: usize, body: &[&[u8]]| {
        let len: usize = body.iter().map(|b| b.len()).sum();
        let mut out = Vec::with_capacity(FRAME_HEAD + len);
        for v in [kind, raw as u32, len as u32] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        body.iter().for_each(|b| out.extend_from_slice(b));
        out
    };
    if let Some((q, page)) = codec
        .grid
        .and_then(|q| Some((q, myriad_format::page::encode_on_grid(batch, &q)?)))
    {
        let grid: Vec<u8> = q
            .scale
            .iter()
            .chain(&q.offset)
            .flat_map(|v| v.to_le_bytes())
            .collect();
        return frame(FRAME_PAGE, batch.len(), &[&grid, &page]);
    }
    let mut rows = Vec::with_capacity(batch.len() * batch.row_size());
    for i in 0..batch.len() {
        batch.put_row(i, &mut rows);
    }
    let z = codec
        .compress
        .then(|| zstd::bulk::compress(&rows, 1).ok())
        .flatten()
        .filter(|z| z.len() < rows.len());
    match z {
        Some(z) => frame(FRAME_ROWS_ZSTD, rows.len(), &[&z]),
        None => frame(FRAME_ROWS, rows.len(), &[&rows]),
    }
}

/// Reads the frames of a spill file one after the other.
pub(crate) struct Frames {
    file: std::io::BufReader<std::fs::File>,
    path: PathBuf,
    at: u64,
}

impl Frames {
    pub fn open(path: &Path) -> Result<Frames> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        Ok(Frames {
            file: std::io::BufReader::with_capacity(1 << 20, file),
            path: path.to_path_buf(),
            at: 0,
        })
    }

    pub fn error(&self, message: impl Into<String>) -> Error {
        Error::at_byte(&self.path, self.at, message)
    }

    /// The next frame's points, in `schema`.
    pub fn next_frame(&mut self, schema: &Schema) -> Result<Option<PointBatch>> {
        let mut head = [0u8; FRAME_HEAD];
        let mut got = 0;
        while got < FRAME_HEAD {
            match self
                .file
                .read(&mut head[got..])
                .map_err(|e| Error::io(&self.path, e))?
            {
                0 if got == 0 => return Ok(None),
                0 => return Err(self.error("spill file ends inside a frame head")),
                k => got += k,
            }
        }
        let word = |k: usize| u32::from_le_bytes(head[4 * k..4 * k + 4].try_into().unwrap());
        let (kind, raw, len) = (word(0), word(1) as usize, word(2) as usize);
        let mut body = vec![0u8; len];
        self.file
            .read_exact(&mut body)
            .map_err(|_| self.error("spill file ends inside a frame"))?;
        let batch = match kind {
            FRAME_PAGE if len < GRID_BYTES => {
                return Err(self.error("spill page frame shorter than its grid"));
            }
            FRAME_PAGE => {
                let f = |k: usize| f64::from_le_bytes(body[8 * k..8 * k + 8].try_into().unwrap());
                let q = Quantization {
                    scale: [f(0), f(1), f(2)],
                    offset: [f(3), f(4), f(5)],
                };
                let b =
                    myriad_format::page::decode(&body[GRID_BYTES..], schema, &q).map_err(|e| {
                        Error::at_byte(
                            &self.path,
                            self.at + (FRAME_HEAD + GRID_BYTES + e.at) as u64,
                            e.message,
                        )
                    })?;
                if b.len() != raw {
                    return Err(self.error("spill frame has the wrong point count"));
                }
                b
            }
            FRAME_ROWS | FRAME_ROWS_ZSTD => {
                let rows = if kind == FRAME_ROWS {
                    body
                } else {
                    zstd::bulk::decompress(&body, raw).map_err(|e| self.error(e.to_string()))?
                };
                let row = PointBatch::with_schema(schema, 0).row_size();
                if rows.len() != raw || rows.len() % row != 0 {
                    return Err(self.error("spill frame has the wrong length"));
                }
                let mut b = PointBatch::with_schema(schema, rows.len() / row);
                for r in rows.chunks_exact(row) {
                    b.push_row(r);
                }
                b
            }
            _ => return Err(self.error(format!("unknown spill frame kind {kind}"))),
        };
        self.at += (FRAME_HEAD + len) as u64;
        Ok(Some(batch))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_core::PointRecord;

    const GRID: Quantization = Quantization {
        scale: [0.001, 0.001, 0.01],
        offset: [500_000.0, 4_400_000.0, 0.0],
    };

    /// Points of every LAS format 3 column and three extra bytes; on `GRID` when `on`.
    fn sample(n: usize, on: bool) -> PointBatch {
        let mut schema = Schema::for_las_format(3);
        schema.extra_bytes = 3;
        let mut b = PointBatch::with_schema(&schema, n);
        for i in 0..n {
            let x = [
                i as i64 * 37 % 5000,
                90_000 - i as i64 * 11,
                (i as i64 * 7) % 300,
            ];
            let mut position = GRID.to_world(x);
            if !on && i == n / 2 {
                position[1] += 1e-7;
            }
            b.push_record(&PointRecord {
                position,
                intensity: (i * 13) as u16,
                return_number: 1 + (i % 3) as u8,
                number_of_returns: 3,
                classification: (i % 7) as u8,
                scan_angle: i as f32 * 0.5 - 20.0,
                user_data: i as u8,
                point_source_id: 4,
                gps_time: 1.0e8 + i as f64 * 1e-5,
                rgb: [(i * 3) as u16, 65535 - i as u16, 7],
                normal: [0.0; 3],
            });
            let e = b.extra_bytes.as_mut().unwrap();
            let at = e.len() - 3;
            e[at..].copy_from_slice(&[i as u8, (i >> 8) as u8, 9]);
        }
        b
    }

    fn kind(frame: &[u8]) -> u32 {
        u32::from_le_bytes(frame[..4].try_into().unwrap())
    }

    fn read_back(path: &Path, schema: &Schema) -> Result<Vec<PointBatch>> {
        let mut frames = Frames::open(path)?;
        let mut out = Vec::new();
        while let Some(b) = frames.next_frame(schema)? {
            out.push(b);
        }
        Ok(out)
    }

    #[test]
    fn frames_give_back_every_bit_as_pages_or_rows() {
        let dir = std::env::temp_dir().join(format!("myriad-spill-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("frames");
        let (on, off) = (sample(5000, true), sample(3000, false));
        let schema = on.schema();
        let grid = Codec {
            compress: false,
            grid: Some(GRID),
        };
        let page = encode_frame(&on, grid);
        assert_eq!(kind(&page), FRAME_PAGE);
        // A node page: far smaller than the rows (55 bytes a point here).
        assert!(
            page.len() < on.len() * on.row_size() / 3,
            "{} bytes",
            page.len()
        );
        // One point off the grid: rows, compressed when asked.
        assert_eq!(kind(&encode_frame(&off, grid)), FRAME_ROWS);
        let zstd = Codec {
            compress: true,
            grid: Some(GRID),
        };
        let rows = encode_frame(&off, zstd);
        assert_eq!(kind(&rows), FRAME_ROWS_ZSTD);
        let no_grid = Codec {
            compress: false,
            grid: None,
        };
        assert_eq!(kind(&encode_frame(&on, no_grid)), FRAME_ROWS);

        let mut file = page.clone();
        file.extend_from_slice(&rows);
        file.extend_from_slice(&encode_frame(&on, no_grid));
        std::fs::write(&path, &file).unwrap();
        let got = read_back(&path, &schema).unwrap();
        assert_eq!(got.len(), 3);
        assert!(got[0] == on, "a page frame changed the points");
        assert!(got[1] == off, "a zstd rows frame changed the points");
        assert!(got[2] == on, "a rows frame changed the points");

        // Cut inside the second frame: the error names the file and where that frame starts.
        std::fs::write(&path, &file[..page.len() + 100]).unwrap();
        let e = read_back(&path, &schema).unwrap_err().to_string();
        assert!(
            e.contains("frames") && e.contains(&format!("byte {}", page.len())),
            "{e}"
        );
        // A damaged page: its column checksum fails, at a byte inside the first frame.
        let mut bad = page.clone();
        let last = bad.len() - 1;
        bad[last] ^= 0xff;
        std::fs::write(&path, &bad).unwrap();
        let e = read_back(&path, &schema).unwrap_err().to_string();
        assert!(e.contains("frames") && e.contains("byte "), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
