//! Streaming readers and writers of the point-cloud formats users have: LAS/LAZ (and COPC, read as
//! LAZ), E57, PLY, PCD, and PTS/XYZ/CSV/TXT text.
//!
//! A reader is a [`PointSource`]: it reports what its header knows ([`SourceInfo`]) on open, without
//! reading points, then yields [`PointBatch`]es; memory does not grow with the file. [`open`] picks
//! the reader from the file's magic bytes, falling back on the extension. Every error names the
//! file and the byte offset (binary formats) or line (text formats). Points whose coordinates are
//! NaN or infinite are skipped and counted ([`PointSource::skipped_non_finite`]).
//!
//! Writers ([`las::LasSink`], [`ply::PlySink`]) write through an [`atomic::AtomicFile`]: the output
//! appears under its name only when complete.

pub mod atomic;
pub mod claim;
pub mod copc;
pub mod e57;
pub mod e57_images;
pub mod geotiff;
pub mod image;
pub mod las;
pub mod las_bytes;
mod las_chunks;
mod las_extra;
mod las_guard;
pub mod las_preview;
mod las_records;
mod las_write;
pub mod mesh;
pub mod pcd;
pub mod placement;
pub mod ply;
pub mod potree;
pub mod process;
pub mod proj;
mod read_util;
pub mod reproject;
pub mod text;
pub mod tiles3d;

pub use read_util::read_small;

use myriad_core::{Aabb, Error, PointBatch, Result, Schema};
use std::path::{Path, PathBuf};

/// An octree's `nodes` with every missing ancestor added as `T::default()`, the root included:
/// what a reader walking down from the root needs to reach every node (COPC, Potree).
pub(crate) fn with_ancestors<T: Default + Clone>(
    nodes: &std::collections::BTreeMap<myriad_core::NodeKey, T>,
) -> std::collections::BTreeMap<myriad_core::NodeKey, T> {
    let mut all = nodes.clone();
    all.entry(myriad_core::NodeKey::ROOT).or_default();
    // Keys in order, parents before children: an ancestor already there has its own.
    for k in nodes.keys() {
        let mut k = *k;
        while k.level > 0 {
            k = k.parent();
            if all.contains_key(&k) {
                break;
            }
            all.insert(k, T::default());
        }
    }
    all
}

/// Points a reader yields per batch unless asked otherwise.
pub const DEFAULT_BATCH: usize = 1 << 16;
/// Readers never yield more than this many points at once, whatever they are asked for, so a
/// caller's `usize::MAX` cannot turn streaming into reading the whole file.
pub const MAX_BATCH: usize = 1 << 20;

pub(crate) fn batch_len(max: usize) -> usize {
    max.clamp(1, MAX_BATCH)
}

/// The file formats Myriad reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Las,
    Laz,
    E57,
    Ply,
    Pcd,
    Text,
}

impl Format {
    pub fn name(&self) -> &'static str {
        match self {
            Format::Las => "LAS",
            Format::Laz => "LAZ",
            Format::E57 => "E57",
            Format::Ply => "PLY",
            Format::Pcd => "PCD",
            Format::Text => "text",
        }
    }
}

/// What a reader knows from the header alone.
#[derive(Debug, Clone)]
pub struct SourceInfo {
    pub path: PathBuf,
    pub format: Format,
    /// Format version and variant, e.g. "1.2 point format 3", "binary_little_endian 1.0", "COPC 1.0".
    pub version: String,
    /// Point count as the header states it; `None` where the format has no count (XYZ text).
    pub points: Option<u64>,
    /// Bounds as the header states them; `None` where the header has none or they are not exact.
    pub bounds: Option<Aabb>,
    pub schema: Schema,
    /// LAS scale and offset per axis.
    pub scale: Option<[f64; 3]>,
    pub offset: Option<[f64; 3]>,
    /// Coordinate reference system: WKT, or "EPSG:n" from GeoTIFF keys.
    pub crs: Option<String>,
    pub file_size: u64,
    /// Where the scanner stood for each of the file's scans, when every scan was taken from
    /// one place (E57 scans with spherical coordinates or a row/column grid: their poses'
    /// translations): a point whose source ID is `s >= 1` was seen from `origins[s - 1]`.
    /// Empty where that is not known (airborne and mobile data, most formats).
    pub origins: Vec<[f64; 3]>,
}

/// How many different coordinate systems, scales and format versions some files have (1 each
/// where they agree): what the tiles of one survey may disagree on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Differences {
    pub crs: usize,
    pub scales: usize,
    pub formats: usize,
}

impl Differences {
    pub fn of<'a>(infos: impl IntoIterator<Item = &'a SourceInfo>) -> Differences {
        use std::collections::BTreeSet;
        let (mut crs, mut scales, mut formats) =
            (BTreeSet::new(), BTreeSet::new(), BTreeSet::new());
        for i in infos {
            crs.insert(i.crs.clone());
            scales.insert(i.scale.map(|s| s.map(f64::to_bits)));
            formats.insert(i.version.clone());
        }
        Differences {
            crs: crs.len(),
            scales: scales.len(),
            formats: formats.len(),
        }
    }
}

