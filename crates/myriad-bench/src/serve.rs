//! `myriad bench serve FILE`: `myriad serve` under load, next to nginx serving the same file in
//! the same run. Each server runs in its own process; `--clients` threads, each with its own
//! keep-alive connection, ask for random byte ranges (the sizes of dataset pages) for
//! `--seconds`; one answer in 64 is compared with the file. Reported: requests/s, MB/s, median
//! and 99th-percentile latency, errors, and the server's resident memory over the run (all its
//! processes), sampled twice a second.
//!
//! `--hostile` runs each server a second time with rude clients beside the normal ones (what a
//! server must survive, issue 40): clients that send a request for the whole file and hang up
//! without reading, 64 silent sockets (reopened when closed), 16 clients asking 32 overlapping
//! 2 MB ranges and never reading, and, for a dataset served by Myriad, 4 slow readers of box
//! downloads (`/x/`, 4 KiB a tenth of a second). The normal clients' latency and the server's
//! peak memory during it are the figures.

use anyhow::{Context, Result, bail};
use clap::Args;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
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
    /// Also run each server with rude clients beside the normal ones (hang-ups, idle sockets,
    /// multi-range floods; for a dataset, slow box downloads, corridors along the longest line a
    /// request holds, the whole extent under the longest filter)
    #[arg(long)]
    hostile: bool,
    /// Which rude clients `--hostile` runs, to tell their costs apart: any of hangups, idle,
    /// floods, slow (box downloads read slowly), corridor, filtered [default: all]
    #[arg(long, value_delimiter = ',', value_parser = RUDE)]
    rude: Vec<String>,
}

/// The kinds of rude client, as `--rude` names them.
const RUDE: [&str; 6] = ["hangups", "idle", "floods", "slow", "corridor", "filtered"];

