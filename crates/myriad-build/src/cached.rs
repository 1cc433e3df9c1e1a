//! Any scan opens directly: `render` and `view` given a scan rather than a dataset (and `serve`
//! a scan file) convert it (with the defaults of `convert` and its progress bar) into a dataset
//! kept next to the scan, or in the user's cache folder where the scan's folder takes no files,
//! and use that dataset again while the scan is unchanged (same path, size and modification
//! time, same format version). A folder of LAS/LAZ tiles (one survey cut into files) is one
//! scan: its tiles become one dataset, kept in the folder, made again when a tile changes, comes
//! or goes.

use crate::convert::{self, ConvertOptions, Report};
use myriad_core::{Error, Result};
use myriad_format::Dataset;
use std::path::{Path, PathBuf};

/// 64-bit FNV-1a: a key that stays the same from one build of Myriad to the next (std's
/// hasher does not promise that).
fn fnv(parts: &[&[u8]]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for p in parts {
        for &b in *p {
            h = (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
        h = (h ^ 0xff).wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The user's cache folder for Myriad: `$XDG_CACHE_HOME/myriad`, else `~/.cache/myriad`.
fn cache_dir() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CACHE_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("myriad"))
}

/// Whether a file can be made in `dir`.
fn takes_files(dir: &Path) -> bool {
    let probe = dir.join(format!(".myriad-probe-{}", std::process::id()));
    let ok = std::fs::File::create(&probe).is_ok();
    let _ = std::fs::remove_file(&probe);
    ok
}

/// Where a scan's dataset is kept: beside it, or in the user's cache folder; the names of its
/// earlier versions start with `prefix`.
struct Places {
    folder: PathBuf,
    beside: PathBuf,
    cached: Option<PathBuf>,
    prefix: String,
}

impl Places {
    /// The dataset made before at one of the places, if one is there and opens.
    fn made(&self) -> Option<PathBuf> {
        std::iter::once(&self.beside)
            .chain(self.cached.as_ref())
            .find(|c| c.is_file() && Dataset::open_stored(c).is_ok())
            .cloned()
    }
}

/// Whether a file is a LAS or LAZ tile by its name; hidden files (a name starting with a dot:
/// our own temporary outputs, a desktop's metadata files) are not.
fn is_tile(path: &Path) -> bool {
    path.is_file()
        && !path
            .file_name()
            .is_some_and(|n| n.to_string_lossy().starts_with('.'))
        && path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("las") || e.eq_ignore_ascii_case("laz"))
}

/// The scan files at `path`: the file itself, the LAS and LAZ files a `.vpc` names (in its
/// order), or a folder's LAS and LAZ files (not its subfolders), sorted by name.
pub fn inputs_of(path: &Path) -> Result<Vec<PathBuf>> {
    let vpc = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vpc"));
    if vpc && !path.is_dir() {
        return myriad_format::foreign::tiles::vpc_scans(path).ok_or_else(|| {
            Error::Invalid(format!(
                "{}: not a virtual point cloud of LAS/LAZ files",
                path.display()
            ))
        });
    }
    if !path.is_dir() {
        return Ok(vec![path.to_path_buf()]);
    }
    let mut tiles: Vec<PathBuf> = std::fs::read_dir(path)
        .map_err(|e| Error::io(path, e))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| is_tile(p))
        .collect();
    tiles.sort();
    if tiles.is_empty() {
        return Err(Error::Invalid(format!(
            "{}: a folder with no LAS or LAZ file in it",
            path.display()
        )));
    }
    Ok(tiles)
}

/// Most bytes of a file's head, and of its chunk table or tail, in its fingerprint.
const FINGERPRINT_BYTES: u64 = 64 << 10;

