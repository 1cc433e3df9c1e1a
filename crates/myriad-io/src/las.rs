//! LAS 1.0-1.4 and LAZ (COPC included, read as plain LAZ) through the `las` crate: it parses
//! headers and VLRs and decompresses LAZ on all cores; records are decoded into columns here
//! (`las_records`), which is several times faster than materializing `las::Point`s. LAZ chunks
//! are found and decompressed by `las_chunks.rs`; [`chunk_bounds`] is the pass over them that
//! gives each chunk's bounds. The writer ([`LasSink`]) is in `las_write.rs`.

use crate::las_chunks;
pub use crate::las_chunks::LazChunk;
pub use crate::las_extra::{extra_bytes_vlr, extra_dims};
use crate::las_guard::{
    HEADER_PREFIX, check_evlr, check_header, check_laz_chunk_table, check_laz_layers, check_vlrs,
    header_bounds,
};
use crate::las_records::{self, Layout, Quantization};
pub use crate::las_write::{LasSink, LasWriteOptions};
use crate::{Format, PointSource, SourceInfo};
use myriad_core::{Aabb, Attribute, Error, PointBatch, Result, Schema};
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};

/// A file handle that publishes how far it has read, so that errors raised deep inside the `las`
/// and `laz` crates can still name a byte offset.
struct Tracked {
    file: File,
    pos: Arc<AtomicU64>,
}

impl Read for Tracked {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.file.read(buf)?;
        self.pos.fetch_add(n as u64, Ordering::Relaxed);
        Ok(n)
    }
}

impl Seek for Tracked {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        let p = self.file.seek(to)?;
        self.pos.store(p, Ordering::Relaxed);
        Ok(p)
    }
}

/// Reads LAS/LAZ. Records are read (and LAZ decompressed on all cores) by a producer thread one
/// block ahead, while the caller decodes the previous block into columns: decoding overlaps
/// decompression instead of following it. LAZ of fixed-size chunks and more than one block has
/// two producers taking the blocks in turn (`produce_records`).
pub struct LasSource {
    info: SourceInfo,
    pub(crate) header: las::Header,
    pub(crate) layout: Layout,
    pub(crate) quant: Quantization,
    pub(crate) record_len: usize,
    /// Offset of the point data.
    pub(crate) data_at: u64,
    remaining: u64,
    stream: Option<RecordStream>,
    /// The LAZ chunks to read, where only some are ([`LasSource::keep_chunks`]).
    kept: Option<Vec<LazChunk>>,
    /// Files of this file's raw records to read instead of its own point data
    /// ([`LasSource::keep_exchanged`]).
    exchanged: Option<Vec<PathBuf>>,
}

/// Raw record blocks from the producer threads, and the part of the last block not yet decoded.
/// A block's buffer goes back to its producer once decoded, to be filled again: no
/// copy out of the `las` crate's buffer, and no fresh memory to fault in for every block.
struct RecordStream {
    /// Per producer: its blocks, and the way back for their buffers. The blocks come from the
    /// producers in turn.
    producers: Vec<(Receiver<Result<las::PointData>>, SyncSender<las::PointData>)>,
    /// The producer of the next block.
    next: usize,
    /// The block being read, and its producer.
    pending: Option<(las::PointData, usize)>,
    at: usize,
}

impl RecordStream {
    /// `stride` producer threads named `name`, taken in turn: thread `first` runs `produce` with
    /// its channel out and the channel of spent buffers coming back.
    fn of(
        stride: usize,
        name: &str,
        produce: impl Fn(usize, SyncSender<Result<las::PointData>>, Receiver<las::PointData>)
        + Clone
        + Send
        + 'static,
    ) -> RecordStream {
        let producers = (0..stride)
            .map(|first| {
                let (tx, rx) = sync_channel(1);
                let (spent, spent_rx) = sync_channel(2);
                let produce = produce.clone();
                std::thread::Builder::new()
                    .name(name.into())
                    .spawn(move || produce(first, tx, spent_rx))
                    .expect("spawn a LAS reader thread");
                (rx, spent)
            })
            .collect();
        RecordStream {
            producers,
            next: 0,
            pending: None,
            at: 0,
        }
    }
}