/// Rude clients against `url` until `stop`: their threads (joined by the caller).
fn hostile(
    url: &str,
    costly: Option<Costly>,
    len: u64,
    rude: &[String],
    downloaded: &Arc<AtomicU64>,
    stop: &Arc<AtomicBool>,
) -> Vec<std::thread::JoinHandle<()>> {
    let runs = |kind: &str| rude.is_empty() || rude.iter().any(|r| r == kind);
    use std::io::{Read, Write};
    let rest = url.trim_start_matches("http://");
    let (host, path) = rest.split_once('/').expect("a URL with a path");
    let addr: std::net::SocketAddr = host.parse().expect("a numeric address");
    let path = format!("/{path}");
    let mut threads = Vec::new();
    let spawn = |f: Box<dyn FnOnce() + Send>| std::thread::spawn(f);
    // Hang-ups: a request for everything, then closed unread.
    if runs("hangups") {
        let (stop, path) = (stop.clone(), path.clone());
        threads.push(spawn(Box::new(move || {
            while !stop.load(Ordering::Relaxed) {
                if let Ok(mut c) = std::net::TcpStream::connect(addr) {
                    let _ = write!(c, "GET {path} HTTP/1.1\r\nHost: localhost\r\n\r\n");
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        })));
    }
    // Silent sockets, reopened when the server closes them.
    if runs("idle") {
        let stop = stop.clone();
        threads.push(spawn(Box::new(move || {
            let mut socks: Vec<Option<std::net::TcpStream>> = (0..64).map(|_| None).collect();
            while !stop.load(Ordering::Relaxed) {
                for s in socks.iter_mut() {
                    let closed = match s {
                        Some(c) => {
                            let _ = c.set_nonblocking(true);
                            let mut b = [0u8; 64];
                            matches!(c.read(&mut b), Ok(0))
                        }
                        None => true,
                    };
                    if closed {
                        *s = std::net::TcpStream::connect(addr).ok();
                    }
                }
                std::thread::sleep(Duration::from_millis(200));
            }
        })));
    }
    // Multi-range floods, never read, held 2 s.
    let last = len.min(2 << 20) - 1;
    let ranges: Vec<String> = (0..32).map(|_| format!("0-{last}")).collect();
    let ranges = ranges.join(",");
    for _ in 0..if runs("floods") { 16 } else { 0 } {
        let (stop, path, ranges) = (stop.clone(), path.clone(), ranges.clone());
        threads.push(spawn(Box::new(move || {
            while !stop.load(Ordering::Relaxed) {
                if let Ok(mut c) = std::net::TcpStream::connect(addr) {
                    let _ = write!(
                        c,
                        "GET {path} HTTP/1.1\r\nHost: localhost\r\nRange: bytes={ranges}\r\n\r\n"
                    );
                    for _ in 0..20 {
                        if stop.load(Ordering::Relaxed) {
                            break;
                        }
                        std::thread::sleep(Duration::from_millis(100));
                    }
                }
            }
        })));
    }
    let Some(costly) = costly else {
        return threads;
    };
    // The costliest downloads read as fast as they come, and box downloads read slowly (4 KiB
    // every 100 ms), again and again.
    let downloads = [
        ("corridor", &costly.line, 65536, 0),
        ("filtered", &costly.filtered, 65536, 0),
        ("slow", &costly.bx, 4096, 100),
    ];
    for (_, p, buffer, pause) in downloads.into_iter().filter(|d| runs(d.0)) {
        for _ in 0..4 {
            let (stop, p, got) = (stop.clone(), p.clone(), downloaded.clone());
            threads.push(spawn(Box::new(move || {
                while !stop.load(Ordering::Relaxed) {
                    let Ok(mut c) = std::net::TcpStream::connect(addr) else {
                        break;
                    };
                    let _ = write!(
                        c,
                        "GET {p} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n"
                    );
                    let _ = c.set_read_timeout(Some(Duration::from_secs(5)));
                    let mut b = vec![0u8; buffer];
                    while !stop.load(Ordering::Relaxed) {
                        match c.read(&mut b) {
                            Ok(0) | Err(_) => break,
                            Ok(n) => {
                                got.fetch_add(n as u64, Ordering::Relaxed);
                                std::thread::sleep(Duration::from_millis(pause))
                            }
                        }
                    }
                }
            })));
        }
    }
    threads
}

/// The downloads of a dataset that cost a server most.
#[derive(Clone)]
struct Costly {
    /// A box of the middle tenth of its extent.
    bx: String,
    /// A corridor 0.1 % of its width wide along a zigzag over the whole extent with as many
    /// vertices as a request head holds (14 KB of them).
    line: String,
    /// The whole extent at its finest, through 12 conditions on every attribute the filter
    /// language knows that the dataset has (a 413 where it passes the server's point limit).
    filtered: String,
}

/// [`Costly`] for `file` (None: not a dataset).
fn costly_paths(file: &Path) -> Option<Costly> {
    let ds = myriad_format::Dataset::open(file).ok()?;
    let b = ds.meta.bounds;
    let c = |a: usize, f: f64| b.min[a] + (b.max[a] - b.min[a]) * f;
    let name = myriad_serve::href(&file.file_name()?.to_string_lossy());
    let bx = format!(
        "/x/{name}?box={},{},{},{},{},{}",
        c(0, 0.45),
        c(1, 0.45),
        b.min[2],
        c(0, 0.55),
        c(1, 0.55),
        b.max[2]
    );
    let mut line = String::new();
    let mut i = 0usize;
    while line.len() < 14_000 {
        let t = (i as f64 * 0.618_034).fract();
        let side = if i.is_multiple_of(2) { 0.02 } else { 0.98 };
        line.push_str(&format!("{:.3},{:.3},", c(0, side), c(1, t)));
        i += 1;
    }
    line.pop();
    let width = 0.001 * (b.max[0] - b.min[0]);
    let line = format!("/x/{name}?line={line}&width={width:.3}");
    let schema = &ds.meta.schema;
    let mut conds = Vec::new();
    for (n, v) in [
        ("intensity", ">=0"),
        ("return_number", ">=0"),
        ("number_of_returns", ">=0"),
        ("gps_time", ">-1e12"),
        ("point_source_id", ">=0"),
        ("scan_angle", ">-1000"),
        ("user_data", ">=0"),
    ] {
        if schema.attributes.iter().any(|a| a.name() == n) {
            conds.push(format!("{n}{v}"));
        }
    }
    while conds.len() < 12 {
        let z = format!("z>{}", b.min[2] - 1.0 - conds.len() as f64);
        conds.push(z);
    }
    let filtered = format!(
        "/x/{name}?box={},{},{},{},{},{}&where={}",
        b.min[0],
        b.min[1],
        b.min[2],
        b.max[0],
        b.max[1],
        b.max[2],
        myriad_serve::href(&conds.join(","))
    );
    Some(Costly { bx, line, filtered })
}

/// A server process (and, for nginx, its workers), stopped when dropped.
struct Running {
    child: Child,
    url: String,
    scratch: Option<PathBuf>,
}

impl Drop for Running {
    fn drop(&mut self) {
        // SIGTERM first: nginx's master then stops its workers (killed, it left them running,
        // holding the bench's output open).
        // SAFETY: kill reads no memory; the pid is our child's, not yet waited for.
        unsafe {
            libc::kill(self.child.id() as i32, libc::SIGTERM);
        }
        let t = Instant::now();
        while t.elapsed() < Duration::from_secs(5) {
            if let Ok(Some(_)) = self.child.try_wait() {
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
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
    /// Bytes the rude clients' downloads received.
    downloaded: u64,
}

fn load(
    server: &Running,
    file: &Path,
    a: &ServeBenchArgs,
    rude: Option<Option<Costly>>,
) -> Result<Load> {
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
    let downloaded = Arc::new(AtomicU64::new(0));
    let rude = rude.map(|bx| hostile(&server.url, bx, len, &a.rude, &downloaded, &stop));
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
                let mut seed = 0x9e37_79b9_7f4a_7c15u64 ^ ((i as u64 + 1) * 0x1234_5678_9abc_def1);
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
        downloaded: 0,
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
    for t in rude.into_iter().flatten() {
        let _ = t.join();
    }
    out.rss = std::mem::take(&mut *rss.lock().unwrap());
    out.downloaded = downloaded.load(Ordering::Relaxed);
    Ok(out)
}

/// The ordinary clients' requests/s and p99 latency beside rude ones, as ratios of alone.
fn ratio(alone: &Load, rude: &Load) -> (f64, f64) {
    let p99 = |l: &Load| {
        let mut v = l.latencies.clone();
        v.sort_unstable();
        v.get((v.len() as f64 * 0.99) as usize)
            .copied()
            .unwrap_or(0)
            .max(1) as f64
    };
    (
        (rude.requests as f64 / rude.seconds) / (alone.requests as f64 / alone.seconds).max(1e-9),
        p99(rude) / p99(alone),
    )
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
    let costly = costly_paths(&a.file);
    let s = start_myriad(&a.file)?;
    let mut ratios = Vec::new();
    let mut alone = load(&s, &a.file, &a, None)?;
    report("myriad", &mut alone);
    if a.hostile {
        let mut rude = load(&s, &a.file, &a, Some(costly.clone()))?;
        report("+hostile", &mut rude);
        ratios.push(("myriad", ratio(&alone, &rude)));
        if costly.is_some() {
            println!(
                "+hostile: the downloads received {:.1} MB in {:.0} s",
                rude.downloaded as f64 / 1e6,
                rude.seconds
            );
        }
    }
    drop(s);
    match nginx {
        Some(n) => {
            let s = start_nginx(&n, &a.file)?;
            let mut alone = load(&s, &a.file, &a, None)?;
            report("nginx", &mut alone);
            if a.hostile {
                let mut rude = load(&s, &a.file, &a, Some(None))?;
                report("+hostile", &mut rude);
                ratios.push(("nginx", ratio(&alone, &rude)));
            }
        }
        None => println!("nginx: not found (apt-get install nginx-light), skipped"),
    }
    if a.hostile {
        println!(
            "+hostile: the same clients beside 100 hang-ups/s, 64 idle sockets, 16 floods of 32 overlapping 2 MB ranges{}",
            if costly.is_some() {
                "; for Myriad also 4 slow box downloads, 4 clients downloading a corridor along a \
                 line of 14 KB of vertices, 4 downloading the whole extent through 12 conditions"
            } else {
                ""
            }
        );
        if !a.rude.is_empty() {
            println!("+hostile: only {} (--rude)", a.rude.join(", "));
        }
        for (name, (rps, p99)) in ratios {
            println!(
                "{name}: the ordinary clients beside the hostile ones: {:.2} x the requests/s, {:.2} x the p99 latency, of alone",
                rps, p99
            );
        }
    }
    Ok(())
}
