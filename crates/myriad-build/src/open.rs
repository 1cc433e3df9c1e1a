//! Opening what a command is given: the one place that decides what an input is. A dataset
//! (a `.myr` file, or one on a web server or S3) opens as it is; a LAS/LAZ scan or a folder of
//! tiles without its dataset is shown from its preview (a sample read without decoding it)
//! while its dataset is built behind it, where the command can show one; any other input is
//! converted first into a dataset kept next to it ([`crate::cached`]). `render`, `view`,
//! `serve` and the tools all come through [`Opener::open`] (serve asks [`served_as_is`] first:
//! exported folders and COPC files are files it hands out, not datasets it reads). Formats read
//! in place (COPC, EPT, Potree 2.0) join here as another kind of [`Opened`].
//!
//! A scan shown from its preview is built by [`Pending::build`]; every scan shown (not a
//! dataset) can be watched for changes with [`Watched`], so that its dataset is built again.

use crate::cached;
/// Whether an input is read as a dataset (a dataset's magic, a URL, a `.myr` name) rather than
/// a scan a dataset is made from: what is shown of it never changes under the viewer.
pub use crate::cached::is_dataset;
use crate::growing::Growing;
use crate::report::Report;
use myriad_core::{Error, Result};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What a command shows of a scan that has no dataset yet.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Preview {
    /// Nothing: the scan is converted first, and the conversion waited for.
    None,
    /// Its sample, drawn as points (`render --no-wait`): no dataset is made; a scan of other
    /// formats than LAS/LAZ is converted first, with a warning.
    Sample,
    /// A small dataset of its sample, made at once in a scratch folder of this process's, while
    /// its own dataset is built (`view`, `serve`).
    Dataset,
}

/// What an input opened as.
pub enum Opened {
    /// A dataset to read: the input itself (a dataset, a URL), or the dataset of a scan, made
    /// now or before.
    Dataset(PathBuf),
    /// A scan shown before its dataset exists: build that with [`Pending::build`].
    Preview(Pending),
}

/// A scan whose dataset is still to be built.
pub struct Pending {
    /// The scan: a file, or a folder of LAS/LAZ tiles.
    pub scan: PathBuf,
    /// Its files (a folder's tiles, sorted by name).
    pub files: Vec<PathBuf>,
    /// The dataset of its preview ([`Preview::Dataset`]); `None` with [`Preview::Sample`].
    pub preview: Option<PathBuf>,
}

impl Pending {
    /// The scan's dataset, built now (or found made meanwhile), its progress told to `report`
    /// and its snapshots made into `growing` while it runs.
    pub fn build(&self, report: &dyn Report, growing: Option<Arc<Growing>>) -> Result<PathBuf> {
        cached::dataset_growing(&self.scan, report, growing)
    }
}

/// Opens a command's inputs, one after another, as the command can show them.
pub struct Opener {
    preview: Preview,
    /// The previews' datasets, one subfolder each (made on the first preview).
    scratch: Option<myriad_io::claim::Folder>,
    previews: usize,
}

/// The prefix of the scratch folders of previews' datasets in the temporary folder.
const PREVIEWS: &str = "myriad-preview-";

impl Opener {
    /// An opener showing scans without a dataset as `preview` says. The scratch folders of
    /// earlier processes that were killed go first.
    pub fn new(preview: Preview) -> Opener {
        if preview == Preview::Dataset {
            myriad_io::claim::remove_stale_folders(&std::env::temp_dir(), PREVIEWS);
        }
        Opener {
            preview,
            scratch: None,
            previews: 0,
        }
    }

    /// `input` opened: a dataset as it is; a scan without its dataset from its preview where
    /// this opener shows one and the scan is LAS/LAZ; else the scan's dataset, converted now
    /// (progress told to `report`) unless made before.
    pub fn open(&mut self, input: &Path, report: &dyn Report) -> Result<Opened> {
        if self.preview != Preview::None && cached::existing(input).is_none() {
            let files = cached::inputs_of(input)?;
            match other_format(&files)? {
                None => return self.preview_of(input, files),
                Some(f) if self.preview == Preview::Sample => eprintln!(
                    "warning: {}: no preview of {} files: converting it first",
                    input.display(),
                    f.name()
                ),
                Some(_) => {}
            }
        }
        Ok(Opened::Dataset(dataset(input, report)?))
    }

