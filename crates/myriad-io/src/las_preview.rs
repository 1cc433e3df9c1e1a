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
    /// The leading points that sample the whole file evenly (all of them but where whole
    /// chunks were decoded after: those follow, dense where they are and nowhere else).
    pub even: usize,
    /// The share of an even sample's points that each later one stands for (1 when none).
    pub detail_share: f64,
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
            even: points.len(),
            points,
            indices: at.iter().map(|a| a.0).collect(),
            bytes_read: f.read,
            how,
            detail_share: 1.0,
        })
    }
}

/// LAZ scans of at most this many points are decoded whole for their preview.
const DECODE_WHOLE: u64 = 2_000_000;

/// How long the preview `render --no-wait` draws of large LAZ scans takes in all: their chunks'
/// first points, then whole chunks spread over them decoded for what is left of it (tiles
/// share it), so that the first image, drawn after, comes within 2 s.
pub const PREVIEW_BUDGET: std::time::Duration = std::time::Duration::from_millis(1500);

impl LasSource {
    /// The preview a viewer shows: [`LasSource::preview`], but a small LAZ scan (up to
    /// [`DECODE_WHOLE`] points: few chunks, and one of 50,000 points would give one point)
    /// decoded whole and taken at a stride, fast at that size and a real sample; a large one's
    /// chunks' first points, then until `deadline` whole chunks decoded in an order that spreads
    /// them over the file ([`LasSource::spread_chunks`]).
    pub fn preview_shown(
        &self,
        path: &Path,
        most: usize,
        deadline: std::time::Instant,
    ) -> Result<Preview> {
        let total = self.header.number_of_points();
        // A scan damaged past its chunks' first points still shows them (its build says what
        // is wrong).
        match (
            self.header.point_format().is_compressed,
            total <= DECODE_WHOLE,
        ) {
            (true, true) => {
                (self.decoded_whole(path, total, most)).or_else(|_| self.preview(path, most))
            }
            (true, false) => {
                Ok(self.spread_chunks(path, self.preview(path, most)?, most, deadline))
            }
            (false, _) => self.preview(path, most),
        }
    }

    /// `starts` (the chunks' first points) with, until `deadline`, whole chunks decoded on all
    /// cores, in an order whose every prefix is spread over the file (the golden ratio's
    /// sequence), each taken at a stride: at most `most` points in all, the chunk starts kept.
    fn spread_chunks(
        &self,
        path: &Path,
        mut starts: Preview,
        most: usize,
        deadline: std::time::Instant,
    ) -> Preview {
        use std::sync::Mutex;
        use std::sync::atomic::{AtomicUsize, Ordering};
        let room = most.saturating_sub(starts.points.len());
        let Ok(Some(chunks)) = self.chunks() else {
            return starts;
        };
        if room == 0 || chunks.is_empty() || std::time::Instant::now() >= deadline {
            return starts;
        }
        let mut first = Vec::with_capacity(chunks.len());
        let mut at = 0u64;
        for c in &chunks {
            first.push(at);
            at += c.points;
        }
        // Each chunk's share of the room (at least 1/64 of it), so that memory stays a few
        // times `most` whatever the chunks decoded.
        let per_chunk = (room / 64).max(1);
        let most_chunks = (2 * room).div_ceil(per_chunk).min(chunks.len());
        let n = chunks.len();
        let mut order: Vec<usize> = Vec::with_capacity(n);
        let mut seen = vec![false; n];
        let phi = 0.618_033_988_749_894_9;
        let mut k = 0usize;
        while order.len() < most_chunks && k < 4 * n {
            let c = ((k as f64 * phi).fract() * n as f64) as usize % n;
            if !seen[c] {
                seen[c] = true;
                order.push(c);
            }
            k += 1;
        }
        let next = AtomicUsize::new(0);
        let got: Mutex<Vec<(usize, PointBatch, Vec<u64>)>> = Mutex::new(Vec::new());
        let threads = std::thread::available_parallelism()
            .map_or(1, |t| t.get())
            .min(8);
        std::thread::scope(|s| {
            for _ in 0..threads {
                s.spawn(|| {
                    loop {
                        if std::time::Instant::now() >= deadline {
                            break;
                        }
                        let k = next.fetch_add(1, Ordering::Relaxed);
                        let Some(&c) = order.get(k) else { break };
                        let Ok(mut src) = LasSource::open(path) else {
                            break;
                        };
                        if src.keep_chunks(&[c as u32]).is_err() {
                            break;
                        }
                        let step = (chunks[c].points as usize).div_ceil(per_chunk).max(1);
                        // The chunk's first point is among the starts. A chunk that does not
                        // decode is left to the build to name.
                        if let Ok((Some(p), idx)) = at_stride(&mut src, step, true, first[c]) {
                            got.lock()
                                .expect("a preview thread panicked")
                                .push((c, p, idx));
                        }
                    }
                });
            }
        });
        let mut got = got.into_inner().expect("a preview thread panicked");
        if got.is_empty() {
            return starts;
        }
        got.sort_by_key(|g| g.0);
        starts.bytes_read += got.iter().map(|g| chunks[g.0].bytes).sum::<u64>();
        let decoded: usize = got.iter().map(|g| g.1.len()).sum();
        let stride = decoded.div_ceil(room).max(1);
        // A chunk start stands for its chunk's points, a decoded sample for step x stride.
        let mean_chunk = at as f64 / n as f64;
        let step = (mean_chunk / per_chunk as f64).ceil().max(1.0);
        starts.detail_share = (step * stride as f64 / mean_chunk).min(1.0);
        // The starts of the chunks decoded go with their chunks' points (drawn fine there, not
        // as one coarse square over them): the even ones first, then those.
        let done: std::collections::HashSet<u64> = got.iter().map(|g| first[g.0]).collect();
        let (coarse, fine): (Vec<u32>, Vec<u32>) = (0..starts.points.len() as u32)
            .partition(|&k| !done.contains(&starts.indices[k as usize]));
        let order: Vec<u32> = coarse.iter().chain(&fine).copied().collect();
        starts.points = starts.points.gather(&order);
        starts.indices = order.iter().map(|&k| starts.indices[k as usize]).collect();
        starts.even = coarse.len();
        let mut i = 0usize;
        for (_, b, idx) in got {
            let keep: Vec<u32> = (0..b.len())
                .filter(|k| (i + k).is_multiple_of(stride))
                .map(|k| k as u32)
                .collect();
            i += b.len();
            starts.indices.extend(keep.iter().map(|&k| idx[k as usize]));
            starts.points.append(&b.gather(&keep));
        }
        starts.how =
            "the first point of each LAZ chunk, then whole chunks spread over the file, decoded";
        starts
    }

