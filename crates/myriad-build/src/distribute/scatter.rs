//! The write buffers of distribution: the points of each chunk of one level, kept until the
//! buffers fill, then the largest appended to their spill files until half is free.

use super::{Chunk, Resident};
use crate::spill::{Codec, encode_frame};
use myriad_core::{Error, PointBatch, Result, Schema};
use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};

#[derive(Debug)]
/// Write buffers of the chunks of one level, the largest flushed to their files when `limit` is
/// reached.
/// A buffer holds its points as a batch; they become rows only when written to a spill file.
pub(super) struct Scatter<'a> {
    pub(super) folder: &'a Path,
    pub(super) level: u32,
    pub(super) schema: &'a Schema,
    /// Bytes of a point as a row: what the budget counts.
    row: usize,
    /// Slot of each cell met so far.
    cells: HashMap<[u32; 3], usize>,
    /// Per slot: the cell, its write buffer, its point count.
    slots: Vec<([u32; 3], PointBatch, u64)>,
    /// Per slot: whether its spill file was written to.
    on_disk: Vec<bool>,
    /// The points of the batch being added grouped by slot, in order, and where each slot's
    /// begin (`slots.len() + 1` entries): one list for all slots, reused. A list per slot kept
    /// the capacity of the most points it ever took from one batch: with thousands of chunks
    /// (a billion points), hundreds of megabytes that grew all through the reading.
    picks: Vec<u32>,
    starts: Vec<usize>,
    /// The slot of each point of the batch being added (reused).
    slot_of: Vec<u32>,
    /// Whether anything was written to the spill files yet.
    spilled: bool,
    buffered: usize,
    limit: usize,
    /// Points the scatter expects in all, and those added so far: how big a chunk will grow.
    expected: f64,
    added: u64,
    pub(super) codec: Codec,
}

impl<'a> Scatter<'a> {
    pub(super) fn new(
        folder: &'a Path,
        level: u32,
        schema: &'a Schema,
        limit: usize,
        resident: usize,
        codec: Codec,
        expected: u64,
    ) -> Scatter<'a> {
        let row = PointBatch::with_schema(schema, 0).row_size();
        // Every point expected to fit in `resident`: the buffers may hold them all.
        let limit = if expected.saturating_mul(row as u64) <= resident as u64 {
            limit.max(resident)
        } else {
            limit
        };
        Scatter {
            folder,
            level,
            schema,
            row,
            cells: HashMap::new(),
            slots: Vec::new(),
            on_disk: Vec::new(),
            picks: Vec::new(),
            starts: Vec::new(),
            slot_of: Vec::new(),
            spilled: false,
            buffered: 0,
            expected: expected as f64,
            added: 0,
            limit,
            codec,
        }
    }
}

pub(super) fn spill_path(folder: &Path, level: u32, c: [u32; 3]) -> PathBuf {
    folder.join(format!("{level}-{}-{}-{}.rows", c[0], c[1], c[2]))
}

