//! `myriad bench`: speed figures as medians over several runs, each next to a baseline measured
//! in the same process, so that a noisy machine still gives a meaningful ratio.

use anyhow::Result;
use clap::{Args, Subcommand};
use myriad_io::OpenOptions;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Subcommand)]
pub enum BenchCommand {
    /// Reading speed of files; for LAS/LAZ also the raw speed of the las/laz crates (baseline)
    Read(ReadArgs),
    /// Speed and peak memory of `synth`
    Synth(SynthBenchArgs),
    /// Conversion speed, peak memory and size (each run a separate `myriad convert` process),
    /// next to the raw LAS/LAZ decode of the same file
    Convert(ConvertBenchArgs),
    /// Image quality of the level of detail at a point budget (PSNR against every point, next
    /// to as many random points) in three standard views, and the frame time of the pipeline
    Render(crate::bench_render::RenderBenchArgs),
    /// The cost of each post pass (fill, shade, ssao, edl, blur, aa) at 1280x720 and
    /// 2160x2160, and the PSNR of no pass, fill, fill+blur and the default chain at 250 k and
    /// 1 M points against every point
    Passes(crate::bench_passes::PassesBenchArgs),
    /// One file converted with every structure (octree, layered, kd): build speed, peak memory,
    /// bytes per point, nodes, depth, PSNR at a budget in three views, frame time
    Structures(crate::bench_structures::StructuresBenchArgs),
    /// Occlusion culling from a view inside and one outside each dataset: nodes and points
    /// selected, nodes culled, selection and frame time, PSNR against every point unculled
    Culling(crate::bench_culling::CullingBenchArgs),
    /// Surfaces (seed 001) from a view's points: cells and the milliseconds of cluster, move,
    /// reduce, reconstruct and the frame for the full method, without move and for an octree
    /// level as the baseline; distance from the points to the surface; holes
    Surface(crate::bench_surface::SurfaceBenchArgs),
    /// Stereo frames (seed 002): mono, both eyes in two passes and in one, with and without the
    /// hidden-area mask, at 2160x2160 per eye
    Stereo(crate::bench_stereo::StereoBenchArgs),
    /// Export speed and peak memory (COPC, Potree) next to PotreeConverter 2 converting the
    /// dataset's input in the same run
    Export(crate::bench_export::ExportBenchArgs),
    /// Opening: time to the first image and to convergence (cold and warm page cache), pages
    /// read and hierarchy memory, next to reading every hierarchy page
    Open(crate::bench_open::OpenBenchArgs),
    /// `myriad serve` under concurrent random range reads, next to nginx in the same run:
    /// requests/s, MB/s, latency, errors, server memory
    Serve(crate::bench_serve::ServeBenchArgs),
    /// Prefetching off and on while orbiting: frames with nodes missing, time to settle
    Prefetch(crate::bench_prefetch::PrefetchBenchArgs),
    /// Time to the first image and to convergence in the browser: Myriad's web viewer next to
    /// Potree 1.8 on PotreeConverter's output, from the same server, in headless Chromium
    Web(crate::bench_web::WebBenchArgs),
    /// A build on one machine next to the same build as N parts and a merge on Slurm (the
    /// cluster SLURM_CONF names), same cores: wall time, each part's time and peak memory, merge
    Partition(crate::bench_partition::PartitionBenchArgs),
}

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
    /// Also run PotreeConverter 2 on each file in the same runs (alternating with convert)
    #[arg(long)]
    peer: bool,
    /// PotreeConverter 2 [default: ../shared/peers/potreeconverter/PotreeConverter when present]
    #[arg(long)]
    peer_path: Option<PathBuf>,
}

#[derive(Args)]
pub struct ReadArgs {
    #[arg(required = true)]
    files: Vec<PathBuf>,
    #[arg(long, default_value_t = 5)]
    runs: usize,
}

#[derive(Args)]
pub struct SynthBenchArgs {
    #[arg(long, value_parser = crate::synth::parse_count, default_value = "100M")]
    points: u64,
    #[arg(long, default_value_t = 3)]
    runs: usize,
    /// Output file (replaced on every run, removed at the end); .las or .laz
    #[arg(short, long, default_value = "myriad-bench-synth.las")]
    output: PathBuf,
}

