//! Distribution, the first phase of the out-of-core build: every input is read once and its
//! points are scattered into chunks, cells of one octree level over the root cube. Memory holds
//! the write buffers (`buffer_bytes` in all, or `resident_bytes` where every point fits in that)
//! and one batch: when the buffers fill, the largest are appended to their chunks' spill files on
//! disk until half of them is free; what they hold at the end goes to the chunks' builds from
//! memory, after what the files hold (every point kept in memory is one not encoded, written,
//! read back and decoded).
//!
//! Decoding LAZ twice (count, then distribute) would halve the speed, so the chunk level comes
//! from the header counts and bounds alone: level `L` is chosen so that a surface of the total
//! point count (occupying about 4^L of the 8^L cells) gives chunks near `chunk_points`, and at
//! least about `min_chunks` of them so that every thread has work until the end. A chunk that
//! ends up larger is split again from its own spill file into its eight children, until it
//! fits. Inputs whose header has no bounds (PLY, PCD, text, E57, placed scans) are read once more
//! for their bounds first.
//!
//! Inputs of different formats merge: the dataset schema is the union of theirs, and a point
//! lacking an attribute gets its zero. Extra bytes are kept when all inputs have the same ones.
//!
//! Spill files are frames of points in the merged schema ([`crate::spill`]: node pages where the
//! points lie on a LAS input's grid, rows otherwise). They live in a private folder that is
//! removed when the [`Distribution`] is dropped, on success and on failure.

use crate::spill::{Codec, Frames, encode_frame};

mod scatter;
use myriad_core::{Aabb, Attribute, Error, PointBatch, Result, Schema};
use myriad_format::Quantization;
use myriad_io::{OpenOptions, PointSource};
use scatter::{Scatter, append_frame, spill_path};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Name of the spill folder, followed by the process's tag ([`myriad_io::claim::tag`]).
pub const SPILL_PREFIX: &str = ".myriad-build-";

/// Deepest chunk level (a 21-bit cell index per axis).
const MAX_LEVEL: u32 = 20;

#[derive(Debug, Clone)]
pub struct DistributeOptions {
    /// A chunk with more points than this is split into its eight children.
    pub chunk_points: u64,
    /// Memory for the chunks' write buffers, in bytes: their points stay in memory until they
    /// fill, then the largest are spilled until half of them is free.
    pub buffer_bytes: usize,
    /// When the declared points fit in this many bytes (when larger than `buffer_bytes`), the
    /// buffers hold them all: nothing is written to disk and read back, and each chunk goes to
    /// its build as it is.
    pub resident_bytes: usize,
    /// Compress spill files of rows (zstd level 1) when the inputs would spill more than this
    /// many bytes: it halves the disk a big build needs, at about 1.5 s of a core per 400 MB.
    /// Points on a LAS input's grid are written as node pages, compressed whatever this says.
    pub compress_above: u64,
    /// At least this many chunks (about), so that every thread has work until the end.
    pub min_chunks: u64,
    /// Where the private spill folder is made (next to the output, so that it is on its disk).
    pub temp_dir: PathBuf,
    /// A grid fixed beforehand (a planned build, [`crate::partition`]) instead of one from the
    /// inputs' headers.
    pub grid: Option<Grid>,
}

/// The root cube, chunk level and schema of a planned build, and the cells a part keeps.
#[derive(Debug, Clone)]
pub struct Grid {
    pub root: Aabb,
    pub level: u32,
    pub schema: Schema,
    /// Only the points in these cells of this level (at most `level`) are kept; `None`: all.
    pub cells: Option<(u32, std::collections::HashSet<[u32; 3]>)>,
}

/// What [`distribute_with`] reports as it goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Progress<'a> {
    /// The inputs' headers declare this many points in all.
    Declared(u64),
    /// This many more points were read.
    Read(u64),
    /// The points just read (in the dataset's schema): what a build drawn while it runs
    /// samples ([`crate::growing`]).
    Points(&'a PointBatch),
}

/// One chunk: an octree cell and the points that fell into it, kept in memory or spilled to
/// disk (or both: the file's first).
#[derive(Debug, Clone, PartialEq)]
pub struct Chunk {
    pub level: u32,
    pub cell: [u32; 3],
    pub points: u64,
    path: PathBuf,
    /// Whether some of its points were written to its spill file (the rest, if any, stayed in
    /// memory).
    on_disk: bool,
}

