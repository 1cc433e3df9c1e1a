//! Builds beyond one machine (issue 18): a plan, its parts built anywhere, and the merge.
//!
//! A one-machine build's result depends on the root cube, the chunk level, the chunk size and
//! the parameters; [`plan`] fixes them from the inputs' headers alone, with a partition level
//! `P` (at most the chunk level) whose occupied cells are split into runs of about equal
//! estimated points, in Morton order. A part ([`build_part`]: `convert` with the plan's options)
//! reads only the inputs whose bounds meet its cells, keeps the points in its cells, and builds exactly what a
//! one-machine build builds there: the chunks below `P` and the levels between them and `P`. It
//! writes that as a dataset of its own (its own levels above `P` too, so that it can be viewed
//! and verified alone) and, in a `.tops` file next to it, its level-`P` nodes as they were before
//! any level above took points from them. [`merge`] links every part's pages below `P` where
//! they are (or copies them, without decoding them) and builds the levels above `P` from the
//! tops as `convert` does: the result has the same nodes with the same points, page for page, as
//! `convert --plan` on one machine. Which LAZ chunks each part reads: `chunks.rs`; the chunks
//! that several parts read decompressed once, before the parts (the exchange): `exchange.rs`;
//! the merge: `merge.rs`; what the drivers that run parts elsewhere need of a plan (an array
//! task's part, the byte ranges a part reads): `driver.rs`; the Slurm driver: `slurm.rs`.
//!
//! Octree and layered structures only: kd and mwkd trees group chunks across the whole scan.

mod chunks;
mod driver;
mod exchange;
mod merge;
pub mod slurm;
mod tops;

pub use driver::{part_index, ranges_read};
pub use exchange::{ScatterSummary, exchange_dir, scatter};
pub use merge::{MergeSummary, merge};

pub use chunks::ChunkedInput;
use chunks::choose_runs;

use crate::above::Above;
use crate::append::cell_of;
use crate::convert::{self, Planned, Report, Structure};
use crate::distribute::{self, Grid, SPILL_PREFIX};
use crate::nested::NestedParams;
use myriad_core::{Aabb, Error, NodeKey, Result};
use myriad_format::{Dataset, DatasetWriter, Metadata};
use myriad_io::OpenOptions;
use rayon::prelude::*;
use serde_json::{Value, json};
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::time::Instant;

const PLAN_FORMAT: u64 = 1;

/// The most parts a plan makes.
pub const MAX_PARTS: usize = 1 << 20;
/// Deepest partition level (8^8 cells).
const MAX_PARTITION_LEVEL: u32 = 8;

/// What `myriad plan` is given: the inputs, the number of parts, and convert's options.
#[derive(Debug, Clone)]
pub struct PlanOptions {
    pub parts: usize,
    pub structure: Structure,
    pub params: NestedParams,
    /// Memory budget of each part, in bytes.
    pub memory: u64,
    /// Threads of each part (they size the chunks, as in `convert`).
    pub threads: usize,
    pub precision: f64,
    /// How the inputs are opened (text columns, placements), as the parts will.
    pub open: OpenOptions,
    pub chunk_points: Option<u64>,
    /// Find which LAZ chunks meet which part (a pass over the coordinates of the inputs that
    /// several parts read), so that each part decompresses only those.
    pub chunks: bool,
    /// Where the chunks' bounds are kept between plans (`PLAN.chunks.json`); `None`: not kept.
    pub chunk_cache: Option<PathBuf>,
}

/// One input as the plan saw its header.
#[derive(Debug, Clone)]
pub struct PlannedInput {
    pub path: PathBuf,
    pub points: u64,
    pub bounds: Aabb,
}