/// Records per block a producer thread reads: several LAZ chunks, so that decompression runs
/// on all cores, and a few tens of megabytes at most.
const PRODUCER_BLOCK: u64 = 1 << 19;

fn header_error(path: &Path, e: las::Error) -> Error {
    Error::at_byte(
        path,
        header_field(&e).unwrap_or(0),
        format!("invalid LAS header: {e}"),
    )
}

/// The header field a `las` crate error is about (LAS 1.4 R15, table 3), where it names one.
fn header_field(e: &las::Error) -> Option<u64> {
    use las::Error as E;
    Some(match e {
        E::InvalidFileSignature(_) => 0,
        E::UnsupportedFeature { .. } => 24,
        E::OffsetToPointDataTooSmall(_) | E::OffsetToPointDataTooLarge(_) => 96,
        E::TooManyVlrs(_) => 100,
        E::InvalidPointFormatNumber(_) | E::UnsupportedFormat { .. } | E::InvalidPointFormat(_) => {
            104
        }
        E::PointDataRecordLengthTooLarge { .. } => 105,
        E::ReturnNumber { .. } => 111,
        E::OffsetToEvlrsTooSmall(_) => 235,
        E::TooManyEvlrs(_) => 243,
        E::TooManyPoints { .. } => 247,
        _ => return None,
    })
}

/// Did reading stop at the end of the file? (`laz` wraps I/O errors without exposing a source.)
fn is_eof(e: &las::Error) -> bool {
    let io = match e {
        las::Error::Io(io) => io,
        las::Error::LasZipError(laz::LasZipError::IoError(io)) => io,
        _ => return false,
    };
    io.kind() == std::io::ErrorKind::UnexpectedEof
}

impl LasSource {
    pub fn open(path: &Path) -> Result<LasSource> {
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        let file_size = file.metadata().map_err(|e| Error::io(path, e))?.len();
        let mut magic = [0u8; 4];
        let n = crate::read_util::read_prefix(path, &mut magic)?;
        if n < 4 || &magic != b"LASF" {
            return Err(Error::at_byte(
                path,
                0,
                "wrong magic number: LAS files start with \"LASF\"",
            ));
        }
        if file_size < 227 {
            return Err(Error::at_byte(
                path,
                file_size,
                "file ends inside the 227-byte LAS header",
            ));
        }
        let mut head = [0u8; HEADER_PREFIX];
        crate::read_util::read_prefix(path, &mut head)?;
        check_header(path, &head, file_size)?;
        let raw = las::raw::Header::read_from(BufReader::new(
            File::open(path).map_err(|e| Error::io(path, e))?,
        ))
        .map_err(|e| header_error(path, e))?;
        check_vlrs(path, &raw)?;
        check_evlr(path, &raw, file_size)?;
        if raw.point_data_record_format & 0xC0 != 0 {
            check_laz_chunk_table(path, &raw, file_size)?;
        }
        let pos = Arc::new(AtomicU64::new(0));
        let tracked = Tracked {
            file,
            pos: pos.clone(),
        };
        // The header and VLRs only: the producer thread opens its own reader (`las::Reader` is
        // not `Send`), and the LAZ chunk table was checked above. Unbuffered, so that the
        // position an error is reported at is the reader's, not a buffer's end (a few hundred
        // small reads).
        let header = las::Header::new(tracked).map_err(|e| {
            let at = pos.load(Ordering::Relaxed).min(file_size);
            if is_eof(&e) {
                Error::at_byte(
                    path,
                    at,
                    "unexpected end of file in the header or VLRs (truncated file?)",
                )
            } else {
                let at = header_field(&e).unwrap_or(at);
                Error::at_byte(path, at, format!("invalid LAS/LAZ header data: {e}"))
            }
        })?;
        if header.point_format().is_compressed {
            check_laz_layers(path, &header, raw.offset_to_point_data as u64, file_size)?;
        }
        let fmt = header.point_format();
        let format_id = fmt.to_u8().map_err(|e| header_error(path, e))?;
        let layout = Layout::new(format_id).ok_or_else(|| {
            Error::at_byte(path, 104, format!("unknown point format {format_id}"))
        })?;
        let record_len = fmt.len() as usize;
        let count = header.number_of_points();
        let compressed = fmt.is_compressed;
        if !compressed {
            let needed = (record_len as u64)
                .checked_mul(count)
                .and_then(|b| b.checked_add(raw.offset_to_point_data as u64));
            if needed.is_none_or(|n| n > file_size) {
                let holds = (file_size - raw.offset_to_point_data as u64) / record_len as u64;
                return Err(Error::at_byte(
                    path,
                    file_size,
                    format!(
                        "file ends after {holds} of the {count} point records its header declares"
                    ),
                ));
            }
        }
        let quant = Quantization::of(&header);
        let bounds = header_bounds(&raw).map(|(min, max)| Aabb::new(min, max));
        let is_copc = header.all_vlrs().any(|v| v.user_id == "copc");
        let version = format!(
            "{}.{} point format {format_id}{}",
            header.version().major,
            header.version().minor,
            if is_copc { " (COPC)" } else { "" }
        );
        let mut schema = Schema::for_las_format(format_id);
        schema.extra_bytes = fmt.extra_bytes as usize;
        schema
            .attributes
            .extend(extra_dims(&header).into_iter().map(Attribute::Extra));
        let info = SourceInfo {
            path: path.to_path_buf(),
            format: if compressed { Format::Laz } else { Format::Las },
            version,
            points: Some(count),
            bounds: bounds.filter(|_| count > 0),
            schema,
            scale: Some(quant.scale),
            offset: Some(quant.offset),
            crs: crs_of(&header),
            file_size,
            origins: Vec::new(),
        };
        Ok(LasSource {
            info,
            header,
            layout,
            quant,
            record_len,
            data_at: raw.offset_to_point_data as u64,
            remaining: count,
            stream: None,
            kept: None,
            exchanged: None,
        })
    }

