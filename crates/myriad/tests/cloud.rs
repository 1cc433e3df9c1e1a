//! The field's cloud formats read in place by the commands (issue 66): Myriad's own COPC export
//! (and copc_converter's, where it is installed) renders as its `.myr` (the same pixels with every point drawn at one pixel, within a small
//! PSNR at the same budget), `profile`, `volume` and `extract --box` find the same points in it,
//! nothing is written beside it, and `myriad serve` hands it to `render` over HTTP.

mod common;
use common::{myriad, s, serve, tempdir};
use std::path::Path;
use std::process::Stdio;

fn pixels(path: &Path) -> Vec<u8> {
    let d = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut r = d.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size().unwrap()];
    r.next_frame(&mut buf).unwrap();
    buf
}

fn psnr(a: &[u8], b: &[u8]) -> f64 {
    let mse = a
        .iter()
        .zip(b)
        .map(|(x, y)| (*x as f64 - *y as f64).powi(2))
        .sum::<f64>()
        / a.len() as f64;
    10.0 * (255.0f64 * 255.0 / mse.max(1e-12)).log10()
}

/// copc_converter, a COPC writer of others' (MYRIAD_COPC_CONVERTER, else on the PATH).
fn copc_converter() -> Option<std::path::PathBuf> {
    if let Ok(p) = std::env::var("MYRIAD_COPC_CONVERTER") {
        return Some(p.into()).filter(|p: &std::path::PathBuf| p.is_file());
    }
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join("copc_converter"))
        .find(|p| p.is_file())
}

fn ok(args: &[&str]) -> String {
    let r = myriad(args);
    assert_eq!(r.code, 0, "{args:?}: {}", r.stderr);
    r.stdout
}

