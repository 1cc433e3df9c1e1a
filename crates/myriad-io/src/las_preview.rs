//! A first look at a LAS or LAZ file without decoding it (after LidarScout, Erler et al. 2025):
//! LAZ stores the first point of every chunk raw at the chunk's start (pointwise and layered
//! chunks alike: layered ones follow it with their point count and layer sizes), and the chunk table says
//! where each chunk begins, so one small read per chunk gives a sample of the whole scan, about
//! 1 point in 50,000, with no compressed byte read. LAS records are read at a stride. COPC is
//! LAZ and takes the same path (its chunks are its nodes: the sample is as even).

use crate::PointSource;
use crate::las::LasSource;
use crate::las_records::{batch_for, decode};
use myriad_core::{Error, PointBatch, Result};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

/// What a preview read, and how.
pub struct Preview {
    /// The sampled points, every attribute the point format has.
    pub points: PointBatch,
    /// Which point of the file each sample is (its index in the file's order).
    pub indices: Vec<u64>,
    /// Bytes read from the file for the sample (the chunk table and the raw points; the header
    /// and VLRs, read by [`LasSource::open`], apart).
    pub bytes_read: u64,
    /// How the sample was taken, in a few words.
    pub how: &'static str,
}

/// Counts the bytes read through it.
struct Counted<R> {
    inner: R,
    read: u64,
}

impl<R: Read> Read for Counted<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.read += n as u64;
        Ok(n)
    }
}

impl<R: Seek> Seek for Counted<R> {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.inner.seek(pos)
    }
}

impl LasSource {
    /// A sample of at most `most` points of the file, read without decompressing anything:
    /// for LAZ the first point of each chunk (every k-th chunk when there are more than `most`),
    /// for LAS every k-th record.
    pub fn preview(&self, path: &Path, most: usize) -> Result<Preview> {
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        let mut f = Counted {
            inner: file,
            read: 0,
        };
        let total = self.header.number_of_points();
        let len = self.record_len;
        let compressed = self.header.point_format().is_compressed;
        // (index in the file, byte offset of the raw record) of each sample.
        let mut at: Vec<(u64, u64)> = Vec::new();
        let how = if compressed {
            let vlr = self
                .header
                .laz_vlr()
                .map_err(|e| Error::at_byte(path, 0, format!("LAZ without its VLR: {e}")))?;
            f.seek(SeekFrom::Start(self.data_at))
                .map_err(|e| Error::io(path, e))?;
            let table = laz::laszip::ChunkTable::read_from(&mut f, &vlr)
                .map_err(|e| Error::at_byte(path, self.data_at, format!("LAZ chunk table: {e}")))?;
            let (mut point, mut byte) = (0u64, self.data_at + 8);
            for chunk in table.as_ref() {
                if point >= total {
                    break;
                }
                if chunk.point_count > 0 {
                    at.push((point, byte));
                }
                point += chunk.point_count;
                byte += chunk.byte_count;
            }
            "the first point of each LAZ chunk (stored raw), no decompression"
        } else {
            let n = (total as usize).min(most.max(1)) as u64;
            at.extend((0..n).map(|k| {
                let i = k * total / n.max(1);
                (i, self.data_at + i * len as u64)
            }));
            "LAS records at a stride"
        };
        if at.len() > most.max(1) {
            let n = at.len();
            let keep = most.max(1);
            at = (0..keep).map(|k| at[k * n / keep]).collect();
        }
        // Samples close together (LAS records a few apart) are read through one buffer, in a
        // pass over the file; far apart ones (LAZ chunks) each on its own, many in flight, so
        // that no compressed byte is read.
        let gap = at.windows(2).map(|w| w[1].1 - w[0].1).max().unwrap_or(0);
        let buffer = if !compressed && gap <= 1 << 16 {
            1 << 20
        } else {
            len.max(1)
        };
        let mut raw = vec![0u8; at.len() * len];
        let eof = |byte: u64| {
            Error::at_byte(
                path,
                byte,
                "file ends inside a point record the preview reads",
            )
        };
        if buffer > len {
            let mut r = std::io::BufReader::with_capacity(buffer, &mut f);
            let mut pos: Option<u64> = None;
            for (k, &(_, byte)) in at.iter().enumerate() {
                let moved = match pos {
                    Some(p) if byte >= p => r.seek_relative((byte - p) as i64),
                    _ => r.seek(SeekFrom::Start(byte)).map(|_| ()),
                };
                moved.map_err(|e| Error::io(path, e))?;
                r.read_exact(&mut raw[k * len..(k + 1) * len])
                    .map_err(|e| match e.kind() {
                        std::io::ErrorKind::UnexpectedEof => eof(byte),
                        _ => Error::io(path, e),
                    })?;
                pos = Some(byte + len as u64);
            }
        } else {
            read_apart(&f.inner, &at, len, &mut raw).map_err(|(byte, e)| match e.kind() {
                std::io::ErrorKind::UnexpectedEof => eof(byte),
                _ => Error::io(path, e),
            })?;
            f.read += (at.len() * len) as u64;
        }
        let extra = len.saturating_sub(self.layout.base_len);
        let mut points = batch_for(&self.layout, extra, at.len());
        decode(&raw, len, &self.layout, &self.quant, &mut points);
        Ok(Preview {
            points,
            indices: at.iter().map(|a| a.0).collect(),
            bytes_read: f.read,
            how,
        })
    }
}

/// LAZ scans of at most this many points are decoded whole for their preview.
const DECODE_WHOLE: u64 = 2_000_000;

