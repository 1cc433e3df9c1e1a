//! The exchange: every LAZ chunk that several parts read is decompressed once. Before the parts,
//! the plan's scatter tasks ([`scatter`]) split those chunks between them (runs in input and
//! chunk order, about as many chunks each) and copy each record, as it is, to a file of the part
//! whose cell holds it (`DIR/exchange/tT-iK-pI.rec`: task T, input K, part I); a task's
//! manifest (`tT.json`, written last) says how many bytes each file holds. A part built with
//! the exchange ([`super::build_part`]) then reads its records of those inputs from the tasks'
//! files in task order instead of decompressing chunks: the same points in the same order, so
//! the same dataset. The merge removes the folder.
//!
//! Records are copied, not decoded: a task decompresses and reads three coordinates a point; the
//! files hold raw records (their point format's size a point, uncompressed), on the filesystem
//! the parts share.

use super::*;
use std::collections::HashMap;
use std::io::Write;

const MANIFEST_FORMAT: u64 = 1;

/// What a scatter task did.
#[derive(Debug, Clone)]
pub struct ScatterSummary {
    /// Points decompressed.
    pub read: u64,
    /// Points written for each part.
    pub routed: Vec<u64>,
    /// Points in no part's cells (no part keeps them, as without the exchange).
    pub outside: u64,
    pub seconds: f64,
}

/// The exchange folder of the parts' folder `dir`.
pub fn exchange_dir(dir: &Path) -> PathBuf {
    dir.join("exchange")
}

fn records_path(dir: &Path, task: usize, input: usize, part: usize) -> PathBuf {
    exchange_dir(dir).join(format!("t{task}-i{input}-p{part}.rec"))
}

fn manifest_path(dir: &Path, task: usize) -> PathBuf {
    exchange_dir(dir).join(format!("t{task}.json"))
}

impl BuildPlan {
    /// The scatter tasks, as many as parts: the chunks that some part reads of each chunked
    /// input, in input and chunk order, cut into runs of about equal numbers of chunks. Each
    /// task: its inputs (plan indices) with their chunks.
    pub fn scatter_tasks(&self) -> Vec<Vec<(usize, Vec<u32>)>> {
        let mut all: Vec<(usize, u32)> = Vec::new();
        for c in &self.chunked {
            let mut read: Vec<u32> = (0..self.parts.len()).flat_map(|p| c.of(p)).collect();
            read.sort_unstable();
            read.dedup();
            all.extend(read.into_iter().map(|k| (c.input, k)));
        }
        let tasks = self.parts.len();
        (0..tasks)
            .map(|t| {
                let run = &all[all.len() * t / tasks..all.len() * (t + 1) / tasks];
                let mut out: Vec<(usize, Vec<u32>)> = Vec::new();
                for &(input, chunk) in run {
                    match out.last_mut() {
                        Some((i, v)) if *i == input => v.push(chunk),
                        _ => out.push((input, vec![chunk])),
                    }
                }
                out
            })
            .collect()
    }

    /// Which part each cell of the partition level belongs to.
    fn owners(&self) -> HashMap<[u32; 3], usize> {
        (self.parts.iter().enumerate())
            .flat_map(|(k, (cells, _))| cells.iter().map(move |&c| (c, k)))
            .collect()
    }
}

/// Per part, a buffer of records and the file it is appended to.
struct Routes {
    dir: PathBuf,
    task: usize,
    input: usize,
    buffers: Vec<Vec<u8>>,
    /// Bytes written to each part's file so far.
    written: Vec<u64>,
    flush_at: usize,
}

impl Routes {
    fn new(dir: &Path, task: usize, input: usize, parts: usize) -> Routes {
        Routes {
            dir: dir.to_path_buf(),
            task,
            input,
            buffers: vec![Vec::new(); parts],
            written: vec![0; parts],
            // 64 MB of buffers in all, 64 KB to 4 MB each.
            flush_at: ((64 << 20) / parts.max(1)).clamp(64 << 10, 4 << 20),
        }
    }

    fn push(&mut self, part: usize, record: &[u8]) -> Result<()> {
        self.buffers[part].extend_from_slice(record);
        if self.buffers[part].len() >= self.flush_at {
            self.flush(part)?;
        }
        Ok(())
    }

    /// Appends part `part`'s buffer to its file (made afresh at its first write).
    fn flush(&mut self, part: usize) -> Result<()> {
        if self.buffers[part].is_empty() {
            return Ok(());
        }
        let path = records_path(&self.dir, self.task, self.input, part);
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .write(true)
            .append(self.written[part] > 0)
            .truncate(self.written[part] == 0)
            .open(&path)
            .map_err(|e| Error::io(&path, e))?;
        f.write_all(&self.buffers[part])
            .map_err(|e| Error::io(&path, e))?;
        self.written[part] += self.buffers[part].len() as u64;
        self.buffers[part].clear();
        Ok(())
    }

    fn finish(mut self) -> Result<Vec<u64>> {
        for part in 0..self.buffers.len() {
            self.flush(part)?;
        }
        Ok(self.written)
    }
}