/// What of a scan file's content its dataset's key holds, beside its size and time: its head
/// (a LAS header with its VLRs, any other format's first 64 KiB) and, for LAZ, its chunk table
/// (where every chunk starts and how many points it holds: a rewritten LAZ has another), else
/// its last 64 KiB. A file changed at the same size with its modification time put back is
/// then another scan (two small reads, whatever the file's size).
fn fingerprint(f: &Path, len: u64) -> Result<Vec<u8>> {
    use std::io::{Read, Seek, SeekFrom};
    let mut file = std::fs::File::open(f).map_err(|e| Error::io(f, e))?;
    let mut read_at = |at: u64, n: u64| -> Result<Vec<u8>> {
        let n = n.min(len.saturating_sub(at));
        let mut b = vec![0u8; n as usize];
        file.seek(SeekFrom::Start(at))
            .and_then(|_| file.read_exact(&mut b))
            .map_err(|e| Error::io(f, e))?;
        Ok(b)
    };
    let mut head = read_at(0, FINGERPRINT_BYTES)?;
    let u32_at = |b: &[u8], i: usize| {
        b.get(i..i + 4)
            .map(|s| u32::from_le_bytes(s.try_into().unwrap()))
    };
    let mut tail = None;
    if head.starts_with(b"LASF")
        && let Some(data) = u32_at(&head, 96).map(u64::from)
    {
        head.truncate((data as usize).min(head.len()));
        let compressed = head.get(104).is_some_and(|b| b & 0x80 != 0);
        if compressed && data + 8 <= len {
            let at = read_at(data, 8)?;
            let table = i64::from_le_bytes(at.try_into().expect("8 bytes"));
            if table > 0 && (table as u64) < len {
                tail = Some(read_at(table as u64, FINGERPRINT_BYTES)?);
            }
        }
    }
    let tail = match tail {
        Some(t) => t,
        None => read_at(len.saturating_sub(FINGERPRINT_BYTES), FINGERPRINT_BYTES)?,
    };
    Ok([fnv(&[&head]).to_le_bytes(), fnv(&[&tail]).to_le_bytes()].concat())
}

/// The places of the dataset of the scan at `path` as it is now: its files' paths, sizes,
/// modification times and fingerprints ([`fingerprint`]), and the format version, make the key.
fn places(path: &Path) -> Result<Places> {
    let canonical = path.canonicalize().map_err(|e| Error::io(path, e))?;
    let dir = canonical.is_dir();
    let mut parts: Vec<Vec<u8>> = Vec::new();
    for f in inputs_of(&canonical)? {
        let meta = std::fs::metadata(&f).map_err(|e| Error::io(&f, e))?;
        if !meta.is_file() {
            return Err(Error::Invalid(format!("{}: not a file", f.display())));
        }
        let mtime = meta
            .modified()
            .ok()
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or(0, |d| d.as_nanos());
        parts.push(f.as_os_str().as_encoded_bytes().to_vec());
        parts.push(meta.len().to_le_bytes().to_vec());
        parts.push(mtime.to_le_bytes().to_vec());
        parts.push(fingerprint(&f, meta.len())?);
    }
    parts.push(myriad_format::FORMAT_VERSION.to_le_bytes().to_vec());
    let key = fnv(&parts.iter().map(|p| p.as_slice()).collect::<Vec<_>>());
    let name = canonical
        .file_name()
        .map_or("scan".into(), |n| n.to_string_lossy().to_string());
    // A folder's dataset is kept in the folder, a file's beside it.
    let folder = if dir {
        canonical.clone()
    } else {
        canonical.parent().unwrap_or(Path::new("/")).to_path_buf()
    };
    // Per scan path (two scans of one name share the cache folder), then per version of it.
    let place = fnv(&[canonical.as_os_str().as_encoded_bytes()]) as u32;
    let prefix = format!(".{name}.myriad-{place:08x}-");
    Ok(Places {
        beside: folder.join(format!("{prefix}{key:016x}.myr")),
        cached: cache_dir().map(|d| d.join(format!("{prefix}{key:016x}.myr"))),
        folder,
        prefix,
    })
}

/// What the tiles of one scan disagree on (coordinate systems, scales, point formats), each in
/// a sentence saying what the dataset of them does about it, from their headers.
fn disagreements(infos: &[myriad_io::SourceInfo]) -> Vec<String> {
    let d = myriad_io::Differences::of(infos);
    let n = infos.len();
    let mut out = Vec::new();
    if d.crs > 1 {
        out.push(format!(
            "the {n} tiles have {} coordinate systems: the dataset takes the first tile's, nothing is reprojected",
            d.crs
        ));
    }
    if d.scales > 1 {
        out.push(format!(
            "the {n} tiles have {} scales: the dataset's grid takes the finest of them",
            d.scales
        ));
    }
    if d.formats > 1 {
        out.push(format!(
            "the {n} tiles have {} point formats: the dataset holds every attribute any tile has (points without one take its default)",
            d.formats
        ));
    }
    out
}

/// Disk a build takes at its peak, per point: the dataset (12.4 bytes for KY, 13.4 for the
/// 1-billion-point synthetic city in docs/guide/benchmarks.md) and, where the points cannot
/// all stay in memory until their chunks are built, the spill files beside it (9-10 bytes
/// more); each with a fifth added.
const DATASET_BYTES_PER_POINT: u64 = 16;
const SPILL_BYTES_PER_POINT: u64 = 12;
/// What a point takes in the build's write buffers (the 50 M point city: 2.8 GB).
const RESIDENT_BYTES_PER_POINT: u64 = 56;

