//! `myriad bench convert FILE...`: conversion speed, peak memory and size, each run a separate
//! `myriad convert` process, next to the raw LAS/LAZ decode of the same file; with `--peer`,
//! PotreeConverter 2 in the same runs, and with `--peer copc-converter`, copc_converter (a COPC
//! builder on crates.io) against our `convert` followed by `export --to copc`.

use crate::median;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct ConvertBenchArgs {
    #[arg(required = true)]
    files: Vec<PathBuf>,
    #[arg(long, default_value_t = 3)]
    runs: usize,
    /// Memory budget passed to convert (e.g. 2GB)
    #[arg(long)]
    memory: Option<String>,
    /// Node capacities to compare, e.g. 16384,65536 [default: convert's default]
    #[arg(long, value_delimiter = ',')]
    capacity: Vec<usize>,
    /// Worker threads passed to convert
    #[arg(long)]
    threads: Option<usize>,
    /// Where the dataset is written (removed at the end)
    #[arg(short, long, default_value = "myriad-bench-convert.myr")]
    output: PathBuf,
    /// Also run a peer on each file in the same runs (alternating with convert):
    /// potreeconverter (the default of a bare --peer) or copc-converter (against convert and
    /// export --to copc); repeat for both
    #[arg(long, num_args = 0..=1, default_missing_value = "potreeconverter",
          value_parser = ["potreeconverter", "copc-converter"])]
    peer: Vec<String>,
    /// PotreeConverter 2 [default: ../shared/peers/potreeconverter/PotreeConverter when present]
    #[arg(long)]
    peer_path: Option<PathBuf>,
    /// copc_converter [default: copc_converter on the PATH, or in ~/.cargo/bin]: install it
    /// with `cargo install copc_converter`
    #[arg(long)]
    copc_converter: Option<PathBuf>,
}

/// copc_converter where `cargo install` puts it.
fn default_copc_converter() -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain(std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cargo/bin")))
        .map(|d| d.join("copc_converter"))
        .find(|p| p.is_file())
}

/// Per phase of the convert: its name, and its seconds and CPU seconds in each run.
type Phases = Vec<(String, Vec<f64>, Vec<f64>)>;

/// Adds the phases of one run's `convert --json` summary.
fn add_phases(phases: &mut Phases, summary: &serde_json::Value) {
    for (i, p) in summary["phases"]
        .as_array()
        .into_iter()
        .flatten()
        .enumerate()
    {
        if phases.len() <= i {
            let name = p["phase"].as_str().unwrap_or("?").to_string();
            phases.push((name, vec![], vec![]));
        }
        phases[i].1.push(p["seconds"].as_f64().unwrap_or(f64::NAN));
        phases[i]
            .2
            .push(p["cpu_seconds"].as_f64().unwrap_or(f64::NAN));
    }
}