    /// The preview of a small LAZ scan: every point decoded, at most `most` kept at a stride.
    fn decoded_whole(&self, path: &Path, total: u64, most: usize) -> Result<Preview> {
        let mut src = LasSource::open(path)?;
        let step = (total as usize).div_ceil(most.max(1)).max(1);
        let (points, indices) = at_stride(&mut src, step, false, 0)?;
        let bytes_read = std::fs::metadata(path).map_or(0, |m| m.len());
        let points = points.unwrap_or_else(|| {
            batch_for(
                &self.layout,
                self.record_len.saturating_sub(self.layout.base_len),
                0,
            )
        });
        Ok(Preview {
            even: points.len(),
            detail_share: 1.0,
            points,
            indices,
            bytes_read,
            how: "a small LAZ scan decoded whole, taken at a stride",
        })
    }
}

/// Every `step`-th point `src` reads to its end (its first too unless `skip_first`), and each
/// one's index in the file (`base` plus its place in what `src` reads).
fn at_stride(
    src: &mut LasSource,
    step: usize,
    skip_first: bool,
    base: u64,
) -> Result<(Option<PointBatch>, Vec<u64>)> {
    let (mut points, mut indices, mut seen): (Option<PointBatch>, Vec<u64>, usize) =
        (None, Vec::new(), 0);
    while let Some(b) = src.read_batch(crate::MAX_BATCH)? {
        let keep: Vec<u32> = (0..b.len())
            .filter(|i| {
                let j = seen + i;
                j.is_multiple_of(step) && !(skip_first && j == 0)
            })
            .map(|i| i as u32)
            .collect();
        indices.extend(keep.iter().map(|&i| base + (seen + i as usize) as u64));
        let part = b.gather(&keep);
        match &mut points {
            Some(p) => p.append(&part),
            None => points = Some(part),
        }
        seen += b.len();
    }
    Ok((points, indices))
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
    /// Each sample's leading points that sample its file evenly ([`Preview::even`]).
    pub even: Vec<usize>,
    /// The share of an even sample's points each later one stands for (the largest of the
    /// files'; 1 when none).
    pub detail_share: f64,
}

/// The previews of `files` (LAS or LAZ each), at most `most` points in all: several files
/// opened and sampled at once (each open reads a header, VLRs and a chunk table, small reads
/// that wait on the disk); large LAZ files' chunk starts then whole chunks decoded until
/// `budget` from the start has passed (none for [`Duration::ZERO`]: a viewer's first frame at
/// once, its build filling in what the decoding would).
///
/// [`Duration::ZERO`]: std::time::Duration::ZERO
pub fn preview_files(
    files: &[std::path::PathBuf],
    most: usize,
    budget: std::time::Duration,
) -> Result<Tiles> {
    const AT_ONCE: usize = 16;
    let per_file = (most / files.len().max(1)).max(1);
    let deadline = std::time::Instant::now() + budget;
    let one = |f: &std::path::PathBuf| -> Result<(LasSource, Preview)> {
        let src = LasSource::open(f)?;
        let p = src.preview_shown(f, per_file, deadline)?;
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
        even: Vec::with_capacity(files.len()),
        detail_share: 0.0,
    };
    for (src, p) in done {
        t.total += src.header().number_of_points();
        t.bytes_read += p.bytes_read;
        if t.how.is_empty() || src.header().point_format().is_compressed {
            t.how = p.how;
        }
        t.even.push(p.even);
        if p.even < p.points.len() {
            t.detail_share = t.detail_share.max(p.detail_share);
        }
        t.samples.push(p.points);
    }
    if t.detail_share == 0.0 {
        t.detail_share = 1.0;
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