/// Bytes of disk the build of `points` points with options `o` takes at its peak (an estimate).
fn disk_needed(points: u64, o: &ConvertOptions) -> u64 {
    let plan = convert::plan(o.memory, o.threads, &o.params);
    let spills = points.saturating_mul(RESIDENT_BYTES_PER_POINT) > plan.resident_bytes as u64;
    let per_point = DATASET_BYTES_PER_POINT + if spills { SPILL_BYTES_PER_POINT } else { 0 };
    points.saturating_mul(per_point) + (16 << 20)
}

/// Bytes as a person reads them: "740 MB", "13.4 GB".
fn size(bytes: u64) -> String {
    match bytes {
        b if b >= 10 << 30 => format!("{:.0} GB", b as f64 / 1e9),
        b if b >= 1 << 30 => format!("{:.1} GB", b as f64 / 1e9),
        b if b >= 10 << 20 => format!("{:.0} MB", b as f64 / 1e6),
        b => format!("{:.1} MB", b as f64 / 1e6),
    }
}

/// The sample of the scan (or folder of tiles) at `path` read without decoding it (the first
/// point of each LAZ chunk, LAS records at a stride; [`myriad_io::las_preview`]): positions,
/// intensity, classification and, where the scan has it, colour.
pub fn preview_batch(path: &Path) -> Result<myriad_core::PointBatch> {
    use myriad_core::{Attribute, PointBatch, Schema};
    let files = inputs_of(path)?;
    let tiles = myriad_io::las_preview::preview_files(&files, 1 << 18, std::time::Duration::ZERO)?;
    let rgb = tiles.samples.iter().any(|s| s.rgb.is_some());
    let mut attributes = vec![Attribute::Intensity, Attribute::Classification];
    if rgb {
        attributes.push(Attribute::Rgb);
    }
    let schema = Schema::new(attributes);
    let n: usize = tiles.samples.iter().map(|s| s.len()).sum();
    let mut b = PointBatch::with_schema(&schema, n);
    let (mut intensity, mut class, mut colour) = (Vec::new(), Vec::new(), Vec::new());
    for s in &tiles.samples {
        let k = s.len();
        b.positions.extend_from_slice(&s.positions);
        intensity.extend(s.intensity.clone().unwrap_or_else(|| vec![0; k]));
        class.extend(s.classification.clone().unwrap_or_else(|| vec![0; k]));
        colour.extend(s.rgb.clone().unwrap_or_else(|| vec![[0; 3]; k]));
    }
    b.intensity = Some(intensity);
    b.classification = Some(class);
    b.rgb = rgb.then_some(colour);
    if n == 0 {
        return Err(Error::Invalid(format!(
            "{}: no points to preview",
            path.display()
        )));
    }
    Ok(b)
}

/// A small dataset of the preview of the scan at `path` (a file or a folder of LAS/LAZ tiles;
/// `myriad_io::las_preview`), made in `dir` in a moment: what a viewer shows while the scan's
/// own dataset is built. Positions (to the millimetre), intensity, class and colour, where the
/// samples have them.
pub fn preview_dataset(path: &Path, dir: &Path) -> Result<PathBuf> {
    let b = preview_batch(path)?;
    let origin = b.positions[0].map(f64::floor);
    let las = dir.join("preview.las");
    let options = myriad_io::las::LasWriteOptions::for_schema(&b.schema(), [0.001; 3], origin)?;
    let mut sink = myriad_io::las::LasSink::create(&las, options, true)?;
    sink.write(&b)?;
    sink.finish()?;
    let out = dir.join("preview.myr");
    let mut o = ConvertOptions::new(&out);
    o.force = true;
    convert::convert(&[las], &o, &convert::Silent)?;
    Ok(out)
}

/// Whether `path` is read as a dataset: a dataset's magic, a URL, or a `.myr` name (a damaged
/// one is named as such when opened).
pub fn is_dataset(path: &Path) -> bool {
    myriad_format::is_dataset(path) || path.extension().is_some_and(|e| e == "myr")
}

/// The dataset already made from the scan at `path` as it is now, if there is one (`path`
/// itself when it is a dataset); converts nothing.
pub fn existing(path: &Path) -> Option<PathBuf> {
    if is_dataset(path) {
        return Some(path.to_path_buf());
    }
    places(path).ok()?.made()
}

/// Conversions of a scan that changes while it is converted before giving up.
const TRIES: u32 = 3;

/// `path` itself when it is a dataset (or a URL), else the dataset made from it, the
/// conversion's progress told to `report`. A scan that changes while it is converted (its
/// size or modification time) is converted again; a build killed part way leaves no dataset
/// (the next one starts over).
pub fn dataset_for(path: &Path, report: &dyn Report) -> Result<PathBuf> {
    dataset_growing(path, report, None)
}