/// A streaming reader of one file. Not `Send`: the `las` reader is not, so a source is opened on
/// the thread that reads it.
pub trait PointSource {
    fn info(&self) -> &SourceInfo;
    /// The next batch of at most `max` points (and at most [`MAX_BATCH`]), or `None` at the end.
    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>>;
    /// Points skipped so far because a coordinate was NaN or infinite.
    fn skipped_non_finite(&self) -> u64 {
        0
    }
    /// Points dropped so far by a placement's trimming box.
    fn trimmed(&self) -> u64 {
        0
    }
    /// Points dropped so far because they did not move into the target CRS (`--to-crs`).
    fn not_transformed(&self) -> u64 {
        0
    }
    /// The placement file applied to this source, if any.
    fn placement_path(&self) -> Option<&Path> {
        None
    }
    /// The LAS header (with VLRs) of a LAS/LAZ source, so that its points can be written back in
    /// their own point format.
    fn las_header(&self) -> Option<&::las::Header> {
        None
    }
}

/// How files are opened.
#[derive(Debug, Clone, Default)]
pub struct OpenOptions {
    /// Column layout for text input, e.g. "x,y,z,intensity,r,g,b"; detected when `None`.
    pub columns: Option<String>,
    /// A placement file (trimming box and transform, see [`placement`]) to apply.
    pub placement: Option<PathBuf>,
    /// Apply `SCAN.placement` next to a scan when it exists and `placement` is `None`.
    pub sidecar_placements: bool,
    /// Move every point into another CRS as it is read (after its placement).
    pub reproject: Option<reproject::Reproject>,
    /// LAZ inputs of which only some chunks are read (their indices in the chunk table,
    /// ascending): a part of a partitioned build reads the chunks that meet its cells.
    pub laz_chunks: Option<std::sync::Arc<std::collections::HashMap<PathBuf, Vec<u32>>>>,
    /// LAS/LAZ inputs whose records are read from other files instead (each file raw records
    /// of the input's point format, in order): a part of a partitioned build reads what the
    /// scatter tasks decompressed for it ([`las::LasSource::keep_exchanged`]).
    pub exchanged: Option<std::sync::Arc<std::collections::HashMap<PathBuf, Vec<PathBuf>>>>,
}

/// Opens `path` with the reader its magic bytes (or, for text, its extension) call for.
pub fn open(path: &Path, options: &OpenOptions) -> Result<Box<dyn PointSource>> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        return Err(Error::unsupported(
            path,
            "is a directory, not a point cloud file",
        ));
    }
    let source: Box<dyn PointSource> = match detect(path)? {
        Format::Las | Format::Laz => {
            let mut s = las::LasSource::open(path)?;
            if let Some(files) = options.exchanged.as_ref().and_then(|m| m.get(path)) {
                s.keep_exchanged(files)?;
            } else if let Some(kept) = options.laz_chunks.as_ref().and_then(|m| m.get(path)) {
                s.keep_chunks(kept)?;
            }
            Box::new(s)
        }
        Format::E57 => Box::new(e57::E57Source::open(path)?),
        Format::Ply => Box::new(ply::PlySource::open(path)?),
        Format::Pcd => Box::new(pcd::PcdSource::open(path)?),
        Format::Text => Box::new(text::TextSource::open(path, options.columns.as_deref())?),
    };
    let placement = match &options.placement {
        Some(p) => Some(p.clone()),
        None if options.sidecar_placements => placement::Placement::sidecar(path),
        None => None,
    };
    let placed: Box<dyn PointSource> = match placement {
        Some(p) => Box::new(placement::Placed::new(
            source,
            placement::Placement::read(&p)?,
        )),
        None => source,
    };
    match &options.reproject {
        Some(r) => Ok(Box::new(reproject::Reprojected::new(placed, r)?)),
        None => Ok(placed),
    }
}

/// Decides the format from the first bytes, then the extension.
pub fn detect(path: &Path) -> Result<Format> {
    let mut head = [0u8; 8];
    let n = read_util::read_prefix(path, &mut head)?;
    let head = &head[..n];
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    if head.starts_with(b"LASF") {
        return Ok(if ext == "laz" {
            Format::Laz
        } else {
            Format::Las
        });
    }
    if head.starts_with(b"ASTM-E57") {
        return Ok(Format::E57);
    }
    if head.starts_with(b"ply") {
        return Ok(Format::Ply);
    }
    let known = |e: &str| match e {
        "las" | "laz" => Some("LAS files start with \"LASF\""),
        "e57" => Some("E57 files start with \"ASTM-E57\""),
        "ply" => Some("PLY files start with \"ply\""),
        _ => None,
    };
    if let Some(what) = known(&ext) {
        return Err(Error::at_byte(
            path,
            0,
            format!("wrong magic number: {what}"),
        ));
    }
    match ext.as_str() {
        "pcd" => Ok(Format::Pcd),
        "xyz" | "txt" | "csv" | "pts" | "asc" => Ok(Format::Text),
        "" => Err(Error::unsupported(
            path,
            "no file extension and no known magic number",
        )),
        other => Err(Error::unsupported(
            path,
            format!(
                "unknown extension \".{other}\" (reads las, laz, e57, ply, pcd, xyz, txt, csv, pts)"
            ),
        )),
    }
}

/// Streams a whole source and returns (points, exact bounds).
pub fn scan(source: &mut dyn PointSource) -> Result<(u64, Aabb)> {
    let mut n = 0u64;
    let mut b = Aabb::EMPTY;
    while let Some(batch) = source.read_batch(DEFAULT_BATCH * 4)? {
        n += batch.len() as u64;
        for p in &batch.positions {
            b.extend(*p);
        }
    }
    Ok((n, b))
}