    /// The file's LAZ chunks (`None`: not LAZ, or written without a chunk table).
    pub fn chunks(&self) -> Result<Option<Vec<LazChunk>>> {
        las_chunks::table(
            &self.info.path,
            &self.header,
            self.data_at,
            self.info.file_size,
        )
    }

    /// Reads only the LAZ chunks `indices` (of the chunk table, ascending), before any point is
    /// read: the source then holds their points only (`info().points` says how many).
    pub fn keep_chunks(&mut self, indices: &[u32]) -> Result<()> {
        let path = &self.info.path;
        if self.stream.is_some() {
            return Err(Error::Invalid(format!(
                "{}: chunks chosen after reading began",
                path.display()
            )));
        }
        let all = self.chunks()?.ok_or_else(|| {
            Error::at_byte(
                path,
                self.data_at,
                "chunks to read were given, but the file has no LAZ chunk table (it changed \
                 since the plan was made?)",
            )
        })?;
        let mut kept = Vec::with_capacity(indices.len());
        for (k, &i) in indices.iter().enumerate() {
            let c = all.get(i as usize).filter(|_| k == 0 || indices[k - 1] < i);
            kept.push(*c.ok_or_else(|| {
                Error::Invalid(format!(
                    "{}: chunk {i} of {} asked for (out of order, or the file changed since the \
                     plan was made: plan again)",
                    path.display(),
                    all.len()
                ))
            })?);
        }
        self.remaining = kept.iter().map(|c| c.points).sum();
        self.info.points = Some(self.remaining);
        self.kept = Some(kept);
        Ok(())
    }

    /// Reads its records from `files` instead of its own point data, before any point is read:
    /// each file holds raw records of this file's point format, one after another, as
    /// [`LasSource::next_records`] gives them (a partitioned build's scatter task wrote them for
    /// one part). The source then holds their points only (`info().points` says how many).
    pub fn keep_exchanged(&mut self, files: &[PathBuf]) -> Result<()> {
        if self.stream.is_some() {
            return Err(Error::Invalid(format!(
                "{}: records to read chosen after reading began",
                self.info.path.display()
            )));
        }
        let len = self.record_len as u64;
        let mut total = 0u64;
        for f in files {
            let bytes = std::fs::metadata(f).map_err(|e| Error::io(f, e))?.len();
            if bytes % len != 0 {
                return Err(Error::at_byte(
                    f,
                    bytes - bytes % len,
                    format!(
                        "ends inside a record of {len} bytes (records of {} cut short?)",
                        self.info.path.display()
                    ),
                ));
            }
            total += bytes / len;
        }
        self.remaining = total;
        self.info.points = Some(total);
        self.kept = None;
        self.exchanged = Some(files.to_vec());
        Ok(())
    }

