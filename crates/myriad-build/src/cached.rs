//! Any scan opens directly: `render`, `view` and `serve` given a scan rather than a dataset
//! convert it (with the defaults of `convert` and its progress bar) into a dataset kept next to
//! the scan, or in the user's cache folder where the scan's folder takes no files, and use that
//! dataset again while the scan is unchanged (same path, size and modification time, same
//! format version).

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

/// `path` itself when it is a dataset (or a URL), else the dataset made from it, the
/// conversion's progress told to `report`.
pub fn dataset_for(path: &Path, report: &dyn Report) -> Result<PathBuf> {
    // A .myr file is read as a dataset whatever it holds (a damaged one is named as such).
    if myriad_format::is_dataset(path) || path.extension().is_some_and(|e| e == "myr") {
        return Ok(path.to_path_buf());
    }
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::Invalid(format!("{}: not a file", path.display())));
    }
    let canonical = path.canonicalize().map_err(|e| Error::io(path, e))?;
    let mtime = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    let key = fnv(&[
        canonical.as_os_str().as_encoded_bytes(),
        &meta.len().to_le_bytes(),
        &mtime.to_le_bytes(),
        &myriad_format::FORMAT_VERSION.to_le_bytes(),
    ]);
    let name = canonical
        .file_name()
        .map_or("scan".into(), |n| n.to_string_lossy().to_string());
    let folder = canonical.parent().unwrap_or(Path::new("/"));
    // Per scan path (two scans of one name share the cache folder), then per version of it.
    let place = fnv(&[canonical.as_os_str().as_encoded_bytes()]) as u32;
    let prefix = format!(".{name}.myriad-{place:08x}-");
    let beside = folder.join(format!("{prefix}{key:016x}.myr"));
    let cached = cache_dir().map(|d| d.join(format!("{prefix}{key:016x}.myr")));
    for c in std::iter::once(&beside).chain(cached.as_ref()) {
        if c.is_file() && Dataset::open(c).is_ok() {
            eprintln!(
                "{}: using {} (converted before; the scan is unchanged)",
                path.display(),
                c.display()
            );
            return Ok(c.clone());
        }
    }
    let target = if takes_files(folder) {
        beside
    } else {
        let c = cached.ok_or_else(|| {
            Error::Invalid("no folder for the converted scan (set XDG_CACHE_HOME)".into())
        })?;
        let dir = c.parent().expect("a cache file has a folder");
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        c
    };
    eprintln!(
        "{}: converting into {} (kept for next time)",
        path.display(),
        target.display()
    );
    let mut o = ConvertOptions::new(&target);
    o.force = true;
    convert::convert(&[path.to_path_buf()], &o, report)?;
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
    Ok(target)
}
