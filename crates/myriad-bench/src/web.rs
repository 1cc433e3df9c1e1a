//! `myriad bench web DATASET [--potree DIR]`: time to the first image and to convergence in
//! the browser (Debian's Chromium, headless, WebGL2 on SwiftShader), for Myriad's web viewer on
//! the dataset and, with `--potree`, for the Potree 1.8 viewer on PotreeConverter's output of
//! the same scan, both from one `myriad serve` over loopback, alternating, each run in a fresh
//! browser (nothing cached). Both at the same point budget and window size, each from its own
//! overview (Myriad's default camera, Potree's `fitToScreen`). Reported: medians, requests and
//! bytes read.

use anyhow::{Context, Result, bail};
use clap::Args;
use myriad_serve::browser::{self, Browser};
use myriad_serve::{Catalog, Options, Server};
use serde_json::Value;
use std::path::PathBuf;
use std::time::Duration;

#[derive(Args)]
pub struct WebBenchArgs {
    /// The dataset (.myr) for Myriad's viewer
    dataset: PathBuf,
    /// PotreeConverter 2's output for the same scan (the folder of metadata.json), for Potree
    #[arg(long)]
    potree: Option<PathBuf>,
    /// The Potree 1.8 viewer (its folder of libs/)
    #[arg(long, default_value = "../shared/peers/potree-viewer")]
    potree_viewer: PathBuf,
    #[arg(long, default_value_t = 5)]
    runs: usize,
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Point budget of both viewers
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "1M")]
    budget: u64,
    /// Myriad's renderer: webgpu or webgl2 [default: the viewer's: WebGPU where it works]
    #[arg(long, value_parser = ["webgpu", "webgl2"])]
    renderer: Option<String>,
}

/// Opens the Potree 2.0 dataset at `cloud` in the Potree 1.8 viewer at `libs`, and records when
/// it first shows points and when its visible nodes are all loaded and stay so for half a second.
const POTREE_PAGE: &str = r#"<!doctype html>
<html><head><meta charset="utf-8"></head><body style="margin:0">
<script>window.errs = []; window.onerror = (m) => errs.push(String(m));</script>
<script src="LIBS/jquery/jquery-3.1.1.min.js"></script>
<script src="LIBS/other/BinaryHeap.js"></script>
<script src="LIBS/tween/tween.min.js"></script>
<script src="LIBS/d3/d3.js"></script>
<script src="LIBS/proj4/proj4.js"></script>
<script src="LIBS/i18next/i18next.js"></script>
<script src="LIBS/potree/potree.js"></script>
<div id="area" style="position:absolute;width:100%;height:100%"></div>
<script>
const viewer = new Potree.Viewer(document.getElementById("area"));
viewer.setPointBudget(BUDGET);
viewer.setBackground("black");
window.result = { first: null, converged: null, points: 0, errors: errs };
Potree.loadPointCloud("CLOUD", "cloud", (e) => {
  const pc = e.pointcloud;
  viewer.scene.addPointCloud(pc);
  viewer.fitToScreen();
  let last = "", since = performance.now();
  const poll = () => {
    const now = performance.now();
    if (pc.numVisiblePoints > 0 && result.first === null) result.first = now;
    const loaded = pc.visibleNodes.filter((n) => n.geometryNode && n.geometryNode.loaded).length;
    const s = pc.visibleNodes.length + "/" + loaded + "/" + pc.numVisiblePoints + "/" + Potree.numNodesLoading;
    if (s !== last) { last = s; since = now; }
    result.points = pc.numVisiblePoints;
    if (result.first !== null && Potree.numNodesLoading === 0 && loaded === pc.visibleNodes.length &&
        now - since > 500) { result.converged = since; return; }
    setTimeout(poll, 5);
  };
  poll();
});
</script></body></html>
"#;

/// A viewer's row: its label, then per run the first image and convergence (ms) and a summary.
type Row = (&'static str, Vec<f64>, Vec<f64>, Vec<String>);

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        f64::NAN
    } else {
        v[v.len() / 2]
    }
}

