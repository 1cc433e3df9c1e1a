//! The merge of a plan's parts ([`merge`]): their pages below the partition level linked where
//! they are (or copied, `single_file`), the levels above built from their tops. The exchange's
//! records ([`super::scatter`]) are removed once the merged dataset is written.

use super::*;

#[derive(Debug, Clone)]
pub struct MergeSummary {
    pub points: u64,
    pub nodes: u64,
    /// Pages below the partition level, copied from the parts as they were (`single_file`)
    /// or linked where they are; nodes built (the levels above the parts).
    pub copied: u64,
    pub built: u64,
    /// Bytes of the merged file (without the parts it links).
    pub bytes: u64,
    /// Part files the dataset links (0 with `single_file`).
    pub linked: u64,
    pub seconds: f64,
}

/// Merges the parts of `plan` in `dir` into one dataset at `out`. The parts' pages below the
/// partition level stay in the parts' files, which the dataset links (by their paths relative
/// to `out`: keep them there), unless `single_file`, which copies them into `out`. Removes
/// `dir/exchange` once the dataset is written.
#[allow(clippy::too_many_arguments)]
pub fn merge(
    plan: &BuildPlan,
    dir: &Path,
    out: &Path,
    force: bool,
    single_file: bool,
    threads: usize,
    report: &dyn Report,
) -> Result<MergeSummary> {
    let start = Instant::now();
    if !force && out.exists() {
        return Err(Error::Invalid(format!(
            "{}: output exists (use --force to replace it)",
            out.display()
        )));
    }
    convert::remove_stale(out);
    let p = plan.partition_level;
    // The tops wait on disk as `convert`'s chunk roots do (one part's in memory at a time).
    let parent = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    // Removed however the merge ends.
    let spill_dir = myriad_io::claim::Folder::create(&parent, SPILL_PREFIX)?;
    // Every part there and from this plan, before anything is written.
    let mut heads = Vec::new();
    let mut pending = Vec::new();
    let mut parts = Vec::new();
    for i in 0..plan.parts.len() {
        let (myr, tops_path) = part_paths(dir, i);
        let (head, nodes) = tops::read(&tops_path, plan, i)?;
        let points = head["points"].as_u64().unwrap_or(0);
        if points > 0 {
            let ds = Dataset::open_stored(&myr)?;
            let param = &ds.meta.parameters;
            if param["plan"].as_str() != Some(plan.id.as_str())
                || param["part"].as_u64() != Some(i as u64)
                || ds.meta.points != points
            {
                return Err(Error::Invalid(format!(
                    "{}: not the dataset of part {i} of plan {} that {} describes: run the part again",
                    myr.display(),
                    plan.id,
                    tops_path.display()
                )));
            }
            parts.push(ds);
        }
        for n in nodes {
            pending.push(crate::nodes::spill(n, spill_dir.path())?);
        }
        heads.push(head);
    }
    // Every point of every input in exactly one part: a part that reads an input reads all its
    // points (or, for a chunked one, all those of the chunks that meet its cells: together its
    // header's count), and the parts together must take them all.
    let mut sources = Vec::new();
    for (k, input) in plan.inputs.iter().enumerate() {
        let (mut taken, mut read) = (0u64, None);
        for h in &heads {
            if let Some(t) = h["inputs"][k].as_object() {
                taken += t["taken"].as_u64().unwrap_or(0);
                read = read.max(t["read"].as_u64());
            }
        }
        if plan.chunked_input(k).is_some() {
            read = Some(input.points);
        }
        let Some(read) = read.or((input.points == 0).then_some(0)) else {
            return Err(Error::Invalid(format!(
                "{}: no part read it (its header's bounds are not where its points are): make \
                 the plan again",
                input.path.display()
            )));
        };
        if taken != read {
            return Err(Error::Invalid(format!(
                "{}: {read} points read, {taken} in the parts (its header's bounds understate \
                 where its points are): make the plan again",
                input.path.display()
            )));
        }
        let mut s = plan.dataset.sources[k].clone();
        s["points"] = json!(taken);
        sources.push(s);
    }

    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .map_err(|e| Error::Invalid(format!("thread pool: {e}")))?;
    let writer = DatasetWriter::create(out, force, plan.dataset.quantization)?;
    // 1. The parts' pages below the partition level: linked where they are, or copied.
    let mut copies = Vec::new();
    for (i, ds) in parts.iter().enumerate() {
        let (entries, damage) = ds.nodes();
        if let Some(d) = damage.first() {
            return Err(ds.damage_error(d));
        }
        copies.extend(
            entries
                .into_iter()
                .filter(|e| e.key.level > p)
                .map(|e| (i, e)),
        );
    }
    let copied = copies.len() as u64;
    let mut files = Vec::new();
    if single_file {
        report.phase("copying", copied);
        pool.install(|| {
            copies.par_iter().try_for_each(|(i, e)| -> Result<()> {
                let ds = &parts[*i];
                let page = ds.node_page(e).map_err(|d| ds.damage_error(&d))?;
                writer.copy_node(e, &page)?;
                report.advance(1);
                Ok(())
            })
        })?;
    } else {
        let abs = |p: &Path| std::fs::canonicalize(p).map_err(|e| Error::io(p, e));
        let from = abs(&parent)?;
        for ds in &parts {
            files.push(myriad_format::linked::LinkedFile {
                path: myriad_format::linked::relative_path(&from, &abs(ds.path())?),
                length: ds.file_length,
                header_crc: ds.header_crc,
            });
        }
        for (i, e) in &copies {
            writer.link_node(e, *i);
        }
    }

    // 2. The levels above, from the parts' tops, as `convert` builds them.
    // Unused: a plan is octree or layered; `Above` takes them for mwkd.
    let mw = crate::mwkd::MwkdParams {
        fanout: 2,
        capacity: plan.params.capacity,
        grid: None,
        orientation: crate::mwkd::Orientation::Up,
    };
    Above {
        structure: plan.structure,
        params: &plan.params,
        mw: &mw,
        root: &plan.dataset.root,
        schema: &plan.dataset.schema,
        writer: &writer,
        pool: &pool,
        spill_dir: spill_dir.path(),
    }
    .build(pending, None, report)?;

    let (written, nodes, _) = writer.totals();
    let points: u64 = heads
        .iter()
        .map(|h| h["points"].as_u64().unwrap_or(0))
        .sum();
    if written != points {
        return Err(Error::Invalid(format!(
            "{}: internal error: the parts hold {points} points, {written} in the nodes",
            out.display()
        )));
    }
    let mut bounds = Aabb::EMPTY;
    for h in &heads {
        if let Some(b) = h["bounds"].as_object() {
            let f3 = |x: &Value| -> [f64; 3] {
                std::array::from_fn(|a| x[a].as_f64().unwrap_or(f64::NAN))
            };
            bounds = bounds.union(&Aabb::new(f3(&b["min"]), f3(&b["max"])));
        }
    }
    let mut meta = plan.dataset.clone();
    meta.points = points;
    meta.bounds = bounds;
    meta.sources = sources;
    meta.parameters["plan"] = json!(plan.id);
    meta.software = format!("myriad {}", env!("CARGO_PKG_VERSION"));
    let linked = files.len() as u64;
    meta.files = files;
    let bytes = writer.finish(meta)?;
    // The scatter tasks' records are in the parts now.
    let _ = std::fs::remove_dir_all(exchange_dir(dir));
    Ok(MergeSummary {
        points,
        nodes,
        copied,
        built: nodes - copied,
        bytes,
        linked,
        seconds: start.elapsed().as_secs_f64(),
    })
}