/// Where the time went: each phase's median seconds, CPU seconds (the cores it kept busy) and
/// CPU nanoseconds a point.
fn phase_line(phases: &Phases, points: u64) -> String {
    phases
        .iter()
        .map(|(name, secs, cpu)| {
            let (s, c) = (median(secs.clone()), median(cpu.clone()));
            let ns = c * 1e9 / points.max(1) as f64;
            format!("{name} {s:.2} s ({c:.2} CPU-s, {ns:.0} ns/pt)")
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// One run of each side of the COPC comparison: seconds, peak bytes, bytes out.
#[derive(Default)]
struct CopcRuns {
    ours: Vec<(f64, u64, u64)>,
    export: Vec<f64>,
    peer: Vec<(f64, u64, u64)>,
}

pub fn run(a: ConvertBenchArgs) -> Result<()> {
    let exe = std::env::current_exe()?;
    let wants = |name: &str| a.peer.iter().any(|p| p == name);
    let peer = match (
        wants("potreeconverter"),
        a.peer_path.clone().or_else(crate::export::default_peer),
    ) {
        (false, _) => None,
        (true, Some(p)) => Some(p),
        (true, None) => anyhow::bail!(
            "--peer: PotreeConverter not found (give --peer-path; ../shared/peers has a build)"
        ),
    };
    let copc_peer = match (
        wants("copc-converter"),
        a.copc_converter.clone().or_else(default_copc_converter),
    ) {
        (false, _) => None,
        (true, Some(p)) => Some(p),
        (true, None) => anyhow::bail!(
            "--peer copc-converter: copc_converter not found (cargo install copc_converter, or give --copc-converter PATH)"
        ),
    };
    let capacities: Vec<Option<usize>> = if a.capacity.is_empty() {
        vec![None]
    } else {
        a.capacity.iter().map(|&c| Some(c)).collect()
    };
    println!(
        "{:<40} {:>9} {:>11} {:>8} {:>10} {:>9} {:>8} {:>10} {:>12} {:>6}",
        "file",
        "capacity",
        "points",
        "seconds",
        "M pts/s",
        "peak MB",
        "B/pt",
        "input B/pt",
        "raw M pts/s",
        "ratio"
    );
    for path in &a.files {
        let name = path.file_name().map_or_else(
            || path.display().to_string(),
            |f| f.to_string_lossy().into_owned(),
        );
        let input_bytes = std::fs::metadata(path)?.len();
        let is_las = matches!(
            myriad_io::detect(path)?,
            myriad_io::Format::Las | myriad_io::Format::Laz
        );
        for cap in &capacities {
            let (mut secs, mut rates, mut raws, mut peaks) = (vec![], vec![], vec![], vec![]);
            let (mut peer_secs, mut peer_peaks, mut walls) = (vec![], vec![], vec![]);
            let mut last = serde_json::Value::Null;
            let mut phases = Phases::new();
            let mut copc = CopcRuns::default();
            for _ in 0..a.runs.max(1) {
                // Baseline first, in the same minute: the las/laz crates decoding the file.
                if is_las {
                    let t = Instant::now();
                    let n = myriad_io::las::read_raw_records(path)?;
                    raws.push(n as f64 / t.elapsed().as_secs_f64());
                }
                let mut cmd = std::process::Command::new(&exe);
                cmd.arg("convert").arg(path).arg("-o").arg(&a.output);
                cmd.args(["--force", "--json"]);
                if let Some(m) = &a.memory {
                    cmd.args(["--memory", m]);
                }
                if let Some(c) = cap {
                    cmd.args(["--capacity", &c.to_string()]);
                }
                if let Some(t) = a.threads {
                    cmd.args(["--threads", &t.to_string()]);
                }
                let wall = Instant::now();
                let out = cmd.output()?;
                walls.push(wall.elapsed().as_secs_f64());
                if !out.status.success() {
                    anyhow::bail!(
                        "convert failed: {}",
                        String::from_utf8_lossy(&out.stderr).trim()
                    );
                }
                last = serde_json::from_slice(&out.stdout)?;
                add_phases(&mut phases, &last);
                secs.push(last["seconds"].as_f64().unwrap_or(f64::NAN));
                rates.push(last["points_per_second"].as_f64().unwrap_or(f64::NAN));
                peaks.push(last["peak_rss_bytes"].as_f64().unwrap_or(f64::NAN));
                if let Some(cc) = &copc_peer {
                    // Our COPC: the dataset just built exported, then removed before the peer
                    // writes its own.
                    let ours = a.output.with_extension("copc.laz");
                    let (t, m) = crate::export::measured(
                        std::process::Command::new(&exe)
                            .arg("export")
                            .arg(&a.output)
                            .args(["--to", "copc", "--force", "-o"])
                            .arg(&ours),
                    )?;
                    let bytes = std::fs::metadata(&ours)?.len();
                    std::fs::remove_file(&ours).ok();
                    let built = last["peak_rss_bytes"].as_f64().unwrap_or(0.0) as u64;
                    copc.ours
                        .push((walls[walls.len() - 1] + t, m.max(built), bytes));
                    copc.export.push(t);
                    std::fs::remove_file(&a.output).ok();
                    let theirs = a.output.with_extension("copc-converter.copc.laz");
                    let (t, m) = crate::export::measured(
                        std::process::Command::new(cc)
                            .args(["--progress", "plain"])
                            .arg(path)
                            .arg(&theirs),
                    )?;
                    let bytes = std::fs::metadata(&theirs)?.len();
                    std::fs::remove_file(&theirs).ok();
                    copc.peer.push((t, m, bytes));
                }
                if let Some(peer) = &peer {
                    // Ours is measured (its size is in the summary): gone before the peer
                    // writes, so that both fit on the disk for a large input.
                    std::fs::remove_file(&a.output).ok();
                    // The peer in the same minute, into a folder next to our output.
                    let dir = a.output.with_extension("potreeconverter");
                    let _ = std::fs::remove_dir_all(&dir);
                    let (t, m) = crate::export::measured(
                        std::process::Command::new(peer)
                            .arg(path)
                            .arg("-o")
                            .arg(&dir),
                    )?;
                    let _ = std::fs::remove_dir_all(&dir);
                    peer_secs.push(t);
                    peer_peaks.push(m as f64);
                }
            }
            std::fs::remove_file(&a.output).ok();
            let points = last["points"].as_u64().unwrap_or(0);
            let ours = median(rates);
            let (raw, ratio) = if raws.is_empty() {
                ("-".to_string(), "-".to_string())
            } else {
                let r = median(raws);
                (
                    format!("{:.2}", r / 1e6),
                    format!("{:.0}%", 100.0 * ours / r),
                )
            };
            println!(
                "{name:<40} {:>9} {points:>11} {:>8.2} {:>10.2} {:>9.0} {:>8.2} {:>10.2} {raw:>12} {ratio:>6}",
                cap.map_or("default".to_string(), |c| c.to_string()),
                median(secs.clone()),
                ours / 1e6,
                peaks.iter().cloned().fold(0.0, f64::max) / 1e6,
                last["bytes_per_point"].as_f64().unwrap_or(f64::NAN),
                input_bytes as f64 / points.max(1) as f64,
            );
            println!("{:<40} phases: {}", "", phase_line(&phases, points));
            if !copc.peer.is_empty() {
                let mb = |b: u64| b as f64 / 1e6;
                let side = |runs: &[(f64, u64, u64)]| {
                    (
                        median(runs.iter().map(|r| r.0).collect()),
                        runs.iter().map(|r| r.1).max().unwrap_or(0),
                        runs[runs.len() - 1].2,
                    )
                };
                let (ot, om, ob) = side(&copc.ours);
                let (pt, pm, pb) = side(&copc.peer);
                println!(
                    "{:<40} copc_converter: {pt:.2} s, {:.0} MB peak, {:.1} MB ({:.2} B/pt); convert + export --to copc {ot:.2} s (export {:.2}), {:.0} MB peak, {:.1} MB ({:.2} B/pt): {:.2}x its speed, {:.3}x its size",
                    "",
                    mb(pm),
                    mb(pb),
                    pb as f64 / points.max(1) as f64,
                    median(copc.export.clone()),
                    mb(om),
                    mb(ob),
                    ob as f64 / points.max(1) as f64,
                    pt / ot,
                    ob as f64 / pb.max(1) as f64,
                );
            }
            if !peer_secs.is_empty() {
                // Both as wall time of the whole process.
                let t = median(peer_secs.clone());
                let w = median(walls.clone());
                println!(
                    "{:<40} PotreeConverter 2: {t:.2} s, {:.2} M pts/s, {:.0} MB peak; convert {w:.2} s: {:.2}x its speed (runs, convert/peer: {})",
                    "",
                    points as f64 / t / 1e6,
                    peer_peaks.iter().cloned().fold(0.0, f64::max) / 1e6,
                    t / w,
                    peer_secs
                        .iter()
                        .zip(&walls)
                        .map(|(p, o)| format!("{:.2}/{:.2} s", o, p))
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
        }
    }
    println!(
        "medians of {} runs; peak MB is the largest peak RSS of the convert processes; ratio = convert / raw decode",
        a.runs
    );
    Ok(())
}
