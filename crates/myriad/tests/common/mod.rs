//! Helpers shared by the tests that run the `myriad` binary.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

pub struct Run {
    pub code: i32,
    pub stdout: String,
    pub stderr: String,
}

/// Runs the binary with `args` to the end.
pub fn myriad(args: &[&str]) -> Run {
    let out = Command::new(env!("CARGO_BIN_EXE_myriad"))
        .args(args)
        .output()
        .expect("run myriad");
    Run {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// Every record of a LAS/LAZ file as comparable integers: position in thousandths (the synthetic
/// scans' scale), GPS time bits, intensity, classification, returns, colour.
pub fn records(path: &Path) -> Vec<Vec<i64>> {
    let mut src = myriad_io::open(path, &myriad_io::OpenOptions::default()).unwrap();
    let mut out = Vec::new();
    while let Some(b) = src.read_batch(myriad_io::DEFAULT_BATCH).unwrap() {
        for i in 0..b.len() {
            let p = b.positions[i];
            let rgb = b.rgb.as_ref().unwrap()[i];
            out.push(vec![
                (p[0] * 1000.0).round() as i64,
                (p[1] * 1000.0).round() as i64,
                (p[2] * 1000.0).round() as i64,
                b.gps_time.as_ref().unwrap()[i].to_bits() as i64,
                b.intensity.as_ref().unwrap()[i] as i64,
                b.classification.as_ref().unwrap()[i] as i64,
                b.return_number.as_ref().unwrap()[i] as i64,
                rgb[0] as i64,
                rgb[1] as i64,
                rgb[2] as i64,
            ]);
        }
    }
    out.sort();
    out
}

/// Runs the binary, which must fail with exit code 1 and one line on stderr that says `says`.
pub fn fails(args: &[&str], says: &str) {
    let r = myriad(args);
    assert_eq!(r.code, 1, "{args:?} should fail: {}", r.stdout);
    let line = r.stderr.trim();
    assert!(line.contains(says), "{args:?}: {line}");
    assert_eq!(line.lines().count(), 1, "one line: {line}");
}

/// Runs the binary, which must succeed; its output.
pub fn ok(args: &[&str]) -> String {
    let r = myriad(args);
    assert_eq!(r.code, 0, "{args:?}: {}", r.stderr);
    r.stdout
}

/// A PNG's width, height and pixels (RGBA8 for the images `render` writes).
pub fn decode_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut img = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut img).unwrap();
    (info.width, info.height, img)
}

