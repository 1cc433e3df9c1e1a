//! `myriad export` as a user runs it, read back by the field's own readers: COPC by laspy's
//! CopcReader and copclib (Python; `MYRIAD_PYTHON` or `python3` with both installed, as `.ci/run`
//! sets up), Potree 2.0 by the Potree 1.8 viewer of ../shared/peers in headless Chromium. Each
//! prints SKIPPED when its reader is missing. Also the errors: a damaged node, a bad target.

mod common;
use common::{Run, myriad, s, tempdir};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn ok(args: &[&str]) -> Run {
    let r = myriad(args);
    assert_eq!(r.code, 0, "{args:?}: {}", r.stderr);
    r
}

fn skipped(why: &str) {
    let _ = writeln!(std::io::stderr(), "SKIPPED: {why}");
}

/// A synthetic scan of `points` converted with small nodes (a deep tree, many hierarchy pages).
fn dataset(d: &Path, points: &str) -> PathBuf {
    let las = d.join("scan.laz");
    let myr = d.join("scan.myr");
    ok(&["synth", "-o", s(&las), "--points", points, "--force"]);
    ok(&[
        "convert",
        s(&las),
        "-o",
        s(&myr),
        "--capacity",
        "500",
        "--force",
    ]);
    myr
}

fn python() -> Option<String> {
    let candidates = std::env::var("MYRIAD_PYTHON")
        .into_iter()
        .chain(["python3".to_string()]);
    for py in candidates {
        let ok = Command::new(&py)
            .args(["-c", "import laspy, copclib, lazrs"])
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if ok {
            return Some(py);
        }
    }
    None
}