/// A plan: everything the parts and the merge must agree on.
#[derive(Debug, Clone)]
pub struct BuildPlan {
    pub id: String,
    pub inputs: Vec<PlannedInput>,
    pub structure: Structure,
    pub params: NestedParams,
    pub memory: u64,
    /// Worker threads of each part (as the chunks were sized for).
    pub threads: usize,
    pub chunk_points: u64,
    pub chunk_level: u32,
    pub partition_level: u32,
    /// Each part's cells at the partition level, in Morton order, and its estimated points.
    pub parts: Vec<(Vec<[u32; 3]>, u64)>,
    /// The dataset's metadata as far as the plan knows it (root, grid, schema, CRS, LAS header).
    pub dataset: Metadata,
    pub columns: Option<String>,
    pub placements: bool,
    pub precision: f64,
    /// `--to-crs` and `--from-crs`: every part moves its points the same way.
    pub reproject: Option<myriad_io::reproject::Reproject>,
    /// The LAZ inputs that meet more than one part, each part's chunks of them.
    pub chunked: Vec<ChunkedInput>,
}

/// A cell's Morton code with x most significant (the plans' order since they were first
/// written).
fn morton(c: [u32; 3]) -> u64 {
    myriad_core::geometry::morton(c[2], c[1], c[0])
}

/// FNV-1a of the text: a plan's identity (not a security measure; it catches mixed-up plans).
fn fingerprint(text: &str) -> String {
    let mut h = 0xcbf29ce484222325u64;
    for b in text.bytes() {
        h = (h ^ b as u64).wrapping_mul(0x100000001b3);
    }
    format!("{h:016x}")
}

/// The fraction of `b` inside `cell` (by extent per axis; an axis `b` is flat on counts whole
/// where it lies in the cell).
fn overlap(b: &Aabb, cell: &Aabb) -> f64 {
    let mut f = 1.0;
    for a in 0..3 {
        let (lo, hi) = (b.min[a].max(cell.min[a]), b.max[a].min(cell.max[a]));
        let len = b.max[a] - b.min[a];
        f *= if len <= 0.0 {
            if b.min[a] >= cell.min[a] && b.min[a] <= cell.max[a] {
                1.0
            } else {
                0.0
            }
        } else {
            ((hi - lo) / len).max(0.0)
        };
    }
    f
}

/// The cells of `level` under `root` that `b` meets.
fn cells_meeting(root: &Aabb, level: u32, b: &Aabb) -> Vec<[u32; 3]> {
    let (lo, hi) = (
        cell_of(root, level, b.min).cell,
        cell_of(root, level, b.max).cell,
    );
    let mut out = Vec::new();
    for x in lo[0]..=hi[0] {
        for y in lo[1]..=hi[1] {
            for z in lo[2]..=hi[2] {
                out.push([x, y, z]);
            }
        }
    }
    out
}

/// Splits `cells` (Morton order, with estimated points) into `parts` runs of about equal sums.
fn runs(cells: &[([u32; 3], f64)], parts: usize) -> Vec<(Vec<[u32; 3]>, u64)> {
    let total: f64 = cells.iter().map(|c| c.1).sum();
    let mut out: Vec<(Vec<[u32; 3]>, f64)> = vec![(Vec::new(), 0.0); parts];
    let mut acc = 0.0;
    let mut part = 0;
    for (i, &(c, n)) in cells.iter().enumerate() {
        // Move to the next run once this one has its share, keeping a cell for each run left.
        let left = cells.len() - i;
        if part + 1 < parts
            && !out[part].0.is_empty()
            && (acc >= total * (part + 1) as f64 / parts as f64 || left < parts - part)
        {
            part += 1;
        }
        out[part].0.push(c);
        out[part].1 += n;
        acc += n;
    }
    out.into_iter()
        .map(|(c, n)| (c, n.round() as u64))
        .collect()
}

/// Each input's estimated points in each cell of `level` that its bounds meet (its points
/// spread evenly over its bounds).
fn shares(
    root: &Aabb,
    level: u32,
    inputs: &[PlannedInput],
) -> std::collections::HashMap<[u32; 3], Vec<(usize, f64)>> {
    let mut share: std::collections::HashMap<[u32; 3], Vec<(usize, f64)>> = Default::default();
    for (k, i) in inputs.iter().enumerate() {
        if i.points == 0 {
            continue;
        }
        let meet = cells_meeting(root, level, &i.bounds);
        let key = |c: [u32; 3]| NodeKey { level, cell: c }.bounds(root);
        let w: Vec<f64> = meet.iter().map(|&c| overlap(&i.bounds, &key(c))).collect();
        let sum: f64 = w.iter().sum();
        for (c, w) in meet.into_iter().zip(w) {
            if sum > 0.0 && w > 0.0 {
                share
                    .entry(c)
                    .or_default()
                    .push((k, i.points as f64 * w / sum));
            }
        }
    }
    share
}