/// An empty folder of this test process, removed when the test is done with it unless it
/// failed (kept to look at): tests that return early no longer leave theirs in the temporary
/// folder.
pub fn tempdir(name: &str) -> TempDir {
    let d = std::env::temp_dir().join(format!("myriad-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    TempDir(d)
}

/// A test's folder ([`tempdir`]).
pub struct TempDir(PathBuf);

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

pub fn synth(dir: &Path, name: &str, points: u64) -> PathBuf {
    let p = dir.join(name);
    let r = myriad(&[
        "synth",
        "-o",
        s(&p),
        "--points",
        &points.to_string(),
        "--seed",
        "5",
    ]);
    assert_eq!(r.code, 0, "synth failed: {}", r.stderr);
    p
}

/// `myriad serve` on a free port; its base URL. Killed when dropped.
pub struct Serving {
    child: Child,
    pub base: String,
    /// What it printed on starting, up to "stop with Ctrl-C".
    pub lines: Vec<String>,
}

impl Drop for Serving {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `myriad serve ARGS --bind 127.0.0.1:0`, its stderr going to `stderr`.
pub fn serve(args: &[&str], stderr: Stdio) -> Serving {
    serve_with(args, &[], stderr)
}

/// [`serve`] with `env` set for it.
pub fn serve_with(args: &[&str], env: &[(&str, &str)], stderr: Stdio) -> Serving {
    let mut child = Command::new(env!("CARGO_BIN_EXE_myriad"))
        .arg("serve")
        .args(args)
        .envs(env.iter().copied())
        .args(["--bind", "127.0.0.1:0"])
        .stdout(Stdio::piped())
        .stderr(stderr)
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let first = lines.next().expect("serve prints its address").unwrap();
    let base = first
        .split(" on ")
        .nth(1)
        .expect("serving N files on URL")
        .trim_end_matches('/')
        .to_string();
    let mut printed = vec![first];
    for l in lines.by_ref() {
        let l = l.unwrap();
        let last = l.starts_with("stop with");
        printed.push(l);
        if last {
            break;
        }
    }
    // Keep reading its output so that it never blocks on a full pipe.
    std::thread::spawn(move || for _ in lines {});
    Serving {
        child,
        base,
        lines: printed,
    }
}

/// Waits until the dataset `name` that a server builds (a scan given to `serve`) is built:
/// its answers no longer say `X-Myriad-Building: yes`.
pub fn wait_built(base: &str, name: &str) {
    use std::io::{Read, Write};
    let addr = base.trim_start_matches("http://");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(300);
    loop {
        let mut c = std::net::TcpStream::connect(addr).unwrap();
        write!(
            c,
            "HEAD /d/{name} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n"
        )
        .unwrap();
        let mut answer = String::new();
        c.read_to_string(&mut answer).unwrap();
        if !answer.to_lowercase().contains("x-myriad-building: yes") {
            return;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "{name} still being built: {answer}"
        );
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
}

/// Two neighbouring scans (west and east halves of a synthetic one) in `d`, and their records.
pub fn two_scans(d: &Path) -> (PathBuf, PathBuf, Vec<Vec<i64>>) {
    let scan = d.join("scan.laz");
    ok(&["synth", "-o", s(&scan), "--points", "300k", "--seed", "4"]);
    let whole = d.join("whole.myr");
    ok(&["convert", s(&scan), "-o", s(&whole)]);
    let (west, east) = halves(d, &whole);
    (west, east, records(&scan))
}

/// The points of a dataset west and east of the middle of its bounds: `d/west.laz` and
/// `d/east.laz`, two neighbouring scans.
pub fn halves(d: &Path, whole: &Path) -> (PathBuf, PathBuf) {
    let b = myriad_format::Dataset::open(whole).unwrap().meta.bounds;
    let mid = 0.5 * (b.min[0] + b.max[0]);
    let bx = |lo: f64, hi: f64| {
        format!(
            "{lo},{},{},{hi},{},{}",
            b.min[1] - 1.0,
            b.min[2] - 1.0,
            b.max[1] + 1.0,
            b.max[2] + 1.0
        )
    };
    let (west, east) = (d.join("west.laz"), d.join("east.laz"));
    for (out, lo, hi) in [
        (&west, b.min[0] - 1.0, mid),
        (&east, mid + 1e-9, b.max[0] + 1.0),
    ] {
        ok(&["extract", s(whole), "-o", s(out), "--box", &bx(lo, hi)]);
    }
    (west, east)
}

pub fn make_plan(d: &Path, inputs: &[&Path], name: &str) -> PathBuf {
    let p = d.join(name);
    let mut args = vec!["plan"];
    args.extend(inputs.iter().map(|i| s(i)));
    args.extend([
        "-o",
        s(&p),
        "--parts",
        "4",
        "--capacity",
        "2000",
        "--chunk-points",
        "20000",
    ]);
    let out = ok(&args);
    assert!(out.contains("part 3"), "{out}");
    p
}

/// The dataset verifies and extracts to `want`.
pub fn holds(dataset: &Path, want: &[Vec<i64>]) {
    let v = ok(&["verify", s(dataset)]);
    assert!(v.contains("ok"), "{v}");
    let las = dataset.with_extension("las");
    ok(&["extract", s(dataset), "-o", s(&las), "--force"]);
    assert!(
        records(&las) == want,
        "{}: not the inputs' records",
        dataset.display()
    );
}

/// A Python that imports `modules` (MYRIAD_PYTHON first, then python3).
pub fn python_with(modules: &str) -> Option<String> {
    std::env::var("MYRIAD_PYTHON")
        .into_iter()
        .chain(["python3".to_string()])
        .find(|py| {
            Command::new(py)
                .args(["-c", &format!("import {modules}")])
                .stderr(Stdio::null())
                .status()
                .is_ok_and(|s| s.success())
        })
}

/// The environment that has `myriad` load the PROJ in pyproj's wheel (its library and its
/// database) instead of Debian's: the same PROJ on both sides. Releases of PROJ choose different
/// operations where several fit (Debian's 9.1 takes NAD83(HARN) to WGS 84 (1), a null
/// transformation good to 2 m, into earth-centred coordinates; pyproj's 9.5 the 1 m Helmert (3)).
pub fn pyprojs_proj(py: &str) -> Vec<(String, String)> {
    let script = r#"
import glob, os, pyproj, pyproj.datadir
site = os.path.dirname(os.path.dirname(pyproj.__file__))
libs = os.path.join(site, "pyproj.libs")
print(libs); print(glob.glob(os.path.join(libs, "libproj*"))[0]); print(pyproj.datadir.get_data_dir())
"#;
    let r = Command::new(py).args(["-c", script]).output().unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let out = String::from_utf8_lossy(&r.stdout).into_owned();
    let l: Vec<&str> = out.lines().collect();
    vec![
        ("LD_LIBRARY_PATH".into(), l[0].into()),
        ("MYRIAD_LIBPROJ".into(), l[1].into()),
        ("PROJ_DATA".into(), l[2].into()),
    ]
}

pub fn ok_env(args: &[&str], env: &[(String, String)]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_myriad"))
        .args(args)
        .envs(env.iter().map(|(k, v)| (k, v)))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// `../shared/data/NAME` when it is there; None, saying SKIPPED, when not.
pub fn shared_data(name: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(name);
    if p.is_file() {
        Some(p)
    } else {
        eprintln!("SKIPPED: ../shared/data/{name} not found");
        None
    }
}

/// Whether PROJ loads; false, saying SKIPPED, when not.
pub fn proj() -> bool {
    if !myriad_io::proj::available() {
        eprintln!(
            "SKIPPED: {} (.ci/run installs it)",
            myriad_io::proj::MISSING
        );
        return false;
    }
    true
}

/// The datasets (`.myr`, hidden ones too: scans' datasets are) in the folder `d`.
pub fn datasets_in(d: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(d)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "myr"))
        .collect()
}

/// A process group a test started (a server, a cluster), stopped when dropped: TERM, then KILL
/// after 10 s; only what the test started.
pub struct Group(Child);

impl Drop for Group {
    fn drop(&mut self) {
        let pg = format!("-{}", self.0.id());
        let _ = Command::new("kill").args(["-TERM", "--", &pg]).status();
        let t = std::time::Instant::now();
        while t.elapsed() < std::time::Duration::from_secs(10) {
            if matches!(self.0.try_wait(), Ok(Some(_))) {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
        let _ = Command::new("kill").args(["-KILL", "--", &pg]).status();
        let _ = self.0.wait();
    }
}

/// `program ARGS` with `env` added, in a process group of its own, its output to `log`.
pub fn spawn_group(program: &Path, args: &[&str], env: &[(&str, &str)], log: &Path) -> Group {
    use std::os::unix::process::CommandExt;
    let out = std::fs::File::create(log).unwrap();
    Group(
        Command::new(program)
            .args(args)
            .envs(env.iter().copied())
            .stdout(out.try_clone().unwrap())
            .stderr(out)
            .stdin(Stdio::null())
            .process_group(0)
            .spawn()
            .unwrap(),
    )
}

/// Waits until `ready` (at most 90 s); else fails, naming `what` and showing its log.
pub fn wait_for(what: &str, log: &Path, mut ready: impl FnMut() -> bool) {
    let t = std::time::Instant::now();
    while !ready() {
        assert!(
            t.elapsed() < std::time::Duration::from_secs(90),
            "{what} did not start: {}",
            std::fs::read_to_string(log).unwrap_or_default()
        );
        std::thread::sleep(std::time::Duration::from_millis(250));
    }
}

/// SeaweedFS (`weed mini`) with the bucket `scans`, its S3 interface on 127.0.0.1:`port`, its
/// files in `dir`, accepting the key and secret `keys`; its log in `log`.
pub fn seaweed(weed: &Path, dir: &Path, port: u16, keys: (&str, &str), log: &Path) -> Group {
    std::fs::create_dir_all(dir).unwrap();
    spawn_group(
        weed,
        &[
            "mini",
            &format!("-dir={}", s(dir)),
            "-ip=127.0.0.1",
            "-ip.bind=127.0.0.1",
            &format!("-s3.port={port}"),
            "-master.telemetry=false",
            "-admin.ui=false",
            "-bucket=scans",
        ],
        &[
            ("AWS_ACCESS_KEY_ID", keys.0),
            ("AWS_SECRET_ACCESS_KEY", keys.1),
        ],
        log,
    )
}

/// `GET PATH` from the server at `base` (`http://HOST:PORT`) with `headers`: the whole answer,
/// status line, headers and body, as text.
pub fn http_get(base: &str, path: &str, headers: &[&str]) -> String {
    use std::io::{Read, Write};
    let addr = base.trim_start_matches("http://");
    let mut c = std::net::TcpStream::connect(addr).unwrap();
    let extra: String = headers.iter().map(|h| format!("{h}\r\n")).collect();
    write!(
        c,
        "GET {path} HTTP/1.1\r\nHost: localhost\r\n{extra}Connection: close\r\n\r\n"
    )
    .unwrap();
    let mut answer = Vec::new();
    c.read_to_end(&mut answer).unwrap();
    String::from_utf8_lossy(&answer).into_owned()
}

/// `render INPUT -o OUT --raster cpu --width W --height H`: the CPU image the tests compare;
/// callers add their own options.
pub fn render_cpu<'a>(input: &'a str, out: &'a str, (w, h): (&'a str, &'a str)) -> Vec<&'a str> {
    vec![
        "render", input, "-o", out, "--raster", "cpu", "--width", w, "--height", h,
    ]
}

/// `METHOD PATH` with `headers` and `body` to the server at `base`: the status and the body.
pub fn http_send(
    base: &str,
    method: &str,
    path: &str,
    headers: &[&str],
    body: &str,
) -> (u16, String) {
    use std::io::{Read, Write};
    let addr = base.trim_start_matches("http://");
    let mut c = std::net::TcpStream::connect(addr).unwrap();
    let extra: String = headers.iter().map(|h| format!("{h}\r\n")).collect();
    // (A server may answer before the body is sent, and close: what it said is read.)
    let _ = write!(
        c,
        "{method} {path} HTTP/1.1\r\nHost: localhost\r\n{extra}Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    let mut answer = Vec::new();
    let _ = c.read_to_end(&mut answer);
    let text = String::from_utf8_lossy(&answer).into_owned();
    let status = text
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let body = text.split_once("\r\n\r\n").map_or("", |b| b.1).to_string();
    (status, body)
}

/// A local map tile server: every `GET /Z/X/Y.png` answered with a 256 x 256 PNG of one colour
/// (CORS open), the paths asked kept in order.
pub struct Tiles {
    pub template: String,
    pub asked: std::sync::Arc<std::sync::Mutex<Vec<String>>>,
}

pub fn tile_server(colour: [u8; 3]) -> Tiles {
    use std::io::{BufRead, BufReader, Write};
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let asked = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let mut png = Vec::new();
    {
        let mut e = png::Encoder::new(&mut png, 256, 256);
        e.set_color(png::ColorType::Rgb);
        e.set_depth(png::BitDepth::Eight);
        let px: Vec<u8> = (0..256 * 256).flat_map(|_| colour).collect();
        e.write_header().unwrap().write_image_data(&px).unwrap();
    }
    let kept = asked.clone();
    std::thread::spawn(move || {
        for s in listener.incoming().flatten() {
            let (kept, png) = (kept.clone(), png.clone());
            std::thread::spawn(move || {
                let mut r = BufReader::new(&s);
                let mut line = String::new();
                if r.read_line(&mut line).is_err() {
                    return;
                }
                loop {
                    let mut h = String::new();
                    if r.read_line(&mut h).map_or(true, |n| n == 0) || h.trim().is_empty() {
                        break;
                    }
                }
                let path = line.split(' ').nth(1).unwrap_or("").to_string();
                kept.lock().unwrap().push(path);
                let head = format!(
                    "HTTP/1.1 200 OK\r\nContent-Type: image/png\r\nContent-Length: {}\r\nAccess-Control-Allow-Origin: *\r\nConnection: close\r\n\r\n",
                    png.len()
                );
                let mut s = &s;
                let _ = s.write_all(head.as_bytes());
                let _ = s.write_all(&png);
            });
        }
    });
    Tiles {
        template: format!("http://127.0.0.1:{port}/{{z}}/{{x}}/{{y}}.png"),
        asked,
    }
}

/// The tiles a map asked for a dataset of EPSG:32633 and `bounds`, checked against pyproj's
/// longitudes and latitudes of its corners: one zoom, the deepest at which the footprint fits
/// in 80 % of 256 pixels, and the tile of its centre among them. None (SKIPPED) without pyproj.
pub fn check_tiles(asked: &[String], bounds: &myriad_core::Aabb) -> Option<()> {
    let py = python_with("pyproj")?;
    let (lo, hi) = (bounds.min, bounds.max);
    let script = format!(
        "import pyproj\nt = pyproj.Transformer.from_crs('EPSG:32633', 'EPSG:4326', always_xy=True)\n\
         for x, y in [({}, {}), ({}, {}), ({}, {}), ({}, {}), ({}, {})]:\n    print(*t.transform(x, y))",
        lo[0],
        lo[1],
        hi[0],
        lo[1],
        hi[0],
        hi[1],
        lo[0],
        hi[1],
        (lo[0] + hi[0]) / 2.0,
        (lo[1] + hi[1]) / 2.0
    );
    let out = Command::new(&py).args(["-c", &script]).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let ll: Vec<(f64, f64)> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split(' ').map(|x| x.parse().unwrap()).collect();
            (v[0], v[1])
        })
        .collect();
    let unit = |(lon, lat): (f64, f64)| {
        let r = f64::to_radians(lat);
        [
            (lon + 180.0) / 360.0,
            (1.0 - (r.tan() + 1.0 / r.cos()).ln() / std::f64::consts::PI) / 2.0,
        ]
    };
    let tiles: Vec<(u32, u32, u32)> = asked
        .iter()
        .map(|p| {
            let v: Vec<u32> = p
                .trim_start_matches('/')
                .trim_end_matches(".png")
                .split('/')
                .map(|x| x.parse().unwrap())
                .collect();
            (v[0], v[1], v[2])
        })
        .collect();
    assert!(!tiles.is_empty(), "no tile asked");
    let z = tiles[0].0;
    assert!(tiles.iter().all(|t| t.0 == z), "one zoom: {tiles:?}");
    let m: Vec<[f64; 2]> = ll[..4].iter().map(|&p| unit(p)).collect();
    let span = |k: usize| {
        m.iter().map(|p| p[k]).fold(f64::MIN, f64::max)
            - m.iter().map(|p| p[k]).fold(f64::MAX, f64::min)
    };
    let px = span(0).max(span(1)) * 256.0 * (1u64 << z) as f64;
    assert!(
        px <= 0.8 * 256.0 + 1.0 && px > 0.4 * 256.0 - 1.0,
        "the footprint {px} pixels wide at zoom {z}"
    );
    let c = unit(ll[4]);
    let n = (1u64 << z) as f64;
    let centre = (z, (c[0] * n).floor() as u32, (c[1] * n).floor() as u32);
    assert!(
        tiles.contains(&centre),
        "the centre's tile {centre:?} in {tiles:?}"
    );
    Some(())
}

/// A PNG of one colour.
pub fn flat_png(w: u32, h: u32, c: [u8; 3]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut e = png::Encoder::new(&mut out, w, h);
    e.set_color(png::ColorType::Rgb);
    e.set_depth(png::BitDepth::Eight);
    let px: Vec<u8> = (0..w * h).flat_map(|_| c).collect();
    e.write_header().unwrap().write_image_data(&px).unwrap();
    out
}

/// An E57 file of three images: "camera", a pinhole photo (`png`, `w` x `h`) taken from `eye`
/// towards `target` (up +z) with a vertical field of view of `fov` degrees; "panorama", a
/// spherical image of one colour (200, 100, 50) at `pano`, its centre column along +x; "site
/// sketch", a visual reference without a pose.
pub fn photo_e57(
    path: &Path,
    (eye, target, fov): ([f64; 3], [f64; 3], f64),
    png: &[u8],
    (w, h): (u32, u32),
    pano: [f64; 3],
) {
    let norm = |v: [f64; 3]| {
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|c| c / n)
    };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    // The camera's frame: x right, y down, z forward.
    let forward = norm(std::array::from_fn(|i| target[i] - eye[i]));
    let right = norm(cross(forward, [0.0, 0.0, 1.0]));
    let down = cross(forward, right);
    let m: [[f64; 3]; 3] = std::array::from_fn(|i| [right[i], down[i], forward[i]]);
    let q = myriad_measure::photos::quaternion(m);
    let focal = (h as f64 / 2.0) / (fov.to_radians() / 2.0).tan();
    let mut wr = e57::E57Writer::from_file(path, "guid-file").unwrap();
    let pose = |p: [f64; 3], q: [f64; 4]| e57::Transform {
        rotation: e57::Quaternion {
            w: q[0],
            x: q[1],
            y: q[2],
            z: q[3],
        },
        translation: e57::Translation {
            x: p[0],
            y: p[1],
            z: p[2],
        },
    };
    let mut img = wr.add_image("guid-pinhole").unwrap();
    img.set_name("camera");
    img.set_transform(pose(eye, q));
    img.add_pinhole(
        e57::ImageFormat::Png,
        &mut &png[..],
        e57::PinholeImageProperties {
            width: w,
            height: h,
            focal_length: focal * 1e-5,
            pixel_width: 1e-5,
            pixel_height: 1e-5,
            principal_x: w as f64 / 2.0,
            principal_y: h as f64 / 2.0,
        },
        None,
    )
    .unwrap();
    img.finalize().unwrap();
    let mut img = wr.add_image("guid-pano").unwrap();
    img.set_name("panorama");
    img.set_transform(pose(pano, [1.0, 0.0, 0.0, 0.0]));
    let flat = flat_png(64, 32, [200, 100, 50]);
    let (pw, ph) = (std::f64::consts::TAU / 64.0, std::f64::consts::PI / 32.0);
    img.add_spherical(
        e57::ImageFormat::Png,
        &mut flat.as_slice(),
        e57::SphericalImageProperties {
            width: 64,
            height: 32,
            pixel_width: pw,
            pixel_height: ph,
        },
        None,
    )
    .unwrap();
    img.finalize().unwrap();
    let mut img = wr.add_image("guid-reference").unwrap();
    img.set_name("site sketch");
    let sketch = flat_png(40, 30, [10, 20, 30]);
    img.add_visual_reference(
        e57::ImageFormat::Png,
        &mut sketch.as_slice(),
        e57::VisualReferenceImageProperties {
            width: 40,
            height: 30,
        },
        None,
    )
    .unwrap();
    img.finalize().unwrap();
    wr.finalize().unwrap();
}
