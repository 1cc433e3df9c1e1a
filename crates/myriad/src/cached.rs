//! Any input opens directly (`myriad_build::open`, the one place that decides what it is): the
//! binary only lends it `convert`'s progress bar for a scan converted first.

use crate::progress::Bar;
use anyhow::Result;
use myriad_build::open::{Opened, Opener};
use std::path::{Path, PathBuf};

/// `input` opened by `opener`, a conversion's progress drawn on a bar.
pub fn open(opener: &mut Opener, input: &Path) -> Result<Opened> {
    with_bar(|bar| opener.open(input, bar))
}

/// The dataset of `input`: itself when it is one (or a URL), else the one made from it (now,
/// with a progress bar, or before).
pub fn dataset_for(input: &Path) -> Result<PathBuf> {
    with_bar(|bar| myriad_build::open::dataset(input, bar))
}

/// The dataset of the scan `pending` shows, built now with a progress bar, its snapshots made
/// into `growing` while it runs.
pub fn build(
    pending: &myriad_build::open::Pending,
    growing: Option<std::sync::Arc<myriad_build::growing::Growing>>,
) -> Result<PathBuf> {
    with_bar(|bar| pending.build(bar, growing))
}

/// `work` with a progress bar to tell, cleared when it ends.
fn with_bar<T>(work: impl FnOnce(&Bar) -> myriad_core::Result<T>) -> Result<T> {
    let bar = Bar::new();
    let done = work(&bar);
    bar.clear();
    Ok(done?)
}
