//! Any scan opens directly (`myriad_build::cached`): the dataset kept next to it, converted
//! with `convert`'s progress bar when there is none yet.

use anyhow::Result;
use std::path::{Path, PathBuf};

/// `path` itself when it is a dataset (or a URL), else the dataset made from it.
pub fn dataset_for(path: &Path) -> Result<PathBuf> {
    let bar = crate::progress::Bar::new();
    let found = myriad_build::cached::dataset_for(path, &bar);
    bar.clear();
    Ok(found?)
}

/// [`dataset_for`], its build's snapshots made into `growing` while it runs.
pub fn dataset_growing(
    path: &Path,
    growing: std::sync::Arc<myriad_build::growing::Growing>,
) -> Result<PathBuf> {
    let bar = crate::progress::Bar::new();
    let found = myriad_build::cached::dataset_growing(path, &bar, Some(growing));
    bar.clear();
    Ok(found?)
}

/// Whether `path` is a LAS/LAZ scan or a folder of them (what has a preview).
pub fn previewable(path: &std::path::Path) -> Result<bool> {
    if myriad_format::is_dataset(path) {
        return Ok(false);
    }
    for f in myriad_build::cached::inputs_of(path)? {
        if !matches!(
            myriad_io::detect(&f)?,
            myriad_io::Format::Las | myriad_io::Format::Laz
        ) {
            return Ok(false);
        }
    }
    Ok(true)
}