    /// The next block of raw records (LAZ decompressed), none decoded into columns: for a
    /// caller that copies records as they are, by their positions ([`LasSource::position_of`]).
    /// `None` at the end.
    pub fn next_records(&mut self) -> Result<Option<&[u8]>> {
        self.take_records(usize::MAX)
    }

    /// The length of one record, in bytes.
    pub fn record_len(&self) -> usize {
        self.record_len
    }

    /// A raw record's position, as [`PointSource::read_batch`] decodes it.
    pub fn position_of(&self) -> impl Fn(&[u8]) -> [f64; 3] + Copy + use<> {
        let q = self.quant;
        move |record| las_records::position(record, &q)
    }

    /// Up to `max` records of the block being read (the next block once it is read to its
    /// end), taken from what remains.
    fn take_records(&mut self, max: usize) -> Result<Option<&[u8]>> {
        if self.remaining == 0 {
            return Ok(None);
        }
        let (path, header) = (&self.info.path, &self.header);
        let (data_at, total) = (self.data_at, self.remaining);
        let (kept, exchanged) = (self.kept.as_deref(), self.exchanged.as_deref());
        let stream = self.stream.get_or_insert_with(|| match (kept, exchanged) {
            (_, Some(files)) => start_file_stream(header, files),
            (Some(k), None) => start_chunk_stream(path, header, k),
            (None, None) => start_stream(path, header, data_at, total),
        });
        if stream.at == stream.pending.as_ref().map_or(0, |d| d.0.raw_bytes().len()) {
            stream.advance(path)?;
        }
        let pending = stream.pending.as_ref().map_or(&[][..], |d| d.0.raw_bytes());
        let left = (pending.len() - stream.at) / self.record_len;
        let n = left.min(max).min(self.remaining as usize);
        let bytes = &pending[stream.at..stream.at + n * self.record_len];
        stream.at += n * self.record_len;
        self.remaining -= n as u64;
        Ok(Some(bytes))
    }

    /// The parsed LAS header, for writers that copy a file's point format, VLRs and scaling.
    pub fn header(&self) -> &las::Header {
        &self.header
    }
}

/// The bounds of each chunk's points (`Aabb::EMPTY` for an empty chunk), in the file's
/// coordinates (records times scale plus offset, as they are read), and each chunk's points.
/// Only X, Y and Z are decompressed where the point format is layered; older formats are
/// decompressed whole (their fields share one arithmetic coder). Chunks run on all cores.
/// `None` when `path` is not LAZ or has no chunk table.
pub fn chunk_bounds(path: &Path) -> Result<Option<Vec<(LazChunk, Aabb)>>> {
    let source = LasSource::open(path)?;
    let Some(chunks) = source.chunks()? else {
        return Ok(None);
    };
    let header = source.header();
    let vlr = header
        .laz_vlr()
        .map_err(|e| Error::at_byte(path, 0, format!("invalid laszip VLR: {e}")))?;
    let q = Quantization::of(header);
    let record = header.point_format().len() as usize;
    let selection = laz::DecompressionSelection::xy_returns_channel().decompress_z();
    let mut file = File::open(path).map_err(|e| Error::io(path, e))?;
    let (mut compressed, mut records) = (Vec::new(), Vec::new());
    let mut out = Vec::with_capacity(chunks.len());
    for block in las_chunks::blocks(&chunks, PRODUCER_BLOCK) {
        let n: u64 = block.iter().map(|c| c.points).sum();
        records.resize(n as usize * record, 0u8);
        las_chunks::decompress(
            path,
            &mut file,
            &vlr,
            &block,
            selection,
            &mut compressed,
            &mut records,
        )?;
        let mut at = 0usize;
        for c in block {
            let end = at + c.points as usize * record;
            let (mut lo, mut hi) = ([i32::MAX; 3], [i32::MIN; 3]);
            for r in records[at..end].chunks_exact(record) {
                for a in 0..3 {
                    let v = i32::from_le_bytes(r[4 * a..4 * a + 4].try_into().unwrap());
                    lo[a] = lo[a].min(v);
                    hi[a] = hi[a].max(v);
                }
            }
            let b = if c.points == 0 {
                Aabb::EMPTY
            } else {
                // A negative scale mirrors the records: both ends, then the order.
                let end = |v: [i32; 3]| -> [f64; 3] {
                    std::array::from_fn(|a| v[a] as f64 * q.scale[a] + q.offset[a])
                };
                let (a, z) = (end(lo), end(hi));
                Aabb::new(
                    std::array::from_fn(|i| a[i].min(z[i])),
                    std::array::from_fn(|i| a[i].max(z[i])),
                )
            };
            out.push((c, b));
            at = end;
        }
    }
    Ok(Some(out))
}