#[test]
fn copc_is_read_by_laspy_and_copclib() {
    let Some(py) = python() else {
        return skipped(
            "no Python with laspy[lazrs] and copclib (MYRIAD_PYTHON); .ci/run installs them",
        );
    };
    let d = tempdir("export-copc");
    let myr = dataset(&d, "200k");
    let copc = d.join("scan.copc.laz");
    let r = ok(&["export", s(&myr), "-o", s(&copc)]);
    assert!(r.stdout.contains("200,000 points"), "{}", r.stdout);
    // Boxes as a user draws them: one inside, one across the edge, one outside.
    let ds = myriad_format::Dataset::open(&myr).unwrap();
    let b = ds.meta.bounds;
    // On the coordinates' grid: laspy rounds a box to it, extract compares the coordinates.
    let q = ds.meta.quantization;
    let at = |f: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|a| {
            let x = b.min[a] + (b.max[a] - b.min[a]) * f[a];
            q.offset[a] + ((x - q.offset[a]) / q.scale[a]).round() * q.scale[a]
        })
    };
    let boxes: Vec<[f64; 6]> = [
        (at([0.2, 0.3, 0.0]), at([0.5, 0.6, 1.0])),
        (at([-0.1, 0.7, 0.0]), at([0.15, 1.2, 1.0])),
        (at([1.1, 1.1, 0.0]), at([1.3, 1.3, 1.0])),
    ]
    .iter()
    .map(|(lo, hi)| [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]])
    .collect();
    let arg = serde_json::to_string(&boxes).unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/readers/copc_check.py");
    let out = Command::new(&py)
        .arg(&script)
        .arg(&copc)
        .arg(&arg)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["header_points"], 200_000, "{v}");
    assert_eq!(v["all"], 200_000, "{v}");
    let levels: u64 = v["levels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l.as_u64().unwrap())
        .sum();
    assert_eq!(levels, 200_000, "every level's points add up: {v}");
    assert!(v["levels"].as_array().unwrap().len() > 4, "{v}");
    assert_eq!(v["laspy_node_points"], 200_000, "{v}");
    assert_eq!(v["laspy_bad_counts"], 0, "{v}");
    assert_eq!(
        v["laspy_outside"], 0,
        "every point in its node's cube (laspy): {v}"
    );
    // Small leaves join their parents' chunks: fewer nodes than the dataset's, the same ones
    // for both readers.
    let nodes = v["laspy_nodes"].as_u64().unwrap();
    assert!(
        nodes > 100 && nodes < ds.meta.nodes,
        "{nodes} of {}: {v}",
        ds.meta.nodes
    );
    assert_eq!(v["copclib_points"], 200_000, "{v}");
    assert_eq!(v["copclib_bad_counts"], 0, "{v}");
    assert_eq!(
        v["copclib_outside"], 0,
        "every point in its node's cube: {v}"
    );
    assert_eq!(v["copclib_nodes"].as_u64(), Some(nodes), "{v}");
    assert_eq!(v["wkt"], true, "{v}");
    for (i, bx) in boxes.iter().enumerate() {
        let las = d.join(format!("box{i}.las"));
        let spec = bx.map(|x| x.to_string()).join(",");
        let e = ok(&["extract", s(&myr), "-o", s(&las), "--box", &spec, "--force"]);
        let n: u64 = e
            .stdout
            .split(": ")
            .nth(1)
            .unwrap()
            .split(' ')
            .next()
            .unwrap()
            .replace(',', "")
            .parse()
            .unwrap();
        assert_eq!(
            v["boxes"][i].as_u64(),
            Some(n),
            "box {i}: laspy against extract --box: {v}"
        );
    }
    assert!(v["boxes"][1].as_u64().unwrap() > 0, "{v}");
    assert_eq!(v["boxes"][2], 0);

    // Filtered: ground and buildings only, as laspy reads the COPC, and as many as extract keeps.
    let some = d.join("some.copc.laz");
    ok(&["export", s(&myr), "-o", s(&some), "--classes", "2,6"]);
    let las = d.join("some.las");
    let e = ok(&["extract", s(&myr), "-o", s(&las), "--classes", "2,6"]);
    let kept: u64 = e
        .stdout
        .split(": ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .replace(',', "")
        .parse()
        .unwrap();
    let out = Command::new(&py)
        .args([
            "-c",
            "import laspy, sys, numpy as np; l = laspy.read(sys.argv[1]); \
             print(len(l.points), sorted(set(np.asarray(l.classification).tolist())))",
            s(&some),
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let said = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        said.trim(),
        format!("{kept} [2, 6]"),
        "laspy on the filtered COPC"
    );
}

#[test]
fn errors_name_the_node_and_the_option() {
    let d = tempdir("export-errors");
    let myr = dataset(&d, "30k");
    let r = myriad(&["export", s(&myr), "-o", s(&d.join("x.txt"))]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("--to"), "{}", r.stderr);
    let r = myriad(&["export", s(&myr), "-o", s(&d.join("x")), "--to", "e57"]);
    assert_eq!(r.code, 2, "{}", r.stderr);
    // A damaged node: the export goes on without it, names it and exits 1.
    let ds = myriad_format::Dataset::open(&myr).unwrap();
    let victim = ds
        .nodes()
        .0
        .into_iter()
        .find(|n| n.points > 100 && n.key.level > 0)
        .unwrap();
    drop(ds);
    let mut bytes = std::fs::read(&myr).unwrap();
    bytes[(victim.page.offset + 12) as usize] ^= 0x40;
    std::fs::write(&myr, &bytes).unwrap();
    let copc = d.join("d.copc.laz");
    let r = myriad(&["export", s(&myr), "-o", s(&copc)]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(!r.stderr.contains("panicked"));
    let k = victim.key;
    let name = format!("{}-{}-{}-{}", k.level, k.cell[0], k.cell[1], k.cell[2]);
    let last = r.stderr.lines().last().unwrap();
    assert!(
        last.starts_with("error: ") && last.contains(&name),
        "{last}"
    );
    assert!(copc.exists(), "the rest was written");
}

/// Serves `routes` (URL prefix, folder) over HTTP/1.1 with single byte ranges, as a static web
/// server does, until the test ends.
fn serve(routes: Vec<(String, PathBuf)>) -> u16 {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let routes = routes.clone();
            std::thread::spawn(move || answer(stream, &routes));
        }
    });
    port
}

