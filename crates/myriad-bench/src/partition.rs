//! `myriad bench partition`: a build on one machine next to the same build as N parts on Slurm
//! (the cluster SLURM_CONF names), on the same cores: the overhead of partitioning and merging,
//! each part's time and peak memory, and the merge's.

use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

#[derive(Args)]
pub struct PartitionBenchArgs {
    /// Input point clouds (tiles: a part reads only those that reach its cells)
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Part counts to run, e.g. 4,8,16
    #[arg(long, value_delimiter = ',', default_value = "4,8,16")]
    parts: Vec<usize>,
    /// Memory budget of the one-machine build and of each part
    #[arg(long, default_value = "2GB")]
    memory: String,
    /// Folder for the outputs (on a filesystem the Slurm node shares; emptied as it goes)
    #[arg(long)]
    scratch: PathBuf,
    /// Slurm CPUs per part task; the parts run with as many threads
    #[arg(long, default_value_t = 1)]
    cpus_per_part: usize,
    /// Plans with `plan --whole-inputs` (each part decompresses every LAZ input that reaches
    /// its cells whole): the partitioned build as it was before chunks were chosen
    #[arg(long)]
    whole_inputs: bool,
    /// Runs `myriad slurm --no-exchange`: each part decompresses the LAZ chunks it shares with
    /// others itself, no scatter job before the parts
    #[arg(long)]
    no_exchange: bool,
}

/// CPU seconds (user and system) of this process's children that have ended.
fn children_cpu() -> f64 {
    // SAFETY: getrusage only fills `u`, which is plain data.
    let u = unsafe {
        let mut u: libc::rusage = std::mem::zeroed();
        libc::getrusage(libc::RUSAGE_CHILDREN, &mut u);
        u
    };
    let t = |v: libc::timeval| v.tv_sec as f64 + v.tv_usec as f64 * 1e-6;
    t(u.ru_utime) + t(u.ru_stime)
}

/// Runs this program with `args`; its stdout, and the seconds it took.
fn run(args: &[&str]) -> Result<(String, f64)> {
    let exe = std::env::current_exe()?;
    let t = Instant::now();
    let out = Command::new(exe).args(args).output()?;
    if !out.status.success() {
        bail!(
            "myriad {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok((
        String::from_utf8_lossy(&out.stdout).into_owned(),
        t.elapsed().as_secs_f64(),
    ))
}

/// What a part's or the merge's Slurm log gives.
struct Figures {
    /// "time  X s", "cpu  X s", "memory  Y MB", "read  N points", "exchanged  N points" (NaN
    /// where absent).
    seconds: f64,
    cpu: f64,
    mb: f64,
    read: f64,
    exchanged: f64,
}