/// Starts the producer threads that read (and decompress) `total` records from `path`.
fn start_stream(path: &Path, header: &las::Header, data_at: u64, total: u64) -> RecordStream {
    // Two producers in turn for LAZ of more than one block (see `produce_records`).
    // Only where blocks are whole fixed-size chunks: each producer seeks to its blocks,
    // and the `laz` crate seeks right only to the start of a chunk of the fixed size (in
    // a file of variable chunks, COPC's, it takes the point's index for its place in the
    // chunk).
    let chunked = fixed_chunk(header).is_some();
    let stride = if chunked && total > producer_block(header) {
        2
    } else {
        1
    };
    let path = path.to_path_buf();
    RecordStream::of(stride, "las-reader", move |first, tx, spent| {
        produce_records(
            path.clone(),
            data_at,
            total,
            (first as u64, stride as u64),
            tx,
            spent,
        )
    })
}

/// Starts the producer threads that read (and decompress) the LAZ chunks `chunks`, in blocks of
/// whole chunks, two producers in turn where there is more than one block.
fn start_chunk_stream(path: &Path, header: &las::Header, chunks: &[LazChunk]) -> RecordStream {
    let blocks = Arc::new(las_chunks::blocks(chunks, producer_block(header)));
    let stride = blocks.len().clamp(1, 2);
    let builder = las::PointDataBuilder::new().for_header(header);
    let vlr = header.laz_vlr().ok();
    let path = path.to_path_buf();
    RecordStream::of(stride, "laz-chunks", move |first, tx, spent_rx| {
        let produce = |tx: &SyncSender<Result<las::PointData>>| -> Result<()> {
            let vlr =
                (vlr.clone()).ok_or_else(|| Error::at_byte(&path, 0, "invalid laszip VLR"))?;
            let mut file = File::open(&path).map_err(|e| Error::io(&path, e))?;
            let mut compressed = Vec::new();
            for block in blocks.iter().skip(first).step_by(stride) {
                let n: u64 = block.iter().map(|c| c.points).sum();
                let mut data = spent_rx
                    .try_recv()
                    .unwrap_or_else(|_| builder.clone().build());
                las_chunks::decompress(
                    &path,
                    &mut file,
                    &vlr,
                    block,
                    laz::DecompressionSelection::all(),
                    &mut compressed,
                    data.resize_for(n as usize),
                )?;
                if tx.send(Ok(data)).is_err() {
                    break; // the source was dropped
                }
            }
            Ok(())
        };
        if let Err(e) = produce(&tx) {
            let _ = tx.send(Err(e));
        }
    })
}

/// Starts the producer thread that reads the raw records of `files` (see
/// [`LasSource::keep_exchanged`]) in blocks, one file after another.
fn start_file_stream(header: &las::Header, files: &[PathBuf]) -> RecordStream {
    let builder = las::PointDataBuilder::new().for_header(header);
    let len = header.point_format().len() as u64;
    let files = files.to_vec();
    RecordStream::of(1, "records-reader", move |_, tx, spent_rx| {
        let produce = |tx: &SyncSender<Result<las::PointData>>| -> Result<()> {
            for path in &files {
                let mut file = File::open(path).map_err(|e| Error::io(path, e))?;
                let bytes = file.metadata().map_err(|e| Error::io(path, e))?.len();
                let (mut left, mut at) = (bytes / len, 0u64);
                while left > 0 {
                    let n = left.min(PRODUCER_BLOCK);
                    let mut data = spent_rx
                        .try_recv()
                        .unwrap_or_else(|_| builder.clone().build());
                    file.read_exact(data.resize_for(n as usize))
                        .map_err(|e| Error::at_byte(path, at, format!("cannot read: {e}")))?;
                    if tx.send(Ok(data)).is_err() {
                        return Ok(()); // the source was dropped
                    }
                    left -= n;
                    at += n * len;
                }
            }
            Ok(())
        };
        if let Err(e) = produce(&tx) {
            let _ = tx.send(Err(e));
        }
    })
}