/// The result of distribution. Dropping it removes the spill files.
#[derive(Debug)]
pub struct Distribution {
    /// The root cube of the octree: the union of the inputs' bounds, made cubic.
    pub root: Aabb,
    pub schema: Schema,
    pub chunks: Vec<Chunk>,
    pub points: u64,
    /// Bounds of the points actually read.
    pub bounds: Aabb,
    /// Points that lay outside the bounds the headers state. When there are any, the chunks
    /// are scattered again over a root cube from the bounds read, so every chunk holds only
    /// points of its own cube.
    pub clamped: u64,
    /// What each input's header said, and the points taken from it.
    pub sources: Vec<(myriad_io::SourceInfo, u64)>,
    /// The points read from each input (more than taken where a grid keeps some cells only).
    pub read: Vec<u64>,
    /// Points skipped for NaN or infinite coordinates, and dropped by placement boxes.
    pub skipped_non_finite: u64,
    pub trimmed: u64,
    /// Points that did not move into the target CRS (`--to-crs`), dropped.
    pub not_transformed: u64,
    /// The first LAS/LAZ input's header with its VLRs ([`myriad_io::las::header_to_bytes`]).
    pub las_header: Option<Vec<u8>>,
    /// Where airborne inputs' scanners saw each flight line's points from (scan angles and
    /// source IDs fitted as they were read); empty where the scans say where they stood.
    pub sides: crate::sides::Sides,
    /// The points that stayed in the write buffers, by level and cell (taken out as the chunks
    /// are loaded): all of a small build's, which writes and reads back no spill files, and the
    /// last of a larger one's.
    resident: std::sync::Mutex<Resident>,
    /// Held so that dropping the distribution removes the spill files.
    _spill: myriad_io::claim::Folder,
}

impl Distribution {
    /// Reads a chunk's points back, once: its spill file is removed as soon as they are in
    /// memory, so that the spill files and the dataset being written are not both on disk
    /// whole (500 M points: 11.9 GB of spill files and 6.7 GB of dataset).
    pub fn load(&self, chunk: &Chunk) -> Result<PointBatch> {
        let resident = self
            .resident
            .lock()
            .expect("resident points")
            .remove(&(chunk.level, chunk.cell));
        if !chunk.on_disk {
            // Points this process scattered whole, none spilled: their count is the chunk's.
            let b = resident.ok_or_else(|| {
                Error::Invalid(format!(
                    "the chunk at level {} cell {:?} was loaded before",
                    chunk.level, chunk.cell
                ))
            })?;
            debug_assert_eq!(b.len() as u64, chunk.points);
            return Ok(b);
        }
        let mut b = PointBatch::with_schema(&self.schema, 0);
        let mut frames = Frames::open(&chunk.path)?;
        while let Some(f) = frames.next_frame(&self.schema)? {
            if b.is_empty() {
                // The first frame as it is; the rest appended, with room for them all.
                b = f;
                b.reserve_exact((chunk.points as usize).saturating_sub(b.len()));
            } else {
                b.append(&f);
            }
        }
        // The points that came after the last flush, kept in memory: they follow the file's.
        if let Some(r) = resident {
            b.append(&r);
        }
        if b.len() as u64 != chunk.points {
            return Err(frames.error(format!(
                "spill file holds {} points, not {}",
                b.len(),
                chunk.points
            )));
        }
        // Nothing reads it again; what is left goes with the folder.
        std::fs::remove_file(&chunk.path).ok();
        Ok(b)
    }

    /// The private folder of the spill files (removed with the distribution), for other
    /// temporary files of the build.
    pub fn spill_dir(&self) -> &Path {
        self._spill.path()
    }

    /// The cube of a chunk's cell.
    pub fn cell_bounds(&self, chunk: &Chunk) -> Aabb {
        let side = self.root.size()[0] / (1u64 << chunk.level) as f64;
        let min: [f64; 3] = std::array::from_fn(|a| self.root.min[a] + chunk.cell[a] as f64 * side);
        Aabb::new(min, min.map(|m| m + side))
    }
}