fn answer(mut stream: TcpStream, routes: &[(String, PathBuf)]) {
    let mut reader = BufReader::new(stream.try_clone().unwrap());
    let mut line = String::new();
    if reader.read_line(&mut line).is_err() {
        return;
    }
    let mut range = None;
    loop {
        let mut h = String::new();
        if reader.read_line(&mut h).is_err() || h.trim().is_empty() {
            break;
        }
        let lower = h.to_ascii_lowercase();
        if let Some(r) = lower.strip_prefix("range: bytes=") {
            let (a, b) = r.trim().split_once('-').unwrap_or(("0", ""));
            range = Some((a.parse::<u64>().unwrap_or(0), b.parse::<u64>().ok()));
        }
    }
    let url = line
        .split_whitespace()
        .nth(1)
        .unwrap_or("/")
        .split('?')
        .next()
        .unwrap()
        .to_string();
    let file = routes
        .iter()
        .find(|(p, _)| url.starts_with(p.as_str()))
        .map(|(p, dir)| dir.join(&url[p.len()..]))
        .filter(|f| !url.contains("..") && f.is_file());
    let Some(file) = file else {
        let _ = stream
            .write_all(b"HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\nConnection: close\r\n\r\n");
        return;
    };
    let mut body = Vec::new();
    std::fs::File::open(&file)
        .unwrap()
        .read_to_end(&mut body)
        .unwrap();
    let total = body.len() as u64;
    let kind = match file.extension().and_then(|e| e.to_str()) {
        Some("html") => "text/html",
        Some("js") => "application/javascript",
        Some("json") => "application/json",
        Some("css") => "text/css",
        _ => "application/octet-stream",
    };
    let head = match range {
        Some((a, b)) => {
            let b = b.unwrap_or(total - 1).min(total - 1);
            body = body[a as usize..=b as usize].to_vec();
            format!("HTTP/1.1 206 Partial Content\r\nContent-Range: bytes {a}-{b}/{total}\r\n")
        }
        None => "HTTP/1.1 200 OK\r\n".to_string(),
    };
    let _ = stream.write_all(
        format!(
            "{head}Content-Type: {kind}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
            body.len()
        )
        .as_bytes(),
    );
    let _ = stream.write_all(&body);
}

#[test]
fn potree_opens_in_the_potree_viewer() {
    let viewer = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/peers/potree-viewer");
    if !viewer.join("libs/potree/potree.js").is_file() {
        return skipped("../shared/peers/potree-viewer not found");
    }
    let chromium = myriad_serve::browser::find();
    let Some(chromium) = chromium else {
        return skipped("no Chromium (apt-get install chromium; .ci/run installs it)");
    };
    let d = tempdir("export-potree");
    let myr = dataset(&d, "300k");
    let cloud = d.join("cloud");
    let r = ok(&["export", s(&myr), "-o", s(&cloud)]);
    assert!(r.stdout.contains("300,000 points"), "{}", r.stdout);
    let v = in_potree_viewer(&chromium, &viewer, &d, &cloud);
    assert_eq!(v["errors"].as_array().map(|e| e.len()), Some(0), "{v}");
    // The root (at most 500 points here) and nodes below it loaded and drawn (here: 17 nodes,
    // 4,996 points, 13,364 lit pixels, busy machine or not: the page steps the viewer itself).
    assert!(v["points"].as_u64().unwrap() >= 1000, "points visible: {v}");
    assert!(v["loaded"].as_u64().unwrap() >= 2, "{v}");
    assert!(v["lit"].as_u64().unwrap() >= 1000, "lit pixels: {v}");

    // Autzen (Oregon Lambert, feet): the metadata's proj4 string puts it on the viewer's map
    // where PROJ puts the same point (within 3e-5 degrees, 3 m: proj4 leaves out the 1 m shift
    // from NAD83(HARN) to WGS 84 PROJ applies).
    let autzen = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/PDAL__laz_autzen_trim.laz");
    if !autzen.is_file() {
        return skipped("../shared/data/PDAL__laz_autzen_trim.laz not found");
    }
    if !myriad_io::proj::available() {
        return skipped(myriad_io::proj::MISSING);
    }
    let amyr = d.join("autzen.myr");
    ok(&["convert", s(&autzen), "-o", s(&amyr)]);
    let acloud = d.join("autzen");
    ok(&["export", s(&amyr), "-o", s(&acloud)]);
    let v = in_potree_viewer(&chromium, &viewer, &d, &acloud);
    assert_eq!(v["errors"].as_array().map(|e| e.len()), Some(0), "{v}");
    assert!(
        v["projection"].as_str().unwrap().contains("+proj=lcc"),
        "{v}"
    );
    let ll: Vec<f64> = v["lonlat"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let wkt = myriad_format::Dataset::open(&amyr)
        .unwrap()
        .meta
        .crs
        .clone()
        .unwrap();
    let mut geo = myriad_io::proj::Geographic::new(&wkt).unwrap();
    let want = geo.of([ll[2], ll[3], 0.0]).unwrap();
    eprintln!("Potree's map: {:?}, PROJ: {want:?}", &ll[..2]);
    assert!(
        (ll[0] - want[0]).abs() < 3e-5 && (ll[1] - want[1]).abs() < 3e-5,
        "{ll:?} {want:?}"
    );
    // Autzen stadium, Eugene, Oregon.
    assert!(
        (ll[0] + 123.07).abs() < 0.01 && (ll[1] - 44.06).abs() < 0.01,
        "{ll:?}"
    );
}

/// What the Potree viewer showed of the Potree dataset in `cloud` (potree_check.html's report).
fn in_potree_viewer(chromium: &Path, viewer: &Path, d: &Path, cloud: &Path) -> serde_json::Value {
    let page = d.join("page");
    std::fs::create_dir_all(&page).unwrap();
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/readers/potree_check.html"),
        page.join("index.html"),
    )
    .unwrap();
    let port = serve(vec![
        ("/libs/".into(), viewer.join("libs")),
        ("/cloud/".into(), cloud.to_path_buf()),
        ("/".into(), page),
    ]);
    let mut child = Command::new(chromium)
        .args([
            "--headless=new",
            "--no-sandbox",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--virtual-time-budget=60000",
            "--window-size=800,600",
            "--dump-dom",
        ])
        .arg(format!("http://127.0.0.1:{port}/index.html"))
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(180) {
            let _ = child.kill();
            panic!("Chromium did not finish in 180 s");
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let mut dom = String::new();
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut dom)
        .unwrap();
    let result = dom
        .split("<pre id=\"result\">")
        .nth(1)
        .and_then(|r| r.split("</pre>").next())
        .unwrap_or("")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&amp;", "&");
    let v: serde_json::Value = serde_json::from_str(&result)
        .unwrap_or_else(|_| panic!("the page did not report: {result:?}"));
    eprintln!("the Potree viewer: {v}");
    v
}