impl RecordStream {
    /// Hands the block read to the end back to its producer to refill (dropped if it has
    /// enough, or has ended) and takes the next block, from the producers in turn.
    fn advance(&mut self, path: &Path) -> Result<()> {
        if let Some((done, from)) = self.pending.take() {
            let _ = self.producers[from].1.try_send(done);
        }
        let from = self.next;
        self.next = (from + 1) % self.producers.len();
        let block = self.producers[from]
            .0
            .recv()
            .map_err(|_| Error::at_byte(path, 0, "the reader thread stopped early"))?;
        self.pending = Some((block?, from));
        self.at = 0;
        Ok(())
    }
}

/// An error from the `las` reader, at the byte the file handle had reached.
fn read_error(path: &Path, at: u64, read: u64, total: u64, e: las::Error) -> Error {
    if is_eof(&e) {
        Error::at_byte(
            path,
            at,
            format!(
                "unexpected end of file while reading points {read}.. of the {total} its header declares"
            ),
        )
    } else {
        Error::at_byte(
            path,
            at,
            format!("cannot decode the points from {read} on: {e}"),
        )
    }
}

/// The byte offset of the first LAZ chunk among points `first..first + count` that does not
/// decompress on its own, found by decompressing them chunk by chunk, and what is wrong with it.
/// `None` when the file is not LAZ, has no chunk table, or every chunk decompresses (the failure
/// lay elsewhere). The last chunk holds the points the header has left for it: when it fails,
/// its data may be damaged or the header's count may exceed what the chunks hold.
fn locate_laz_damage(
    path: &Path,
    header: &las::Header,
    data_at: u64,
    first: u64,
    count: u64,
) -> Option<(u64, String)> {
    if !header.point_format().is_compressed {
        return None;
    }
    let vlr = header.laz_vlr().ok()?;
    let mut f = BufReader::new(File::open(path).ok()?);
    f.seek(SeekFrom::Start(data_at)).ok()?;
    let table = laz::laszip::ChunkTable::read_from(&mut f, &vlr).ok()?;
    let file_size = f.get_ref().metadata().ok()?.len();
    let record_len = header.point_format().len() as usize;
    let (mut point, mut byte) = (0u64, data_at + 8);
    let total = header.number_of_points();
    let chunks = table.as_ref().len();
    for (i, chunk) in table.as_ref().iter().enumerate() {
        let last = i + 1 == chunks;
        let n = if last {
            total.saturating_sub(point)
        } else {
            chunk.point_count.min(total.saturating_sub(point))
        };
        if byte
            .checked_add(chunk.byte_count)
            .is_none_or(|end| end > file_size)
        {
            return Some((
                byte,
                format!(
                    "LAZ chunk {i} ({} bytes) runs past the end of the file",
                    chunk.byte_count
                ),
            ));
        }
        if point + n > first && point < first + count && n > 0 {
            // The chunk's own bytes alone, as the parallel decoder sees them: a decoder that
            // runs past its chunk fails here too.
            let ok = (|| -> Option<()> {
                let n = n.min(crate::MAX_BATCH as u64);
                let len = usize::try_from(chunk.byte_count).ok()?;
                let mut bytes = vec![0u8; len];
                f.seek(SeekFrom::Start(byte)).ok()?;
                f.read_exact(&mut bytes).ok()?;
                let mut out = vec![0u8; n as usize * record_len];
                let entry = laz::laszip::ChunkTableEntry {
                    point_count: n,
                    byte_count: chunk.byte_count,
                };
                // The laz crate panics on some damaged chunks: a damaged chunk like any other.
                myriad_core::guard::catching(|| {
                    laz::par_decompress(&bytes, &mut out, &vlr, &[entry])
                })
                .ok()?
                .ok()
            })();
            if ok.is_none() {
                let what = if last {
                    format!(
                        "the last LAZ chunk ({i}) does not hold the {n} points the header's count of {total} leaves for it"
                    )
                } else {
                    format!(
                        "LAZ chunk {i} (points {point}..{}) does not decompress",
                        point + n
                    )
                };
                return Some((byte, what));
            }
        }
        point += n;
        byte += chunk.byte_count;
    }
    None
}