    /// The scan `input` of LAS/LAZ `files`, shown from its preview.
    fn preview_of(&mut self, input: &Path, files: Vec<PathBuf>) -> Result<Opened> {
        let preview = match self.preview {
            Preview::Dataset => {
                if self.scratch.is_none() {
                    let tmp = std::env::temp_dir();
                    self.scratch = Some(myriad_io::claim::Folder::create(&tmp, PREVIEWS)?);
                }
                let scratch = self.scratch.as_ref().expect("made above").path();
                let dir = scratch.join(self.previews.to_string());
                self.previews += 1;
                std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
                Some(cached::preview_dataset(input, &dir)?)
            }
            _ => None,
        };
        Ok(Opened::Preview(Pending {
            scan: input.to_path_buf(),
            files,
            preview,
        }))
    }
}

/// The dataset of `input`: itself when it is one (or a URL), else the dataset of the scan,
/// made before or converted now (progress told to `report`): what commands that show no
/// preview read.
pub fn dataset(input: &Path, report: &dyn Report) -> Result<PathBuf> {
    cached::dataset_for(input, report)
}

/// The format of the first of `files` that has no preview (not LAS or LAZ), if any.
fn other_format(files: &[PathBuf]) -> Result<Option<myriad_io::Format>> {
    let mut other = None;
    for f in files {
        match myriad_io::detect(f)? {
            myriad_io::Format::Las | myriad_io::Format::Laz => {}
            k => other = Some(k),
        }
    }
    Ok(other)
}

/// Whether `serve` hands `input` out as it is, files for other viewers and tools rather than a
/// scan to build: a dataset, a URL, a COPC file, or a folder that is not a folder of LAS/LAZ
/// tiles (a Potree or 3D Tiles export, any folder of files).
pub fn served_as_is(input: &Path) -> bool {
    if myriad_format::remote::is_url(input) || myriad_format::is_dataset(input) {
        return true;
    }
    if input.is_dir() {
        return !is_tile_folder(input);
    }
    let name = input
        .file_name()
        .map(|n| n.to_string_lossy().to_lowercase());
    name.is_some_and(|n| n.ends_with(".copc.laz"))
}

/// Whether the folder `dir` is one scan cut into LAS/LAZ tiles: it holds some and is no
/// export (Potree's metadata.json or hierarchy.bin, a 3D Tiles tileset.json, COPC files).
pub fn is_tile_folder(dir: &Path) -> bool {
    if ["metadata.json", "tileset.json", "hierarchy.bin"]
        .iter()
        .any(|f| dir.join(f).exists())
    {
        return false;
    }
    cached::inputs_of(dir).is_ok_and(|tiles| {
        !tiles.iter().any(|t| {
            t.file_name()
                .is_some_and(|n| n.to_string_lossy().to_lowercase().ends_with(".copc.laz"))
        })
    })
}

/// The coordinate system of what `input` names, converting nothing: its dataset's (itself, or
/// made from it before), else its (first) file's header's.
pub fn crs_of(input: &Path) -> Result<Option<String>> {
    if let Some(ds) = cached::existing(input) {
        return Ok(myriad_format::Dataset::open_stored(&ds)?.meta.crs.clone());
    }
    let inputs = cached::inputs_of(input)?;
    let Some(first) = inputs.first() else {
        return Err(Error::Invalid(format!(
            "{}: no scan there",
            input.display()
        )));
    };
    let src = myriad_io::open(first, &myriad_io::OpenOptions::default())?;
    Ok(src.info().crs.clone())
}

/// The bounds of what `input` names, converting nothing: its dataset's (itself, or made from it
/// before), else its files' headers' (all of a folder's tiles); `None` where none are known.
pub fn bounds_of(input: &Path) -> Result<Option<myriad_core::Aabb>> {
    if let Some(ds) = cached::existing(input) {
        let b = myriad_format::Dataset::open_stored(&ds)?.meta.bounds;
        return Ok((!b.is_empty()).then_some(b));
    }
    let mut all: Option<myriad_core::Aabb> = None;
    for f in cached::inputs_of(input)? {
        let src = myriad_io::open(&f, &myriad_io::OpenOptions::default())?;
        if let Some(b) = src.info().bounds {
            all = Some(all.map_or(b, |a| a.union(&b)));
        }
    }
    Ok(all)
}