#[test]
fn bench_convert_sets_our_copc_beside_copc_converter() {
    // A stand-in for copc_converter that records its arguments and writes a file of a known
    // size: the benchmark must run it on the input, measure our convert + export --to copc in
    // the same run, compare the two sizes, and leave no output behind.
    let d = tempdir("bench-copc-peer");
    let las = d.join("scan.laz");
    ok(&["synth", "-o", s(&las), "--points", "60k", "--force"]);
    let args = d.join("args.txt");
    let fake = d.join("copc_converter");
    std::fs::write(
        &fake,
        format!(
            "#!/bin/sh\necho \"$@\" > {}\nhead -c 1000000 /dev/zero > \"$4\"\n",
            args.display()
        ),
    )
    .unwrap();
    Command::new("chmod").arg("+x").arg(&fake).status().unwrap();
    let out = d.join("b.myr");
    let bench = |peer: &Path| {
        myriad(&[
            "bench",
            "convert",
            s(&las),
            "--runs",
            "1",
            "--peer",
            "copc-converter",
            "--copc-converter",
            s(peer),
            "-o",
            s(&out),
        ])
    };
    let r = bench(&fake);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let line = r
        .stdout
        .lines()
        .find(|l| l.contains("copc_converter:"))
        .unwrap_or_else(|| panic!("{}", r.stdout));
    let given = std::fs::read_to_string(&args).unwrap();
    assert!(
        given.starts_with("--progress plain ") && given.contains(s(&las)),
        "{given}"
    );
    // Our COPC of the same input, made again: the ratio printed is its size over 1 MB.
    let myr = d.join("again.myr");
    let copc = d.join("again.copc.laz");
    ok(&["convert", s(&las), "-o", s(&myr)]);
    ok(&["export", s(&myr), "--to", "copc", "-o", s(&copc)]);
    let ours = std::fs::metadata(&copc).unwrap().len() as f64;
    let ratio: f64 = line
        .split("x its size")
        .next()
        .and_then(|l| l.rsplit(", ").next())
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    assert!(
        (ratio - ours / 1e6).abs() < 0.002,
        "{ratio} vs {ours}: {line}"
    );
    assert!(
        line.contains("copc_converter: ") && line.contains("1.0 MB"),
        "{line}"
    );
    // Nothing left of either run.
    let left: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("b."))
        .collect();
    assert!(left.is_empty(), "{left:?}");
    // A missing peer is named.
    let r = bench(&d.join("nowhere"));
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(r.stderr.contains("nowhere"), "{}", r.stderr);
    std::fs::remove_dir_all(&d).ok();
}