/// Records per block for `header`'s file: LAZ in blocks of whole chunks, as many per core, so
/// that none waits on another's last chunk (KY, 50,000-point chunks on 2 cores: 8 a block, not
/// 10.5, made reading ~5 % shorter).
fn producer_block(header: &las::Header) -> u64 {
    match fixed_chunk(header) {
        Some(c) => {
            let cores = rayon::current_num_threads().max(1) as u64;
            (PRODUCER_BLOCK / (c * cores)).max(1) * cores * c
        }
        None => PRODUCER_BLOCK,
    }
}

/// The points per LAZ chunk, when the file is LAZ of chunks of one fixed size.
fn fixed_chunk(header: &las::Header) -> Option<u64> {
    if !header.point_format().is_compressed {
        return None;
    }
    let c = header.laz_vlr().ok()?.chunk_size() as u64;
    (c > 0 && c != u32::MAX as u64).then_some(c)
}

/// A producer thread: reads every `stride`-th block of records from the `first`, of `total`
/// records in all, and sends them, or the first error. LAZ of fixed-size chunks is read by two
/// producers in turn:
/// one's blocks decompress while the other's last chunks finish (a block's chunks run in
/// parallel, and the cores wait for the slowest), so that the cores are not left waiting.
fn produce_records(
    path: PathBuf,
    data_at: u64,
    total: u64,
    (first, stride): (u64, u64),
    tx: SyncSender<Result<las::PointData>>,
    spent: Receiver<las::PointData>,
) {
    let pos = Arc::new(AtomicU64::new(0));
    let opened = File::open(&path)
        .map_err(|e| Error::io(&path, e))
        .and_then(|file| {
            let tracked = Tracked {
                file,
                pos: pos.clone(),
            };
            las::Reader::new(BufReader::with_capacity(1 << 20, tracked))
                .map_err(|e| header_error(&path, e))
        });
    let mut reader = match opened {
        Ok(r) => r,
        Err(e) => {
            let _ = tx.send(Err(e));
            return;
        }
    };
    let builder = las::PointDataBuilder::new().for_header(reader.header());
    let block = producer_block(reader.header());
    let mut at = 0u64; // where the reader stands
    let mut read = first * block;
    while read < total {
        let want = (total - read).min(block);
        let mut data = spent.try_recv().unwrap_or_else(|_| builder.clone().build());
        let sought = if at == read {
            Ok(())
        } else {
            reader.seek(read)
        };
        // The laz crate panics on some damaged chunks (found by fuzzing): an error here.
        let filled = sought.and_then(|()| {
            myriad_core::guard::catching(|| reader.fill_points(want, &mut data)).unwrap_or_else(
                |m| {
                    Err(las::Error::Io(std::io::Error::new(
                        std::io::ErrorKind::InvalidData,
                        m,
                    )))
                },
            )
        });
        let result = match filled {
            Ok(got) if got == want => Ok(data),
            Ok(got) => Err(Error::at_byte(
                &path,
                if reader.header().point_format().is_compressed {
                    pos.load(Ordering::Relaxed)
                } else {
                    data_at + (read + got) * reader.header().point_format().len() as u64
                },
                format!(
                    "file ends after {} of the {total} points its header declares",
                    read + got
                ),
            )),
            // The reader's position is where a block of chunks ended: name the chunk.
            Err(e) => match locate_laz_damage(&path, reader.header(), data_at, read, want) {
                Some((at, what)) => Err(Error::at_byte(&path, at, format!("{what}: {e}"))),
                None => Err(read_error(
                    &path,
                    pos.load(Ordering::Relaxed),
                    read,
                    total,
                    e,
                )),
            },
        };
        let failed = result.is_err();
        if tx.send(result).is_err() || failed {
            return; // the source was dropped, or the error is delivered
        }
        at = read + want;
        read += stride * block;
    }
}