/// The scanner positions of every input's scans in one table, and each input's first index in
/// it (its points' source IDs are moved up by that much), when every input says where its scans
/// were taken from (`SourceInfo::origins`); None otherwise: the IDs are then left as read.
pub fn scan_origins(infos: &[&myriad_io::SourceInfo]) -> Option<(Vec<[f64; 3]>, Vec<u16>)> {
    if infos.is_empty() || infos.iter().any(|i| i.origins.is_empty()) {
        return None;
    }
    let mut table = Vec::new();
    let mut offsets = Vec::new();
    for i in infos {
        offsets.push(u16::try_from(table.len()).ok()?);
        table.extend_from_slice(&i.origins);
    }
    (table.len() <= u16::MAX as usize).then_some((table, offsets))
}

/// The union of the inputs' schemas, in the canonical column order.
pub(crate) fn merged_schema(infos: &[myriad_io::SourceInfo]) -> Result<Schema> {
    let mut all = Schema::for_las_format(10).attributes;
    all.push(Attribute::ScannerChannel);
    all.push(Attribute::Normal);
    let mut attributes: Vec<Attribute> = all
        .into_iter()
        .filter(|a| infos.iter().any(|i| i.schema.has(a)))
        .collect();
    attributes.dedup();
    let first = &infos[0].schema;
    let extras: Vec<&Attribute> = first
        .attributes
        .iter()
        .filter(|a| matches!(a, Attribute::Extra(_)))
        .collect();
    for i in &infos[1..] {
        let theirs: Vec<&Attribute> = i
            .schema
            .attributes
            .iter()
            .filter(|a| matches!(a, Attribute::Extra(_)))
            .collect();
        if i.schema.extra_bytes != first.extra_bytes || theirs != extras {
            return Err(Error::unsupported(
                &i.path,
                format!(
                    "its extra bytes differ from those of {}; inputs to one dataset must share them",
                    infos[0].path.display()
                ),
            ));
        }
    }
    attributes.extend(extras.into_iter().cloned());
    Ok(Schema {
        attributes,
        extra_bytes: first.extra_bytes,
    })
}

/// Gives `b` exactly the columns of `schema`: missing ones are filled with zeros.
pub(crate) fn conform(mut b: PointBatch, schema: &Schema) -> PointBatch {
    let n = b.len();
    let mut target = PointBatch::with_schema(schema, 0);
    macro_rules! take {
        ($($f:ident),*) => {$(
            target.$f = match (target.$f.is_some(), b.$f.take()) {
                (true, Some(c)) => Some(c),
                (true, None) => Some(vec![Default::default(); n]),
                (false, _) => None,
            };
        )*};
    }
    take!(
        intensity,
        return_number,
        number_of_returns,
        classification,
        classification_flags,
        scan_flags
    );
    take!(
        scanner_channel,
        scan_angle,
        user_data,
        point_source_id,
        gps_time,
        rgb,
        nir,
        wave_packet,
        normal
    );
    target.extra_bytes = if schema.extra_bytes > 0 {
        b.extra_bytes.take()
    } else {
        None
    };
    target.positions = b.positions;
    target
}

/// The root cube around `bounds`. Headers state bounds rounded to their scale (and some are a
/// step off): a margin of one scale `step` and 1e-5 of the extent keeps such points inside.
pub(crate) fn root_cube(bounds: &Aabb, step: f64) -> Aabb {
    let extent = bounds.size().into_iter().fold(0.0f64, f64::max).max(1e-9);
    let margin = step + extent * 1e-5;
    let min = bounds.min.map(|m| m - margin);
    Aabb::new(min, min.map(|m| m + extent + 2.0 * margin))
}

pub(crate) fn cell_of(root: &Aabb, level: u32, p: [f64; 3], clamped: &mut u64) -> [u32; 3] {
    let side = root.size()[0];
    let n = (1u64 << level) as f64;
    let mut outside = false;
    let c = std::array::from_fn(|a| {
        // In [0, n) exactly when its floor is; `as` truncates (the floor, from 0 up) and
        // saturates (below 0 and NaN to 0), so no library call for the floor.
        let v = (p[a] - root.min[a]) / side * n;
        outside |= !(0.0..n).contains(&v);
        (v as u32).min(n as u32 - 1)
    });
    *clamped += outside as u64;
    c
}

