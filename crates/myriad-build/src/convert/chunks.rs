//! Step 2 of `convert`: the chunks' subtrees built on the pool's threads, each thread taking
//! the next chunk (or kd and mwkd group of chunks) as it is free, largest first or nearest a
//! viewer's focus first; every node but a subtree's root written as it is built, the roots
//! spilled for the levels above.

use super::{Report, Structure};
use crate::kd;
use crate::nested::{self, NestedParams};
use crate::nodes::{Pending, spill, write};
use myriad_core::{Error, NodeKey, PointBatch, Result};
use myriad_format::{DatasetWriter, Metadata};
use std::path::Path;

/// What step 2 builds the chunks' subtrees with: each subtree's nodes but its root written as
/// they are built, its root spilled for the levels above.
pub(super) struct Chunks<'a> {
    pub(super) dist: &'a crate::distribute::Distribution,
    pub(super) params: &'a NestedParams,
    pub(super) writer: &'a DatasetWriter,
    pub(super) pool: &'a rayon::ThreadPool,
    pub(super) spill_dir: &'a Path,
    pub(super) report: &'a dyn Report,
}

impl Chunks<'_> {
    /// kd and mwkd: the chunks grouped by count ([`kd::group_chunks`]), each group's subtree
    /// built, largest group first.
    pub(super) fn build_groups(
        &self,
        structure: Structure,
        mw: &crate::mwkd::MwkdParams,
        chunk_points: u64,
    ) -> Result<Vec<Pending>> {
        let Chunks {
            dist,
            params,
            writer,
            pool,
            spill_dir,
            report,
        } = *self;
        let boxes: Vec<_> = dist
            .chunks
            .iter()
            .map(|c| (dist.cell_bounds(c), c.points))
            .collect();
        let arity = if structure == Structure::Mwkd {
            mw.fanout
        } else {
            2
        };
        let mut groups = kd::group_chunks(&boxes, chunk_points, arity);
        groups.sort_by_key(|g| std::cmp::Reverse(g.points));
        largest_first(pool, &groups, |g| -> Result<Pending> {
            let mut batch = PointBatch::with_schema(&dist.schema, g.points as usize);
            for &i in &g.chunks {
                batch.append(&dist.load(&dist.chunks[i])?);
            }
            if structure == Structure::Mwkd {
                let n = batch.len() as u64;
                let top = crate::mwkd::build_subtree_with(batch, g.key, mw, &mut |node| {
                    write(writer, node.into_built()).map(|_| ())
                })?;
                report.advance(n);
                return spill(top.into_built(), spill_dir);
            }
            let mut top = None;
            kd::build_subtree_with(batch, g.key, params, &mut |node| {
                report.advance(node.points.len() as u64);
                if node.key == g.key {
                    top = Some(spill(node, spill_dir)?);
                } else {
                    write(writer, node)?;
                }
                Ok::<(), Error>(())
            })?;
            Ok(top.expect("a group has points, so its subtree has a root"))
        })
    }

    /// Octree and layered: each chunk's subtree ([`nested::build_subtree_with`]), largest
    /// first, or nearest first where a viewer looks at the build as it grows (offered a
    /// snapshot as each chunk is done, and once when all are).
    pub(super) fn build_nested(
        &self,
        growing: Option<&std::sync::Arc<crate::growing::Growing>>,
        meta: &Metadata,
    ) -> Result<Vec<Pending>> {
        let Chunks {
            dist,
            params,
            writer,
            pool,
            spill_dir,
            report,
        } = *self;
        let root = dist.root;
        let chunk_keys: Vec<NodeKey> = (dist.chunks.iter())
            .map(|c| NodeKey {
                level: c.level,
                cell: c.cell,
            })
            .collect();
        let built = std::sync::Mutex::new(std::collections::HashSet::new());
        let offer = |force: bool| {
            if let Some(g) = growing {
                g.offer(writer, meta, &chunk_keys, &built, force);
            }
        };
        let mut chunks = dist.chunks.clone();
        chunks.sort_by_key(|c| std::cmp::Reverse(c.points));
        // Where a viewer looks, the chunks nearest that point first.
        let nearer = |left: &[usize]| -> Option<usize> {
            let at = growing?.focus()?;
            let far = |i: &usize| {
                let c = &chunks[*i];
                let cube = NodeKey {
                    level: c.level,
                    cell: c.cell,
                }
                .bounds(&root);
                (0..3)
                    .map(|a| {
                        (cube.min[a] - at[a])
                            .max(at[a] - cube.max[a])
                            .max(0.0)
                            .powi(2)
                    })
                    .sum::<f64>()
            };
            left.iter()
                .copied()
                .min_by(|a, b| far(a).total_cmp(&far(b)))
        };
        let pending = in_order(pool, &chunks, &nearer, |chunk| -> Result<Pending> {
            let batch = dist.load(chunk)?;
            let key = NodeKey {
                level: chunk.level,
                cell: chunk.cell,
            };
            let mut top = None;
            nested::build_subtree_with(batch, &root, key, params, &mut |node| {
                report.advance(node.points.len() as u64);
                if node.key == key {
                    top = Some(spill(node, spill_dir)?);
                } else {
                    write(writer, node)?;
                }
                Ok::<(), Error>(())
            })?;
            built.lock().expect("built lock").insert(key);
            if let Some(g) = growing {
                g.built(key);
            }
            offer(false);
            Ok(top.expect("a chunk has points, so its subtree has a root"))
        })?;
        offer(true);
        Ok(pending)
    }
}

/// `build` of every item on the pool's threads, each thread taking the next item as it is free:
/// with the items largest first, the last to finish is a small one (a split of the list, as
/// `par_iter` makes, can leave one thread the big items). The results in the items' order; the
/// first error stops the others at their next item.
fn largest_first<T: Sync, R: Send>(
    pool: &rayon::ThreadPool,
    items: &[T],
    build: impl Fn(&T) -> Result<R> + Sync,
) -> Result<Vec<R>> {
    in_order(pool, items, &|_| None, build)
}

/// [`largest_first`], but for the items `nearer` puts first when a worker takes its next one:
/// given the items not taken yet (by index), the one to take, or `None` for the first of them
/// (what a viewer looks at, built before the rest: [`crate::growing::Growing::focus`]).
fn in_order<T: Sync, R: Send>(
    pool: &rayon::ThreadPool,
    items: &[T],
    nearer: &(dyn Fn(&[usize]) -> Option<usize> + Sync),
    build: impl Fn(&T) -> Result<R> + Sync,
) -> Result<Vec<R>> {
    use std::sync::atomic::{AtomicBool, Ordering};
    let left = std::sync::Mutex::new((0..items.len()).collect::<Vec<usize>>());
    let failed = AtomicBool::new(false);
    let done = std::sync::Mutex::new(Vec::with_capacity(items.len()));
    pool.broadcast(|_| {
        while !failed.load(Ordering::Relaxed) {
            let i = {
                let mut left = left.lock().expect("queue lock");
                if left.is_empty() {
                    break;
                }
                let at = nearer(&left)
                    .and_then(|i| left.iter().position(|&j| j == i))
                    .unwrap_or(0);
                left.remove(at)
            };
            let Some(item) = items.get(i) else { break };
            let r = build(item);
            failed.fetch_or(r.is_err(), Ordering::Relaxed);
            done.lock().expect("results").push((i, r));
        }
    });
    let mut done = done.into_inner().expect("results");
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, r)| r).collect()
}
