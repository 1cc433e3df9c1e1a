//! Sharing (issue 16): `myriad serve` in its own process, every dataset command on its URL as on
//! the file (the same image, a fraction of the bytes), a server that ignores Range refused with
//! a clear error, and a scan opened directly by `render` and `serve` (converted once, kept).

mod common;
use common::{myriad, s, serve, tempdir};
use std::io::{Read, Write};
use std::process::Stdio;

fn pixels(path: &std::path::Path) -> Vec<u8> {
    let d = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut r = d.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size().unwrap()];
    r.next_frame(&mut buf).unwrap();
    buf
}

#[test]
fn datasets_over_http_and_scans_opened_directly() {
    let d = tempdir("remote");
    let scan = d.join("scan.laz");
    let r = myriad(&["synth", "-o", s(&scan), "--points", "300000"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let site = d.join("site.myr");
    // Small nodes: a small image needs the top of the tree only.
    let r = myriad(&["convert", s(&scan), "-o", s(&site), "--capacity", "3000"]);
    assert_eq!(r.code, 0, "{}", r.stderr);

    // The scan given to serve is converted once (its preview served meanwhile) and served as
    // scan.myr.
    let server = serve(&[s(&site), s(&scan)], Stdio::inherit());
    common::wait_built(&server.base, "scan.myr");
    let url = format!("{}/d/site.myr", server.base);
    let r = myriad(&["info", "--json", &url]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let v: serde_json::Value = serde_json::from_str(r.stdout.trim()).unwrap();
    assert_eq!(v["points"], 300_000);
    let r = myriad(&["info", "--json", &format!("{}/d/scan.myr", server.base)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let cached: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .filter(|n| n.starts_with(".scan.laz.myriad-") && n.ends_with(".myr"))
        .collect();
    assert_eq!(cached.len(), 1, "{cached:?}");

    // The same image from the URL as from the file, for a fraction of the bytes (a 30 k point
    // budget: the top of the tree).
    let render = |input: &str, out: &std::path::Path| {
        let mut args = common::render_cpu(input, s(out), ("320", "240"));
        args.extend(["--budget", "30k", "--force"]);
        let r = myriad(&args);
        assert_eq!(r.code, 0, "{}", r.stderr);
        r.stdout
    };
    let (local, remote) = (d.join("local.png"), d.join("remote.png"));
    render(s(&site), &local);
    let said = render(&url, &remote);
    assert_eq!(pixels(&local), pixels(&remote));
    let fetched = said
        .lines()
        .find_map(|l| l.strip_prefix("fetched "))
        .unwrap_or_else(|| panic!("no fetched line: {said}"));
    let bytes: u64 = fetched
        .split(' ')
        .next()
        .unwrap()
        .replace(',', "")
        .parse()
        .unwrap();
    let size = std::fs::metadata(&site).unwrap().len();
    assert!(bytes < size / 2, "fetched {bytes} of {size}");
    let r = myriad(&["verify", &url]);
    assert_eq!(r.code, 0, "{}{}", r.stdout, r.stderr);
    let back = d.join("back.las");
    let r = myriad(&["extract", &url, "-o", s(&back)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let r = myriad(&["info", "--json", s(&back)]);
    assert!(r.stdout.contains("\"points\":300000"), "{}", r.stdout);
    // The points in a box, as LAZ: the same file `extract --box` writes.
    let (lo, hi) = (&v["bounds"]["min"], &v["bounds"]["max"]);
    let c = |a: usize, f: f64| {
        let (l, h) = (lo[a].as_f64().unwrap(), hi[a].as_f64().unwrap());
        l + (h - l) * f
    };
    let bbox = format!(
        "{},{},{},{},{},{}",
        c(0, 0.25),
        c(1, 0.25),
        c(2, 0.0),
        c(0, 0.6),
        c(1, 0.5),
        c(2, 1.0)
    );
    let want = d.join("box.laz");
    let r = myriad(&["extract", s(&site), "-o", s(&want), "--box", &bbox]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let get = |url: &str| {
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .build()
            .into();
        let mut r = agent.get(url).call().unwrap();
        let status = r.status().as_u16();
        let points = r
            .headers()
            .get("x-myriad-points")
            .map(|v| v.to_str().unwrap().to_string());
        let body = r
            .body_mut()
            .with_config()
            .limit(1 << 30)
            .read_to_vec()
            .unwrap();
        (status, points, body)
    };
    let (status, points, body) = get(&format!("{}/x/site.myr?box={bbox}", server.base));
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    assert_eq!(body, std::fs::read(&want).unwrap());
    assert!(points.unwrap().parse::<u64>().unwrap() > 1000);
    let (status, _, _) = get(&format!("{}/x/site.myr?box=1,2,3", server.base));
    assert_eq!(status, 400);
    let (status, _, _) = get(&format!("{}/x/nothing.myr?box={bbox}", server.base));
    assert_eq!(status, 404);

    // A name the server does not have: one line naming the URL.
    let missing = format!("{}/d/nothing.myr", server.base);
    let r = myriad(&["info", &missing]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.starts_with(&format!("error: {missing}")) && r.stderr.contains("404"),
        "{}",
        r.stderr
    );
    drop(server);

    // A server that ignores Range (always 200 and the whole file) is refused, and said so.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let body = std::fs::read(&site).unwrap();
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten().take(8) {
            let mut stream = stream;
            let mut buf = [0u8; 4096];
            let _ = stream.read(&mut buf);
            let _ = write!(
                stream,
                "HTTP/1.1 200 OK\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
                body.len()
            );
            let _ = stream.write_all(&body);
        }
    });
    let plain = format!("http://127.0.0.1:{port}/site.myr");
    let r = myriad(&["info", &plain]);
    assert_eq!(r.code, 1, "{}", r.stdout);
    assert!(r.stderr.contains("ignores Range"), "{}", r.stderr);
    assert_eq!(r.stderr.lines().count(), 1, "{}", r.stderr);

    // A scan given to render: converted the first time, reused the next.
    let png = d.join("direct.png");
    let r = myriad(&[
        "render",
        s(&scan),
        "-o",
        s(&png),
        "--raster",
        "cpu",
        "--width",
        "64",
        "--height",
        "48",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stderr.contains("using"), "{}", r.stderr);
    std::fs::remove_dir_all(&d).unwrap();
}

/// A dataset replaced on the server while it is read (issue 40): the reads after the change
/// fail naming it instead of mixing pages of two versions, and the dataset says so; a command
/// writes nothing from it.
#[test]
fn a_dataset_replaced_while_read_fails_instead_of_mixing_versions() {
    let d = tempdir("remote-version");
    let scan = d.join("scan.las");
    let r = myriad(&["synth", "-o", s(&scan), "--points", "100000"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let site = d.join("site.myr");
    let other = d.join("other.myr");
    for (out, cap) in [(&site, "3000"), (&other, "1000")] {
        let r = myriad(&["convert", s(&scan), "-o", s(out), "--capacity", cap]);
        assert_eq!(r.code, 0, "{}", r.stderr);
    }
    let server = serve(&[s(&site)], Stdio::inherit());
    let url = format!("{}/d/site.myr", server.base);
    let ds = myriad_format::Dataset::open(std::path::Path::new(&url)).unwrap();
    let (before, damage) = ds.nodes();
    assert!(damage.is_empty() && !before.is_empty());
    assert!(ds.check_unchanged().is_ok());
    // Replaced as `convert --append` and `--force` do: a new file renamed over the old.
    let tmp = d.join(".site.myr.new");
    std::fs::copy(&other, &tmp).unwrap();
    std::fs::rename(&tmp, &site).unwrap();
    let read = ds.read_node(&before[before.len() / 2]);
    let e = read.expect_err("a page of the new file was taken for the old one's");
    assert!(e.message.contains("changed on the server"), "{}", e.message);
    let e = ds.check_unchanged().unwrap_err().to_string();
    assert!(
        e.contains("site.myr") && e.contains("changed on the server"),
        "{e}"
    );
    // Every read from then on fails the same way, even where the bytes would match.
    assert!(ds.read_node(&before[0]).is_err() || before[0].page.length == 0);
    // A fresh open reads the new version whole.
    let out = d.join("new.las");
    let r = myriad(&["extract", &url, "-o", s(&out)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let r = myriad(&["verify", &url]);
    assert_eq!(r.code, 0, "{}", r.stdout);
}

/// Issue 41 item 3: `serve tiles/` serves a folder of LAS/LAZ tiles as one dataset made of them
/// (`tiles.myr`, kept in the folder), while a folder of an export is still served as it is.
#[test]
fn a_folder_of_tiles_is_served_as_one_dataset() {
    let d = tempdir("serve-tiles");
    let (west, east, want) = common::two_scans(&d);
    let tiles = d.join("tiles");
    std::fs::create_dir_all(&tiles).unwrap();
    for t in [&west, &east] {
        std::fs::rename(t, tiles.join(t.file_name().unwrap())).unwrap();
    }
    let site = d.join("site.myr");
    let (w, e) = (tiles.join("west.laz"), tiles.join("east.laz"));
    let r = myriad(&["convert", s(&w), s(&e), "-o", s(&site)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let cloud = d.join("cloud");
    let r = myriad(&["export", s(&site), "-o", s(&cloud)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let server = serve(&[s(&tiles), s(&cloud)], Stdio::inherit());
    assert!(
        server.lines.iter().any(|l| l.ends_with("/view/tiles.myr")),
        "{:?}",
        server.lines
    );
    assert!(
        server
            .lines
            .iter()
            .any(|l| l.contains("/d/cloud/metadata.json")),
        "{:?}",
        server.lines
    );
    common::wait_built(&server.base, "tiles.myr");
    let r = myriad(&["info", "--json", &format!("{}/d/tiles.myr", server.base)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let v: serde_json::Value = serde_json::from_str(r.stdout.trim()).unwrap();
    assert_eq!(v["points"].as_u64(), Some(want.len() as u64), "{v}");
    // Its dataset is the tiles' records, kept in the folder for next time.
    let kept = common::datasets_in(&tiles);
    assert_eq!(kept.len(), 1, "{kept:?}");
    common::holds(&kept[0], &want);
}
