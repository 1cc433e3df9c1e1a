//! `myriad serve` against rude clients (issue 40), each kind bounded in count and time and on
//! the loopback only: clients that send a request and hang up without reading (the server used
//! to die of SIGPIPE), silent and idle sockets that took every connection slot, floods of
//! multi-range requests that were answered from memory, and box downloads that were too large
//! or abandoned. After each, a normal request must be answered within a second, and the
//! server's memory must stay within a bound.

mod common;
use common::{myriad, s, synth, tempdir};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Serving {
    child: Child,
    addr: SocketAddr,
    lines: Vec<String>,
}

impl Drop for Serving {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Serving {
    fn alive(&mut self) -> bool {
        self.child.try_wait().unwrap().is_none()
    }

    fn rss_mib(&self) -> f64 {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).unwrap();
        let kib: f64 = status
            .lines()
            .find_map(|l| l.strip_prefix("VmRSS:"))
            .and_then(|v| v.split_whitespace().next()?.parse().ok())
            .unwrap();
        kib / 1024.0
    }
}

/// `myriad serve INPUTS ARGS` on a free port, with its temporary folder `tmp`.
fn serve(inputs: &[&Path], args: &[&str], tmp: &Path) -> Serving {
    std::fs::create_dir_all(tmp).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_myriad"))
        .arg("serve")
        .args(inputs)
        .args(args)
        .args(["--bind", "127.0.0.1:0"])
        .env("TMPDIR", tmp)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let mut lines = Vec::new();
    loop {
        let mut l = String::new();
        if out.read_line(&mut l).unwrap() == 0 {
            break;
        }
        let done = l.starts_with("stop with");
        lines.push(l.trim_end().to_string());
        if done {
            break;
        }
    }
    std::thread::spawn(move || for _ in out.lines() {});
    let base = lines[0]
        .split(" on ")
        .nth(1)
        .expect("serving N files on URL");
    let addr = base
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .parse()
        .unwrap();
    Serving { child, addr, lines }
}

/// A GET that must be answered in full within `within`: its status and body.
fn get(addr: SocketAddr, path: &str, extra: &str, within: Duration) -> (u16, Vec<u8>) {
    let t = Instant::now();
    let mut c = TcpStream::connect_timeout(&addr, within).unwrap();
    c.set_read_timeout(Some(within)).unwrap();
    write!(
        c,
        "GET {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n{extra}\r\n"
    )
    .unwrap();
    let mut out = Vec::new();
    c.read_to_end(&mut out)
        .unwrap_or_else(|e| panic!("GET {path}: no answer in {within:?}: {e}"));
    assert!(
        t.elapsed() <= within + Duration::from_millis(200),
        "GET {path} took {:?}",
        t.elapsed()
    );
    let split = out
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .unwrap_or_else(|| panic!("GET {path}: no answer head in {} bytes", out.len()));
    let head = String::from_utf8_lossy(&out[..split]).to_string();
    let status = head.split(' ').nth(1).unwrap().parse().unwrap();
    (status, out[split + 4..].to_vec())
}

const SECOND: Duration = Duration::from_secs(1);

/// The tests here run one at a time: each measures answer times and memory, which the others'
/// floods would disturb on a two-core machine.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn alone() -> std::sync::MutexGuard<'static, ()> {
    ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner())
}

fn files(d: &Path) -> (PathBuf, Vec<u8>) {
    let dir = d.join("files");
    std::fs::create_dir_all(&dir).unwrap();
    let big: Vec<u8> = (0..(4u32 << 20))
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
        .collect();
    std::fs::write(dir.join("big.bin"), &big).unwrap();
    std::fs::write(dir.join("a b%2e.json"), b"{\"odd\": true}").unwrap();
    (dir, big)
}

