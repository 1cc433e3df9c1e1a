//! What the drivers that run a plan's parts elsewhere need from it: which part an array task
//! is ([`part_index`]: Slurm, Kubernetes indexed jobs, AWS Batch), and which byte ranges of an
//! input a part reads ([`ranges_read`]: the Ray driver stages only those from S3).

use super::BuildPlan;
use myriad_core::{Error, Result};
use std::path::Path;

/// The environment variables array jobs name their task's index in: Slurm's, a Kubernetes
/// indexed job's, AWS Batch's.
const ARRAY_INDEX: [&str; 3] = [
    "SLURM_ARRAY_TASK_ID",
    "JOB_COMPLETION_INDEX",
    "AWS_BATCH_JOB_ARRAY_INDEX",
];

/// The part (or scatter task) index `s` names, as given to option `flag`: a number, or `auto`
/// from the engine's array index.
pub fn part_index(s: &str, flag: &str) -> Result<usize> {
    if s != "auto" {
        return (s.parse())
            .map_err(|_| Error::Invalid(format!("{flag} {s:?}: an index or \"auto\"")));
    }
    for var in ARRAY_INDEX {
        if let Ok(v) = std::env::var(var) {
            return v
                .trim()
                .parse()
                .map_err(|_| Error::Invalid(format!("{flag} auto: {var}={v:?} is not an index")));
        }
    }
    Err(Error::Invalid(format!(
        "{flag} auto: none of SLURM_ARRAY_TASK_ID, JOB_COMPLETION_INDEX, \
         AWS_BATCH_JOB_ARRAY_INDEX is set (give the index)"
    )))
}

/// The byte ranges of input `path` that part `index` reads (end excluded; `None`: to the end,
/// the input read whole): for a LAZ input it reads some chunks of, everything before the first
/// chunk (header, VLRs, the chunk table's place), its chunks, and what follows the last chunk
/// (the chunk table, EVLRs).
pub fn ranges_read(plan: &BuildPlan, index: usize, path: &Path) -> Result<Vec<(u64, Option<u64>)>> {
    let k = (plan.inputs.iter().position(|i| i.path == path))
        .ok_or_else(|| Error::Invalid(format!("{}: not an input of the plan", path.display())))?;
    let Some(chunked) = plan.chunked_input(k) else {
        return Ok(vec![(0, None)]);
    };
    let src = myriad_io::las::LasSource::open(path)?;
    let table = src.chunks()?.ok_or_else(|| {
        Error::Invalid(format!(
            "{}: no LAZ chunk table (fetch the header and the chunk table first)",
            path.display()
        ))
    })?;
    let (Some(first), Some(last)) = (table.first(), table.last()) else {
        return Ok(vec![(0, None)]);
    };
    let mut out = vec![(0, Some(first.byte_at))];
    for c in chunked.of(index) {
        let c = table.get(c as usize).ok_or_else(|| {
            Error::Invalid(format!(
                "{}: chunk {c} of {} in the plan",
                path.display(),
                table.len()
            ))
        })?;
        let end = c.byte_at + c.bytes;
        match out.last_mut() {
            Some((_, Some(b))) if *b == c.byte_at => *b = end,
            _ => out.push((c.byte_at, Some(end))),
        }
    }
    out.push((last.byte_at + last.bytes, None));
    Ok(out)
}