pub fn run(a: WebBenchArgs) -> Result<()> {
    let Some(exe) = browser::find() else {
        bail!("no Chromium on the PATH (apt-get install chromium)");
    };
    let name = a
        .dataset
        .file_name()
        .and_then(|n| n.to_str())
        .context("the dataset's file name")?
        .to_string();
    let mut catalog = Catalog::default();
    catalog.add_input(&a.dataset)?;
    let scratch = std::env::temp_dir().join(format!("myriad-bench-web-{}", std::process::id()));
    let potree = match &a.potree {
        Some(dir) => {
            if !a.potree_viewer.join("libs/potree/potree.js").is_file() {
                bail!(
                    "{}: not the Potree viewer (no libs/potree/potree.js)",
                    a.potree_viewer.display()
                );
            }
            catalog.add_input(&a.potree_viewer.join("libs"))?;
            catalog.add_input(dir)?;
            let cloud = dir
                .file_name()
                .and_then(|n| n.to_str())
                .context("--potree's name")?;
            let page = scratch.join("potree-page");
            std::fs::create_dir_all(&page)?;
            std::fs::write(
                page.join("index.html"),
                POTREE_PAGE
                    .replace("LIBS", "/d/libs")
                    .replace("CLOUD", &format!("/d/{cloud}/metadata.json"))
                    .replace("BUDGET", &a.budget.to_string()),
            )?;
            catalog.add_input(&page)?;
            true
        }
        None => false,
    };
    let server = Server::start(catalog, "127.0.0.1:0".parse()?, Options::default())?;
    let base = format!("http://{}", server.addr);
    println!(
        "time to the first image in Chromium (headless, SwiftShader), {}x{}, budget {}, {} runs",
        a.width, a.height, a.budget, a.runs
    );
    let timeout = Duration::from_secs(300);
    let mut rows: Vec<Row> = vec![("Myriad web viewer", vec![], vec![], vec![])];
    if potree {
        rows.push((
            "Potree 1.8 (PotreeConverter 2's output)",
            vec![],
            vec![],
            vec![],
        ));
    }
    for run in 0..a.runs {
        for k in 0..rows.len() {
            // Alternating which goes first.
            let which = (k + run) % rows.len();
            let mut b = Browser::launch(&exe)?;
            let (first, converged, what) = if which == 0 {
                let mut url = format!(
                    "{base}/view/{}#budget={}",
                    myriad_serve::href(&name),
                    a.budget
                );
                if let Some(r) = &a.renderer {
                    url.push_str(&format!("&renderer={r}"));
                }
                b.open(&url, a.width, a.height)
                    .map_err(anyhow::Error::msg)?;
                let st = b
                    .wait_for(
                        "window.myriad && (myriad.state.converged || myriad.state.errors.length > 0) && myriad.state",
                        timeout,
                    )
                    .map_err(anyhow::Error::msg)?;
                if st["errors"].as_array().is_some_and(|e| !e.is_empty()) {
                    bail!("the web viewer: {}", st["errors"]);
                }
                (
                    st["firstImageMs"].as_f64().unwrap_or(f64::NAN),
                    st["convergedMs"].as_f64().unwrap_or(f64::NAN),
                    format!(
                        "{}, {} points, {} requests, {:.1} MB",
                        st["renderer"].as_str().unwrap_or("?"),
                        st["points"],
                        st["requests"],
                        st["bytes"].as_f64().unwrap_or(0.0) / 1e6
                    ),
                )
            } else {
                b.open(
                    &format!("{base}/d/potree-page/index.html"),
                    a.width,
                    a.height,
                )
                .map_err(anyhow::Error::msg)?;
                let r: Value = b
                    .wait_for(
                        "window.result && window.result.converged !== null && window.result",
                        timeout,
                    )
                    .map_err(anyhow::Error::msg)?;
                if r["errors"].as_array().is_some_and(|e| !e.is_empty()) {
                    bail!("the Potree viewer: {}", r["errors"]);
                }
                (
                    r["first"].as_f64().unwrap_or(f64::NAN),
                    r["converged"].as_f64().unwrap_or(f64::NAN),
                    format!("{} points", r["points"]),
                )
            };
            drop(b);
            println!(
                "  run {}: {:<42} first image {:>7.0} ms, converged {:>7.0} ms ({what})",
                run + 1,
                rows[which].0,
                first,
                converged
            );
            rows[which].1.push(first);
            rows[which].2.push(converged);
            rows[which].3.push(what);
        }
    }
    println!("medians:");
    for (label, first, converged, _) in &rows {
        println!(
            "  {label:<42} first image {:>7.0} ms, converged {:>7.0} ms",
            median(first.clone()),
            median(converged.clone())
        );
    }
    if rows.len() == 2 {
        println!(
            "  Potree / Myriad: first image {:.2}x, converged {:.2}x",
            median(rows[1].1.clone()) / median(rows[0].1.clone()),
            median(rows[1].2.clone()) / median(rows[0].2.clone())
        );
    }
    drop(server);
    let _ = std::fs::remove_dir_all(&scratch);
    Ok(())
}
