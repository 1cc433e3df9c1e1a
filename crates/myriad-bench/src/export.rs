//! `myriad bench export DATASET --input FILE`: export speed and peak memory (COPC, Potree and
//! 3D Tiles, each run a separate `myriad export` process, its peak read by `wait4`), next to a baseline
//! (`extract` of every point to one LAZ file: the same decoding and LAZ compression without a
//! tree) and to PotreeConverter 2 converting the dataset's input, in the same run, alternating,
//! so that the machine's drift between minutes falls on all of them.

use anyhow::{Result, bail};
use clap::Args;
use myriad_format::Dataset;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

#[derive(Args)]
pub struct ExportBenchArgs {
    /// The dataset (.myr)
    dataset: PathBuf,
    /// The file the dataset was built from, for PotreeConverter
    #[arg(long)]
    input: Option<PathBuf>,
    /// PotreeConverter 2 [default: ../shared/peers/potreeconverter/PotreeConverter when present]
    #[arg(long)]
    peer: Option<PathBuf>,
    /// The dataset's CRS where it names none, for the 3D Tiles row (which places points on
    /// the globe); without either that row is left out
    #[arg(long, value_name = "CRS")]
    from_crs: Option<String>,
    #[arg(long, default_value_t = 3)]
    runs: usize,
    /// Folder for the outputs (removed at the end)
    #[arg(long, default_value = "myriad-bench-export")]
    scratch: PathBuf,
}

/// Runs `cmd` to the end; returns its wall time and peak resident memory in bytes.
pub(crate) fn measured(cmd: &mut Command) -> Result<(f64, u64)> {
    let start = Instant::now();
    let child = cmd
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| anyhow::anyhow!("{}: {e}", Path::new(cmd.get_program()).display()))?;
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: rusage is plain data (all zeros is valid); wait4 fills it for our own child.
    let (r, usage) = unsafe {
        let mut usage: libc::rusage = std::mem::zeroed();
        (libc::wait4(pid, &mut status, 0, &mut usage), usage)
    };
    let secs = start.elapsed().as_secs_f64();
    if r != pid || !libc::WIFEXITED(status) || libc::WEXITSTATUS(status) != 0 {
        let mut err = String::new();
        if let Some(mut e) = child.stderr {
            std::io::Read::read_to_string(&mut e, &mut err).ok();
        }
        bail!("{:?} failed: {}", cmd.get_program(), err.trim());
    }
    Ok((secs, usage.ru_maxrss as u64 * 1024))
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

pub(crate) fn default_peer() -> Option<PathBuf> {
    let exe = std::env::current_exe().ok()?;
    exe.ancestors()
        .map(|a| a.join("shared/peers/potreeconverter/PotreeConverter"))
        .chain(std::iter::once(PathBuf::from(
            "../shared/peers/potreeconverter/PotreeConverter",
        )))
        .find(|p| p.is_file())
}

/// Bytes of the files below `p` (or of the file `p`).
fn size(p: &Path) -> u64 {
    match std::fs::metadata(p) {
        Ok(m) if m.is_dir() => std::fs::read_dir(p)
            .map(|d| d.flatten().map(|e| size(&e.path())).sum())
            .unwrap_or(0),
        Ok(m) => m.len(),
        Err(_) => 0,
    }
}

pub fn run(a: ExportBenchArgs) -> Result<()> {
    let exe = std::env::current_exe()?;
    let ds = Dataset::open(&a.dataset)?;
    let points = ds.meta.points;
    std::fs::create_dir_all(&a.scratch)?;
    let peer = a.peer.clone().or_else(default_peer);
    let peer_out = a.scratch.join("potreeconverter");
    // (row, command, output, extra arguments)
    let mut targets: Vec<(&str, &str, PathBuf, Vec<String>)> = vec![
        (
            "export copc",
            "export",
            a.scratch.join("export.copc.laz"),
            vec![],
        ),
        ("export potree", "export", a.scratch.join("potree"), vec![]),
    ];
    if ds.meta.crs.is_some() || a.from_crs.is_some() {
        let mut args = vec!["--to".to_string(), "3dtiles".to_string()];
        if let (None, Some(c)) = (&ds.meta.crs, &a.from_crs) {
            args.extend(["--from-crs".to_string(), c.clone()]);
        }
        targets.push(("export 3dtiles", "export", a.scratch.join("3dtiles"), args));
    } else {
        println!("no 3D Tiles run: the dataset names no CRS (give --from-crs)");
    }
    targets.push((
        "extract to LAZ (baseline)",
        "extract",
        a.scratch.join("extract.laz"),
        vec![],
    ));
    let mut rows: Vec<(&str, Vec<f64>, Vec<f64>)> =
        targets.iter().map(|t| (t.0, vec![], vec![])).collect();
    let with_peer = match (&peer, &a.input) {
        (Some(_), Some(_)) => {
            rows.push(("PotreeConverter (from the input)", vec![], vec![]));
            true
        }
        _ => {
            println!("no PotreeConverter run: give --input (and --peer where it is not found)");
            false
        }
    };
    for _ in 0..a.runs.max(1) {
        for (i, (_, command, out, args)) in targets.iter().enumerate() {
            let (t, m) = measured(
                Command::new(&exe)
                    .arg(command)
                    .arg(&a.dataset)
                    .arg("-o")
                    .arg(out)
                    .args(args)
                    .arg("--force"),
            )?;
            rows[i].1.push(t);
            rows[i].2.push(m as f64);
        }
        if with_peer {
            let _ = std::fs::remove_dir_all(&peer_out);
            let (t, m) = measured(
                Command::new(peer.as_ref().unwrap())
                    .arg(a.input.as_ref().unwrap())
                    .arg("-o")
                    .arg(&peer_out),
            )?;
            let last = rows.len() - 1;
            rows[last].1.push(t);
            rows[last].2.push(m as f64);
        }
    }
    let mut sizes: Vec<u64> = targets.iter().map(|t| size(&t.2)).collect();
    sizes.push(size(&peer_out));
    println!(
        "{}: {} points, medians of {} runs",
        a.dataset.display(),
        myriad_core::units::thousands(points),
        a.runs.max(1)
    );
    println!(
        "{:<34} {:>9} {:>10} {:>9} {:>10} {:>8}",
        "", "seconds", "M pts/s", "peak MB", "MB out", "B/pt"
    );
    let mut medians = Vec::new();
    for (i, (name, secs, peaks)) in rows.iter_mut().enumerate() {
        let t = median(secs);
        let peak = peaks.iter().cloned().fold(0.0, f64::max);
        println!(
            "{:<34} {:>9.2} {:>10.2} {:>9.0} {:>10.1} {:>8.2}",
            name,
            t,
            points as f64 / t / 1e6,
            peak / 1e6,
            sizes[i] as f64 / 1e6,
            sizes[i] as f64 / points.max(1) as f64
        );
        medians.push((*name, t));
    }
    let of = |name: &str| medians.iter().find(|m| m.0 == name).map(|m| m.1);
    let e = of("extract to LAZ (baseline)").unwrap_or(1.0);
    for row in ["export copc", "export potree", "export 3dtiles"] {
        if let Some(t) = of(row) {
            print!(
                "{row} at {:.0} % of the speed of extract to LAZ",
                100.0 * e / t
            );
            match of("PotreeConverter (from the input)") {
                Some(b) => println!(", {:.1}x PotreeConverter's", b / t),
                None => println!(),
            }
        }
    }
    let _ = std::fs::remove_dir_all(&a.scratch);
    Ok(())
}