/// [`dataset_for`], the build's snapshots made into `growing` while it runs (the scan's
/// preview filling what is not built yet): what `view` and `serve` show until it ends.
pub fn dataset_growing(
    path: &Path,
    report: &dyn Report,
    growing: Option<std::sync::Arc<crate::growing::Growing>>,
) -> Result<PathBuf> {
    if is_dataset(path) {
        return Ok(path.to_path_buf());
    }
    if let Some(g) = &growing
        && let Ok(b) = preview_batch(path)
    {
        g.set_fill(b);
    }
    for _ in 0..TRIES {
        if let Some(d) = build(path, report, growing.clone())? {
            return Ok(d);
        }
        eprintln!(
            "warning: {}: changed while it was converted (its size or modification time): starting over",
            path.display()
        );
    }
    Err(Error::Invalid(format!(
        "{}: changed during each of {TRIES} conversions: open it when it is complete",
        path.display()
    )))
}

/// The dataset of the scan at `path`, made now or before; None when the scan changed while it
/// was converted (what was made is removed).
fn build(
    path: &Path,
    report: &dyn Report,
    growing: Option<std::sync::Arc<crate::growing::Growing>>,
) -> Result<Option<PathBuf>> {
    let here = places(path)?;
    if let Some(c) = here.made() {
        eprintln!(
            "{}: using {} (converted before; the scan is unchanged)",
            path.display(),
            c.display()
        );
        return Ok(Some(c));
    }
    let Places {
        folder,
        beside,
        cached,
        prefix,
    } = here;
    let inputs = inputs_of(path)?;
    let mut infos = Vec::with_capacity(inputs.len());
    for i in &inputs {
        infos.push(
            myriad_io::open(i, &myriad_io::OpenOptions::default())?
                .info()
                .clone(),
        );
    }
    // The disk the build will take, checked before it starts (where the headers count the
    // points): beside the scan, else in the cache folder, else one line saying so.
    let need = infos
        .iter()
        .map(|i| i.points)
        .sum::<Option<u64>>()
        .map(|n| disk_needed(n, &ConvertOptions::new(&beside)));
    let room = |dir: &Path| -> Option<u64> {
        let free = myriad_io::process::free_bytes(dir)?;
        need.filter(|n| *n > free).map(|_| free)
    };
    let short_beside = takes_files(&folder).then(|| room(&folder));
    let target = match short_beside {
        Some(None) => beside,
        _ => {
            let c = cached.ok_or_else(|| {
                Error::Invalid("no folder for the converted scan (set XDG_CACHE_HOME)".into())
            })?;
            let dir = c.parent().expect("a cache file has a folder");
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            if let Some(free) = room(dir) {
                let there = match short_beside {
                    Some(Some(f)) => format!("{} has {} free, ", folder.display(), size(f)),
                    _ => String::new(),
                };
                return Err(Error::Invalid(format!(
                    "{}: its dataset needs about {} of disk and {there}the cache folder {} has {} free: \
                     free some space, or set XDG_CACHE_HOME to a folder on a larger disk",
                    path.display(),
                    size(need.unwrap_or(0)),
                    dir.display(),
                    size(free)
                )));
            }
            if let Some(Some(free)) = short_beside {
                eprintln!(
                    "{}: {} has {} free, the dataset needs about {}: kept in the cache folder",
                    path.display(),
                    folder.display(),
                    size(free),
                    size(need.unwrap_or(0))
                );
            }
            c
        }
    };
    eprintln!(
        "{}: converting into {} (kept for next time)",
        path.display(),
        target.display()
    );
    if inputs.len() > 1 {
        for why in disagreements(&infos) {
            eprintln!("warning: {}: {why}", path.display());
        }
    }
    let mut o = ConvertOptions::new(&target);
    o.force = true;
    o.growing = growing;
    let built = convert::convert(&inputs, &o, report);
    // A scan that changed under the build (the files' sizes or times are not those its name
    // was made from): whatever came of it, success or a read that met the new file, is not the
    // scan's; started over. A scan that stopped opening keeps the build's own error.
    let changed = match places(path) {
        Ok(now) => now.beside != target && now.cached.as_ref() != Some(&target),
        Err(_) => false,
    };
    if changed {
        let _ = std::fs::remove_file(&target);
        return Ok(None);
    }
    built?;
    // Conversions of earlier versions of the scan go.
    let dir = target.parent().expect("a dataset has a folder");
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let n = e.file_name().to_string_lossy().to_string();
            if n.starts_with(&prefix) && n.ends_with(".myr") && e.path() != target {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
    Ok(Some(target))
}
