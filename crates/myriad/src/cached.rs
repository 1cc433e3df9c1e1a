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