/// The candidate runs of `cells` (Morton order, with estimated points) at `level` into
/// `parts`: in Morton order; and, where it balances as well (its largest part at most 10 % over
/// Morton's), with the cells grouped by the input that holds most of their points, the inputs
/// in the Morton order of their centres, so that a part takes whole tiles where it can. Each
/// part's cells in Morton order. [`choose_runs`] takes the one that decodes fewer points.
fn candidate_runs(
    root: &Aabb,
    level: u32,
    inputs: &[PlannedInput],
    cells: &[([u32; 3], f64)],
    parts: usize,
) -> Vec<Vec<(Vec<[u32; 3]>, u64)>> {
    let by_morton = runs(cells, parts);
    if inputs.len() < 2 || parts < 2 {
        return vec![by_morton];
    }
    let share = shares(root, level, inputs);
    let largest = |r: &[(Vec<[u32; 3]>, u64)]| r.iter().map(|p| p.1).max().unwrap_or(0) as f64;
    let centre = |b: &Aabb| {
        let c = [0, 1, 2].map(|a| (b.min[a] + b.max[a]) / 2.0);
        morton(cell_of(root, level, c).cell)
    };
    let owner = |c: &[u32; 3]| {
        share.get(c).and_then(|v| {
            v.iter()
                .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
                .map(|s| s.0)
        })
    };
    let mut grouped = cells.to_vec();
    grouped.sort_by_key(|(c, _)| {
        let o = owner(c);
        (o.map(|k| centre(&inputs[k].bounds)), o, morton(*c))
    });
    let mut by_tile = runs(&grouped, parts);
    for r in &mut by_tile {
        r.0.sort_by_key(|c| morton(*c));
    }
    if largest(&by_tile) <= 1.1 * largest(&by_morton) {
        vec![by_morton, by_tile]
    } else {
        vec![by_morton]
    }
}

