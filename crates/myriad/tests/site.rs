//! The web viewer as a static site (issue 66): `myriad export --to web` writes the page, its
//! scripts and WebAssembly and the dataset; Debian's nginx serves the folder as it is and the
//! viewer opens and converges in Chromium with every point; a server that ignores ranges
//! (Python's http.server) is named in one line; `--force` replaces only a site. Skipped (with a
//! message) where Chromium or nginx is missing; `.ci/run` installs both.

mod common;
use common::{myriad, ok, s, tempdir};
use myriad_serve::browser::{self, Browser};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

struct Server(std::process::Child);

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn free_port() -> u16 {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    l.local_addr().unwrap().port()
}

/// Waits until something listens on `port`.
fn listening(port: u16) {
    let t = Instant::now();
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            t.elapsed() < Duration::from_secs(20),
            "nothing listens on {port}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Debian's nginx serving `root` (its own files in `dir`), or `None` where it is missing.
fn nginx(root: &Path, dir: &Path) -> Option<(Server, u16)> {
    let exe = ["/usr/sbin/nginx", "/usr/bin/nginx"]
        .iter()
        .map(Path::new)
        .find(|p| p.exists())?;
    let port = free_port();
    let conf = dir.join("nginx.conf");
    let t = dir.display();
    std::fs::write(
        &conf,
        format!(
            "daemon off; master_process off; pid {t}/nginx.pid; error_log {t}/error.log warn;\n\
             events {{}}\n\
             http {{ access_log off; client_body_temp_path {t}; proxy_temp_path {t};\n\
             fastcgi_temp_path {t}; uwsgi_temp_path {t}; scgi_temp_path {t};\n\
             types {{ text/html html; text/javascript js; application/wasm wasm; }}\n\
             default_type application/octet-stream;\n\
             server {{ listen 127.0.0.1:{port}; root {}; }} }}\n",
            root.display()
        ),
    )
    .unwrap();
    let child = Command::new(exe)
        .args(["-c", s(&conf), "-p", s(dir)])
        .stderr(Stdio::inherit())
        .spawn()
        .ok()?;
    let server = Server(child);
    listening(port);
    Some((server, port))
}

#[test]
fn the_web_viewer_runs_from_a_static_site() {
    let d = tempdir("site");
    let scan = d.join("scan.laz");
    ok(&["synth", "-o", s(&scan), "--points", "100000"]);
    let myr = d.join("town.myr");
    ok(&["convert", s(&scan), "-o", s(&myr)]);
    let site = d.join("site");
    ok(&["export", s(&myr), "-o", s(&site), "--to", "web"]);
    let page = std::fs::read_to_string(site.join("index.html")).unwrap();
    assert!(
        page.contains("window.MYRIAD_SITE = {\"datasets\":[\"data/town.myr\"]}"),
        "{page}"
    );
    assert!(page.contains("src=\"viewer/viewer.js\"") && !page.contains("\"/viewer/"));
    for f in [
        "viewer.js",
        "worker.js",
        "webgl2.js",
        "myriad_web.wasm",
        "draw.wgsl",
    ] {
        assert!(site.join("viewer").join(f).is_file(), "{f}");
    }
    assert_eq!(
        std::fs::read(site.join("data/town.myr")).unwrap(),
        std::fs::read(&myr).unwrap()
    );
    // An existing output: kept without --force; with it, only a site is replaced.
    let again = myriad(&["export", s(&myr), "-o", s(&site), "--to", "web"]);
    assert_eq!(again.code, 1, "{}", again.stderr);
    ok(&["export", s(&myr), "-o", s(&site), "--to", "web", "--force"]);
    let other = d.join("other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("notes.txt"), b"mine").unwrap();
    let r = myriad(&["export", s(&myr), "-o", s(&other), "--to", "web", "--force"]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert_eq!(std::fs::read(other.join("notes.txt")).unwrap(), b"mine");
    // Selections have no meaning for the site: refused.
    let r = myriad(&[
        "export",
        s(&myr),
        "-o",
        s(&d.join("s2")),
        "--to",
        "web",
        "--box",
        "0,0,0,1,1,1",
    ]);
    assert_eq!(r.code, 1, "{}", r.stderr);

    // The cloud formats beside it, read in place by the browser: a COPC file (Myriad's export)
    // and, where the shared data is here, an EPT dataset Entwine wrote (its folder).
    let copc = d.join("town.copc.laz");
    ok(&["export", s(&myr), "-o", s(&copc), "--to", "copc"]);
    let ept =
        Some(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/ept/lone-star-laszip"))
            .filter(|p| p.join("ept.json").is_file());
    if ept.is_none() {
        eprintln!("SKIPPED (the EPT part): ../shared/ept/lone-star-laszip not found");
    }
    let cloud = d.join("cloud");
    let mut args = vec![
        "export",
        s(&myr),
        "-o",
        s(&cloud),
        "--to",
        "web",
        "--add",
        s(&copc),
    ];
    if let Some(e) = &ept {
        args.extend(["--add", s(e)]);
    }
    ok(&args);
    let page = std::fs::read_to_string(cloud.join("index.html")).unwrap();
    assert!(page.contains("\"data/town.copc.laz\""), "{page}");
    if ept.is_some() {
        assert!(
            page.contains("\"data/lone-star-laszip/ept.json\""),
            "{page}"
        );
    }

    // A virtual point cloud beside them: the COPC file as two tiles (a set repeating one file
    // under two items, as big sets are tried here), every point of each.
    let item = |id: &str| {
        serde_json::json!({"type": "Feature", "stac_version": "1.0.0", "id": id, "properties": {},
            "assets": {"data": {"href": "./town.copc.laz", "roles": ["data"]}}})
    };
    let vpc = serde_json::json!({"type": "FeatureCollection", "features": [item("a"), item("b")]});
    std::fs::write(cloud.join("data/twice.vpc"), vpc.to_string()).unwrap();

    // The same files read by the command line from nginx (ranges over HTTP, native readers).
    std::fs::create_dir_all(d.join("nginx-cloud")).unwrap();
    let Some((_cloud_server, cloud_port)) = nginx(&cloud, &d.join("nginx-cloud")) else {
        eprintln!("SKIPPED: no nginx (apt-get install nginx-light; .ci/run installs it)");
        return;
    };
    let info = |url: &str| -> serde_json::Value {
        serde_json::from_str(&ok(&["info", "--json", url])).unwrap()
    };
    let v = info(&format!("http://127.0.0.1:{cloud_port}/data/town.copc.laz"));
    assert_eq!(
        (v["points"].as_u64(), v["format"].as_str()),
        (Some(100_000), Some("COPC 1.0")),
        "{v}"
    );
    let v = info(&format!("http://127.0.0.1:{cloud_port}/data/twice.vpc"));
    assert_eq!(v["points"], 200_000, "{v}");
    if ept.is_some() {
        let url = format!("http://127.0.0.1:{cloud_port}/data/lone-star-laszip/ept.json");
        assert_eq!(info(&url)["points"], 518_862);
        let png = d.join("ept-nginx.png");
        ok(&common::render_cpu(&url, s(&png), ("160", "120")));
    }

    let Some(exe) = browser::find() else {
        eprintln!("SKIPPED: no Chromium (apt-get install chromium; .ci/run installs it)");
        return;
    };
    let Some((_nginx, port)) = nginx(&site, &d) else {
        eprintln!("SKIPPED: no nginx (apt-get install nginx-light; .ci/run installs it)");
        return;
    };
    let mut b = Browser::launch(&exe).unwrap();
    b.open(
        &format!("http://127.0.0.1:{port}/index.html#renderer=webgl2"),
        640,
        480,
    )
    .unwrap();
    let st = b
        .wait_for(
            "window.myriad && (myriad.state.converged || myriad.state.errors.length > 0) && myriad.state",
            Duration::from_secs(240),
        )
        .unwrap();
    eprintln!("the static site on nginx: {st}");
    assert_eq!(st["errors"], serde_json::json!([]), "{st}");
    assert_eq!(st["points"], 100_000, "{st}");

    // This page's origin is not `myriad serve --edit`'s (another port): it reads nothing there
    // and writes nothing (issue 67: any page could write through a local server).
    let served = common::serve(&[s(&myr), "--edit"], Stdio::null());
    let js = format!(
        "(async () => {{ let read, write;\n\
         try {{ await fetch('{0}/d/town.myr', {{ headers: {{ Range: 'bytes=0-3' }} }}); read = 'read'; }} catch (e) {{ read = 'blocked'; }}\n\
         try {{ const r = await fetch('{0}/work/town.myr', {{ method: 'PUT', headers: {{ 'Content-Type': 'application/json' }},\n\
           body: JSON.stringify({{ myriad: 'work', version: 1, annotations: [] }}) }}); write = 'HTTP ' + r.status; }} catch (e) {{ write = 'blocked'; }}\n\
         return read + '/' + write; }})()",
        served.base
    );
    assert_eq!(b.eval(&js).unwrap(), "blocked/blocked");
    assert!(!d.join("town.work.json").exists(), "nothing written");
    drop(served);

    // COPC and EPT from a static server: every point, decoded in the viewer's workers.
    let mut sets = vec![
        ("data/town.copc.laz", 100_000u64),
        ("data/twice.vpc", 200_000),
    ];
    if ept.is_some() {
        sets.push(("data/lone-star-laszip/ept.json", 518_862));
    }
    for (set, points) in sets {
        b.open(
            &format!(
                "http://127.0.0.1:{cloud_port}/index.html?d={set}#renderer=webgl2&budget=1000000"
            ),
            640,
            480,
        )
        .unwrap();
        let st = b
            .wait_for(
                "window.myriad && (myriad.state.converged || myriad.state.errors.length > 0) && myriad.state",
                Duration::from_secs(240),
            )
            .unwrap();
        eprintln!(
            "{set} from nginx: points {}, first image {} ms, converged {} ms, requests {}, bytes {}",
            st["points"], st["firstImageMs"], st["convergedMs"], st["requests"], st["bytes"]
        );
        assert_eq!(st["errors"], serde_json::json!([]), "{set}: {st}");
        // Converged: every point of the small COPC; of the EPT, what is bigger than a pixel in
        // this view (its deepest nodes are finer).
        let drawn = st["points"].as_u64().unwrap();
        assert!(drawn <= points && drawn * 2 > points, "{set}: {st}");
        if set.ends_with(".copc.laz") || set.ends_with(".vpc") {
            assert_eq!(drawn, points, "{set}: {st}");
        }
    }

    // A server that answers a range request with the whole file: one line, nothing drawn.
    let port = free_port();
    let py = Command::new("python3")
        .args([
            "-m",
            "http.server",
            &port.to_string(),
            "--bind",
            "127.0.0.1",
            "--directory",
            s(&site),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn();
    let Ok(py) = py else {
        eprintln!("SKIPPED (the no-range part): no python3");
        return;
    };
    let _py = Server(py);
    listening(port);
    b.open(
        &format!("http://127.0.0.1:{port}/index.html#renderer=webgl2"),
        640,
        480,
    )
    .unwrap();
    let st = b
        .wait_for(
            "window.myriad && myriad.state.errors.length > 0 && myriad.state",
            Duration::from_secs(60),
        )
        .unwrap();
    let errors = st["errors"].as_array().unwrap();
    assert_eq!(errors.len(), 1, "{st}");
    let e = errors[0].as_str().unwrap();
    eprintln!("the site on a server without ranges: {e}");
    assert!(
        e.contains("does not answer range requests") && !e.contains('\n'),
        "{e}"
    );
}