pub fn run(c: BenchCommand) -> Result<()> {
    match c {
        BenchCommand::Read(a) => read(a),
        BenchCommand::Synth(a) => synth(a),
        BenchCommand::Convert(a) => convert(a),
        BenchCommand::Render(a) => crate::bench_render::run(a),
        BenchCommand::Structures(a) => crate::bench_structures::run(a),
        BenchCommand::Passes(a) => crate::bench_passes::run(a),
        BenchCommand::Culling(a) => crate::bench_culling::run(a),
        BenchCommand::Surface(a) => crate::bench_surface::run(a),
        BenchCommand::Stereo(a) => crate::bench_stereo::run(a),
        BenchCommand::Export(a) => crate::bench_export::run(a),
        BenchCommand::Open(a) => crate::bench_open::run(a),
        BenchCommand::Serve(a) => crate::bench_serve::run(a),
        BenchCommand::Prefetch(a) => crate::bench_prefetch::run(a),
        BenchCommand::Web(a) => crate::bench_web::run(a),
        BenchCommand::Partition(a) => crate::bench_partition::run_bench(a),
    }
}

pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Peak resident memory of this process so far, from /proc (Linux); None elsewhere.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    Some(line.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
}

fn time_points(f: impl Fn() -> Result<u64>, runs: usize) -> Result<(u64, f64)> {
    let mut rates = Vec::new();
    let mut n = 0;
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        n = f()?;
        rates.push(n as f64 / t.elapsed().as_secs_f64());
    }
    Ok((n, median(rates)))
}

fn read(a: ReadArgs) -> Result<()> {
    println!(
        "{:<48} {:>12} {:>14} {:>16} {:>7}",
        "file", "points", "myriad pts/s", "las/laz raw pts/s", "ratio"
    );
    for path in &a.files {
        let format = myriad_io::detect(path)?;
        let (n, ours) = time_points(
            || {
                let mut src = myriad_io::open(path, &OpenOptions::default())?;
                let mut n = 0u64;
                let mut sum = 0.0;
                while let Some(b) = src.read_batch(myriad_io::MAX_BATCH)? {
                    n += b.len() as u64;
                    sum += b.positions.first().map_or(0.0, |p| p[0]); // keep the decode live
                }
                std::hint::black_box(sum);
                Ok(n)
            },
            a.runs,
        )?;
        let name = path.file_name().map_or_else(
            || path.display().to_string(),
            |f| f.to_string_lossy().into_owned(),
        );
        if matches!(format, myriad_io::Format::Las | myriad_io::Format::Laz) {
            let (_, raw) = time_points(|| Ok(myriad_io::las::read_raw_records(path)?), a.runs)?;
            println!(
                "{name:<48} {n:>12} {:>14.0} {:>16.0} {:>6.0}%",
                ours,
                raw,
                100.0 * ours / raw
            );
        } else {
            println!("{name:<48} {n:>12} {ours:>14.0} {:>16} {:>7}", "-", "-");
        }
    }
    println!(
        "medians of {} runs each; ratio = myriad / raw decode by the las and laz crates",
        a.runs
    );
    Ok(())
}

fn synth(a: SynthBenchArgs) -> Result<()> {
    let options = myriad_synth::SynthOptions {
        points: a.points,
        scene: myriad_synth::SceneKind::City,
        seed: 1,
    };
    let (n, rate) = time_points(
        || Ok(myriad_synth::write(&options, &a.output, true, |_| {})?),
        a.runs,
    )?;
    let bytes = std::fs::metadata(&a.output).map(|m| m.len()).unwrap_or(0);
    std::fs::remove_file(&a.output).ok();
    println!(
        "synth {n} points to {}: median {:.2} M points/s over {} runs, {bytes} bytes",
        a.output.display(),
        rate / 1e6,
        a.runs
    );
    match peak_rss_bytes() {
        Some(p) => println!("peak resident memory: {:.1} MB", p as f64 / 1e6),
        None => println!("peak resident memory: unknown on this platform"),
    }
    Ok(())
}

fn convert(a: ConvertBenchArgs) -> Result<()> {
    let exe = std::env::current_exe()?;
    let peer = match (
        a.peer,
        a.peer_path
            .clone()
            .or_else(crate::bench_export::default_peer),
    ) {
        (false, _) => None,
        (true, Some(p)) => Some(p),
        (true, None) => anyhow::bail!(
            "--peer: PotreeConverter not found (give --peer-path; ../shared/peers has a build)"
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
                secs.push(last["seconds"].as_f64().unwrap_or(f64::NAN));
                rates.push(last["points_per_second"].as_f64().unwrap_or(f64::NAN));
                peaks.push(last["peak_rss_bytes"].as_f64().unwrap_or(f64::NAN));
                if let Some(peer) = &peer {
                    // Ours is measured (its size is in the summary): gone before the peer
                    // writes, so that both fit on the disk for a large input.
                    std::fs::remove_file(&a.output).ok();
                    // The peer in the same minute, into a folder next to our output.
                    let dir = a.output.with_extension("potreeconverter");
                    let _ = std::fs::remove_dir_all(&dir);
                    let (t, m) = crate::bench_export::measured(
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
