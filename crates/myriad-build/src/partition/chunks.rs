//! Which LAZ chunks each part of a plan reads: the chunks' bounds from a pass over the inputs'
//! coordinates (kept beside the plan in `PLAN.chunks.json`), the parts each chunk's bounds meet,
//! and the choice between the candidate runs of cells by the points the parts would decode.

use super::*;

/// A LAZ input that several parts read: the chunks (of its chunk table) whose points meet each
/// part's cells, found by [`myriad_io::las::chunk_bounds`] when the plan was made. A part
/// decompresses only its chunks; a chunk whose bounds meet several parts' cells is read by each.
#[derive(Debug, Clone, PartialEq)]
pub struct ChunkedInput {
    /// The input's index in the plan.
    pub input: usize,
    /// Its chunks, and its points.
    pub chunks: u32,
    /// Per part: half-open ranges of chunk indices, ascending.
    pub parts: Vec<Vec<(u32, u32)>>,
}

impl ChunkedInput {
    /// The chunk indices part `part` reads.
    pub fn of(&self, part: usize) -> Vec<u32> {
        self.parts[part].iter().flat_map(|&(a, b)| a..b).collect()
    }
}

/// Ascending indices as half-open ranges.
fn ranges(indices: &[u32]) -> Vec<(u32, u32)> {
    let mut out: Vec<(u32, u32)> = Vec::new();
    for &i in indices {
        match out.last_mut() {
            Some(r) if r.1 == i => r.1 += 1,
            _ => out.push((i, i + 1)),
        }
    }
    out
}

/// The parts whose cells (`owner`: cell to part, at `level`) the box `b` meets, with a margin
/// for rounding (as [`BuildPlan::inputs_of`]).
fn parts_meeting(
    root: &Aabb,
    level: u32,
    owner: &std::collections::HashMap<[u32; 3], usize>,
    b: &Aabb,
) -> Vec<usize> {
    if b.is_empty() {
        return Vec::new();
    }
    let m = root.size()[0] * 1e-5;
    let b = Aabb::new(b.min.map(|v| v - m), b.max.map(|v| v + m));
    let (lo, hi) = (
        cell_of(root, level, b.min).cell,
        cell_of(root, level, b.max).cell,
    );
    let span: u64 = (0..3).map(|a| (hi[a] - lo[a]) as u64 + 1).product();
    let mut out: Vec<usize> = if span <= owner.len() as u64 {
        cells_meeting(root, level, &b)
            .iter()
            .filter_map(|c| owner.get(c).copied())
            .collect()
    } else {
        owner
            .iter()
            .filter(|(c, _)| (0..3).all(|a| c[a] >= lo[a] && c[a] <= hi[a]))
            .map(|(_, &k)| k)
            .collect()
    };
    out.sort_unstable();
    out.dedup();
    out
}

/// Of the `candidates` runs, the one whose parts decode fewer points in all (Morton's on a
/// tie), and the LAZ inputs that meet more than one of its parts with the chunks of each that
/// meet each part (their bounds from a pass over the coordinates,
/// [`myriad_io::las::chunk_bounds`], kept in the cache beside the plan). Points decoded: a
/// chunk's for each part its bounds meet, an input read whole (not LAZ, no chunk table, or
/// `o.chunks` off) for each part its bounds meet. Not chunked: inputs whose points move as
/// they are read (a placement, `--to-crs`), since their chunks' bounds in the file are not
/// where the points land.
#[allow(clippy::type_complexity)]
pub(super) fn choose_runs(
    plan: &BuildPlan,
    candidates: Vec<Vec<(Vec<[u32; 3]>, u64)>>,
    infos: &[myriad_io::SourceInfo],
    o: &PlanOptions,
) -> Result<(Vec<(Vec<[u32; 3]>, u64)>, Vec<ChunkedInput>)> {
    let root = &plan.dataset.root;
    let p = plan.partition_level;
    let owners: Vec<std::collections::HashMap<[u32; 3], usize>> = candidates
        .iter()
        .map(|runs| {
            runs.iter()
                .enumerate()
                .flat_map(|(k, (cells, _))| cells.iter().map(move |&c| (c, k)))
                .collect()
        })
        .collect();
    let chunking = o.chunks && o.parts > 1 && plan.reproject.is_none();
    let mut cache = ChunkCache::load(o.chunk_cache.as_deref());
    // Each input's chunks (their points and bounds), where some candidate has several parts
    // read it.
    let mut chunks = Vec::new();
    for (input, info) in plan.inputs.iter().zip(infos) {
        let moved = o.open.placement.is_some()
            || (o.open.sidecar_placements
                && myriad_io::placement::Placement::sidecar(&input.path).is_some());
        let shared = owners
            .iter()
            .any(|owner| parts_meeting(root, p, owner, &input.bounds).len() > 1);
        chunks.push(
            if chunking && shared && !moved && info.format == myriad_io::Format::Laz {
                cache.bounds(&input.path)?
            } else {
                None
            },
        );
    }
    cache.save()?;
    let decoded = |owner: &std::collections::HashMap<[u32; 3], usize>| -> u64 {
        plan.inputs
            .iter()
            .zip(&chunks)
            .map(|(input, c)| match c {
                Some(c) => c
                    .iter()
                    .filter(|(n, _)| *n > 0)
                    .map(|(n, b)| n * parts_meeting(root, p, owner, b).len() as u64)
                    .sum(),
                None => input.points * parts_meeting(root, p, owner, &input.bounds).len() as u64,
            })
            .sum()
    };
    let best = (0..candidates.len())
        .min_by_key(|&k| (decoded(&owners[k]), k))
        .unwrap_or(0);
    let owner = &owners[best];
    let mut chunked = Vec::new();
    for (k, (input, c)) in plan.inputs.iter().zip(&chunks).enumerate() {
        let Some(c) = c else { continue };
        if parts_meeting(root, p, owner, &input.bounds).len() < 2 {
            continue; // one part reads it whole
        }
        let mut per_part: Vec<Vec<u32>> = vec![Vec::new(); o.parts];
        for (i, (n, b)) in c.iter().enumerate() {
            if *n > 0 {
                for part in parts_meeting(root, p, owner, b) {
                    per_part[part].push(i as u32);
                }
            }
        }
        chunked.push(ChunkedInput {
            input: k,
            chunks: c.len() as u32,
            parts: per_part.iter().map(|v| ranges(v)).collect(),
        });
    }
    let mut candidates = candidates;
    Ok((candidates.swap_remove(best), chunked))
}