/// How often a scan shown is looked at for changes.
pub const WATCH_EVERY: std::time::Duration = std::time::Duration::from_secs(1);

/// The size and modification time of each file of a scan (`None` where one cannot be read).
type Stamp = Option<Vec<(u64, std::time::SystemTime)>>;

/// The scans shown (each with the caller's index, a layer's), watched for changes on disk: a
/// scan whose files' sizes or modification times are no longer those its last build started
/// from is to be built again.
pub struct Watched {
    scans: Vec<(usize, PathBuf, Stamp)>,
}

impl Watched {
    /// `scans` as they are now.
    pub fn new(scans: Vec<(usize, PathBuf)>) -> Watched {
        let scans = (scans.into_iter())
            .map(|(i, p)| {
                let s = stamp(&p);
                (i, p, s)
            })
            .collect();
        Watched { scans }
    }

    /// Whether no scan is watched.
    pub fn is_empty(&self) -> bool {
        self.scans.is_empty()
    }

    /// The scans that changed since they were last looked at (each then taken as it is now).
    pub fn changed(&mut self) -> Vec<(usize, PathBuf)> {
        let mut out = Vec::new();
        for (i, p, was) in &mut self.scans {
            let now = stamp(p);
            if *was != now {
                *was = now;
                out.push((*i, p.clone()));
            }
        }
        out
    }
}

/// The size and modification time of each file of the scan at `path`.
fn stamp(path: &Path) -> Stamp {
    cached::inputs_of(path)
        .ok()?
        .iter()
        .map(|f| {
            let m = std::fs::metadata(f).ok()?;
            Some((m.len(), m.modified().ok()?))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A folder of its own under the temporary folder, removed on drop.
    struct Dir(PathBuf);
    impl Dir {
        fn new(name: &str) -> Dir {
            let d = std::env::temp_dir().join(format!("myriad-open-{name}-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&d);
            std::fs::create_dir_all(&d).unwrap();
            Dir(d)
        }
    }
    impl Drop for Dir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    #[test]
    fn serve_hands_out_exports_and_copc_files_and_builds_tile_folders() {
        let d = Dir::new("served");
        let tiles = d.0.join("tiles");
        let potree = d.0.join("potree");
        let copcs = d.0.join("copcs");
        for f in [&tiles, &potree, &copcs] {
            std::fs::create_dir_all(f).unwrap();
        }
        std::fs::write(tiles.join("a.laz"), b"x").unwrap();
        std::fs::write(potree.join("metadata.json"), b"{}").unwrap();
        std::fs::write(potree.join("a.laz"), b"x").unwrap();
        std::fs::write(copcs.join("a.copc.laz"), b"x").unwrap();
        assert!(is_tile_folder(&tiles) && !served_as_is(&tiles));
        assert!(!is_tile_folder(&potree) && served_as_is(&potree));
        assert!(!is_tile_folder(&copcs) && served_as_is(&copcs));
        assert!(served_as_is(&copcs.join("a.copc.laz")));
        assert!(!served_as_is(&tiles.join("a.laz")));
        assert!(served_as_is(Path::new("https://example.org/a.myr")));
    }

    #[test]
    fn a_watched_scan_is_named_once_each_time_it_changes() {
        let d = Dir::new("watched");
        let scan = d.0.join("a.las");
        std::fs::write(&scan, b"12345").unwrap();
        let mut w = Watched::new(vec![(3, scan.clone())]);
        assert!(w.changed().is_empty());
        std::fs::write(&scan, b"1234567").unwrap();
        assert_eq!(w.changed(), vec![(3, scan.clone())]);
        assert!(w.changed().is_empty());
        std::fs::remove_file(&scan).unwrap();
        assert_eq!(w.changed(), vec![(3, scan)]);
    }
}