/// The level whose cells the points are first scattered to: a surface of `declared` points fills
/// about 4^L of the 8^L cells of level L, giving chunks near `chunk_points`, and at least about
/// `min_chunks` of them.
pub(crate) fn chunk_level(declared: u64, chunk_points: u64, min_chunks: u64) -> u32 {
    let per_chunk = chunk_points.max(1) as f64;
    let chunks = (declared as f64 / per_chunk)
        .max(min_chunks as f64)
        .max(1.0);
    // Never chunks smaller than the budget needs to make sense of (1/16 of chunk_points).
    let chunks = chunks.min((declared as f64 * 16.0 / per_chunk).max(1.0));
    (chunks.log(4.0).ceil() as u32).min(MAX_LEVEL)
}

/// Reads every input once and scatters its points into chunks under `options.temp_dir`.
pub fn distribute(
    inputs: &[PathBuf],
    open: &OpenOptions,
    options: &DistributeOptions,
) -> Result<Distribution> {
    distribute_with(inputs, open, options, &mut |_| {})
}

/// [`distribute`], calling `on_read` with the number of points of each batch read, and once
/// with the total the headers declare (`on_declared`) before the scatter pass.
pub fn distribute_with(
    inputs: &[PathBuf],
    open: &OpenOptions,
    options: &DistributeOptions,
    on_read: &mut dyn FnMut(Progress),
) -> Result<Distribution> {
    if inputs.is_empty() {
        return Err(Error::Invalid("no inputs".into()));
    }
    let Headers {
        infos,
        sources,
        bounds,
        declared,
        las_header,
    } = read_headers(inputs, open, options)?;
    let margin_step = infos
        .iter()
        .filter_map(|i| i.scale)
        .flatten()
        .fold(0.0f64, f64::max);
    let (schema, root) = match &options.grid {
        Some(g) => (g.schema.clone(), g.root),
        None => (merged_schema(&infos)?, root_cube(&bounds, margin_step)),
    };
    let level = match &options.grid {
        Some(g) => g.level,
        None => chunk_level(declared, options.chunk_points, options.min_chunks),
    };

    let folder = myriad_io::claim::Folder::create(&options.temp_dir, SPILL_PREFIX)?;
    let codec = spill_codec(&infos, declared, &schema, options.compress_above);
    let mut scatter = Scatter::new(
        folder.path(),
        level,
        &schema,
        options.buffer_bytes,
        options.resident_bytes,
        codec,
        declared,
    );
    on_read(Progress::Declared(declared));
    let pass = Pass {
        open,
        options,
        root,
        level,
        schema: &schema,
    };
    let tally = pass.run(inputs, sources, &infos, &mut scatter, on_read)?;
    let (root, chunks, mut resident) = settle(&mut scatter, &tally, root, margin_step, options)?;
    let done = split_large(
        chunks,
        &root,
        &schema,
        folder.path(),
        options,
        codec,
        &mut resident,
    )?;
    Ok(Distribution {
        root,
        schema,
        chunks: done,
        points: tally.points,
        bounds: tally.actual,
        clamped: tally.clamped,
        sources: infos.into_iter().zip(tally.taken).collect(),
        read: tally.read,
        skipped_non_finite: tally.skipped,
        trimmed: tally.trimmed,
        not_transformed: tally.not_transformed,
        las_header,
        sides: tally.sides,
        resident: std::sync::Mutex::new(resident),
        _spill: folder,
    })
}

/// What the inputs' headers say, before any point is scattered.
struct Headers {
    infos: Vec<myriad_io::SourceInfo>,
    /// Sources whose header gave the bounds are kept open for the scatter pass; a source that
    /// was read for its bounds is opened again (None).
    sources: Vec<Option<Box<dyn PointSource>>>,
    bounds: Aabb,
    declared: u64,
    /// The first LAS/LAZ input's header with its VLRs.
    las_header: Option<Vec<u8>>,
}