impl PointSource for LasSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn las_header(&self) -> Option<&las::Header> {
        Some(&self.header)
    }

    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>> {
        let (record_len, layout, quant) = (self.record_len, self.layout, self.quant);
        let Some(bytes) = self.take_records(crate::batch_len(max))? else {
            return Ok(None);
        };
        let n = bytes.len() / record_len;
        let extra = record_len - layout.base_len;
        let mut batch = las_records::batch_for(&layout, extra, n);
        las_records::decode(bytes, record_len, &layout, &quant, &mut batch);
        Ok(Some(batch))
    }
}

/// Reads every point record of a LAS/LAZ file as raw bytes, decoding none into columns: the
/// speed of the `las`/`laz` crates alone, the baseline for [`LasSource`], read by the same
/// producer threads (LAZ decompressed on all cores, two producers in turn): what reading could
/// reach if decoding records cost nothing. Returns the records read.
pub fn read_raw_records(path: &Path) -> Result<u64> {
    let source = LasSource::open(path)?;
    let total = source.remaining;
    let mut stream = start_stream(path, &source.header, source.data_at, total);
    let mut read = 0u64;
    while read < total {
        stream.advance(path)?;
        let records =
            stream.pending.as_ref().map_or(0, |d| d.0.raw_bytes().len()) / source.record_len;
        if records == 0 {
            return Err(Error::at_byte(path, 0, "the reader thread stopped early"));
        }
        read += records as u64;
    }
    Ok(read)
}

pub(crate) fn crs_of(header: &las::Header) -> Option<String> {
    if let Some(wkt) = header.get_wkt_crs_bytes() {
        let s = String::from_utf8_lossy(wkt)
            .trim_end_matches('\0')
            .trim()
            .to_string();
        if !s.is_empty() {
            return Some(s);
        }
    }
    let gt = header.get_geotiff_crs().ok().flatten()?;
    let code = gt
        .get_projected_crs_geo_key_value()
        .or_else(|| gt.get_geodetic_crs_geo_key_value())?;
    let mut s = format!("EPSG:{code}");
    if let Some(v) = gt.get_vertical_crs_geo_key_value() {
        s.push_str(&format!("+{v}"));
    }
    Some(s)
}

/// A LAS header with its VLRs and EVLRs as the bytes of an empty LAS file (uncompressed, without
/// the LAZ and COPC records), to be stored and read back with [`header_from_bytes`].
pub fn header_to_bytes(header: &las::Header) -> Result<Vec<u8>> {
    let invalid = |e: las::Error| Error::Invalid(format!("LAS header: {e}"));
    let mut b = las::Builder::from(header.clone());
    b.point_format.is_compressed = false;
    b.vlrs
        .retain(|v| !(v.user_id == "laszip encoded" || v.user_id == "copc"));
    b.evlrs.retain(|v| v.user_id != "copc");
    let header = b.into_header().map_err(invalid)?;
    let w = las::Writer::new(std::io::Cursor::new(Vec::new()), header).map_err(invalid)?;
    Ok(w.into_inner().map_err(invalid)?.into_inner())
}

/// The header [`header_to_bytes`] stored. The bytes come from a dataset file, so they get the
/// same checks as a LAS file's header before the `las` crate sizes anything from them.
pub fn header_from_bytes(bytes: &[u8]) -> Result<las::Header> {
    let name = Path::new("stored LAS header");
    let raw = las::raw::Header::read_from(std::io::Cursor::new(bytes))
        .map_err(|e| header_error(name, e))?;
    if raw.point_data_record_format & 0xC0 != 0 {
        return Err(Error::at_byte(
            name,
            104,
            "stored LAS headers are uncompressed",
        ));
    }
    check_evlr(name, &raw, bytes.len() as u64)?;
    las::Header::new(std::io::Cursor::new(bytes)).map_err(|e| header_error(name, e))
}
