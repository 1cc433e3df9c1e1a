//! `myriad bench serve FILE`: `myriad serve` under load, next to nginx serving the same file in
//! the same run. Each server runs in its own process; `--clients` threads, each with its own
//! keep-alive connection, ask for random byte ranges (the sizes of dataset pages) for
//! `--seconds`; one answer in 64 is compared with the file. Reported: requests/s, MB/s, median
//! and 99th-percentile latency, errors, and the server's resident memory over the run (all its
//! processes), sampled twice a second.

use anyhow::{Context, Result, bail};
use clap::Args;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

#[derive(Args)]
pub struct ServeBenchArgs {
    /// The file to serve (a dataset, any file)
    file: PathBuf,
    #[arg(long, default_value_t = 64)]
    clients: usize,
    #[arg(long, default_value_t = 30)]
    seconds: u64,
    /// Largest range asked for, in bytes (each is 4 KiB to this)
    #[arg(long, default_value_t = 256 << 10)]
    max_range: u64,
    /// nginx binary for the side-by-side run [default: nginx on PATH; none: skipped]
    #[arg(long)]
    nginx: Option<PathBuf>,
}

/// A server process (and, for nginx, its workers), stopped when dropped.
struct Running {
    child: Child,
    url: String,
    scratch: Option<PathBuf>,
}

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        if let Some(d) = &self.scratch {
            let _ = std::fs::remove_dir_all(d);
        }
    }
}

fn start_myriad(file: &Path) -> Result<Running> {
    let exe = std::env::current_exe()?;
    let mut child = Command::new(exe)
        .arg("serve")
        .arg(file)
        .args(["--bind", "127.0.0.1:0", "--max-connections", "1024"])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()?;
    let mut lines = BufReader::new(child.stdout.take().expect("piped")).lines();
    let first = lines.next().context("myriad serve said nothing")??;
    let base = first
        .split(" on ")
        .nth(1)
        .context("no address from myriad serve")?
        .trim_end_matches('/')
        .to_string();
    std::thread::spawn(move || for _ in lines {});
    let name = file.file_name().unwrap_or_default().to_string_lossy();
    Ok(Running {
        child,
        url: format!("{base}/d/{name}"),
        scratch: None,
    })
}