/// Step 1: every input opened, its header read (and its points counted and bounded, where the
/// header does not say and no plan fixes the grid).
fn read_headers(
    inputs: &[PathBuf],
    open: &OpenOptions,
    options: &DistributeOptions,
) -> Result<Headers> {
    let mut infos = Vec::new();
    let mut sources: Vec<Option<Box<dyn PointSource>>> = Vec::new();
    let mut bounds = Aabb::EMPTY;
    let mut declared = 0u64;
    let mut las_header = None;
    for path in inputs {
        let mut src = myriad_io::open(path, open)?;
        let info = src.info().clone();
        if las_header.is_none()
            && let Some(h) = src.las_header()
        {
            las_header = Some(myriad_io::las::header_to_bytes(h)?);
        }
        let ((n, b), kept) = match (info.points, info.bounds) {
            (Some(n), Some(b)) => ((n, b), Some(src)),
            // A planned build knows its grid: no pass for bounds.
            (n, _) if options.grid.is_some() => ((n.unwrap_or(0), Aabb::EMPTY), Some(src)),
            // No exact header bounds: one pass for them.
            _ => (myriad_io::scan(src.as_mut())?, None),
        };
        declared += n;
        bounds = bounds.union(&b);
        infos.push(info);
        sources.push(kept);
    }
    Ok(Headers {
        infos,
        sources,
        bounds,
        declared,
        las_header,
    })
}

/// How the spill files are written: compressed where the inputs would spill more than
/// `compress_above` bytes as rows, as pages on the first input's grid where one has a grid.
fn spill_codec(
    infos: &[myriad_io::SourceInfo],
    declared: u64,
    schema: &Schema,
    compress_above: u64,
) -> Codec {
    let row = PointBatch::with_schema(schema, 0).row_size() as u64;
    Codec {
        compress: declared.saturating_mul(row) > compress_above,
        // The grid of the first input with one, its step's size (a negative LAS scale mirrors
        // the records, not the coordinates). Frames are checked to lie on it.
        grid: infos
            .iter()
            .find_map(|i| Some((i.scale?, i.offset?)))
            .map(|(s, offset)| Quantization {
                scale: s.map(f64::abs),
                offset,
            }),
    }
}

/// Step 2, the scatter pass: where its points go (the root cube and chunk level, in the
/// dataset's schema; the cells a part keeps).
struct Pass<'a> {
    open: &'a OpenOptions,
    options: &'a DistributeOptions,
    root: Aabb,
    level: u32,
    schema: &'a Schema,
}

/// What the scatter pass counted.
struct Tally {
    /// Points taken, those outside the root cube (sent to the nearest cell), and their bounds.
    points: u64,
    clamped: u64,
    actual: Aabb,
    skipped: u64,
    trimmed: u64,
    not_transformed: u64,
    /// Per input: the points taken, and those read.
    taken: Vec<u64>,
    read: Vec<u64>,
    sides: crate::sides::Sides,
}