#[test]
fn clients_that_hang_up_or_idle_cannot_kill_or_starve_the_server() {
    let _alone = alone();
    let d = tempdir("hostile-conn");
    let (dir, big) = files(&d);
    let mut server = serve(
        &[&dir],
        &[
            "--max-connections",
            "8",
            "--header-timeout",
            "2",
            "--idle-timeout",
            "2",
        ],
        &d.join("tmp"),
    );
    let addr = server.addr;

    // The URL it prints for an odd name works as printed (percent-encoded).
    let line = server
        .lines
        .iter()
        .find(|l| l.contains(".json"))
        .expect("the JSON file is listed")
        .clone();
    let url = line.split_whitespace().next().unwrap();
    assert!(url.ends_with("/d/files/a%20b%252e.json"), "{line}");
    let path = url.split_once(&addr.to_string()).unwrap().1;
    assert_eq!(
        get(addr, path, "", SECOND),
        (200, b"{\"odd\": true}".to_vec())
    );

    // 1. Requests for a 4 MB file from clients that close without reading: the server used to
    // die of SIGPIPE after a few of them.
    for _ in 0..300 {
        if let Ok(mut c) = TcpStream::connect(addr) {
            let _ = c.write_all(b"GET /d/files/big.bin HTTP/1.1\r\nHost: localhost\r\n\r\n");
            std::thread::sleep(Duration::from_millis(3));
        }
    }
    std::thread::sleep(Duration::from_millis(300));
    assert!(server.alive(), "the server died of clients that hung up");
    let (status, body) = get(addr, "/d/files/big.bin", "", SECOND * 3);
    assert_eq!((status, body.len()), (200, big.len()));

    // 2. Every slot taken by silent sockets (and one HTTP/2 preface with nothing after): a new
    // client is still answered at once (the idlest is shed for it), and the silent ones are
    // closed once the header timeout passes.
    let mut silent: Vec<TcpStream> = (0..7).map(|_| TcpStream::connect(addr).unwrap()).collect();
    let mut h2 = TcpStream::connect(addr).unwrap();
    h2.write_all(b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n\x00\x00\x00\x04\x00\x00\x00\x00\x00")
        .unwrap();
    silent.push(h2);
    std::thread::sleep(Duration::from_millis(800));
    let t = Instant::now();
    assert_eq!(get(addr, "/d/files/a%20b%252e.json", "", SECOND).0, 200);
    assert!(t.elapsed() < SECOND, "answered after {:?}", t.elapsed());
    std::thread::sleep(Duration::from_millis(2_500));
    for (i, c) in silent.iter_mut().enumerate() {
        c.set_read_timeout(Some(SECOND * 2)).unwrap();
        let mut b = [0u8; 4096];
        // Closed: end of file (after the HTTP/2 server's own SETTINGS, for the last one).
        let closed = loop {
            match c.read(&mut b) {
                Ok(0) => break true,
                Ok(_) => continue,
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => break true,
                Err(_) => break false,
            }
        };
        assert!(
            closed,
            "silent socket {i} still open after the header timeout"
        );
    }

    // An idle keep-alive connection is closed after the idle timeout.
    let mut keep = TcpStream::connect(addr).unwrap();
    keep.write_all(b"GET /d/files/a%20b%252e.json HTTP/1.1\r\nHost: localhost\r\n\r\n")
        .unwrap();
    keep.set_read_timeout(Some(SECOND * 5)).unwrap();
    let t = Instant::now();
    let mut all = Vec::new();
    let _ = keep.read_to_end(&mut all);
    assert!(
        all.starts_with(b"HTTP/1.1 200"),
        "{}",
        String::from_utf8_lossy(&all)
    );
    let idle = t.elapsed();
    assert!(
        idle > Duration::from_millis(1_500) && idle < SECOND * 4,
        "an idle connection closed after {idle:?} (idle timeout 2 s)"
    );
    assert!(server.alive());
}

#[test]
fn multi_range_floods_stream_within_a_memory_bound() {
    let _alone = alone();
    let d = tempdir("hostile-ranges");
    let (dir, big) = files(&d);
    let mut server = serve(&[&dir], &["--idle-timeout", "30"], &d.join("tmp"));
    let addr = server.addr;
    // Overlapping ranges are merged: one range comes back.
    let (status, body) = get(
        addr,
        "/d/files/big.bin",
        "Range: bytes=0-99, 50-149\r\n",
        SECOND,
    );
    assert_eq!((status, &body[..]), (206, &big[..150]));
    // Ranges apart: multipart, streamed, each part's bytes.
    let (status, body) = get(
        addr,
        "/d/files/big.bin",
        "Range: bytes=0-9, 3000000-3000009\r\n",
        SECOND,
    );
    assert_eq!(status, 206);
    assert!(body.windows(10).any(|w| w == &big[3_000_000..3_000_010]));

    let base = server.rss_mib();
    // 16 clients asking 32 overlapping 2 MB ranges, and 16 asking 32 disjoint 128 KB ones
    // (all 4 MB), none reading: 1.5-3 GB when answers were built in memory.
    let overlapping: Vec<String> = (0..32).map(|_| "0-2097151".to_string()).collect();
    let disjoint: Vec<String> = (0..32u64)
        .map(|i| format!("{}-{}", i << 17, (i << 17) + 131_000))
        .collect();
    let mut flood = Vec::new();
    for ranges in [&overlapping, &disjoint] {
        for _ in 0..16 {
            let mut c = TcpStream::connect(addr).unwrap();
            write!(
                c,
                "GET /d/files/big.bin HTTP/1.1\r\nHost: localhost\r\nRange: bytes={}\r\n\r\n",
                ranges.join(",")
            )
            .unwrap();
            flood.push(c);
        }
    }
    let mut peak = base;
    for _ in 0..10 {
        std::thread::sleep(Duration::from_millis(150));
        peak = peak.max(server.rss_mib());
    }
    // A normal request is answered while they wait.
    let (status, body) = get(addr, "/d/files/big.bin", "Range: bytes=100-199\r\n", SECOND);
    assert_eq!((status, &body[..]), (206, &big[100..200]));
    assert!(
        peak - base < 160.0,
        "the server grew from {base:.0} to {peak:.0} MiB under the flood"
    );
    drop(flood);
    std::thread::sleep(SECOND);
    let after = server.rss_mib();
    assert!(
        after - base < 100.0,
        "{after:.0} MiB after the flood, {base:.0} before"
    );
    assert!(server.alive());
}

#[test]
fn box_downloads_are_capped_cancelled_and_leave_no_files() {
    let _alone = alone();
    let d = tempdir("hostile-box");
    let las = synth(&d, "site.las", 200_000);
    let site = d.join("site.myr");
    let r = myriad(&["convert", s(&las), "-o", s(&site), "--capacity", "5000"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let tmp = d.join("tmp");
    std::fs::create_dir_all(&tmp).unwrap();
    // What an older server left: removed when the next one starts.
    let old = tmp.join(".myriad-serve-77-0.laz.77.partial");
    std::fs::write(&old, b"half a download").unwrap();
    std::fs::File::options()
        .write(true)
        .open(&old)
        .unwrap()
        .set_modified(std::time::SystemTime::now() - Duration::from_secs(60))
        .unwrap();
    let mut server = serve(&[&site], &["--max-box-points", "50000"], &tmp);
    let addr = server.addr;
    assert!(!old.exists(), "a stale partial download was kept");

    // A box of everything (±1e300): refused with 413 and a message, at once.
    let all = "/x/site.myr?box=-1e300,-1e300,-1e300,1e300,1e300,1e300";
    let (status, body) = get(addr, all, "", SECOND * 2);
    assert_eq!(status, 413, "{}", String::from_utf8_lossy(&body));
    assert!(String::from_utf8_lossy(&body).contains("50000 points"));
    // A small box is served.
    let info = myriad(&["info", "--json", s(&site)]);
    let v: serde_json::Value = serde_json::from_str(info.stdout.trim()).unwrap();
    let b: Vec<f64> = ["min", "max"]
        .iter()
        .flat_map(|k| {
            v["bounds"][k]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect::<Vec<_>>()
        })
        .collect();
    let small = format!(
        "/x/site.myr?box={},{},{},{},{},{}",
        b[0],
        b[1],
        b[2],
        b[0] + (b[3] - b[0]) / 10.0,
        b[1] + (b[4] - b[1]) / 10.0,
        b[5]
    );
    let (status, body) = get(addr, &small, "", SECOND * 5);
    assert_eq!(status, 200);
    assert!(body.starts_with(b"LASF"));

    // Ten clients that ask and hang up: the server goes on answering.
    for _ in 0..10 {
        let mut c = TcpStream::connect(addr).unwrap();
        write!(c, "GET {small} HTTP/1.1\r\nHost: localhost\r\n\r\n").unwrap();
    }
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(get(addr, &small, "", SECOND * 5).0, 200);

    // Stopped by SIGTERM: exit 0, its temporary folder gone.
    let scratch = |tmp: &Path| {
        std::fs::read_dir(tmp)
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .file_name()
                    .to_string_lossy()
                    .starts_with(".myriad-serve")
            })
            .count()
    };
    assert_eq!(scratch(&tmp), 1, "one scratch folder while it runs");
    // SAFETY: kill(2) on our own child's pid.
    unsafe { libc::kill(server.child.id() as i32, libc::SIGTERM) };
    let t = Instant::now();
    let status = loop {
        if let Some(s) = server.child.try_wait().unwrap() {
            break s;
        }
        assert!(
            t.elapsed() < SECOND * 10,
            "still running 10 s after SIGTERM"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success(), "{status:?}");
    assert_eq!(scratch(&tmp), 0, "temporary files left after stopping");
}

/// The server's counters once every download started has ended (cancelled or finished), or
/// after 20 s: a download stops at its next node, which a busy machine may take more than a
/// second to reach; one that ran on would finish (seconds of LAZ writing) and be counted so.
fn settled(server: &myriad_serve::Server) -> myriad_serve::Stats {
    std::thread::sleep(SECOND);
    let until = std::time::Instant::now() + Duration::from_secs(20);
    loop {
        let s = server.stats();
        let ended = s.downloads_cancelled + s.downloads_finished;
        if s.downloads_started == ended || std::time::Instant::now() > until {
            return s;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn abandoned_box_downloads_stop_instead_of_running_on() {
    let _alone = alone();
    let d = tempdir("hostile-cancel");
    let las = synth(&d, "big.las", 3_000_000);
    let site = d.join("big.myr");
    let r = myriad(&["convert", s(&las), "-o", s(&site)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let catalog = myriad_serve::Catalog::new(std::slice::from_ref(&site)).unwrap();
    let server = myriad_serve::Server::start(
        catalog,
        "127.0.0.1:0".parse().unwrap(),
        myriad_serve::Options {
            max_box_points: u64::MAX,
            ..Default::default()
        },
    )
    .unwrap();
    // Ten downloads of every point (seconds of LAZ writing each), sent together and abandoned
    // together: the two that had their turn stop at their next node, the others never start.
    // 3 M points: of 1 M, an extraction could end before its client's hang-up was seen (about a
    // fifth of the runs here), its client gone, neither finished nor cancelled.
    let burst: Vec<TcpStream> = (0..10)
        .map(|_| {
            let mut c = TcpStream::connect(server.addr).unwrap();
            write!(
                c,
                "GET /x/big.myr?box=-1e300,-1e300,-1e300,1e300,1e300,1e300 HTTP/1.1\r\nHost: localhost\r\n\r\n"
            )
            .unwrap();
            c
        })
        .collect();
    std::thread::sleep(Duration::from_millis(300));
    // Last sent first: the waiting clients are gone before those extracting leave their turns
    // (closing in order, a waiter not yet closed could take a turn between two closes).
    for c in burst.into_iter().rev() {
        drop(c);
    }
    let stats = settled(&server);
    assert!(
        stats.downloads_started <= 4,
        "abandoned downloads started: {stats:?}"
    );
    assert!(stats.downloads_cancelled >= 1, "{stats:?}");
    assert_eq!(stats.downloads_finished, 0, "{stats:?}");
    assert_eq!(
        stats.downloads_started, stats.downloads_cancelled,
        "{stats:?}"
    );
    // Abandoned one after another: each stops when its client leaves.
    for _ in 0..5 {
        let mut c = TcpStream::connect(server.addr).unwrap();
        write!(
            c,
            "GET /x/big.myr?box=-1e300,-1e300,-1e300,1e300,1e300,1e300 HTTP/1.1\r\nHost: localhost\r\n\r\n"
        )
        .unwrap();
        std::thread::sleep(Duration::from_millis(100));
    }
    let stats = settled(&server);
    assert_eq!(stats.downloads_finished, 0, "{stats:?}");
    assert_eq!(
        stats.downloads_started, stats.downloads_cancelled,
        "{stats:?}"
    );
    // The server's scratch folder holds nothing once they are gone.
    assert_eq!(
        std::fs::read_dir(server.scratch()).unwrap().count(),
        1,
        "only its lock"
    );
}
