//! `myriad classify --apply`: a dataset written again with the edits kept beside it
//! ([`myriad_format::edits`]) in its points. Nodes no edit meets are copied page for page;
//! the others are decoded as stored, edited, and encoded again in the same place of the same
//! hierarchy, their levels of detail counted anew over the points kept (removing points keeps
//! the order of the rest, so each level stays a prefix and a level's prefix still holds at
//! most one point per cell). The input and its edits stay as they are.

use crate::report::Report;
use myriad_core::{Error, Result};
use myriad_format::{Dataset, DatasetWriter, NodeShape};
use rayon::prelude::*;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// What [`apply`] wrote.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Applied {
    pub nodes: u64,
    /// Nodes decoded and encoded again (the others' pages copied).
    pub edited: u64,
    pub points: u64,
    pub removed: u64,
    pub bytes: u64,
}

/// Writes `ds` with its edits applied to `out` (a `.myr`), atomically and checked as `append`
/// checks what it writes.
pub fn apply(ds: &Dataset, out: &Path, force: bool, report: &dyn Report) -> Result<Applied> {
    let path = ds.path();
    if let Some(f) = ds.foreign_format() {
        return Err(Error::Invalid(format!(
            "{}: a {f} dataset: --apply writes a .myr from a .myr (`myriad convert` it first)",
            path.display()
        )));
    }
    let Some(edits) = ds.edits() else {
        return Err(Error::Invalid(format!(
            "{}: no edits to apply (`myriad classify {} --list`)",
            path.display(),
            path.display()
        )));
    };
    myriad_io::atomic::refuse_input_as_output(out, &[path])?;
    let (nodes, damage) = ds.nodes();
    if let Some(d) = damage.first() {
        return Err(ds.damage_error(d));
    }
    if nodes.iter().any(|e| e.splats.is_some()) {
        return Err(Error::Invalid(format!(
            "{}: an mwkd dataset (splats drawn from its points): --apply writes octree, layered \
             and kd datasets; extract the points and convert them",
            path.display()
        )));
    }
    let writer = DatasetWriter::create(out, force, ds.meta.quantization)?;
    let (edited, removed) = (AtomicU64::new(0), AtomicU64::new(0));
    report.phase("applying edits", nodes.len() as u64);
    nodes.par_iter().try_for_each(|e| -> Result<()> {
        let cube = ds.edit_cube(e);
        if e.points == 0 || !edits.meets(&cube) {
            let page = ds.node_page(e).map_err(|d| ds.damage_error(&d))?;
            writer.copy_node(e, &page)?;
        } else {
            let mut b = ds
                .read_node_stored(e, &ds.meta.schema)
                .map_err(|d| ds.damage_error(&d))?;
            let keep = edits.apply(&cube, &mut b).map_err(|m| {
                Error::Invalid(format!(
                    "{}: node {}: its edits: {m}",
                    path.display(),
                    e.key
                ))
            })?;
            let prefix: Vec<u64> = match keep {
                None => e.prefix.iter().map(|&p| p as u64).collect(),
                Some(keep) => {
                    removed.fetch_add(
                        keep.iter().filter(|k| !**k).count() as u64,
                        Ordering::Relaxed,
                    );
                    // A level's points are the first `p`: those of them kept.
                    let mut kept = 0u64;
                    let mut at = 0usize;
                    (e.prefix.iter())
                        .map(|&p| {
                            while at < p as usize {
                                kept += keep[at] as u64;
                                at += 1;
                            }
                            kept
                        })
                        .collect()
                }
            };
            let shape = NodeShape {
                bounds: e.bounds,
                contour: e.contour,
                detail: e.detail,
            };
            writer.write_node(e.key, &b, &prefix, &e.spacing, shape)?;
            edited.fetch_add(1, Ordering::Relaxed);
        }
        report.advance(1);
        Ok(())
    })?;
    let mut meta = ds.meta.clone();
    // Every page is in this file now.
    meta.files.clear();
    let mut written = Applied {
        edited: edited.into_inner(),
        removed: removed.into_inner(),
        ..Applied::default()
    };
    written.bytes = writer.finish_checked(meta, |out| {
        let r = crate::extract::verify(out, |_| {});
        written.nodes = r.nodes;
        written.points = r.points;
        match r.damage.first() {
            None => Ok(()),
            Some(d) => Err(Error::Invalid(format!(
                "{}: the dataset written fails its check (node {}: {}); nothing written \
                 (please report this)",
                path.display(),
                d.key,
                d.message
            ))),
        }
    })?;
    Ok(written)
}