/// Reads the inputs' headers (an input without bounds in its header is read once for them) and
/// makes the plan.
pub fn plan(inputs: &[PathBuf], o: &PlanOptions) -> Result<BuildPlan> {
    if !matches!(o.structure, Structure::Octree | Structure::Layered) {
        return Err(Error::Invalid(format!(
            "--structure {}: a partitioned build makes octree and layered datasets (kd and mwkd \
             trees group chunks across the whole scan)",
            o.structure.name()
        )));
    }
    // A part is at least one cell of 8^8 (and, past a million parts, each a few points).
    if o.parts == 0 || o.parts > MAX_PARTS {
        return Err(Error::Invalid(format!(
            "--parts {}: between 1 and {MAX_PARTS}",
            o.parts
        )));
    }
    convert::check_memory(o.memory)?;
    convert::check_precision(o.precision)?;
    myriad_io::atomic::refuse_repeated_inputs(inputs)?;
    let mut infos = Vec::new();
    let mut planned = Vec::new();
    let mut las_header = None;
    for path in inputs {
        let mut src = myriad_io::open(path, &o.open)?;
        let info = src.info().clone();
        if las_header.is_none()
            && let Some(h) = src.las_header()
        {
            las_header = Some(myriad_io::las::header_to_bytes(h)?);
        }
        let (points, bounds) = match (info.points, info.bounds) {
            (Some(n), Some(b)) => (n, b),
            _ => myriad_io::scan(src.as_mut())?,
        };
        planned.push(PlannedInput {
            path: path.clone(),
            points,
            bounds,
        });
        infos.push(info);
    }
    let declared: u64 = planned.iter().map(|i| i.points).sum();
    if declared == 0 {
        return Err(Error::Invalid(format!(
            "{}: the inputs hold no points",
            inputs[0].display()
        )));
    }
    let bounds = planned.iter().fold(Aabb::EMPTY, |b, i| b.union(&i.bounds));
    let schema = distribute::merged_schema(&infos)?;
    let step = infos
        .iter()
        .filter_map(|i| i.scale)
        .flatten()
        .fold(0.0f64, f64::max);
    let root = distribute::root_cube(&bounds, step);
    let refs: Vec<_> = infos.iter().collect();
    let quantization = convert::quantization(&refs, &root, o.precision)?;
    let params = NestedParams {
        ntree: o.structure == Structure::Layered,
        ..o.params
    };
    let sizing = convert::plan(o.memory, o.threads.max(1), &params);
    let chunk_points = o.chunk_points.unwrap_or(sizing.chunk_points);

    // The partition level: enough occupied cells that the runs come out even (8 per part).
    let estimate = |level: u32| {
        let mut v: Vec<([u32; 3], f64)> = shares(&root, level, &planned)
            .into_iter()
            .map(|(c, s)| (c, s.iter().map(|x| x.1).sum::<f64>()))
            .filter(|c| c.1 > 0.0)
            .collect();
        v.sort_by_key(|c| morton(c.0));
        v
    };
    let mut p = 1;
    let mut cells = estimate(p);
    while cells.len() < 8 * o.parts && p < MAX_PARTITION_LEVEL {
        p += 1;
        cells = estimate(p);
    }
    let chunk_level =
        distribute::chunk_level(declared, chunk_points, 8 * sizing.threads as u64).max(p);
    let candidates = candidate_runs(&root, p, &planned, &cells, o.parts);

    let dataset = Metadata {
        structure: o.structure.stored_name().into(),
        parameters: convert::parameters(o.structure, &params, None, None),
        points: declared,
        nodes: 0,
        depth: 0,
        bounds,
        root,
        quantization,
        crs: infos.iter().find_map(|i| i.crs.clone()),
        schema,
        sources: infos
            .iter()
            .zip(&planned)
            .map(|(i, p)| convert::source(i, p.points))
            .collect(),
        las_header,
        software: format!("myriad {}", env!("CARGO_PKG_VERSION")),
        levels: Vec::new(),
        files: Vec::new(),
    };
    let mut plan = BuildPlan {
        id: String::new(),
        inputs: planned,
        structure: o.structure,
        params,
        memory: o.memory,
        threads: sizing.threads,
        chunk_points,
        chunk_level,
        partition_level: p,
        parts: Vec::new(),
        dataset,
        columns: o.open.columns.clone(),
        placements: o.open.sidecar_placements,
        precision: o.precision,
        reproject: o.open.reproject.clone(),
        chunked: Vec::new(),
    };
    (plan.parts, plan.chunked) = choose_runs(&plan, candidates, &infos, o)?;
    plan.id = fingerprint(&plan.body().to_string());
    Ok(plan)
}