impl Scatter<'_> {
    /// The chunks written so far.
    pub(super) fn chunks(&self) -> Vec<Chunk> {
        self.slots
            .iter()
            .zip(&self.on_disk)
            .map(|(&(cell, _, n), &on_disk)| Chunk {
                level: self.level,
                cell,
                points: n,
                path: spill_path(self.folder, self.level, cell),
                on_disk,
            })
            .collect()
    }

    /// Adds the points `picked` of `batch`, which fall in the cells `cells` (one each).
    pub(super) fn add(
        &mut self,
        batch: &PointBatch,
        picked: &[u32],
        cells: &[[u32; 3]],
    ) -> Result<()> {
        let seen = (self.added + picked.len() as u64).max(1);
        self.added = seen;
        // Points the write buffers hold without spilling.
        let fits = (self.limit / self.row.max(1)) as f64;
        let mut last: Option<([u32; 3], usize)> = None;
        debug_assert_eq!(picked.len(), cells.len());
        for &cell in cells {
            // Consecutive points mostly share a cell.
            let slot = match last {
                Some((c, s)) if c == cell => s,
                _ => {
                    let next = self.slots.len();
                    let s = *self.cells.entry(cell).or_insert(next);
                    if s == next {
                        self.slots
                            .push((cell, PointBatch::with_schema(self.schema, 0), 0));
                        self.on_disk.push(false);
                    }
                    last = Some((cell, s));
                    s
                }
            };
            self.slot_of.push(slot as u32);
        }
        // The points grouped by slot, each slot's in their order (a counting sort).
        self.starts.clear();
        self.starts.resize(self.slots.len() + 1, 0);
        for &s in &self.slot_of {
            self.starts[s as usize + 1] += 1;
        }
        for k in 1..self.starts.len() {
            self.starts[k] += self.starts[k - 1];
        }
        self.picks.clear();
        self.picks.resize(picked.len(), 0);
        for (&i, &s) in picked.iter().zip(&self.slot_of) {
            // `starts[s]` moves up to the next slot's start as its points are placed...
            let at = &mut self.starts[s as usize];
            self.picks[*at] = i;
            *at += 1;
        }
        self.slot_of.clear();
        for (k, slot) in self.slots.iter_mut().enumerate() {
            // ...so that it ends where slot `k + 1` begins: slot `k`'s are those before.
            let begin = if k == 0 { 0 } else { self.starts[k - 1] };
            let picks = &self.picks[begin..self.starts[k]];
            if !picks.is_empty() {
                let (len, want) = (slot.1.len(), slot.1.len() + picks.len());
                if want > slot.1.capacity() && !self.spilled && self.expected <= fits {
                    // Where every point is expected to stay in memory: grown to what the
                    // chunk will hold if the rest of the input falls as the part read so far
                    // did, and a quarter more, but by at least half (so a chunk whose points
                    // come late, or an input that declares too few, still grows
                    // geometrically): few reallocations, each copying and faulting in its
                    // points again (KY: 39 copying 3.7 M points, against 71 copying 9.4 M when
                    // growth was capped at double). Room reserved and never filled is address
                    // space, not memory.
                    let projected =
                        (slot.2 + picks.len() as u64) as f64 * self.expected / seen as f64;
                    let least = want.max(len + len / 2).max(1024);
                    // No more than the points yet to come could hold.
                    let most = want + (self.expected - seen as f64).max(0.0) as usize;
                    let target = ((projected * 1.25) as usize).min(most).max(least);
                    slot.1.reserve_exact(target - len);
                }
                slot.1.extend_gather(batch, picks);
                slot.2 += picks.len() as u64;
                self.buffered += picks.len() * self.row;
            }
        }
        if self.buffered > self.limit {
            // The largest buffers, until half of them is free: what stays is never written and
            // read back, if the buffers do not fill again before the end.
            self.flush_largest(self.buffered - self.limit / 2)?;
        }
        Ok(())
    }

    /// The points still in the buffers, by level and cell (those of a chunk whose spill file
    /// was written to come after the file's).
    pub(super) fn take_resident(&mut self) -> Resident {
        self.buffered = 0;
        let level = self.level;
        self.slots
            .iter_mut()
            .filter(|(_, buf, _)| !buf.is_empty())
            .map(|(cell, buf, _)| ((level, *cell), std::mem::take(buf)))
            .collect()
    }

    /// Writes the largest buffers to their spill files until at least `bytes` of points are
    /// out of memory.
    fn flush_largest(&mut self, bytes: usize) -> Result<()> {
        let mut by_size: Vec<usize> = (0..self.slots.len()).collect();
        by_size.sort_unstable_by_key(|&s| std::cmp::Reverse(self.slots[s].1.len()));
        let mut out = vec![false; self.slots.len()];
        let mut freed = 0;
        for s in by_size {
            if freed >= bytes {
                break;
            }
            out[s] = true;
            freed += self.slots[s].1.len() * self.row;
        }
        self.write(&out)?;
        self.buffered = self.buffered.saturating_sub(freed);
        Ok(())
    }

    /// Appends every buffer to its chunk's spill file.
    pub(super) fn flush(&mut self) -> Result<()> {
        self.write(&vec![true; self.slots.len()])?;
        self.buffered = 0;
        Ok(())
    }

    /// Appends the buffers of the slots marked in `which` to their spill files, in parallel: a
    /// flush on the reading thread alone left the decoding threads waiting (a quarter of the two
    /// cores idle while 500 M points were read).
    fn write(&mut self, which: &[bool]) -> Result<()> {
        use rayon::prelude::*;
        let (folder, level, codec, schema) = (self.folder, self.level, self.codec, self.schema);
        for ((slot, written), &w) in self.slots.iter().zip(&mut self.on_disk).zip(which) {
            if w && !slot.1.is_empty() {
                *written = true;
                self.spilled = true;
            }
        }
        self.slots
            .par_iter_mut()
            .zip(which)
            .filter(|((_, b, _), w)| **w && !b.is_empty())
            .try_for_each(|((cell, buf, _), _)| {
                let frame = encode_frame(buf, codec);
                // Freed, not cleared: capacities would otherwise outgrow the budget.
                *buf = PointBatch::with_schema(schema, 0);
                append_frame(&spill_path(folder, level, *cell), &frame)
            })
    }
}

/// Appends a spill frame to the file at `path` (made if missing).
pub(super) fn append_frame(path: &Path, frame: &[u8]) -> Result<()> {
    std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .and_then(|mut f| f.write_all(frame))
        .map_err(|e| Error::io(path, e))
}