/// The chunks' bounds of LAZ inputs, kept in a file beside the plan (`PLAN.chunks.json`) so
/// that a plan made again (other parts, other options) does not pass over the inputs again. An
/// entry holds while its input's size and modification time are those it was made from; a
/// cache that cannot be read is ignored (and written anew).
struct ChunkCache {
    path: Option<PathBuf>,
    entries: serde_json::Map<String, Value>,
    changed: bool,
}

/// The size and modification time (nanoseconds) an input's cached entry was made from.
fn stamp(path: &Path) -> Result<(u64, u128)> {
    let m = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    let t = m
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    Ok((m.len(), t))
}

impl ChunkCache {
    fn load(path: Option<&Path>) -> ChunkCache {
        let entries = path
            .and_then(|p| std::fs::read_to_string(p).ok())
            .and_then(|t| serde_json::from_str::<Value>(&t).ok())
            .filter(|v| v["myriad_chunk_bounds"] == json!(1))
            .and_then(|v| v["inputs"].as_object().cloned())
            .unwrap_or_default();
        ChunkCache {
            path: path.map(Path::to_path_buf),
            entries,
            changed: false,
        }
    }

    /// The bounds and points of each chunk of `path` (`None`: no chunk table), from the cache
    /// when it holds them for the file as it is, else from a pass over the file.
    fn bounds(&mut self, path: &Path) -> Result<Option<Vec<(u64, Aabb)>>> {
        let key = path.display().to_string();
        let (size, modified) = stamp(path)?;
        let e = &self.entries.get(&key);
        if let Some(e) = e
            && e["size"].as_u64() == Some(size)
            && e["modified"].as_str() == Some(&modified.to_string())
        {
            let parse = |c: &Value| -> Option<(u64, Aabb)> {
                let a = c.as_array().filter(|a| a.len() == 7)?;
                let f = |i: usize| a[i].as_f64();
                Some((
                    a[0].as_u64()?,
                    Aabb::new([f(1)?, f(2)?, f(3)?], [f(4)?, f(5)?, f(6)?]),
                ))
            };
            if e["chunks"].is_null() {
                return Ok(None);
            }
            if let Some(v) = e["chunks"]
                .as_array()
                .and_then(|c| c.iter().map(parse).collect())
            {
                return Ok(Some(v));
            }
        }
        let found = myriad_io::las::chunk_bounds(path)?.map(|v| {
            v.into_iter()
                .map(|(c, b)| (c.points, b))
                .collect::<Vec<_>>()
        });
        let chunks = found.as_ref().map(|v| {
            v.iter()
                .map(|(n, b)| {
                    // An empty chunk's bounds are infinite: stored as zeros (never read: it has
                    // no points to meet a part).
                    let f = |x: f64| if x.is_finite() { x } else { 0.0 };
                    json!([
                        n,
                        f(b.min[0]),
                        f(b.min[1]),
                        f(b.min[2]),
                        f(b.max[0]),
                        f(b.max[1]),
                        f(b.max[2])
                    ])
                })
                .collect::<Vec<_>>()
        });
        self.entries.insert(
            key,
            json!({"size": size, "modified": modified.to_string(), "chunks": chunks}),
        );
        self.changed = true;
        Ok(found)
    }

    fn save(&self) -> Result<()> {
        let Some(path) = self.path.as_ref().filter(|_| self.changed) else {
            return Ok(());
        };
        let text = json!({"myriad_chunk_bounds": 1, "inputs": self.entries}).to_string();
        let file = myriad_io::atomic::AtomicFile::create(path, true)?;
        std::fs::write(file.temp_path(), text).map_err(|e| Error::io(path, e))?;
        file.commit()
    }
}