impl Pass<'_> {
    /// Every input read once (`sources`: those still open from their header), its scan numbers
    /// moved into the table of every input's scans where there is one, its points scattered to
    /// their cells (those a part keeps), `on_read` told of each batch.
    fn run(
        &self,
        inputs: &[PathBuf],
        sources: Vec<Option<Box<dyn PointSource>>>,
        infos: &[myriad_io::SourceInfo],
        scatter: &mut Scatter,
        on_read: &mut dyn FnMut(Progress),
    ) -> Result<Tally> {
        let (open, options, root, level, schema) =
            (self.open, self.options, self.root, self.level, self.schema);
        let keep = options.grid.as_ref().and_then(|g| g.cells.as_ref());
        let (mut picked, mut cells) = (Vec::new(), Vec::new());
        let (mut points, mut clamped, mut actual) = (0u64, 0u64, Aabb::EMPTY);
        let (mut skipped, mut trimmed, mut taken, mut read) = (0u64, 0u64, Vec::new(), Vec::new());
        let mut not_transformed = 0u64;
        let origins = scan_origins(&infos.iter().collect::<Vec<_>>());
        let mut sides = crate::sides::Sides::default();
        for (k, (path, kept)) in inputs.iter().zip(sources).enumerate() {
            let scan_offset = origins.as_ref().map_or(0, |o| o.1[k]);
            let mut src = match kept {
                Some(src) => src,
                None => myriad_io::open(path, open)?,
            };
            let before = points;
            let mut all = 0u64;
            while let Some(b) = src.read_batch(myriad_io::DEFAULT_BATCH)? {
                all += b.len() as u64;
                let mut b = conform(b, schema);
                // Scan numbers into the table of every input's scans.
                if let (true, Some(ids)) = (scan_offset > 0, &mut b.point_source_id) {
                    for id in ids.iter_mut().filter(|id| **id > 0) {
                        *id += scan_offset;
                    }
                }
                picked.clear();
                cells.clear();
                for i in 0..b.len() {
                    let p = b.positions[i];
                    let cell = cell_of(&root, level, p, &mut clamped);
                    if clamped > 0 && options.grid.is_some() {
                        return Err(Error::Invalid(format!(
                            "{}: a point at ({}, {}, {}) lies outside the planned root cube \
                             {:?} to {:?} (its header understates its bounds): plan again",
                            path.display(),
                            p[0],
                            p[1],
                            p[2],
                            root.min,
                            root.max
                        )));
                    }
                    if let Some((at, cells)) = keep
                        && !cells.contains(&cell.map(|c| c >> (level - at)))
                    {
                        continue;
                    }
                    actual.extend(p);
                    picked.push(i as u32);
                    cells.push(cell);
                }
                scatter.add(&b, &picked, &cells)?;
                if origins.is_none() {
                    sides.add(&b, &picked);
                }
                points += picked.len() as u64;
                on_read(Progress::Points(&b));
                on_read(Progress::Read(b.len() as u64));
            }
            skipped += src.skipped_non_finite();
            trimmed += src.trimmed();
            not_transformed += src.not_transformed();
            taken.push(points - before);
            read.push(all);
        }
        Ok(Tally {
            points,
            clamped,
            actual,
            skipped,
            trimmed,
            not_transformed,
            taken,
            read,
            sides,
        })
    }
}

/// The chunks' points that stayed in the write buffers, by level and cell.
type Resident = HashMap<(u32, [u32; 3]), PointBatch>;

/// The chunks as the pass left them: the points still in the write buffers kept in memory, all
/// flushed to their spill files and scattered again over a root cube from the bounds read where
/// points fell outside the headers' bounds or those overstate them by far. The root cube, the
/// chunks, and their points kept in memory.
fn settle(
    scatter: &mut Scatter,
    tally: &Tally,
    root: Aabb,
    margin_step: f64,
    options: &DistributeOptions,
) -> Result<(Aabb, Vec<Chunk>, Resident)> {
    let (clamped, actual, level) = (tally.clamped, &tally.actual, scatter.level);
    // Points outside the headers' bounds went to the nearest cell, whose cube does not hold
    // them. Rare (a header not updated after editing), but the tree must contain its points:
    // scatter the spill files again over a root cube from the bounds actually read. So too when
    // the headers overstate the bounds by far (a damaged header: 1e300): the points would share
    // one chunk and the tree would spend its levels on empty space.
    let overstated = options.grid.is_none()
        && !actual.is_empty()
        && root.size()[0] > 16.0 * root_cube(actual, margin_step).size()[0];
    // What is still in the write buffers stays in memory, unless every chunk is to be
    // scattered again (KY: 374 MB not written to disk and read back; the reading phase 2.7-3.0
    // -> 1.9-2.1 s).
    let resident = if clamped > 0 || overstated {
        scatter.flush()?;
        Resident::new()
    } else {
        scatter.take_resident()
    };
    let mut chunks = scatter.chunks();
    let root = if clamped > 0 || overstated {
        let root = root_cube(actual, margin_step);
        chunks = rescatter(
            &chunks,
            &root,
            level + 1,
            scatter.schema,
            scatter.folder,
            options.buffer_bytes,
            scatter.codec,
        )?;
        root
    } else {
        root
    };
    Ok((root, chunks, resident))
}

