//! `myriad serve SCAN` before the scan has a dataset (issue 41 item 4): the server answers at
//! once with the scan's preview, then the build's snapshots, then the finished dataset, each a
//! version the answers name; the web viewer (Chromium, headless) shows the preview while the
//! build still runs (the server's log says so) and converges on the finished dataset after.

mod common;
use common::{myriad, s, serve, tempdir};
use myriad_serve::browser::{self, Browser};
use std::time::Duration;

const W: u32 = 640;
const H: u32 = 480;

#[test]
fn a_raw_scan_is_served_at_once_and_refined_as_it_is_built() {
    let Some(exe) = browser::find() else {
        eprintln!("SKIPPED: no Chromium (apt-get install chromium; .ci/run installs it)");
        return;
    };
    let d = tempdir("serve-build");
    let laz = d.join("big.laz");
    let r = myriad(&["synth", "-o", s(&laz), "--points", "8M", "--scene", "city"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    // The browser first, so that the page opens as soon as the server answers.
    let mut b = Browser::launch(&exe).unwrap();
    let log = d.join("serve.log");
    let server = serve(&[s(&laz)], std::fs::File::create(&log).unwrap().into());
    b.open(
        &format!("{}/view/big.myr#renderer=webgl2", server.base),
        W,
        H,
    )
    .unwrap();
    // The first image: drawn from a version before the final one (the preview, or a snapshot of
    // what the build has read or built), the build still running.
    let first = b
        .wait_for(
            "window.myriad && (myriad.state.nodes > 0 || myriad.state.errors.length > 0) && myriad.state",
            Duration::from_secs(120),
        )
        .unwrap();
    let said = std::fs::read_to_string(&log).unwrap();
    let brief = |st: &serde_json::Value| {
        [
            "version",
            "building",
            "points",
            "nodes",
            "refreshes",
            "nodesKept",
            "nodesDropped",
            "firstImageMs",
            "errors",
        ]
        .map(|k| format!("{k} {}", st[k]))
        .join(", ")
    };
    eprintln!("first image: {}\nserver log then: {said}", brief(&first));
    assert_eq!(first["errors"], serde_json::json!([]), "{first}");
    assert!(
        said.contains("big.laz: serving its preview while its dataset is built"),
        "{said}"
    );
    assert!(
        !said.contains("its dataset is built, served from now on"),
        "the build ended before the first image: {said}"
    );
    assert_ne!(first["version"], "final", "{first}");
    assert_eq!(first["building"], true, "{first}");

    // Then the viewer follows the build to its end and converges on the finished dataset.
    let last = b
        .wait_for(
            "window.myriad && ((myriad.state.version === 'final' && !myriad.state.building && myriad.state.converged) \
             || myriad.state.errors.length > 0) && myriad.state",
            Duration::from_secs(300),
        )
        .unwrap();
    eprintln!("converged: {}", brief(&last));
    assert_eq!(last["errors"], serde_json::json!([]), "{last}");
    assert!(last["refreshes"].as_u64().unwrap() >= 1, "{last}");
    assert!(
        last["points"].as_u64() > first["points"].as_u64()
            && last["nodes"].as_u64() > first["nodes"].as_u64(),
        "detail grew: {} -> {}",
        brief(&first),
        brief(&last)
    );
    let said = std::fs::read_to_string(&log).unwrap();
    assert!(
        said.contains("big.laz: its dataset is built, served from now on"),
        "{said}"
    );
    // The dataset is kept next to the scan, and a server started again serves it at once.
    let kept: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().ends_with(".myr"))
        .collect();
    assert_eq!(kept.len(), 1, "{kept:?}");
    drop(server);
    let again = serve(&[s(&laz)], std::process::Stdio::piped());
    let head = myriad_format::remote::HttpBytes::open(&format!("{}/d/big.myr", again.base));
    assert!(head.is_ok());
    let _ = std::fs::remove_dir_all(&d);
}

/// A build that fails (a LAZ damaged past its preview: 50 bytes flipped in a chunk) is said
/// everywhere the dataset is read, its preview never passed off as the dataset (issue 67 item
/// 2): `/build/` names the failure, `/d/` answers 500 saying why, a command over HTTP fails in
/// one line, the web viewer shows it.
#[test]
fn a_failed_build_is_said_everywhere() {
    let d = tempdir("serve-failed");
    let laz = d.join("bad.laz");
    let r = myriad(&["synth", "-o", s(&laz), "--points", "200k"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let mut bytes = std::fs::read(&laz).unwrap();
    let mid = bytes.len() / 2;
    for b in &mut bytes[mid..mid + 50] {
        *b ^= 0x5a;
    }
    std::fs::write(&laz, &bytes).unwrap();
    let server = serve(&[s(&laz)], std::process::Stdio::null());
    let t = std::time::Instant::now();
    let answer = loop {
        let a = common::http_get(&server.base, "/build/bad.myr?since=", &[]);
        if a.contains("\"failed\":\"") {
            break a;
        }
        assert!(t.elapsed() < Duration::from_secs(120), "never failed: {a}");
        std::thread::sleep(Duration::from_millis(200));
    };
    assert!(answer.contains("\"building\":false"), "{answer}");
    let a = common::http_get(&server.base, "/d/bad.myr", &["Range: bytes=0-99"]);
    assert!(a.starts_with("HTTP/1.1 500"), "{a}");
    let lower = a.to_ascii_lowercase();
    assert!(
        lower.contains("x-myriad-building: failed") && lower.contains("x-myriad-failed: "),
        "{a}"
    );
    let url = format!("{}/d/bad.myr", server.base);
    let r = myriad(&["info", &url]);
    assert_eq!(r.code, 1, "{}", r.stdout);
    assert!(
        r.stderr.contains("its build on the server failed") && r.stderr.trim().lines().count() == 1,
        "{}",
        r.stderr
    );
    let Some(exe) = browser::find() else {
        eprintln!("SKIPPED (the browser part): no Chromium");
        return;
    };
    let mut b = Browser::launch(&exe).unwrap();
    b.open(
        &format!("{}/view/bad.myr#renderer=webgl2", server.base),
        W,
        H,
    )
    .unwrap();
    let st = b
        .wait_for(
            "window.myriad && myriad.state.errors.length > 0 && myriad.state",
            Duration::from_secs(60),
        )
        .unwrap();
    assert!(
        st["errors"][0]
            .as_str()
            .unwrap()
            .contains("build on the server failed"),
        "{st}"
    );
}

/// A scan changed after its dataset was built, while the server runs (issue 67 item 11): noticed
/// (its size, time or content), served from its new preview and built again, of a new
/// generation: commands over HTTP read the new points, and a version of the old one is gone.
#[test]
fn a_scan_changed_after_its_build_is_built_again() {
    let d = tempdir("serve-changed");
    let laz = d.join("site.laz");
    let r = myriad(&["synth", "-o", s(&laz), "--points", "100k"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let server = serve(&[s(&laz)], std::process::Stdio::null());
    let url = format!("{}/d/site.myr", server.base);
    let points = || {
        let r = myriad(&["info", &url]);
        assert_eq!(r.code, 0, "{}", r.stderr);
        let l = (r.stdout.lines())
            .find(|l| l.trim_start().starts_with("points"))
            .unwrap()
            .to_string();
        l.split_whitespace().nth(1).unwrap().replace(',', "")
    };
    let built = |version: &str| {
        let t = std::time::Instant::now();
        loop {
            let a = common::http_get(&server.base, "/build/site.myr?since=", &[]);
            if a.contains(&format!("\"version\":\"{version}\"")) {
                break;
            }
            assert!(
                t.elapsed() < Duration::from_secs(90),
                "never {version}: {a}"
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    };
    built("final");
    assert_eq!(points(), "100000");
    let head = common::http_get(&server.base, "/d/site.myr?v=final", &["Range: bytes=0-9"]);
    assert!(head.starts_with("HTTP/1.1 206"), "{head}");
    // Another scan in its place.
    let r = myriad(&[
        "synth",
        "-o",
        s(&laz),
        "--points",
        "150k",
        "--seed",
        "9",
        "--force",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    built("final~1");
    assert_eq!(points(), "150000");
    let gone = common::http_get(&server.base, "/d/site.myr?v=final", &["Range: bytes=0-9"]);
    assert!(gone.starts_with("HTTP/1.1 410"), "{gone}");
    // A server started again serves the built dataset at once, as final.
    drop(server);
    let again = serve(&[s(&laz)], std::process::Stdio::null());
    let a = common::http_get(&again.base, "/build/site.myr?since=", &[]);
    assert!(
        a.contains("\"version\":\"final\"") && a.contains("\"building\":false"),
        "{a}"
    );
    let _ = std::fs::remove_dir_all(&d);
}