/// The numbers a part's or the merge's Slurm log gives.
fn log_figures(path: &Path) -> Result<Figures> {
    let text = std::fs::read_to_string(path).with_context(|| path.display().to_string())?;
    let field = |name: &str| {
        text.lines()
            .find_map(|l| l.trim().strip_prefix(name))
            .and_then(|r| r.split_whitespace().next())
            .and_then(|v| v.replace(',', "").parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    Ok(Figures {
        seconds: field("time"),
        cpu: field("cpu"),
        mb: field("memory"),
        read: field("read"),
        exchanged: field("exchanged"),
    })
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

pub fn run_bench(a: PartitionBenchArgs) -> Result<()> {
    if std::env::var_os("SLURM_CONF").is_none() && Command::new("sinfo").output().is_err() {
        bail!(
            "bench partition needs a Slurm cluster: scripts/slurm-local.sh start DIR, then export SLURM_CONF=DIR/slurm.conf"
        );
    }
    std::fs::create_dir_all(&a.scratch)?;
    let scratch = std::path::absolute(&a.scratch)?;
    let inputs: Vec<String> = a.inputs.iter().map(|p| p.display().to_string()).collect();
    let s = |p: &Path| p.display().to_string();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());

    // One machine, all cores.
    let one = scratch.join("one.myr");
    let mut args = vec!["convert"];
    args.extend(inputs.iter().map(String::as_str));
    let one_s = s(&one);
    args.extend(["-o", &one_s, "--force", "--json", "--memory", &a.memory]);
    let before = children_cpu();
    let (out, one_secs) = run(&args)?;
    let one_cpu = children_cpu() - before;
    let v: serde_json::Value = serde_json::from_str(&out)?;
    let points = v["points"].as_u64().unwrap_or(0);
    let one_peak = v["peak_rss_bytes"].as_f64().unwrap_or(f64::NAN) / 1e6;
    std::fs::remove_file(&one)?;
    println!(
        "one machine ({cores} cores): {points} points, {one_secs:.1} s, {one_cpu:.1} CPU s, {:.2} M points/s, {one_peak:.0} MB peak",
        points as f64 / one_secs / 1e6
    );
    println!(
        "{:>5} {:>3} {:>7} {:>8} {:>8} {:>6} {:>7} {:>8} {:>8} {:>7} {:>7} {:>7} {:>8} {:>8} {:>7} {:>9}",
        "parts",
        "P",
        "plan s",
        "plan cpu",
        "wall s",
        "x one",
        "part s",
        "part max",
        "cpu s",
        "x one",
        "read x",
        "part MB",
        "merge s",
        "merge MB",
        "copy s",
        "scatter s"
    );
    for &n in &a.parts {
        let plan = scratch.join(format!("plan-{n}.json"));
        let plan_s = s(&plan);
        let threads = a.cpus_per_part.to_string();
        let parts = n.to_string();
        let mut args = vec!["plan"];
        args.extend(inputs.iter().map(String::as_str));
        args.extend([
            "-o",
            &plan_s,
            "--parts",
            &parts,
            "--force",
            "--memory",
            &a.memory,
            "--threads",
            &threads,
        ]);
        if a.whole_inputs {
            args.push("--whole-inputs");
        }
        let before = children_cpu();
        let (_, plan_secs) = run(&args)?;
        let plan_cpu = children_cpu() - before;
        let p: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&plan)?)?;
        let out = scratch.join(format!("parts-{n}.myr"));
        let dir = scratch.join(format!("parts-{n}"));
        let _ = std::fs::remove_dir_all(&dir);
        let cpus = format!("--cpus-per-task={}", a.cpus_per_part);
        let (out_s, dir_s) = (s(&out), s(&dir));
        let mut args = vec![
            "slurm",
            &plan_s,
            "-o",
            &out_s,
            "--parts-dir",
            &dir_s,
            "--wait",
        ];
        if a.no_exchange {
            args.push("--no-exchange");
        }
        args.extend(["--", &cpus]);
        let (log, wall) = run(&args)?;
        let job = log
            .lines()
            .find_map(|l| l.strip_prefix("parts  job "))
            .and_then(|r| r.split_whitespace().next())
            .context("the parts' job id")?
            .to_string();
        let merge_job = log
            .lines()
            .find_map(|l| l.strip_prefix("merge  job "))
            .and_then(|r| r.split_whitespace().next())
            .context("the merge's job id")?
            .to_string();
        let scatter_job = log
            .lines()
            .find_map(|l| l.strip_prefix("scatter job "))
            .and_then(|r| r.split_whitespace().next());
        let mut times = Vec::new();
        let (mut peak, mut cpu, mut read) = (0f64, 0f64, 0f64);
        let (mut scatter_max, mut scatter_cpu) = (0f64, 0f64);
        for i in 0..n {
            let f = log_figures(&dir.join(format!("slurm-{job}_{i}.out")))?;
            times.push(f.seconds);
            peak = peak.max(f.mb);
            cpu += f.cpu;
            // Points the part decompressed itself: what it read of the exchange is counted where
            // it was decompressed, by the scatter tasks.
            read += f.read - f.exchanged.max(0.0);
            if let Some(sj) = scatter_job {
                let f = log_figures(&dir.join(format!("slurm-scatter-{sj}_{i}.out")))?;
                scatter_max = scatter_max.max(f.seconds);
                scatter_cpu += f.cpu;
                peak = peak.max(f.mb);
                read += f.read;
            }
        }
        cpu += scatter_cpu;
        let m = log_figures(&dir.join(format!("slurm-merge-{merge_job}.out")))?;
        // The whole build's CPU: plan, parts and merge.
        cpu += plan_cpu + m.cpu;
        let max = times.iter().copied().fold(0.0, f64::max);
        let med = median(&mut times);
        // The same parts merged into one file (every page copied), for the merge's time.
        let single = scratch.join(format!("parts-{n}-single.myr"));
        let (_, copy_secs) = run(&[
            "merge",
            &plan_s,
            &s(&dir),
            "-o",
            &s(&single),
            "--force",
            "--single-file",
        ])?;
        std::fs::remove_file(&single)?;
        println!(
            "{n:>5} {:>3} {plan_secs:>7.2} {plan_cpu:>8.2} {wall:>8.1} {:>6.2} {med:>7.1} {max:>8.1} {cpu:>8.1} {:>7.3} {:>7.2} {peak:>7.0} {:>8.1} {:>8.0} {copy_secs:>7.1} {scatter_max:>9.1}",
            p["partition_level"].as_u64().unwrap_or(0),
            wall / one_secs,
            cpu / one_cpu,
            read / points as f64,
            m.seconds,
            m.mb
        );
        let merged = myriad_format::Dataset::open(&out)?;
        if merged.meta.points != points {
            bail!(
                "{}: {} points, one machine {points}",
                out.display(),
                merged.meta.points
            );
        }
        drop(merged);
        std::fs::remove_file(&out)?;
        std::fs::remove_dir_all(&dir)?;
    }
    println!(
        "(part s: median of the parts; wall: submission to merged, {cores} cores shared by the parts; \
         cpu s: plan, scatter tasks, parts and merge together, x one against the one-machine build's; \
         read x: points decompressed (by the parts, and by the scatter tasks) over the points; \
         merge s: the merge that links the parts' files, copy s: the same parts merged with \
         --single-file; scatter s: the longest scatter task, 0 without the exchange)"
    );
    Ok(())
}