impl BuildPlan {
    /// The plan as JSON, without its id.
    fn body(&self) -> Value {
        let aabb = |b: &Aabb| json!({"min": b.min, "max": b.max});
        json!({
            "myriad_plan": PLAN_FORMAT,
            "structure": self.structure.name(),
            "capacity": self.params.capacity,
            "inner_depth": self.params.inner_depth,
            "max_level": self.params.max_level,
            "memory": self.memory,
            "threads": self.threads,
            "chunk_points": self.chunk_points,
            "chunk_level": self.chunk_level,
            "partition_level": self.partition_level,
            "columns": self.columns,
            "placements": self.placements,
            "precision": self.precision,
            "to_crs": self.reproject.as_ref().map(|r| &r.to),
            "from_crs": self.reproject.as_ref().and_then(|r| r.from.as_ref()),
            "inputs": self.inputs.iter().map(|i| json!({
                "path": i.path.display().to_string(), "points": i.points, "bounds": aabb(&i.bounds),
            })).collect::<Vec<_>>(),
            "parts": self.parts.iter().map(|(c, n)| json!({
                "estimated_points": n, "cells": c,
            })).collect::<Vec<_>>(),
            "chunked": self.chunked.iter().map(|c| json!({
                "input": c.input, "chunks": c.chunks,
                "parts": c.parts.iter().map(|r| r.iter().map(|&(a, b)| [a, b]).collect::<Vec<_>>())
                    .collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
            "dataset": self.dataset.to_json(),
        })
    }

    pub fn to_json(&self) -> Value {
        let mut v = self.body();
        v["id"] = json!(self.id);
        v
    }

    /// Reads a plan written by [`BuildPlan::to_json`]; refuses one edited since (its id).
    pub fn load(path: &Path) -> Result<BuildPlan> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let bad =
            |m: String| Error::Invalid(format!("{}: not a Myriad build plan: {m}", path.display()));
        let v: Value = serde_json::from_str(&text).map_err(|e| {
            Error::Invalid(format!(
                "{}: line {}: not JSON: {e}",
                path.display(),
                e.line()
            ))
        })?;
        if v["myriad_plan"].as_u64() != Some(PLAN_FORMAT) {
            return Err(bad(format!("no \"myriad_plan\": {PLAN_FORMAT}")));
        }
        let u = |k: &str| {
            v[k].as_u64()
                .ok_or_else(|| bad(format!("\"{k}\" is not a count")))
        };
        let f3 = |x: &Value| -> Option<[f64; 3]> {
            let a = x.as_array().filter(|a| a.len() == 3)?;
            Some([a[0].as_f64()?, a[1].as_f64()?, a[2].as_f64()?])
        };
        let aabb = |x: &Value| Some(Aabb::new(f3(&x["min"])?, f3(&x["max"])?));
        let structure = Structure::parse(v["structure"].as_str().unwrap_or("")).map_err(bad)?;
        let mut inputs = Vec::new();
        for i in v["inputs"]
            .as_array()
            .ok_or_else(|| bad("no inputs".into()))?
        {
            let points = i["points"]
                .as_u64()
                .ok_or_else(|| bad("input points".into()))?;
            inputs.push(PlannedInput {
                path: PathBuf::from(i["path"].as_str().ok_or_else(|| bad("input path".into()))?),
                points,
                // An empty input has no bounds (written as nulls).
                bounds: aabb(&i["bounds"])
                    .or((points == 0).then_some(Aabb::EMPTY))
                    .ok_or_else(|| bad("input bounds".into()))?,
            });
        }
        let mut parts = Vec::new();
        for p in v["parts"]
            .as_array()
            .ok_or_else(|| bad("no parts".into()))?
        {
            let cells = p["cells"]
                .as_array()
                .ok_or_else(|| bad("part cells".into()))?
                .iter()
                .map(|c| {
                    let a = c.as_array().filter(|a| a.len() == 3)?;
                    Some([
                        a[0].as_u64()? as u32,
                        a[1].as_u64()? as u32,
                        a[2].as_u64()? as u32,
                    ])
                })
                .collect::<Option<Vec<_>>>()
                .ok_or_else(|| bad("a part's cell is not 3 integers".into()))?;
            parts.push((cells, p["estimated_points"].as_u64().unwrap_or(0)));
        }
        let mut chunked = Vec::new();
        for c in v["chunked"].as_array().map_or(&[][..], |a| a.as_slice()) {
            let bad_chunks = || bad("a chunked input is not {input, chunks, parts}".into());
            let n = |x: &Value| x.as_u64().and_then(|n| u32::try_from(n).ok());
            let input = c["input"].as_u64().ok_or_else(bad_chunks)? as usize;
            let chunks = n(&c["chunks"]).ok_or_else(bad_chunks)?;
            let mut per_part = Vec::new();
            for r in c["parts"].as_array().ok_or_else(bad_chunks)? {
                let mut v = Vec::new();
                for pair in r.as_array().ok_or_else(bad_chunks)? {
                    let (a, b) = (
                        n(&pair[0]).ok_or_else(bad_chunks)?,
                        n(&pair[1]).ok_or_else(bad_chunks)?,
                    );
                    if a >= b || b > chunks || v.last().is_some_and(|l: &(u32, u32)| l.1 > a) {
                        return Err(bad_chunks());
                    }
                    v.push((a, b));
                }
                per_part.push(v);
            }
            if input >= inputs.len() || per_part.len() != parts.len() {
                return Err(bad_chunks());
            }
            chunked.push(ChunkedInput {
                input,
                chunks,
                parts: per_part,
            });
        }
        let partition_level = u("partition_level")? as u32;
        let chunk_level = u("chunk_level")? as u32;
        if partition_level > chunk_level || parts.is_empty() {
            return Err(bad(
                "partition level above the chunk level, or no parts".into()
            ));
        }
        let plan = BuildPlan {
            id: v["id"].as_str().unwrap_or("").to_string(),
            inputs,
            structure,
            params: NestedParams {
                capacity: u("capacity")? as usize,
                inner_depth: u("inner_depth")? as u32,
                max_level: u("max_level")? as u32,
                ntree: structure == Structure::Layered,
            },
            memory: u("memory")?,
            threads: u("threads")?.max(1) as usize,
            chunk_points: u("chunk_points")?,
            chunk_level,
            partition_level,
            parts,
            dataset: Metadata::from_json(&v["dataset"]).map_err(bad)?,
            columns: v["columns"].as_str().map(String::from),
            placements: v["placements"].as_bool().unwrap_or(true),
            precision: v["precision"].as_f64().unwrap_or(1e-4),
            reproject: v["to_crs"]
                .as_str()
                .map(|to| myriad_io::reproject::Reproject {
                    to: to.to_string(),
                    from: v["from_crs"].as_str().map(String::from),
                }),
            chunked,
        };
        if plan.id != fingerprint(&plan.body().to_string()) {
            return Err(Error::Invalid(format!(
                "{}: the plan was edited after it was made (its id does not match): make it \
                 again with `myriad plan`",
                path.display()
            )));
        }
        Ok(plan)
    }

    /// The open options the plan's inputs are read with.
    pub fn open_options(&self) -> OpenOptions {
        OpenOptions {
            columns: self.columns.clone(),
            sidecar_placements: self.placements,
            reproject: self.reproject.clone(),
            ..Default::default()
        }
    }

    /// The inputs whose bounds meet part `index`'s cells (all inputs for `None`: the whole plan).
    pub fn inputs_of(&self, index: Option<usize>) -> Vec<PathBuf> {
        let root = &self.dataset.root;
        let cells: Option<HashSet<[u32; 3]>> =
            index.map(|i| self.parts[i].0.iter().copied().collect());
        self.inputs
            .iter()
            .enumerate()
            .filter(|(k, i)| {
                match (
                    &cells,
                    index.and_then(|p| Some((p, self.chunked_input(*k)?))),
                ) {
                    (None, _) => true,
                    // Chunked: the part reads it where some of its chunks meet the part's cells.
                    (Some(_), Some((p, c))) => !c.parts[p].is_empty(),
                    (Some(set), None) => {
                        // The header's bounds with a margin for rounding to the scale.
                        let m = root.size()[0] * 1e-5;
                        let b = Aabb::new(i.bounds.min.map(|v| v - m), i.bounds.max.map(|v| v + m));
                        cells_meeting(root, self.partition_level, &b)
                            .iter()
                            .any(|c| set.contains(c))
                    }
                }
            })
            .map(|(_, i)| i.path.clone())
            .collect()
    }

    /// The chunks of input `k` that each part reads, where the parts read some of them.
    pub fn chunked_input(&self, k: usize) -> Option<&ChunkedInput> {
        self.chunked.iter().find(|c| c.input == k)
    }

    /// `convert`'s options for part `index` (`None`: the whole plan on one machine), written to
    /// `output`.
    pub fn convert_options(
        &self,
        index: Option<usize>,
        output: &Path,
        threads: usize,
    ) -> convert::ConvertOptions {
        let mut o = convert::ConvertOptions::new(output);
        o.structure = self.structure;
        o.memory = self.memory;
        o.threads = threads;
        o.precision = self.precision;
        o.params = self.params;
        o.open = self.open_options();
        if let Some(i) = index {
            o.open.laz_chunks = Some(std::sync::Arc::new(
                self.chunked
                    .iter()
                    .map(|c| (self.inputs[c.input].path.clone(), c.of(i)))
                    .collect(),
            ));
        }
        o.chunk_points = Some(self.chunk_points);
        o.force = true;
        let p = self.partition_level;
        o.planned = Some(Planned {
            grid: Grid {
                root: self.dataset.root,
                level: self.chunk_level,
                schema: self.dataset.schema.clone(),
                cells: index.map(|i| (p, self.parts[i].0.iter().copied().collect())),
            },
            quantization: self.dataset.quantization,
            crs: self.dataset.crs.clone(),
            las_header: self.dataset.las_header.clone(),
            tops_level: index.map(|_| p),
            parameters: match index {
                Some(i) => json!({"plan": self.id, "part": i, "parts": self.parts.len(),
                                  "partition_level": p}),
                None => json!({"plan": self.id}),
            },
        });
        o
    }
}

/// The files of part `index` in `dir`.
pub fn part_paths(dir: &Path, index: usize) -> (PathBuf, PathBuf) {
    (
        dir.join(format!("part-{index}.myr")),
        dir.join(format!("part-{index}.tops")),
    )
}

/// What a part built, besides its dataset: written as the head of its `.tops` file.
#[derive(Debug, Clone)]
pub struct PartSummary {
    pub points: u64,
    pub bounds: Aabb,
    /// Per input of the plan: points taken into this part and points read (`None`: not opened).
    pub inputs: Vec<Option<(u64, u64)>>,
    pub skipped_non_finite: u64,
    pub trimmed: u64,
    pub seconds: f64,
    pub bytes: u64,
    pub nodes: u64,
}

/// Builds part `index` of `plan` into `dir` (`part-I.myr` and `part-I.tops`), replacing what a
/// previous run of it left. A part whose cells hold no points writes only its `.tops`. With
/// `exchanged`, the part reads its points of the chunked inputs from what the plan's scatter
/// tasks wrote in `dir` ([`scatter`]), which must all have run, instead of decompressing chunks.
pub fn build_part(
    plan: &BuildPlan,
    index: usize,
    dir: &Path,
    threads: usize,
    exchanged: bool,
    report: &dyn Report,
) -> Result<PartSummary> {
    if index >= plan.parts.len() {
        return Err(Error::Invalid(format!(
            "--part {index}: the plan has parts 0 to {}",
            plan.parts.len() - 1
        )));
    }
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let (myr, tops_path) = part_paths(dir, index);
    let inputs = plan.inputs_of(Some(index));
    let mut summary = PartSummary {
        points: 0,
        bounds: Aabb::EMPTY,
        inputs: vec![None; plan.inputs.len()],
        skipped_non_finite: 0,
        trimmed: 0,
        seconds: 0.0,
        bytes: 0,
        nodes: 0,
    };
    let start = Instant::now();
    let mut top_nodes = Vec::new();
    if !inputs.is_empty() {
        let mut o = plan.convert_options(Some(index), &myr, threads);
        if exchanged && !plan.chunked.is_empty() {
            o.open.exchanged = Some(std::sync::Arc::new(exchange::files_of(plan, index, dir)?));
        }
        let s = convert::convert(&inputs, &o, report)?;
        for (path, taken, read) in &s.sources {
            let i = plan
                .inputs
                .iter()
                .position(|p| &p.path == path)
                .expect("a part opens the plan's inputs");
            summary.inputs[i] = Some((*taken, *read));
        }
        summary.points = s.points;
        summary.bounds = s.bounds;
        summary.skipped_non_finite = s.skipped_non_finite;
        summary.trimmed = s.trimmed;
        summary.bytes = s.bytes;
        summary.nodes = s.nodes;
        top_nodes = s.tops;
    }
    if summary.points == 0 {
        // Nothing here: no dataset (a previous run's is removed: it cannot have had points).
        let _ = std::fs::remove_file(&myr);
    }
    summary.seconds = start.elapsed().as_secs_f64();
    tops::write(&tops_path, plan, index, &summary, &top_nodes)?;
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_are_even_and_in_order() {
        let cells: Vec<([u32; 3], f64)> = (0..40u32).map(|i| ([i, 0, 0], 10.0)).collect();
        let r = runs(&cells, 4);
        assert_eq!(r.len(), 4);
        assert!(r.iter().all(|(c, n)| c.len() == 10 && *n == 100), "{r:?}");
        let flat: Vec<_> = r.iter().flat_map(|(c, _)| c.clone()).collect();
        assert_eq!(flat, cells.iter().map(|c| c.0).collect::<Vec<_>>());
        // Fewer cells than parts: the last parts are empty, none has two cells.
        let r = runs(&cells[..3], 5);
        assert_eq!(
            r.iter().map(|(c, _)| c.len()).collect::<Vec<_>>(),
            [1, 1, 1, 0, 0]
        );
        // One heavy cell first: it is a run alone.
        let mut cells = cells;
        cells[0].1 = 1000.0;
        let r = runs(&cells, 2);
        assert_eq!(r[0].0.len(), 1);
    }

    /// Eight tiles of 0.6 x 0.5 in a row of four by two over a cube of side 3, split into 4
    /// parts: the cells of level 3 (0.375 wide) cut the tiles; grouped by tile, fewer of each
    /// tile's points lie outside the part that holds most of it than in Morton order.
    #[test]
    fn runs_follow_the_tiles_where_they_balance() {
        let root = Aabb::new([0.0; 3], [3.0; 3]);
        let inputs: Vec<PlannedInput> = (0..8)
            .map(|k| {
                let (x, y) = ((k % 4) as f64 * 0.6, (k / 4) as f64 * 0.5);
                PlannedInput {
                    path: format!("t{k}.laz").into(),
                    points: 1000,
                    bounds: Aabb::new([x, y, 0.0], [x + 0.6, y + 0.5, 0.1]),
                }
            })
            .collect();
        let level = 3;
        let share = shares(&root, level, &inputs);
        let mut cells: Vec<([u32; 3], f64)> = share
            .iter()
            .map(|(c, s)| (*c, s.iter().map(|x| x.1).sum()))
            .collect();
        cells.sort_by_key(|c| morton(c.0));
        // Each tile's points outside the part that holds most of them: what other parts must
        // decode of it.
        let spread = |r: &[(Vec<[u32; 3]>, u64)]| -> f64 {
            (0..inputs.len())
                .map(|k| {
                    let per_part: Vec<f64> = r
                        .iter()
                        .map(|(cs, _)| {
                            cs.iter()
                                .flat_map(|c| share[c].iter().filter(|s| s.0 == k))
                                .map(|s| s.1)
                                .sum()
                        })
                        .collect();
                    per_part.iter().sum::<f64>() - per_part.iter().copied().fold(0.0, f64::max)
                })
                .sum()
        };
        let morton_runs = runs(&cells, 4);
        let c = candidate_runs(&root, level, &inputs, &cells, 4);
        assert_eq!(c.len(), 2);
        assert_eq!(c[0], morton_runs);
        let tiled = c[1].clone();
        assert!(
            spread(&tiled) < spread(&morton_runs),
            "{} points outside their tile's part, Morton {}",
            spread(&tiled),
            spread(&morton_runs)
        );
        // Every cell in one part, the parts within 10 % of Morton's largest.
        let mut all: Vec<[u32; 3]> = tiled.iter().flat_map(|p| p.0.clone()).collect();
        all.sort_by_key(|c| morton(*c));
        assert_eq!(all, cells.iter().map(|c| c.0).collect::<Vec<_>>());
        let max = |r: &[(Vec<[u32; 3]>, u64)]| r.iter().map(|p| p.1).max().unwrap() as f64;
        assert!(max(&tiled) <= 1.1 * max(&morton_runs));
        // Each part's cells in Morton order.
        assert!(tiled.iter().all(|p| p.0.is_sorted_by_key(|c| morton(*c))));
    }

    #[test]
    fn overlap_of_flat_bounds() {
        let cell = Aabb::new([0.0; 3], [1.0; 3]);
        let flat = Aabb::new([0.5, 0.0, 0.5], [1.5, 1.0, 0.5]);
        assert_eq!(overlap(&flat, &cell), 0.5);
        let away = Aabb::new([0.5, 0.0, 2.0], [1.5, 1.0, 2.0]);
        assert_eq!(overlap(&away, &cell), 0.0);
    }
}