/// Scatter task `task` of `plan`: decompresses its chunks and writes each record to the file of
/// the part whose cell holds it, in `dir/exchange`, then its manifest. Replaces what an earlier
/// run of it wrote.
pub fn scatter(
    plan: &BuildPlan,
    task: usize,
    dir: &Path,
    report: &dyn Report,
) -> Result<ScatterSummary> {
    let start = Instant::now();
    let tasks = plan.scatter_tasks();
    if task >= tasks.len() {
        return Err(Error::Invalid(format!(
            "--scatter {task}: the plan has scatter tasks 0 to {}",
            tasks.len() - 1
        )));
    }
    let folder = exchange_dir(dir);
    std::fs::create_dir_all(&folder).map_err(|e| Error::io(&folder, e))?;
    let manifest = manifest_path(dir, task);
    match std::fs::remove_file(&manifest) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            return Err(Error::io(&manifest, e));
        }
        _ => {}
    }
    let owners = plan.owners();
    let (root, level, p) = (&plan.dataset.root, plan.chunk_level, plan.partition_level);
    let parts = plan.parts.len();
    let mut summary = ScatterSummary {
        read: 0,
        routed: vec![0; parts],
        outside: 0,
        seconds: 0.0,
    };
    let mut sources = Vec::new();
    for (input, chunks) in &tasks[task] {
        let mut src = myriad_io::las::LasSource::open(&plan.inputs[*input].path)?;
        src.keep_chunks(chunks)?;
        sources.push((*input, src));
    }
    let total = sources
        .iter()
        .map(|(_, s)| myriad_io::PointSource::info(s).points.unwrap_or(0))
        .sum();
    report.phase("scatter", total);
    let mut entries = Vec::new();
    let mut clamped = 0u64;
    for (input, mut src) in sources {
        let mut routes = Routes::new(dir, task, input, parts);
        let (len, position) = (src.record_len(), src.position_of());
        while let Some(records) = src.next_records()? {
            for r in records.chunks_exact(len) {
                let c = crate::distribute::cell_of(root, level, position(r), &mut clamped);
                match owners.get(&c.map(|v| v >> (level - p))) {
                    Some(&part) => {
                        routes.push(part, r)?;
                        summary.routed[part] += 1;
                    }
                    None => summary.outside += 1,
                }
            }
            let n = (records.len() / len) as u64;
            summary.read += n;
            report.advance(n);
        }
        let written = routes.finish()?;
        entries.push(json!({"input": input, "record_length": len, "bytes": written}));
    }
    summary.seconds = start.elapsed().as_secs_f64();
    let text = json!({
        "myriad_exchange": MANIFEST_FORMAT, "plan": plan.id, "task": task,
        "inputs": entries, "read": summary.read, "outside": summary.outside,
    })
    .to_string();
    let file = myriad_io::atomic::AtomicFile::create(&manifest, true)?;
    std::fs::write(file.temp_path(), text).map_err(|e| Error::io(&manifest, e))?;
    file.commit()?;
    Ok(summary)
}

/// The files part `index` reads instead of each chunked input's chunks, in task order, from the
/// manifests of the scatter tasks that read the input (each checked: from this plan, its files
/// as long as it says).
pub(super) fn files_of(
    plan: &BuildPlan,
    index: usize,
    dir: &Path,
) -> Result<HashMap<PathBuf, Vec<PathBuf>>> {
    let mut out: HashMap<PathBuf, Vec<PathBuf>> = plan
        .chunked
        .iter()
        .map(|c| (plan.inputs[c.input].path.clone(), Vec::new()))
        .collect();
    for (task, inputs) in plan.scatter_tasks().iter().enumerate() {
        if inputs.is_empty() {
            continue;
        }
        let path = manifest_path(dir, task);
        let text = std::fs::read_to_string(&path).map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                Error::Invalid(format!(
                    "{}: missing: scatter task {task} has not run (myriad convert --plan PLAN \
                     --scatter {task} -o {})",
                    path.display(),
                    dir.display()
                ))
            } else {
                Error::io(&path, e)
            }
        })?;
        let bad = |m: &str| Error::Invalid(format!("{}: {m}", path.display()));
        let v: Value = serde_json::from_str(&text).map_err(|_| bad("not a scatter manifest"))?;
        if v["myriad_exchange"].as_u64() != Some(MANIFEST_FORMAT) {
            return Err(bad("not a scatter manifest"));
        }
        if v["plan"].as_str() != Some(&plan.id) {
            return Err(bad(&format!(
                "written for plan {}, not {}: run the scatter tasks of this plan again",
                v["plan"], plan.id
            )));
        }
        for (input, _) in inputs {
            let e = (v["inputs"].as_array().into_iter().flatten())
                .find(|e| e["input"].as_u64() == Some(*input as u64))
                .ok_or_else(|| bad(&format!("no records of input {input}")))?;
            let bytes = e["bytes"]
                .as_array()
                .and_then(|b| b.get(index))
                .and_then(Value::as_u64)
                .ok_or_else(|| bad(&format!("no byte count for part {index}")))?;
            if bytes == 0 {
                continue;
            }
            let file = records_path(dir, task, *input, index);
            let len = std::fs::metadata(&file)
                .map_err(|e| Error::io(&file, e))?
                .len();
            if len != bytes {
                return Err(Error::at_byte(
                    &file,
                    len.min(bytes),
                    format!("{len} bytes, but scatter task {task} wrote {bytes}: run it again"),
                ));
            }
            out.get_mut(&plan.inputs[*input].path)
                .expect("a scatter task reads chunked inputs")
                .push(file);
        }
    }
    Ok(out)
}