fn names(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_copc_export_reads_in_place_as_its_myr() {
    let d = tempdir("cloud");
    let scan = d.join("scan.laz");
    ok(&["synth", "-o", s(&scan), "--points", "200000"]);
    let myr = d.join("site.myr");
    ok(&["convert", s(&scan), "-o", s(&myr)]);
    let sub = d.join("copc");
    std::fs::create_dir_all(&sub).unwrap();
    let copc = sub.join("site.copc.laz");
    ok(&["export", s(&myr), "-o", s(&copc), "--to", "copc"]);
    let before = names(&sub);

    let render = |input: &str, out: &Path, extra: &[&str]| {
        let mut args = common::render_cpu(input, s(out), ("320", "240"));
        args.extend(extra);
        args.push("--force");
        ok(&args)
    };
    let info: serde_json::Value = serde_json::from_str(&ok(&["info", "--json", s(&myr)])).unwrap();
    let (min, max) = (&info["bounds"]["min"], &info["bounds"]["max"]);
    let f = |v: &serde_json::Value, i: usize| v[i].as_f64().unwrap();
    let (x0, y0, x1, y1) = (f(min, 0), f(min, 1), f(max, 0), f(max, 1));
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let (w, h) = (x1 - x0, y1 - y0);
    // One camera and one colour for both (the default view frames the root node's points,
    // which differ between the hierarchies).
    let camera = format!(
        "{},{},{},{},{},{}",
        cx,
        y0 - 0.8 * h,
        f(max, 2) + 0.8 * h,
        cx,
        cy,
        (f(min, 2) + f(max, 2)) / 2.0
    );
    let fixed = ["--camera", camera.as_str(), "--color", "classification"];
    // Every point at one pixel: the same image.
    let (a, b) = (d.join("full-myr.png"), d.join("full-copc.png"));
    render(
        s(&myr),
        &a,
        &[&fixed[..], &["--full", "--point-size", "fixed:1"]].concat(),
    );
    render(
        s(&copc),
        &b,
        &[&fixed[..], &["--full", "--point-size", "fixed:1"]].concat(),
    );
    // Points of equal depth in a pixel blend in drawing order, which the two hierarchies
    // differ in: a few pixels of the edge of overlaps differ, nothing else.
    let differ = |a: &[u8], b: &[u8]| a.chunks(4).zip(b.chunks(4)).filter(|(x, y)| x != y).count();
    let (pa, pb) = (pixels(&a), pixels(&b));
    let n = differ(&pa, &pb);
    assert!(
        n * 1000 <= pa.len() / 4,
        "every point drawn: {n} pixels differ"
    );
    // At a budget: the hierarchies differ (COPC's export re-places points), the images are
    // close.
    let (a, b) = (d.join("b-myr.png"), d.join("b-copc.png"));
    render(s(&myr), &a, &[&fixed[..], &["--budget", "60k"]].concat());
    let said = render(s(&copc), &b, &[&fixed[..], &["--budget", "60k"]].concat());
    let p = psnr(&pixels(&a), &pixels(&b));
    assert!(p > 20.0, "PSNR {p:.1} dB at the same budget ({said})");

    // The tools find the same points.
    let line = format!("{},{},{},{}", x0 + 0.1 * w, cy, x1 - 0.1 * w, cy);
    let profile = |input: &Path, out: &Path| {
        ok(&[
            "profile",
            s(input),
            "--line",
            &line,
            "--width",
            "2",
            "-o",
            s(out),
        ])
    };
    let (pa, pb) = (d.join("pa.csv"), d.join("pb.csv"));
    let said_a = profile(&myr, &pa);
    let said_b = profile(&copc, &pb);
    let rows = |p: &Path| {
        let mut v: Vec<String> = std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').take(4).collect::<Vec<_>>().join(","))
            .collect();
        v.sort();
        v
    };
    let (ra, rb) = (rows(&pa), rows(&pb));
    assert!(ra.len() > 100, "{said_a}");
    assert_eq!(ra, rb, "the profile's points: {said_a} / {said_b}");
    let polygon = format!(
        "{},{},{},{},{},{},{},{}",
        cx - 0.2 * w,
        cy - 0.2 * h,
        cx + 0.2 * w,
        cy - 0.2 * h,
        cx + 0.2 * w,
        cy + 0.2 * h,
        cx - 0.2 * w,
        cy + 0.2 * h
    );
    let vol = |input: &Path| -> serde_json::Value {
        serde_json::from_str(&ok(&["volume", s(input), "--polygon", &polygon, "--json"])).unwrap()
    };
    let (va, vb) = (vol(&myr), vol(&copc));
    assert_eq!(va["points"], vb["points"], "volume: {va} / {vb}");
    for k in ["fill", "cut"] {
        let (a, b) = (va[k].as_f64().unwrap(), vb[k].as_f64().unwrap());
        // The same points summed in another order.
        assert!(
            (a - b).abs() <= 1e-9 * a.abs().max(1.0),
            "volume {k}: {va} / {vb}"
        );
    }
    let bbox = format!(
        "{},{},{},{},{},{}",
        cx - 0.25 * w,
        cy - 0.25 * h,
        f(min, 2) - 1.0,
        cx + 0.25 * w,
        cy + 0.25 * h,
        f(max, 2) + 1.0
    );
    let (ea, eb) = (d.join("ea.las"), d.join("eb.las"));
    ok(&["extract", s(&myr), "--box", &bbox, "-o", s(&ea)]);
    ok(&["extract", s(&copc), "--box", &bbox, "-o", s(&eb)]);
    let count = |p: &Path| -> u64 {
        let v: serde_json::Value = serde_json::from_str(&ok(&["info", "--json", s(p)])).unwrap();
        v["points"].as_u64().unwrap()
    };
    let n = count(&ea);
    assert!(n > 1000);
    assert_eq!(n, count(&eb), "extract --box: the same points");

    // Nothing was written beside the COPC file.
    assert_eq!(names(&sub), before);

    // A second writer: copc_converter (crates.io; MYRIAD_COPC_CONVERTER or the PATH, as .ci/run
    // installs it): every point in the same pixels, close at the same budget.
    match copc_converter() {
        Some(cc) => {
            let theirs = d.join("cc.copc.laz");
            let out = std::process::Command::new(&cc)
                .args([s(&scan), s(&theirs), "--progress", "plain"])
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            let c = d.join("full-cc.png");
            render(
                s(&theirs),
                &c,
                &[&fixed[..], &["--full", "--point-size", "fixed:1"]].concat(),
            );
            let (pa, pc) = (pixels(&d.join("full-myr.png")), pixels(&c));
            let n = differ(&pa, &pc);
            assert!(
                n * 1000 <= pa.len() / 4,
                "copc_converter's, every point drawn: {n} pixels differ"
            );
            let c = d.join("b-cc.png");
            render(s(&theirs), &c, &[&fixed[..], &["--budget", "60k"]].concat());
            let p = psnr(&pixels(&d.join("b-myr.png")), &pixels(&c));
            assert!(
                p > 20.0,
                "copc_converter's: PSNR {p:.1} dB at the same budget"
            );
        }
        None => eprintln!(
            "SKIPPED (copc_converter's COPC): no copc_converter (cargo install copc_converter; .ci/run installs it)"
        ),
    }

    // The scan cut into four COPC tiles, read as one (a folder of them, and a `.vpc` naming
    // them): every point once, the same image with every point drawn, the same points found.
    let tiles = d.join("tiles");
    std::fs::create_dir_all(&tiles).unwrap();
    // Cut between quantized coordinates: no point on an edge.
    let (mx, my) = (cx + 0.000_37, cy + 0.000_41);
    let mut features = Vec::new();
    for (i, (ax, bx, ay, by)) in [
        (x0 - 1.0, mx, y0 - 1.0, my),
        (mx, x1 + 1.0, y0 - 1.0, my),
        (x0 - 1.0, mx, my, y1 + 1.0),
        (mx, x1 + 1.0, my, y1 + 1.0),
    ]
    .into_iter()
    .enumerate()
    {
        let b = format!(
            "{ax},{ay},{},{bx},{by},{}",
            f(min, 2) - 1.0,
            f(max, 2) + 1.0
        );
        let t = tiles.join(format!("t{i}.copc.laz"));
        ok(&["export", s(&myr), "-o", s(&t), "--to", "copc", "--box", &b]);
        features.push(serde_json::json!({"type": "Feature", "stac_version": "1.0.0", "id": format!("t{i}"),
            "properties": {}, "assets": {"data": {"href": format!("./tiles/t{i}.copc.laz"), "roles": ["data"]}}}));
    }
    let vpc = d.join("site.vpc");
    let fc = serde_json::json!({"type": "FeatureCollection", "features": features});
    std::fs::write(&vpc, fc.to_string()).unwrap();
    let before = names(&tiles);
    for set in [&tiles, &vpc] {
        let v: serde_json::Value = serde_json::from_str(&ok(&["info", "--json", s(set)])).unwrap();
        assert_eq!(v["points"], 200_000, "{v}");
    }
    let t = d.join("full-tiles.png");
    render(
        s(&tiles),
        &t,
        &[&fixed[..], &["--full", "--point-size", "fixed:1"]].concat(),
    );
    let (pa, pt) = (pixels(&d.join("full-myr.png")), pixels(&t));
    let n = differ(&pa, &pt);
    assert!(
        n * 1000 <= pa.len() / 4,
        "tiles, every point drawn: {n} pixels differ"
    );
    let et = d.join("et.las");
    ok(&["extract", s(&vpc), "--box", &bbox, "-o", s(&et)]);
    assert_eq!(
        count(&ea),
        count(&et),
        "extract --box of the tiles: the same points"
    );
    assert_eq!(vol(&vpc)["points"], va["points"], "volume of the tiles");
    let pt = d.join("pt.csv");
    profile(&tiles, &pt);
    assert_eq!(rows(&pt), ra, "the tiles' profile");
    // At a budget the overview draws every tile's share (points at every zoom).
    let bt = d.join("b-tiles.png");
    render(s(&vpc), &bt, &[&fixed[..], &["--budget", "60k"]].concat());
    let p = psnr(&pixels(&d.join("b-myr.png")), &pixels(&bt));
    assert!(p > 18.0, "tiles: PSNR {p:.1} dB at the same budget");
    assert_eq!(names(&tiles), before);
    // A tile that is not there: one line naming it.
    let broken = d.join("broken.vpc");
    let fc = serde_json::json!({"type": "FeatureCollection", "features": [
        {"type": "Feature", "id": "a", "assets": {"data": {"href": "tiles/t0.copc.laz", "roles": ["data"]}}},
        {"type": "Feature", "id": "b", "assets": {"data": {"href": "tiles/gone.copc.laz", "roles": ["data"]}}}]});
    std::fs::write(&broken, fc.to_string()).unwrap();
    let r = myriad(&["info", s(&broken)]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(
        r.stderr.contains("gone.copc.laz") && r.stderr.trim().lines().count() == 1,
        "{}",
        r.stderr
    );

    // A large `.vpc` whose items tell each tile's bounds and count (`proj:bbox`, `pc:count`,
    // as PDAL wrench writes them): 100 items over the four tiles. Every other one is opened up
    // front (64 at most), the others when a view reaches them: the same image with every
    // point drawn (each 25 times, in place), and a missing tile among those opened late is a
    // hole named when reached, not a set that cannot open.
    let told: Vec<serde_json::Value> = (0..4)
        .map(|i| {
            let t = tiles.join(format!("t{i}.copc.laz"));
            let v: serde_json::Value =
                serde_json::from_str(&ok(&["info", "--json", s(&t)])).unwrap();
            let (a, b) = (&v["bounds"]["min"], &v["bounds"]["max"]);
            serde_json::json!({"pc:count": v["points"], "proj:bbox": [a[0], a[1], a[2], b[0], b[1], b[2]]})
        })
        .collect();
    let large = |gone: bool| {
        let features: Vec<serde_json::Value> = (0..100)
            .map(|i| {
                // Item 2 is among those opened first, the odd ones past 50 opened late.
                let href = match gone && ((i % 2 == 1 && i > 50) || i == 2) {
                    true => "./tiles/gone.copc.laz".to_string(),
                    false => format!("./tiles/t{}.copc.laz", i % 4),
                };
                serde_json::json!({"type": "Feature", "stac_version": "1.0.0", "id": format!("i{i}"),
                    "properties": told[i % 4], "assets": {"data": {"href": href, "roles": ["data"]}}})
            })
            .collect();
        serde_json::json!({"type": "FeatureCollection", "features": features}).to_string()
    };
    let lazy = d.join("large.vpc");
    std::fs::write(&lazy, large(false)).unwrap();
    let v: serde_json::Value = serde_json::from_str(&ok(&["info", "--json", s(&lazy)])).unwrap();
    assert_eq!(v["points"], 5_000_000, "{v}");
    let lt = d.join("full-large.png");
    render(
        s(&lazy),
        &lt,
        &[&fixed[..], &["--full", "--point-size", "fixed:1"]].concat(),
    );
    let n = differ(&pixels(&t), &pixels(&lt));
    assert!(
        n * 1000 <= pa.len() / 4,
        "a large .vpc, every point drawn: {n} pixels differ"
    );
    let holes = d.join("holes.vpc");
    std::fs::write(&holes, large(true)).unwrap();
    let hp = d.join("holes.png");
    let mut args = common::render_cpu(s(&holes), s(&hp), ("320", "240"));
    args.extend(["--full", "--force"]);
    let r = myriad(&args);
    eprintln!(
        "a large .vpc with missing tiles: exit {}, {}",
        r.code, r.stderr
    );
    assert!(r.stderr.contains("gone.copc.laz"), "{}", r.stderr);
    assert!(!r.stderr.contains("panicked"), "{}", r.stderr);
    // The holes are theirs alone: the rest is drawn.
    assert!(!r.stderr.contains("nothing left to draw"), "{}", r.stderr);
    assert!(hp.exists(), "{}", r.stderr);

    // A `.vpc` naming itself: one line, not a stack overflow.
    let me = d.join("me.vpc");
    let fc = serde_json::json!({"type": "FeatureCollection", "features": [
        {"type": "Feature", "id": "a", "assets": {"data": {"href": "me.vpc", "roles": ["data"]}}}]});
    std::fs::write(&me, fc.to_string()).unwrap();
    let r = myriad(&["info", s(&me)]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(
        r.stderr.contains("cannot be a tile") && r.stderr.trim().lines().count() == 1,
        "{}",
        r.stderr
    );

    // Over HTTP through `myriad serve`: the same image.
    let server = serve(&[s(&copc)], Stdio::inherit());
    let url = format!("{}/d/site.copc.laz", server.base);
    let c = d.join("http.png");
    let said = render(
        &url,
        &c,
        &[&fixed[..], &["--full", "--point-size", "fixed:1"]].concat(),
    );
    assert_eq!(pixels(&c), pixels(&d.join("full-copc.png")), "{said}");
    let v: serde_json::Value = serde_json::from_str(&ok(&["info", "--json", &url])).unwrap();
    assert_eq!(v["format"], "COPC 1.0");
    assert_eq!(v["points"], 200_000);
}