impl LasSource {
    /// The preview a viewer shows: [`LasSource::preview`], but a small LAZ scan (up to
    /// [`DECODE_WHOLE`] points: few chunks, and one of 50,000 points would give one point)
    /// decoded whole and taken at a stride, fast at that size and a real sample.
    pub fn preview_shown(&self, path: &Path, most: usize) -> Result<Preview> {
        let total = self.header.number_of_points();
        // A scan damaged past its chunks' first points still shows them (its build says what
        // is wrong).
        match self.header.point_format().is_compressed && total <= DECODE_WHOLE {
            true => (self.decoded_whole(path, total, most)).or_else(|_| self.preview(path, most)),
            false => self.preview(path, most),
        }
    }

    /// The preview of a small LAZ scan: every point decoded, at most `most` kept at a stride.
    fn decoded_whole(&self, path: &Path, total: u64, most: usize) -> Result<Preview> {
        let mut src = LasSource::open(path)?;
        let step = (total as usize).div_ceil(most.max(1)).max(1);
        let mut points: Option<PointBatch> = None;
        let mut indices = Vec::new();
        let mut seen = 0u64;
        while let Some(b) = src.read_batch(crate::MAX_BATCH)? {
            let keep: Vec<u32> = (0..b.len())
                .filter(|i| (seen as usize + i).is_multiple_of(step))
                .map(|i| i as u32)
                .collect();
            indices.extend(keep.iter().map(|&i| seen + i as u64));
            let part = b.gather(&keep);
            match &mut points {
                Some(p) => p.append(&part),
                None => points = Some(part),
            }
            seen += b.len() as u64;
        }
        let bytes_read = std::fs::metadata(path).map_or(0, |m| m.len());
        Ok(Preview {
            points: points.unwrap_or_else(|| {
                batch_for(
                    &self.layout,
                    self.record_len.saturating_sub(self.layout.base_len),
                    0,
                )
            }),
            indices,
            bytes_read,
            how: "a small LAZ scan decoded whole, taken at a stride",
        })
    }
}

/// The previews of several files (the tiles of one survey), and what the files disagree on.
pub struct Tiles {
    /// Each file's sample, in the files' order.
    pub samples: Vec<PointBatch>,
    /// Points in all the files, by their headers.
    pub total: u64,
    pub bytes_read: u64,
    /// How the samples were taken (the last file's way; LAS and LAZ tiles mixed say LAZ's).
    pub how: &'static str,
    /// What the files disagree on.
    pub differences: crate::Differences,
}

/// The previews of `files` (LAS or LAZ each), at most `most` points in all: several files
/// opened and sampled at once (each open reads a header, VLRs and a chunk table, small reads
/// that wait on the disk).
pub fn preview_files(files: &[std::path::PathBuf], most: usize) -> Result<Tiles> {
    const AT_ONCE: usize = 16;
    let per_file = (most / files.len().max(1)).max(1);
    let one = |f: &std::path::PathBuf| -> Result<(LasSource, Preview)> {
        let src = LasSource::open(f)?;
        let p = src.preview_shown(f, per_file)?;
        Ok((src, p))
    };
    let per = files.len().div_ceil(AT_ONCE).max(1);
    let done: Vec<Result<(LasSource, Preview)>> = std::thread::scope(|s| {
        let jobs: Vec<_> = files
            .chunks(per)
            .map(|group| s.spawn(move || group.iter().map(one).collect::<Vec<_>>()))
            .collect();
        jobs.into_iter()
            .flat_map(|j| j.join().expect("a preview thread panicked"))
            .collect()
    });
    let done = done.into_iter().collect::<Result<Vec<_>>>()?;
    let mut t = Tiles {
        samples: Vec::with_capacity(files.len()),
        total: 0,
        bytes_read: 0,
        how: "",
        differences: crate::Differences::of(done.iter().map(|(src, _)| src.info())),
    };
    for (src, p) in done {
        t.total += src.header().number_of_points();
        t.bytes_read += p.bytes_read;
        if t.how.is_empty() || src.header().point_format().is_compressed {
            t.how = p.how;
        }
        t.samples.push(p.points);
    }
    Ok(t)
}

/// Reads the `len`-byte records at the offsets of `at` into `raw`, many reads in flight at once
/// (one at a time, each waits on the disk: 20,000 reads of a cold 8 GB file took about 1.5 s).
/// The failing read's offset, with its error.
fn read_apart(
    file: &File,
    at: &[(u64, u64)],
    len: usize,
    raw: &mut [u8],
) -> std::result::Result<(), (u64, std::io::Error)> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileExt;
        const IN_FLIGHT: usize = 32;
        let per = at.len().div_ceil(IN_FLIGHT).max(1);
        std::thread::scope(|s| {
            let jobs: Vec<_> = at
                .chunks(per)
                .zip(raw.chunks_mut(per * len))
                .map(|(offsets, out)| {
                    s.spawn(move || {
                        for (k, &(_, byte)) in offsets.iter().enumerate() {
                            file.read_exact_at(&mut out[k * len..(k + 1) * len], byte)
                                .map_err(|e| (byte, e))?;
                        }
                        Ok(())
                    })
                })
                .collect();
            jobs.into_iter()
                .try_for_each(|j| j.join().expect("a preview reader panicked"))
        })
    }
    #[cfg(not(unix))]
    {
        let mut f = file;
        for (k, &(_, byte)) in at.iter().enumerate() {
            f.seek(SeekFrom::Start(byte)).map_err(|e| (byte, e))?;
            f.read_exact(&mut raw[k * len..(k + 1) * len])
                .map_err(|e| (byte, e))?;
        }
        Ok(())
    }
}