/// Split chunks that came out too large until they fit: in memory where all their points
/// stayed there, else from their own spill files (the points kept in memory written after
/// them first), those of one round in parallel, each with its share of the write buffers (one
/// at a time left a core idle for 130 of the 420 s that 500 M points took). Every chunk, by
/// level and cell.
fn split_large(
    mut chunks: Vec<Chunk>,
    root: &Aabb,
    schema: &Schema,
    folder: &Path,
    options: &DistributeOptions,
    codec: Codec,
    resident: &mut Resident,
) -> Result<Vec<Chunk>> {
    let mut done = Vec::new();
    loop {
        let (fit, big): (Vec<Chunk>, Vec<Chunk>) = chunks
            .into_iter()
            .partition(|c| c.points <= options.chunk_points || c.level >= MAX_LEVEL);
        done.extend(fit);
        if big.is_empty() {
            break;
        }
        let (in_memory, big): (Vec<Chunk>, Vec<Chunk>) = big.into_iter().partition(|c| !c.on_disk);
        let mut next = Vec::new();
        for chunk in in_memory {
            let points = resident
                .remove(&(chunk.level, chunk.cell))
                .unwrap_or_else(|| PointBatch::with_schema(schema, 0));
            next.extend(split_in_memory(&chunk, points, root, folder, resident));
        }
        for chunk in &big {
            if let Some(rest) = resident.remove(&(chunk.level, chunk.cell)) {
                append_frame(&chunk.path, &encode_frame(&rest, codec))?;
            }
        }
        use rayon::prelude::*;
        let share = options.buffer_bytes / rayon::current_num_threads().clamp(1, big.len().max(1));
        let split: Vec<Vec<Chunk>> = big
            .par_iter()
            .map(|chunk| {
                rescatter(
                    std::slice::from_ref(chunk),
                    root,
                    chunk.level + 1,
                    schema,
                    folder,
                    share.max(1 << 20),
                    codec,
                )
            })
            .collect::<Result<_>>()?;
        chunks = split.into_iter().flatten().chain(next).collect();
    }
    done.sort_by_key(|c| (c.level, c.cell));
    Ok(done)
}

/// The points of `chunk`, all in memory, sorted into its eight children (one level down), kept
/// in memory in their turn: the chunks they make.
fn split_in_memory(
    chunk: &Chunk,
    points: PointBatch,
    root: &Aabb,
    folder: &Path,
    resident: &mut Resident,
) -> Vec<Chunk> {
    let level = chunk.level + 1;
    let mut outside = 0;
    let mut picks: [Vec<u32>; 8] = Default::default();
    for (i, &p) in points.positions.iter().enumerate() {
        // A point of the chunk's cube falls in one of its children's: twice its coordinate in
        // cells, exactly.
        let c = cell_of(root, level, p, &mut outside);
        let child = (0..3).fold(0, |k, a| k | ((c[a] & 1) as usize) << a);
        picks[child].push(i as u32);
    }
    (0..8)
        .filter(|&k| !picks[k].is_empty())
        .map(|k| {
            let cell = std::array::from_fn(|a| chunk.cell[a] * 2 + ((k >> a) & 1) as u32);
            resident.insert((level, cell), points.gather(&picks[k]));
            Chunk {
                level,
                cell,
                points: picks[k].len() as u64,
                path: spill_path(folder, level, cell),
                on_disk: false,
            }
        })
        .collect()
}

/// Scatters the points of `chunks` into the cells of `level` over `root` and removes their
/// spill files: a chunk into its eight children, or every chunk into a new root's cells.
fn rescatter(
    chunks: &[Chunk],
    root: &Aabb,
    level: u32,
    schema: &Schema,
    folder: &Path,
    buffer_bytes: usize,
    codec: Codec,
) -> Result<Vec<Chunk>> {
    let expected = chunks.iter().map(|c| c.points).sum();
    let mut scatter = Scatter::new(folder, level, schema, buffer_bytes, 0, codec, expected);
    let mut outside = 0;
    for chunk in chunks {
        let mut frames = Frames::open(&chunk.path)?;
        while let Some(b) = frames.next_frame(schema)? {
            let cells: Vec<[u32; 3]> = b
                .positions
                .iter()
                .map(|&p| cell_of(root, level, p, &mut outside))
                .collect();
            scatter.add(&b, &(0..b.len() as u32).collect::<Vec<_>>(), &cells)?;
        }
        drop(frames);
        std::fs::remove_file(&chunk.path).map_err(|e| Error::io(&chunk.path, e))?;
    }
    scatter.flush()?;
    Ok(scatter.chunks())
}
