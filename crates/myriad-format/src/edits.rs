//! Edits kept beside a dataset (classes set, points removed: `myriad classify`), applied to
//! every node a reader decodes, never written into the dataset. What an edit is, and the file
//! that keeps a dataset's edits, belong to `myriad_measure::edits` (a floor above, with the
//! regions and filters an edit is made of); this module is the seam: [`set_loader`] is called
//! once by a program that applies edits, and [`crate::Dataset::open`] then asks the loader for
//! the edits of every dataset it opens on disk. A program that never sets it (a library user, a
//! test) reads datasets as stored.

use crate::Metadata;
use myriad_core::{Aabb, PointBatch, Result};
use std::path::Path;
use std::sync::{Arc, OnceLock};

/// A dataset's edits, ready to apply.
pub trait Edits: Send + Sync + std::fmt::Debug {
    /// Whether an edit may touch a point in the box (a node's cube): nodes it does not meet are
    /// read as stored.
    fn meets(&self, cube: &Aabb) -> bool;
    /// Applies the edits to the points of a node (its cube, every column of the dataset):
    /// classes set, points removed. Where points were removed, the flags of those kept, one per
    /// point given (so that a writer can count a node's levels again); `None` where none was.
    /// An error (a damaged file the edits read) makes the node unreadable.
    fn apply(
        &self,
        cube: &Aabb,
        batch: &mut PointBatch,
    ) -> std::result::Result<Option<Vec<bool>>, String>;
    /// The terrain the edits classify ground by (the last ground edit's), for heights above it.
    fn ground(&self) -> Option<Arc<dyn myriad_core::ground::GroundHeight>> {
        None
    }
}

/// Finds the edits of the dataset at a path (`None`: it has none); an error names their file.
pub type Loader = fn(&Path, &Metadata) -> Result<Option<Arc<dyn Edits>>>;

static LOADER: OnceLock<Loader> = OnceLock::new();

/// Makes every dataset opened from now on carry its edits (the first loader set stays).
pub fn set_loader(loader: Loader) {
    let _ = LOADER.set(loader);
}

/// The edits of the dataset at `path`, as the loader set finds them.
pub(crate) fn load(path: &Path, meta: &Metadata) -> Result<Option<Arc<dyn Edits>>> {
    match LOADER.get() {
        Some(f) => f(path, meta),
        None => Ok(None),
    }
}
