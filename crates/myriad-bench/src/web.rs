//! `myriad bench web DATASET [--potree DATASET]`: time to the first image and to convergence in
//! the browser (Debian's Chromium, headless, WebGL2 on SwiftShader), for Myriad's web viewer on
//! the dataset (a `.myr`, COPC, EPT or Potree 2.0) and, with `--potree`, for the Potree 1.8
//! viewer on a Potree 2.0 or EPT dataset (its two loaders: the same data as Myriad's, or
//! PotreeConverter's output of the same scan). Both are pages of one static site (Myriad's as
//! `export --to web` writes it) served by Debian's nginx over loopback, alternating, each run in
//! a fresh browser (nothing cached), at the same point budget and window size, each from its own
//! overview (Myriad's default camera, Potree's `fitToScreen`). Reported: medians, requests and
//! bytes read.

use anyhow::{Context, Result, bail};
use clap::Args;
use myriad_serve::browser::{self, Browser};
use serde_json::Value;
use std::path::PathBuf;
use std::time::Duration;

#[derive(Args)]
pub struct WebBenchArgs {
    /// The dataset for Myriad's viewer: .myr, COPC, EPT (ept.json or its folder) or Potree 2.0
    dataset: PathBuf,
    /// The dataset for Potree 1.8: Potree 2.0 (metadata.json or its folder) or EPT (ept.json or
    /// its folder)
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
<script src="LIBS/plasio/vendor/bluebird.js"></script>
<script src="LIBS/plasio/js/laslaz.js"></script>
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

/// Where a dataset lies for a page of the site: the file or folder linked into `data/` and the
/// file a viewer opens in it (a folder's `ept.json` or `metadata.json`).
fn site_entry(path: &std::path::Path) -> Result<(PathBuf, Option<&'static str>)> {
    let ds = myriad_format::Dataset::open(path)?;
    let doc = match ds.foreign_format() {
        Some("EPT") => Some("ept.json"),
        Some("Potree 2.0") => Some("metadata.json"),
        _ => None,
    };
    let at = match doc.is_some() && !path.is_dir() {
        true => path
            .parent()
            .unwrap_or(std::path::Path::new("."))
            .to_path_buf(),
        false => path.to_path_buf(),
    };
    Ok((
        std::fs::canonicalize(&at).with_context(|| at.display().to_string())?,
        doc,
    ))
}

/// Debian's nginx serving `root` on a free loopback port (its own files in `dir`); stopped when
/// dropped.
struct Nginx(std::process::Child);

impl Drop for Nginx {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn nginx(root: &std::path::Path, dir: &std::path::Path) -> Result<(Nginx, u16)> {
    let exe = ["/usr/sbin/nginx", "/usr/bin/nginx"]
        .iter()
        .map(std::path::Path::new)
        .find(|p| p.exists())
        .context("no nginx (apt-get install nginx-light)")?;
    let port = std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port();
    let t = dir.display();
    let conf = dir.join("nginx.conf");
    std::fs::write(
        &conf,
        format!(
            "daemon off; master_process off; pid {t}/nginx.pid; error_log {t}/error.log warn;\n\
             events {{}}\n\
             http {{ access_log off; client_body_temp_path {t}; proxy_temp_path {t};\n\
             fastcgi_temp_path {t}; uwsgi_temp_path {t}; scgi_temp_path {t};\n\
             types {{ text/html html; text/javascript js; application/wasm wasm; application/json json; }}\n\
             default_type application/octet-stream;\n\
             server {{ listen 127.0.0.1:{port}; root {}; }} }}\n",
            root.display()
        ),
    )?;
    let child = std::process::Command::new(exe)
        .arg("-c")
        .arg(&conf)
        .arg("-p")
        .arg(dir)
        .spawn()?;
    let n = Nginx(child);
    let t0 = std::time::Instant::now();
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        if t0.elapsed() > Duration::from_secs(20) {
            bail!("nginx did not start (see {t}/error.log)");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    Ok((n, port))
}

pub fn run(a: WebBenchArgs) -> Result<()> {
    let Some(exe) = browser::find() else {
        bail!("no Chromium on the PATH (apt-get install chromium)");
    };
    let scratch = std::env::temp_dir().join(format!("myriad-bench-web-{}", std::process::id()));
    let site = scratch.join("site");
    std::fs::create_dir_all(site.join("data"))?;
    let (mine, doc) = site_entry(&a.dataset)?;
    let link = |from: &std::path::Path, name: &str| -> Result<String> {
        let to = site.join("data").join(name);
        if !to.exists() {
            std::os::unix::fs::symlink(from, &to)?;
        }
        Ok(format!("data/{name}"))
    };
    let mine_name = mine
        .file_name()
        .context("the dataset's name")?
        .to_string_lossy()
        .into_owned();
    let mut url = link(&mine, &mine_name)?;
    if let Some(d) = doc {
        url = format!("{url}/{d}");
    }
    myriad_serve::viewer::write_site(&site, std::slice::from_ref(&url))?;
    let potree = match &a.potree {
        Some(p) => {
            if !a.potree_viewer.join("libs/potree/potree.js").is_file() {
                bail!(
                    "{}: not the Potree viewer (no libs/potree/potree.js)",
                    a.potree_viewer.display()
                );
            }
            let (theirs, doc) = site_entry(p)?;
            let Some(doc) = doc else {
                bail!(
                    "{}: Potree 1.8 reads Potree 2.0 and EPT, not this",
                    p.display()
                );
            };
            let name = format!(
                "potree-{}",
                theirs
                    .file_name()
                    .context("--potree's name")?
                    .to_string_lossy()
            );
            let cloud = format!("{}/{doc}", link(&theirs, &name)?);
            std::os::unix::fs::symlink(
                std::fs::canonicalize(a.potree_viewer.join("libs"))?,
                site.join("libs"),
            )?;
            std::fs::write(
                site.join("potree.html"),
                POTREE_PAGE
                    .replace("LIBS", "libs")
                    .replace("CLOUD", &cloud)
                    .replace("BUDGET", &a.budget.to_string()),
            )?;
            Some(doc)
        }
        None => None,
    };
    let (server, port) = nginx(&site, &scratch)?;
    let base = format!("http://127.0.0.1:{port}");
    println!(
        "time to the first image in Chromium (headless, SwiftShader), {}x{}, budget {}, {} runs",
        a.width, a.height, a.budget, a.runs
    );
    let timeout = Duration::from_secs(300);
    let mut rows: Vec<Row> = vec![("Myriad web viewer", vec![], vec![], vec![])];
    if let Some(doc) = potree {
        rows.push((
            if doc == "ept.json" {
                "Potree 1.8 (its EPT loader)"
            } else {
                "Potree 1.8 (Potree 2.0)"
            },
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
                let mut url = format!("{base}/index.html#budget={}", a.budget);
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
                b.open(&format!("{base}/potree.html"), a.width, a.height)
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