fn start_nginx(nginx: &Path, file: &Path) -> Result<Running> {
    let listener = std::net::TcpListener::bind("127.0.0.1:0")?;
    let port = listener.local_addr()?.port();
    drop(listener);
    let scratch = std::env::temp_dir().join(format!("myriad-bench-nginx-{}", std::process::id()));
    std::fs::create_dir_all(scratch.join("logs"))?;
    let root = file
        .canonicalize()?
        .parent()
        .context("the file has no folder")?
        .to_path_buf();
    let conf = format!(
        "worker_processes auto;\nerror_log stderr error;\npid {p}/nginx.pid;\n\
         events {{ worker_connections 1024; }}\n\
         http {{ access_log off; sendfile on; tcp_nodelay on; keepalive_requests 100000;\n\
         client_body_temp_path {p}; proxy_temp_path {p}; fastcgi_temp_path {p};\n\
         uwsgi_temp_path {p}; scgi_temp_path {p};\n\
         server {{ listen 127.0.0.1:{port}; root {r}; }} }}\n",
        p = scratch.display(),
        r = root.display()
    );
    std::fs::write(scratch.join("nginx.conf"), conf)?;
    let child = Command::new(nginx)
        .arg("-p")
        .arg(&scratch)
        .arg("-c")
        .arg(scratch.join("nginx.conf"))
        .args(["-g", "daemon off;"])
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .with_context(|| format!("starting {}", nginx.display()))?;
    let name = file.file_name().unwrap_or_default().to_string_lossy();
    let url = format!("http://127.0.0.1:{port}/{name}");
    // Until it answers.
    let t = Instant::now();
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        if t.elapsed() > Duration::from_secs(10) {
            bail!("nginx did not start listening");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    Ok(Running {
        child,
        url,
        scratch: Some(scratch),
    })
}

/// Resident memory of a process and its children, in bytes (Linux).
fn rss_tree(pid: u32) -> u64 {
    let rss = |p: u32| -> u64 {
        std::fs::read_to_string(format!("/proc/{p}/status"))
            .ok()
            .and_then(|s| {
                let l = s.lines().find(|l| l.starts_with("VmRSS:"))?.to_string();
                l.split_whitespace().nth(1)?.parse::<u64>().ok()
            })
            .unwrap_or(0)
            * 1024
    };
    let mut total = rss(pid);
    if let Ok(entries) = std::fs::read_dir("/proc") {
        for e in entries.flatten() {
            let Some(p) = e.file_name().to_str().and_then(|n| n.parse::<u32>().ok()) else {
                continue;
            };
            let parent = std::fs::read_to_string(format!("/proc/{p}/stat"))
                .ok()
                .and_then(|s| {
                    s.rsplit(')')
                        .next()?
                        .split_whitespace()
                        .nth(1)?
                        .parse()
                        .ok()
                });
            if parent == Some(pid) {
                total += rss(p);
            }
        }
    }
    total
}

struct Load {
    requests: u64,
    bytes: u64,
    errors: u64,
    latencies: Vec<u32>,
    rss: Vec<u64>,
    seconds: f64,
}

fn load(server: &Running, file: &Path, a: &ServeBenchArgs) -> Result<Load> {
    let len = std::fs::metadata(file)?.len();
    if len < 4096 {
        bail!("{}: too small to read ranges from", file.display());
    }
    let stop = Arc::new(AtomicBool::new(false));
    let pid = server.child.id();
    let rss = Arc::new(Mutex::new(Vec::new()));
    let sampler = {
        let (stop, rss) = (stop.clone(), rss.clone());
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                rss.lock().unwrap().push(rss_tree(pid));
                std::thread::sleep(Duration::from_millis(500));
            }
        })
    };
    let t0 = Instant::now();
    let clients: Vec<_> = (0..a.clients)
        .map(|i| {
            let (url, stop, file) = (server.url.clone(), stop.clone(), file.to_path_buf());
            let max = a.max_range.clamp(4096, len);
            std::thread::spawn(move || {
                use std::os::unix::fs::FileExt;
                let f = std::fs::File::open(&file).ok();
                let agent: ureq::Agent = ureq::Agent::config_builder()
                    .http_status_as_error(false)
                    .timeout_global(Some(Duration::from_secs(30)))
                    .build()
                    .into();
                let mut seed = 0x9e37_79b9_7f4a_7c15u64 ^ (i as u64 + 1) * 0x1234_5678_9abc_def1;
                let mut next = move || {
                    seed ^= seed << 13;
                    seed ^= seed >> 7;
                    seed ^= seed << 17;
                    seed
                };
                let (mut n, mut bytes, mut errors, mut lat) = (0u64, 0u64, 0u64, Vec::new());
                while !stop.load(Ordering::Relaxed) {
                    let size = 4096 + next() % (max - 4096 + 1);
                    let at = next() % (len - size + 1);
                    let t = Instant::now();
                    let r = agent
                        .get(&url)
                        .header("Range", format!("bytes={at}-{}", at + size - 1))
                        .call();
                    let ok = match r {
                        Ok(mut r) if r.status().as_u16() == 206 => {
                            match r.body_mut().with_config().limit(size + 1).read_to_vec() {
                                Ok(b) if b.len() as u64 == size => {
                                    // One answer in 64 checked against the file.
                                    n % 64 != 0
                                        || f.as_ref().is_none_or(|f| {
                                            let mut want = vec![0; size as usize];
                                            f.read_exact_at(&mut want, at).is_ok() && want == b
                                        })
                                }
                                _ => false,
                            }
                        }
                        _ => false,
                    };
                    lat.push(t.elapsed().as_micros().min(u32::MAX as u128) as u32);
                    n += 1;
                    if ok {
                        bytes += size;
                    } else {
                        errors += 1;
                    }
                }
                (n, bytes, errors, lat)
            })
        })
        .collect();
    std::thread::sleep(Duration::from_secs(a.seconds));
    stop.store(true, Ordering::Relaxed);
    let mut out = Load {
        requests: 0,
        bytes: 0,
        errors: 0,
        latencies: Vec::new(),
        rss: Vec::new(),
        seconds: 0.0,
    };
    for c in clients {
        let (n, b, e, l) = c.join().expect("a client thread");
        out.requests += n;
        out.bytes += b;
        out.errors += e;
        out.latencies.extend(l);
    }
    out.seconds = t0.elapsed().as_secs_f64();
    let _ = sampler.join();
    out.rss = std::mem::take(&mut *rss.lock().unwrap());
    Ok(out)
}

fn report(name: &str, l: &mut Load) {
    l.latencies.sort_unstable();
    let q = |f: f64| {
        l.latencies
            .get(((l.latencies.len() as f64 * f) as usize).min(l.latencies.len().saturating_sub(1)))
            .copied()
            .unwrap_or(0) as f64
            / 1e3
    };
    let mb = |b: u64| b as f64 / 1e6;
    let first = l.rss.get(2).or(l.rss.first()).copied().unwrap_or(0);
    println!(
        "{name:<8} {:>9.0} {:>9.1} {:>8.2} {:>8.2} {:>7} {:>8.1} {:>8.1} {:>8.1}",
        l.requests as f64 / l.seconds,
        mb(l.bytes) / l.seconds,
        q(0.5),
        q(0.99),
        l.errors,
        mb(first),
        mb(l.rss.iter().copied().max().unwrap_or(0)),
        mb(l.rss.last().copied().unwrap_or(0)),
    );
}

pub fn run(a: ServeBenchArgs) -> Result<()> {
    let nginx = a.nginx.clone().or_else(|| {
        ["/usr/sbin/nginx", "/usr/bin/nginx"]
            .iter()
            .map(PathBuf::from)
            .find(|p| p.exists())
    });
    println!(
        "{} clients, random ranges of 4 KiB to {} KiB, {} s per server, loopback",
        a.clients,
        a.max_range >> 10,
        a.seconds
    );
    println!(
        "{:<8} {:>9} {:>9} {:>8} {:>8} {:>7} {:>8} {:>8} {:>8}",
        "server", "req/s", "MB/s", "p50 ms", "p99 ms", "errors", "RSS MB", "max MB", "end MB"
    );
    let s = start_myriad(&a.file)?;
    report("myriad", &mut load(&s, &a.file, &a)?);
    drop(s);
    match nginx {
        Some(n) => {
            let s = start_nginx(&n, &a.file)?;
            report("nginx", &mut load(&s, &a.file, &a)?);
        }
        None => println!("nginx: not found (apt-get install nginx-light), skipped"),
    }
    Ok(())
}
