//! The web viewer (issue 16) in Debian's Chromium, headless (WebGL2 on SwiftShader), on
//! `myriad serve`: a converted scan of 300 k points shows, converged, as `myriad render` draws
//! it for the same camera; the dataset is read by range requests only; picking gives the
//! point's attributes as stored; measuring, the camera link and the clipping box with its LAZ
//! download work. Skipped (with a message) where Chromium is missing; `.ci/run` installs it.

mod common;
use common::{myriad, ok, s, serve, tempdir};
use myriad_core::NodeKey;
use myriad_format::Dataset;
use myriad_serve::browser::{self, Browser};
use serde_json::Value;
use std::time::Duration;

const W: u32 = 800;
const H: u32 = 600;
const CONVERGED: &str = "window.myriad && (myriad.state.converged || myriad.state.errors.length > 0) \
                         && myriad.state";

fn png(bytes: &[u8]) -> (u32, u32, Vec<[u8; 3]>) {
    let mut r = png::Decoder::new(std::io::Cursor::new(bytes))
        .read_info()
        .unwrap();
    let mut buf = vec![0; r.output_buffer_size().unwrap()];
    let info = r.next_frame(&mut buf).unwrap();
    let step = info.color_type.samples();
    let px = buf[..info.buffer_size()]
        .chunks(step)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    (info.width, info.height, px)
}

fn lit(c: [u8; 3]) -> bool {
    c.iter().map(|&v| v as u32).sum::<u32>() > 30
}

fn converge(b: &mut Browser) -> Value {
    let st = b.wait_for(CONVERGED, Duration::from_secs(240)).unwrap();
    assert_eq!(st["errors"], serde_json::json!([]), "{st}");
    st
}

/// Where the page's camera draws `p` (CSS pixels from the canvas's top left).
fn on_screen(b: &mut Browser, p: [f64; 3]) -> (f64, f64) {
    let cam = b.eval("myriad.camera()").unwrap();
    let v3 = |k: &str| -> [f64; 3] { std::array::from_fn(|a| cam[k][a].as_f64().unwrap()) };
    let camera = myriad_lod::Camera {
        position: v3("position"),
        target: v3("target"),
        up: v3("up"),
        fov_y: cam["fov"].as_f64().unwrap(),
        width: W,
        height: H,
        near: 1.0,
        far: 2.0,
    };
    let e = camera.to_eye(p);
    (
        W as f64 / 2.0 + e[0] / e[2] * camera.focal(),
        H as f64 / 2.0 - e[1] / e[2] * camera.focal(),
    )
}

#[test]
fn the_web_viewer_draws_picks_measures_clips_and_links() {
    let Some(exe) = browser::find() else {
        eprintln!("SKIPPED: no Chromium (apt-get install chromium; .ci/run installs it)");
        return;
    };
    let d = tempdir("web");
    let laz = d.join("s.laz");
    let r = myriad(&[
        "synth",
        "-o",
        s(&laz),
        "--points",
        "300k",
        "--scene",
        "city",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let myr = d.join("s.myr");
    let r = myriad(&["convert", s(&laz), "-o", s(&myr)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let ds = Dataset::open(&myr).unwrap();
    let (entries, _) = ds.nodes();
    // A copy with one node page damaged (not the root's).
    let bad = d.join("bad.myr");
    let mut bytes = std::fs::read(&myr).unwrap();
    let victim = entries
        .iter()
        .filter(|e| e.key.level > 0)
        .max_by_key(|e| e.points)
        .unwrap();
    let at = victim.page.offset as usize + victim.page.length as usize / 2;
    bytes[at] ^= 0x5a;
    std::fs::write(&bad, bytes).unwrap();
    // The same scan built in 4 parts and merged: a dataset of 5 files (the parts linked).
    let plan = common::make_plan(&d, &[&laz], "plan.json");
    let parts = d.join("parts");
    for i in 0..4 {
        ok(&[
            "convert",
            "--plan",
            s(&plan),
            "--part",
            &i.to_string(),
            "-o",
            s(&parts),
        ]);
    }
    let merged = d.join("merged.myr");
    ok(&["merge", s(&plan), s(&parts), "-o", s(&merged)]);
    assert_eq!(Dataset::open(&merged).unwrap().files().len(), 4);
    let single = d.join("single.myr");
    ok(&[
        "merge",
        s(&plan),
        s(&parts),
        "-o",
        s(&single),
        "--single-file",
    ]);
    let log = d.join("serve.log");
    let server = serve(
        &[s(&myr), s(&bad), s(&merged), s(&single), "--log"],
        std::fs::File::create(&log).unwrap().into(),
    );
    let mut b = Browser::launch(&exe).unwrap();

    // Opened at the default camera: everything in, converged, every point drawn (WebGL2 here;
    // WebGPU below).
    b.open(&format!("{}/view/s.myr#renderer=webgl2", server.base), W, H)
        .unwrap();
    let st = converge(&mut b);
    eprintln!("the viewer: {st}");
    assert_eq!(st["points"], 300_000, "{st}");
    assert_eq!(st["nodes"].as_u64(), Some(ds.meta.nodes), "{st}");
    assert!(st["firstImageMs"].as_f64().unwrap() > 0.0);
    assert_eq!(st["renderer"], "webgl2");

    // The same picture as `myriad render` for the same camera (no occlusion culling, EDL).
    b.eval("document.getElementById('panel').style.display = 'none'; new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
        .unwrap();
    let shot = b.screenshot().unwrap();
    std::fs::write(d.join("web.png"), &shot).unwrap();
    let native = d.join("native.png");
    let r = myriad(&[
        "render",
        s(&myr),
        "-o",
        s(&native),
        "--width",
        "800",
        "--height",
        "600",
        "--passes",
        "none",
        "--edl",
        "--occlusion",
        "off",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let (ww, wh, web) = png(&shot);
    let (nw, nh, cpu) = png(&std::fs::read(&native).unwrap());
    assert_eq!((ww, wh), (nw, nh));
    let both = web
        .iter()
        .zip(&cpu)
        .filter(|(a, b)| lit(**a) && lit(**b))
        .count();
    let either = web
        .iter()
        .zip(&cpu)
        .filter(|(a, b)| lit(**a) || lit(**b))
        .count();
    let close = web
        .iter()
        .zip(&cpu)
        .filter(|(a, b)| lit(**a) && lit(**b))
        .filter(|(a, b)| (0..3).all(|k| (a[k] as i32 - b[k] as i32).abs() <= 24))
        .count();
    eprintln!(
        "screenshot against myriad render: {both} of {either} lit pixels in both, {close} within 24 levels"
    );
    assert!(
        either > 50_000,
        "the scan covers much of the view: {either}"
    );
    assert!(both as f64 >= 0.97 * either as f64, "{both} of {either}");
    assert!(close as f64 >= 0.9 * both as f64, "{close} of {both}");

    // WebGPU, where this browser has it: the same picture.
    let mut g = Browser::launch(&exe).unwrap();
    g.open(&format!("{}/view/s.myr#renderer=webgpu", server.base), W, H)
        .unwrap();
    let gpu = g.wait_for(CONVERGED, Duration::from_secs(240)).unwrap();
    if gpu["renderer"] == "webgpu" {
        assert_eq!(gpu["errors"], serde_json::json!([]), "{gpu}");
        g.eval("document.getElementById('panel').style.display = 'none'; new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
            .unwrap();
        let shot = g.screenshot().unwrap();
        std::fs::write(d.join("webgpu.png"), &shot).unwrap();
        let (_, _, px) = png(&shot);
        let same = px
            .iter()
            .zip(&cpu)
            .filter(|(a, b)| lit(**a) && lit(**b))
            .filter(|(a, b)| (0..3).all(|k| (a[k] as i32 - b[k] as i32).abs() <= 24))
            .count();
        let either = px
            .iter()
            .zip(&cpu)
            .filter(|(a, b)| lit(**a) || lit(**b))
            .count();
        eprintln!("WebGPU against myriad render: {same} of {either} lit pixels alike");
        assert!(same as f64 >= 0.9 * either as f64, "{same} of {either}");
    } else {
        eprintln!("SKIPPED (WebGPU part): this Chromium has no working WebGPU: {gpu}");
    }
    drop(g);

    // Picking: the lit pixel nearest the centre gives a point stored in the dataset, whose
    // attributes are those stored.
    let (cx, cy) = (0..ww * wh)
        .filter(|&i| lit(web[i as usize]))
        .map(|i| (i % ww, i / ww))
        .min_by_key(|&(x, y)| (x as i64 - 400).pow(2) + (y as i64 - 380).pow(2))
        .unwrap();
    let p = b.eval(&format!("myriad.pick({cx}, {cy})")).unwrap();
    eprintln!("picked at ({cx}, {cy}): {p}");
    let key: Vec<u32> = p["node"]
        .as_str()
        .unwrap()
        .split('-')
        .map(|v| v.parse().unwrap())
        .collect();
    let key = NodeKey {
        level: key[0],
        cell: [key[1], key[2], key[3]],
    };
    let (entries, _) = ds.nodes();
    let entry = entries
        .iter()
        .find(|e| e.key == key)
        .expect("the node exists");
    let batch = ds.read_node(entry).unwrap();
    let i = p["index"].as_u64().unwrap() as usize;
    assert_eq!(p["x"].as_f64(), Some(batch.positions[i][0]));
    assert_eq!(p["y"].as_f64(), Some(batch.positions[i][1]));
    assert_eq!(p["z"].as_f64(), Some(batch.positions[i][2]));
    assert_eq!(
        p["intensity"].as_u64(),
        Some(batch.intensity.as_ref().unwrap()[i] as u64)
    );
    assert_eq!(
        p["classification"].as_u64(),
        Some(batch.classification.as_ref().unwrap()[i] as u64)
    );
    assert_eq!(
        p["gps_time"].as_f64(),
        Some(batch.gps_time.as_ref().unwrap()[i])
    );
    // ... with its longitude, latitude and ellipsoidal height (the server's PROJ, /geo/) as
    // PROJ gives them for the dataset's CRS (the synthetic city's UTM zone 33N) ...
    if myriad_io::proj::available() {
        let crs = ds.meta.crs.clone().unwrap();
        let want = myriad_io::proj::Geographic::new(&crs)
            .unwrap()
            .of(batch.positions[i])
            .unwrap();
        for (k, w) in ["lon", "lat", "h"].iter().zip(want) {
            let got = p[k].as_f64().unwrap_or_else(|| panic!("no {k}: {p}"));
            assert!((got - w).abs() < 1e-9, "{k}: {got} against {w}");
        }
        let text = b
            .eval("document.getElementById('picked').textContent")
            .unwrap();
        let text = text.as_str().unwrap();
        assert!(text.contains(&format!("lat: {:.8}°", want[1])), "{text}");
        assert!(text.contains("m above the WGS 84 ellipsoid"), "{text}");
        let bad = b
            .eval("fetch('/geo/' + encodeURIComponent(myriad.state.dataset) + '?at=1,2').then((r) => r.status)")
            .unwrap();
        assert_eq!(bad.as_u64(), Some(400));
    } else {
        eprintln!(
            "SKIPPED (longitude and latitude): {}",
            myriad_io::proj::MISSING
        );
    }
    // ... and lies where the click was, as the camera projects it.
    let cam = b.eval("myriad.camera()").unwrap();
    let v3 = |k: &str| -> [f64; 3] { std::array::from_fn(|a| cam[k][a].as_f64().unwrap()) };
    let camera = myriad_lod::Camera {
        position: v3("position"),
        target: v3("target"),
        up: v3("up"),
        fov_y: 60.0,
        width: W,
        height: H,
        near: 1.0,
        far: 2.0,
    };
    let e = camera.to_eye(batch.positions[i]);
    let (sx, sy) = (
        W as f64 / 2.0 + e[0] / e[2] * camera.focal(),
        H as f64 / 2.0 - e[1] / e[2] * camera.focal(),
    );
    assert!(
        (sx - cx as f64).abs() <= 7.0 && (sy - cy as f64).abs() <= 7.0,
        "picked point at ({sx:.1}, {sy:.1}), clicked ({cx}, {cy})"
    );

    // Measuring: two clicks on the canvas in measure mode give the distance between the
    // points they pick.
    b.eval("document.getElementById('measure').click()")
        .unwrap();
    let spots: Vec<(u32, u32)> = [(300, 420), (520, 460)]
        .iter()
        .map(|&(tx, ty)| {
            (0..ww * wh)
                .filter(|&i| lit(web[i as usize]))
                .map(|i| (i % ww, i / ww))
                .min_by_key(|&(x, y)| (x as i64 - tx).pow(2) + (y as i64 - ty).pow(2))
                .unwrap()
        })
        .collect();
    for &(x, y) in &spots {
        b.click(x as f64, y as f64).unwrap();
        std::thread::sleep(Duration::from_millis(300));
    }
    let m = b
        .wait_for(
            "myriad.state.measured && myriad.state.measured.count >= 2 && myriad.state",
            Duration::from_secs(30),
        )
        .unwrap();
    let a: Vec<f64> = (0..3)
        .map(|k| m["measure"][0]["position"][k].as_f64().unwrap())
        .collect();
    let c: Vec<f64> = (0..3)
        .map(|k| m["measure"][1]["position"][k].as_f64().unwrap())
        .collect();
    let want = (0..3).map(|k| (a[k] - c[k]).powi(2)).sum::<f64>().sqrt();
    assert!(want > 1.0, "two different points: {m}");
    assert!(
        (m["measured"]["value"].as_f64().unwrap() - want).abs() < 1e-9,
        "{m}"
    );

    // The link restores the camera it was made at.
    b.eval("myriad.setCamera({ position: [500010.5, 4399990.25, 80.125] })")
        .unwrap();
    converge(&mut b);
    let link = b
        .eval("myriad.link()")
        .unwrap()
        .as_str()
        .unwrap()
        .to_string();
    assert!(
        link.contains("#camera=500010.5,4399990.25,80.125,"),
        "{link}"
    );
    drop(b);
    let mut b = Browser::launch(&exe).unwrap();
    b.open(&link, W, H).unwrap();
    converge(&mut b);
    let cam2 = b.eval("myriad.camera()").unwrap();
    assert_eq!(
        cam2["position"],
        serde_json::json!([500010.5, 4399990.25, 80.125]),
        "{link}"
    );

    // Clipping to a box: fewer points drawn, and the download link gives the points in it.
    let vb = &st["info"]["view_bounds"];
    let v = |k: usize| vb[k].as_f64().unwrap();
    // The middle of the ground plan, every height.
    let bx: Vec<f64> = [0.3, 0.3, -0.1, 0.6, 0.6, 1.1]
        .iter()
        .enumerate()
        .map(|(k, f)| v(k % 3) + f * (v(k % 3 + 3) - v(k % 3)))
        .collect();
    let clip = bx
        .iter()
        .map(|x| format!("{x:.3}"))
        .collect::<Vec<_>>()
        .join(",");
    let bx: Vec<f64> = clip.split(',').map(|x| x.parse().unwrap()).collect();
    drop(b);
    let mut b = Browser::launch(&exe).unwrap();
    b.open(&format!("{}/view/s.myr#clip={clip}", server.base), W, H)
        .unwrap();
    let st = converge(&mut b);
    assert!(st["points"].as_u64().unwrap() < 300_000, "{st}");
    let href = b.eval("document.getElementById('download').href").unwrap();
    let href = href.as_str().unwrap().to_string();
    assert!(href.contains("/x/s.myr?box="), "{href}");
    let mut laz = Vec::new();
    use std::io::Read;
    ureq::get(&href)
        .call()
        .unwrap()
        .into_body()
        .into_reader()
        .read_to_end(&mut laz)
        .unwrap();
    assert_eq!(&laz[..4], b"LASF");
    let count = if laz[25] >= 4 {
        u64::from_le_bytes(laz[247..255].try_into().unwrap())
    } else {
        u32::from_le_bytes(laz[107..111].try_into().unwrap()) as u64
    };
    let inside = entries
        .iter()
        .map(|e| ds.read_node(e).unwrap())
        .flat_map(|b| b.positions)
        .filter(|p| (0..3).all(|a| p[a] >= bx[a] && p[a] <= bx[a + 3]))
        .count() as u64;
    assert!(inside > 1000);
    assert_eq!(count, inside, "points in the box's download");
    drop(b);

    // The class list: buildings hidden by their box, none of their colour is drawn, and the
    // link keeps them hidden.
    let mut b = Browser::launch(&exe).unwrap();
    b.open(
        &format!("{}/view/s.myr#color=classification&edl=0", server.base),
        W,
        H,
    )
    .unwrap();
    let before = converge(&mut b);
    let building = myriad_core::colour::class_colour(6);
    let of_buildings = |b: &mut Browser| {
        b.eval("document.getElementById('panel').style.display = 'none'; new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
            .unwrap();
        let (_, _, px) = png(&b.screenshot().unwrap());
        b.eval("document.getElementById('panel').style.display = ''")
            .unwrap();
        px.iter()
            .filter(|p| (0..3).all(|k| (p[k] as i32 - building[k] as i32).abs() <= 4))
            .count()
    };
    let shown = of_buildings(&mut b);
    assert!(shown > 2000, "{shown} pixels of buildings' colour");
    let rows = b
        .eval("[...document.querySelectorAll('#classes label.class')].map(l => l.textContent)")
        .unwrap();
    assert!(rows.to_string().contains("6 building: "), "{rows}");
    b.eval("document.querySelector('#classes input[data-class=\"6\"]').click()")
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let after = converge(&mut b);
    let buildings = entries
        .iter()
        .map(|e| ds.read_node(e).unwrap())
        .flat_map(|b| b.classification.unwrap())
        .filter(|&c| c == 6)
        .count() as u64;
    assert_eq!(
        after["points"].as_u64().unwrap(),
        before["points"].as_u64().unwrap() - buildings,
        "{after}"
    );
    assert_eq!(
        of_buildings(&mut b),
        0,
        "buildings' colour drawn while hidden"
    );
    let link = b.eval("myriad.link()").unwrap();
    assert!(link.as_str().unwrap().contains("hide=6"), "{link}");
    drop(b);

    // The dataset of five files draws what the same merge in one file draws, its pages
    // fetched from the parts' files (below, in the log), nothing said wrong.
    let mut shown = Vec::new();
    for name in ["merged.myr", "single.myr"] {
        let mut b = Browser::launch(&exe).unwrap();
        b.open(
            &format!("{}/view/{name}#renderer=webgl2", server.base),
            W,
            H,
        )
        .unwrap();
        let st = converge(&mut b);
        assert_eq!(st["errors"], serde_json::json!([]), "{st}");
        b.eval("document.getElementById('panel').style.display = 'none'; new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
            .unwrap();
        shown.push((
            st["points"].clone(),
            st["nodes"].clone(),
            png(&b.screenshot().unwrap()),
        ));
    }
    assert!(shown[0].0.as_u64().unwrap() > 200_000, "{:?}", shown[0].0);
    assert!(shown[0] == shown[1], "points, nodes or pixels differ");

    // A damaged node page: the viewer shows the rest and says which file, node and byte.
    let mut b = Browser::launch(&exe).unwrap();
    b.open(&format!("{}/view/bad.myr", server.base), W, H)
        .unwrap();
    let st = b
        .wait_for(
            "window.myriad && myriad.state.converged && myriad.state",
            Duration::from_secs(240),
        )
        .unwrap();
    let errors = st["errors"].to_string();
    assert!(
        errors.contains("bad.myr") && errors.contains(&format!("byte {}", victim.page.offset)),
        "{st}"
    );
    assert!(
        st["points"].as_u64().unwrap() >= 300_000 - victim.points as u64 - 1,
        "{st}"
    );
    drop(b);

    // The dataset was read by range requests only (the page and its files whole); the
    // browser revalidates ranges it has cached (304).
    drop(server);
    let log = std::fs::read_to_string(&log).unwrap();
    for i in 0..4 {
        let part = format!(" /d/parts/part-{i}.myr ");
        assert!(
            log.lines()
                .any(|l| l.contains(&part) && l.contains(" 206 ")),
            "no page read from{part}: {log}"
        );
    }
    let reads: Vec<&str> = log.lines().filter(|l| l.contains(" /d/s.myr ")).collect();
    assert!(reads.len() >= 10, "{log}");
    for l in &reads {
        assert!(
            l.starts_with("HEAD ")
                || (l.contains("range=bytes=") && (l.contains(" 206 ") || l.contains(" 304 "))),
            "not a range request: {l}"
        );
    }
}

/// Saved work in the browser (`serve --edit`): the annotation and the measurement that
/// `myriad annotate` kept show where the camera projects them, with the server's label; a
/// click places a new annotation, its title is typed in the panel, and both are there, in the
/// sidecar too, when the page opens again.
#[test]
fn the_web_viewer_shows_and_saves_annotations() {
    let Some(exe) = browser::find() else {
        eprintln!("SKIPPED: no Chromium (apt-get install chromium; .ci/run installs it)");
        return;
    };
    let d = tempdir("web-work");
    let laz = d.join("w.laz");
    let r = myriad(&[
        "synth",
        "-o",
        s(&laz),
        "--points",
        "100k",
        "--scene",
        "city",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let myr = d.join("w.myr");
    let r = myriad(&["convert", s(&laz), "-o", s(&myr)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let b0 = Dataset::open(&myr).unwrap().meta.bounds;
    let c = b0.center();
    let top = b0.max[2];
    let r = myriad(&[
        "annotate",
        s(&myr),
        "--add",
        &format!("{},{},{top}", c[0], c[1]),
        "--title",
        "gate",
        "--measure",
        &format!(
            "distance:{},{},{top},{},{},{top}",
            c[0] - 20.0,
            c[1],
            c[0] + 20.0,
            c[1]
        ),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let server = serve(&[s(&myr), "--edit"], std::process::Stdio::null());
    let mut b = Browser::launch(&exe).unwrap();
    b.open(&format!("{}/view/w.myr#renderer=webgl2", server.base), W, H)
        .unwrap();
    converge(&mut b);
    let st = b
        .wait_for(
            "window.myriad && myriad.state.work && myriad.state.work.loaded && myriad.state.work",
            Duration::from_secs(30),
        )
        .unwrap();
    assert_eq!(st["editable"], true, "{st}");
    assert_eq!(st["doc"]["annotations"][0]["title"], "gate", "{st}");
    b.eval("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
        .unwrap();
    let label = b
        .eval(
            "(() => { const e = document.querySelector('#labels .label.annotation'); \
             const r = e.getBoundingClientRect(); \
             return { text: e.textContent, left: r.left, bottom: r.bottom }; })()",
        )
        .unwrap();
    let measured = b
        .eval("document.querySelector('#labels .label.measurement').textContent")
        .unwrap();
    assert_eq!(measured, "40.000 m", "the server's label");
    let (sx, sy) = on_screen(&mut b, [c[0], c[1], top]);
    assert_eq!(label["text"], "gate");
    let (lx, ly) = (
        label["left"].as_f64().unwrap(),
        label["bottom"].as_f64().unwrap(),
    );
    assert!(
        (lx - 10.0 - sx).abs() <= 2.0 && (ly - sy).abs() <= 2.0,
        "label at ({lx}, {ly}), the point at ({sx:.1}, {sy:.1})"
    );
    // Its mark is drawn there.
    let (_, _, px) = png(&b.screenshot().unwrap());
    let marks = px
        .iter()
        .enumerate()
        .filter(|(i, p)| {
            let (x, y) = ((i % W as usize) as f64, (i / W as usize) as f64);
            (x - sx).abs() <= 8.0
                && (y - sy).abs() <= 8.0
                && (p[0] as i32 - 255).abs() <= 6
                && (p[1] as i32 - 64).abs() <= 6
                && (p[2] as i32 - 200).abs() <= 6
        })
        .count();
    assert!(marks >= 60, "{marks} pixels of the mark at the annotation");

    // An area through three clicked points: the figure `myriad annotate` gives for them; kept
    // with the work when measuring stops.
    let spots: Vec<(i64, i64)> = [(450, 330), (650, 330), (600, 450)]
        .iter()
        .map(|&(tx, ty)| {
            px.iter()
                .enumerate()
                .filter(|(_, p)| lit(**p))
                .map(|(i, _)| ((i % W as usize) as i64, (i / W as usize) as i64))
                .filter(|&(x, _)| x > 380)
                .min_by_key(|&(x, y)| (x - tx).pow(2) + (y - ty).pow(2))
                .unwrap()
        })
        .collect();
    b.eval(
        "(() => { const k = document.getElementById('measure-kind'); k.value = 'area'; \
         k.dispatchEvent(new Event('change')); document.getElementById('units').value = '1'; \
         document.getElementById('units').dispatchEvent(new Event('change')); \
         document.getElementById('measure').click(); })()",
    )
    .unwrap();
    for &(x, y) in &spots {
        b.click(x as f64, y as f64).unwrap();
        std::thread::sleep(Duration::from_millis(300));
    }
    let m = b
        .wait_for(
            "myriad.state.measured && myriad.state.measured.count === 3 && myriad.state",
            Duration::from_secs(30),
        )
        .unwrap();
    let pts: Vec<String> = (0..3)
        .flat_map(|i| (0..3).map(move |k| (i, k)))
        .map(|(i, k)| m["measure"][i]["position"][k].to_string())
        .collect();
    // (On a copy elsewhere: the CLI would otherwise write to the work the page saves.)
    std::fs::create_dir_all(d.join("cli")).unwrap();
    std::fs::copy(&myr, d.join("cli/w.myr")).unwrap();
    let cli = myriad(&[
        "annotate",
        s(&d.join("cli/w.myr")),
        "--measure",
        &format!("area:{}", pts.join(",")),
    ]);
    let label = m["measured"]["label"].as_str().unwrap().to_string();
    assert!(label.ends_with("m² area"), "{label}");
    assert!(
        cli.stdout.contains(&format!("measurement 1 area: {label}")),
        "{label} against {}",
        cli.stdout
    );
    b.eval("document.getElementById('measure').click()")
        .unwrap();
    b.wait_for(
        "myriad.state.work.doc.measurements.length === 2 && myriad.state.work.saves >= 1",
        Duration::from_secs(30),
    )
    .unwrap();
    let r = myriad(&["annotate", s(&myr), "--json"]);
    let saved: Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(saved["measurements"][1]["label"], label.as_str(), "{saved}");

    // A click in annotating mode places one; its title typed in the panel; both saved.
    let spot = px
        .iter()
        .enumerate()
        .filter(|(_, p)| lit(**p))
        .map(|(i, _)| ((i % W as usize) as i64, (i / W as usize) as i64))
        .filter(|&(x, _)| x > 380)
        .min_by_key(|&(x, y)| (x - 600).pow(2) + (y - 380).pow(2))
        .unwrap();
    b.eval("document.getElementById('annotate').click()")
        .unwrap();
    b.click(spot.0 as f64, spot.1 as f64).unwrap();
    b.wait_for(
        "myriad.state.work.doc.annotations.length === 2 && myriad.state.work.saves >= 1",
        Duration::from_secs(30),
    )
    .unwrap();
    b.eval(
        "(() => { const t = document.querySelector('#work input.title[data-index=\"1\"]'); \
         t.value = 'well'; t.dispatchEvent(new Event('change')); })()",
    )
    .unwrap();
    b.wait_for("myriad.state.work.saves >= 2", Duration::from_secs(30))
        .unwrap();
    drop(b);
    let mut b = Browser::launch(&exe).unwrap();
    b.open(&format!("{}/view/w.myr#renderer=webgl2", server.base), W, H)
        .unwrap();
    let st = b
        .wait_for(
            "window.myriad && myriad.state.work && myriad.state.work.loaded && myriad.state.work",
            Duration::from_secs(120),
        )
        .unwrap();
    let titles: Vec<&str> = (st["doc"]["annotations"].as_array().unwrap().iter())
        .map(|a| a["title"].as_str().unwrap())
        .collect();
    assert_eq!(titles, ["gate", "well"], "{st}");
    let p = &st["doc"]["annotations"][1]["position"];
    assert!(p[0].as_f64().unwrap() > b0.min[0] - 1.0, "{p}");
    // A cross-section cut in the browser: the points `myriad profile` cuts (the same CSV
    // rows), two clicks in its picture measure between them, its LAZ link the same points.
    converge(&mut b);
    let (x0, x1, yl) = (b0.min[0] + 5.0, b0.max[0] - 5.0, c[1]);
    let cut = b
        .eval(&format!("myriad.cut([[{x0}, {yl}], [{x1}, {yl}]], 2)"))
        .unwrap();
    let csv = d.join("cut.csv");
    let r = myriad(&[
        "profile",
        s(&myr),
        "--line",
        &format!("{x0},{yl},{x1},{yl}"),
        "--width",
        "2",
        "-o",
        s(&csv),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let rows = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(
        cut["points"].as_u64().unwrap() as usize,
        rows.lines().count() - 1,
        "{cut}"
    );
    assert!(cut["points"].as_u64().unwrap() > 100, "{cut}");
    let web_csv = b.eval("myriad.state.section.csv").unwrap();
    assert_eq!(
        web_csv.as_str().unwrap(),
        rows,
        "the same rows as myriad profile's"
    );
    let at = b
        .eval(
            "(() => { const r = document.querySelector('#profile canvas').getBoundingClientRect(); \
             return [r.left, r.top, r.width, r.height]; })()",
        )
        .unwrap();
    let v = |k: usize| at[k].as_f64().unwrap();
    b.click(v(0) + 0.25 * v(2), v(1) + 0.8 * v(3)).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    b.click(v(0) + 0.75 * v(2), v(1) + 0.3 * v(3)).unwrap();
    let between = b
        .wait_for("myriad.state.section.between", Duration::from_secs(30))
        .unwrap();
    let between = between.as_str().unwrap().to_string();
    assert!(
        between.starts_with("along ") && between.contains(" m, slope +"),
        "{between}"
    );
    let href = b
        .eval("document.querySelector('#profile a.laz').href")
        .unwrap();
    let mut laz = Vec::new();
    use std::io::Read;
    ureq::get(href.as_str().unwrap())
        .call()
        .unwrap()
        .into_body()
        .into_reader()
        .read_to_end(&mut laz)
        .unwrap();
    assert_eq!(&laz[..4], b"LASF");
    let count = u32::from_le_bytes(laz[107..111].try_into().unwrap()) as u64;
    let count = if count == 0 {
        u64::from_le_bytes(laz[247..255].try_into().unwrap())
    } else {
        count
    };
    assert_eq!(count, cut["points"].as_u64().unwrap(), "{href}");

    // The top view, then parallel: straight down, a 1° field of view, what is seen at the
    // target the same size, the scan drawn.
    converge(&mut b);
    b.eval("document.getElementById('view-top').click()")
        .unwrap();
    std::thread::sleep(Duration::from_millis(500));
    converge(&mut b);
    let seen = |c: &Value| {
        let v: Vec<f64> = (0..3)
            .map(|k| c["position"][k].as_f64().unwrap() - c["target"][k].as_f64().unwrap())
            .collect();
        let d = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        (
            2.0 * d * (c["fov"].as_f64().unwrap().to_radians() / 2.0).tan(),
            v,
        )
    };
    let (before, v) = seen(&b.eval("myriad.camera()").unwrap());
    assert!(
        v[0].abs() < 1e-6 && v[1].abs() < 1e-6 && v[2] > 0.0,
        "{v:?}"
    );
    b.eval("document.getElementById('parallel').click()")
        .unwrap();
    let st = converge(&mut b);
    let cam = b.eval("myriad.camera()").unwrap();
    assert_eq!(cam["fov"], 1.0, "{cam}");
    let (after, _) = seen(&cam);
    assert!(
        (after - before).abs() < 1e-6 * before,
        "{before} then {after}"
    );
    assert!(st["points"].as_u64().unwrap() > 10_000, "{st}");
    let link = b.eval("myriad.link()").unwrap();
    assert!(
        link.as_str().unwrap().contains("fov=1&parallel=60"),
        "{link}"
    );
    drop(b);
    let r = myriad(&["annotate", s(&myr)]);
    assert!(
        r.stdout.contains("2 annotations, 2 measurements") && r.stdout.contains("\"well\""),
        "{}",
        r.stdout
    );
}

/// Colours, conditions and volumes in the browser: any attribute through a gradient (the grey
/// ramp draws grey, the link keeps it), a `where` condition drops the points that fail it (from
/// the view and from downloads, as `extract --where` does; an unknown attribute is said and
/// changes nothing), and a polygon clicked on stockpiles measures the volume `myriad volume`
/// gives for it, drawn with its base and grid.
#[test]
fn the_web_viewer_colours_filters_and_measures_volumes() {
    let Some(exe) = browser::find() else {
        eprintln!("SKIPPED: no Chromium (apt-get install chromium; .ci/run installs it)");
        return;
    };
    let d = tempdir("web-volume");
    let las = d.join("p.las");
    let r = myriad(&[
        "synth",
        "--scene",
        "stockpiles",
        "-o",
        s(&las),
        "--points",
        "100k",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let piles: Vec<Vec<f64>> = (r.stdout.lines().chain(r.stderr.lines()))
        .filter(|l| l.starts_with("pile "))
        .filter_map(|l| l.split("--polygon ").nth(1))
        .map(|p| p.trim().split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert!(!piles.is_empty(), "{}", r.stdout);
    let myr = d.join("p.myr");
    let r = myriad(&["convert", s(&las), "-o", s(&myr)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let bounds = Dataset::open(&myr).unwrap().meta.bounds;
    let server = serve(&[s(&myr)], std::process::Stdio::null());
    let mut b = Browser::launch(&exe).unwrap();
    b.open(
        &format!("{}/view/p.myr#renderer=webgl2&edl=0", server.base),
        W,
        H,
    )
    .unwrap();
    converge(&mut b);
    b.eval("document.getElementById('view-top').click()")
        .unwrap();
    std::thread::sleep(Duration::from_millis(500));
    converge(&mut b);
    let grey_share = |b: &mut Browser| {
        let (_, _, px) = png(&b.screenshot().unwrap());
        let lit: Vec<_> = px.into_iter().filter(|p| lit(*p)).collect();
        let grey = lit
            .iter()
            .filter(|p| p.iter().max().unwrap() - p.iter().min().unwrap() <= 3)
            .count();
        (grey as f64 / lit.len().max(1) as f64, lit.len())
    };
    let (before, _) = grey_share(&mut b);
    assert!(before < 0.5, "{before} of the scan grey before the ramp");

    // z through the grey gradient: grey, the range fitted within the data's heights.
    b.eval(
        "(() => { const s = document.getElementById('scheme'); s.value = 'ramp:z'; \
         s.dispatchEvent(new Event('change')); })()",
    )
    .unwrap();
    b.wait_for(
        "myriad.state.style && myriad.state.style.color === 'z'",
        Duration::from_secs(30),
    )
    .unwrap();
    b.eval(
        "(() => { const g = document.getElementById('gradient'); g.value = 'grey'; \
         g.dispatchEvent(new Event('change')); })()",
    )
    .unwrap();
    let style = b
        .wait_for(
            "myriad.state.style && myriad.state.style.gradient === 'grey' && myriad.state.style",
            Duration::from_secs(30),
        )
        .unwrap();
    let range: Vec<f64> = (0..2)
        .map(|k| style["range"][k].as_f64().unwrap())
        .collect();
    assert!(
        bounds.min[2] <= range[0] && range[0] < range[1] && range[1] <= bounds.max[2],
        "{style}"
    );
    converge(&mut b);
    let (grey, lit_px) = grey_share(&mut b);
    assert!(
        grey > 0.95 && lit_px > 10_000,
        "{grey} of {lit_px} pixels grey"
    );
    let link = b.eval("myriad.link()").unwrap();
    assert!(
        link.as_str()
            .unwrap()
            .contains("color=z&gradient=grey&range="),
        "{link}"
    );

    // Only the points under the middle height: none drawn above it; downloads the same.
    let cut = (0.5 * (bounds.min[2] + bounds.max[2]) * 1000.0).round() / 1000.0;
    let set_where = |b: &mut Browser, w: &str| {
        b.eval(&format!(
            "(() => {{ const e = document.getElementById('where'); e.value = '{w}'; \
             e.dispatchEvent(new Event('change')); }})()"
        ))
        .unwrap();
    };
    set_where(&mut b, &format!("z<{cut}"));
    b.wait_for(
        &format!("myriad.state.style && myriad.state.style.where === 'z<{cut}'"),
        Duration::from_secs(30),
    )
    .unwrap();
    let st = converge(&mut b);
    assert!(st["points"].as_u64().unwrap() > 1000, "{st}");
    let loaded = b.eval("myriad.loadedBounds()").unwrap();
    let top = loaded[1][2].as_f64().unwrap();
    assert!(top < cut + 0.01, "a point at {top} drawn, above {cut}");
    set_where(&mut b, "nosuch>1");
    let problem = b
        .wait_for("myriad.state.styleProblem", Duration::from_secs(30))
        .unwrap();
    assert!(
        problem
            .as_str()
            .unwrap()
            .contains("no attribute \"nosuch\""),
        "{problem}"
    );
    assert_eq!(
        b.eval("myriad.state.style.where").unwrap(),
        format!("z<{cut}").as_str()
    );
    let c = bounds.center();
    let bbox = format!(
        "{},{},{},{},{},{}",
        c[0] - 30.0,
        c[1] - 30.0,
        bounds.min[2] - 1.0,
        c[0] + 30.0,
        c[1] + 30.0,
        bounds.max[2] + 1.0
    );
    let want = d.join("below.laz");
    let r = myriad(&[
        "extract",
        s(&myr),
        "-o",
        s(&want),
        "--box",
        &bbox,
        "--where",
        &format!("z<{cut}"),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .build()
        .into();
    let get = |q: &str| {
        let mut r = agent
            .get(&format!("{}/x/p.myr?box={bbox}&{q}", server.base))
            .call()
            .unwrap();
        let body = r
            .body_mut()
            .with_config()
            .limit(1 << 30)
            .read_to_vec()
            .unwrap();
        (r.status().as_u16(), body)
    };
    let (status, laz) = get(&format!("where=z%3C{cut}"));
    assert_eq!(status, 200);
    let want = std::fs::read(&want).unwrap();
    let count = |b: &[u8]| match u32::from_le_bytes(b[107..111].try_into().unwrap()) {
        0 => u64::from_le_bytes(b[247..255].try_into().unwrap()),
        n => n as u64,
    };
    assert_eq!(
        count(&laz),
        count(&want),
        "the points extract --where keeps"
    );
    assert!(count(&laz) > 0);
    let (status, body) = get("where=nosuch%3E1");
    assert_eq!(status, 400, "{}", String::from_utf8_lossy(&body));
    assert!(String::from_utf8_lossy(&body).contains("nosuch"));
    set_where(&mut b, "");
    b.wait_for("myriad.state.style.where === ''", Duration::from_secs(30))
        .unwrap();
    converge(&mut b);

    // The first pile's polygon clicked, corner after corner, then measured: the figures
    // `myriad volume` gives for the polygon picked; its base and grid drawn.
    // The first pile seen from above, right of the panel (on the left).
    let pile = piles[0].clone();
    let n = (pile.len() / 2) as f64;
    let (cx, cy) = (
        pile.iter().step_by(2).sum::<f64>() / n,
        pile.iter().skip(1).step_by(2).sum::<f64>() / n,
    );
    let z = 0.5 * (bounds.min[2] + bounds.max[2]);
    b.eval(&format!(
        "myriad.setCamera({{ position: [{}, {cy}, {}], target: [{}, {cy}, {z}], up: [0, 1, 0] }})",
        cx - 20.0,
        z + 80.0,
        cx - 20.0
    ))
    .unwrap();
    converge(&mut b);
    let at: Vec<(f64, f64)> = (pile.chunks_exact(2))
        .map(|c| on_screen(&mut b, [c[0], c[1], z]))
        .collect();
    assert!(
        at.iter()
            .all(|&(x, y)| x > 400.0 && x < W as f64 - 20.0 && y > 20.0 && y < H as f64 - 20.0),
        "{at:?}"
    );
    b.eval("document.getElementById('volume').click()").unwrap();
    for &(x, y) in &at {
        b.click(x, y).unwrap();
        std::thread::sleep(Duration::from_millis(300));
    }
    let corners = pile.len() / 2;
    if let Err(e) = b.wait_for(
        &format!("myriad.state.volume.polygon.length === {corners}"),
        Duration::from_secs(30),
    ) {
        let st = b
            .eval("({ v: myriad.state.volume, e: myriad.state.errors, p: myriad.state.picked, c: myriad.camera() })")
            .unwrap();
        panic!("{e}: {st} after clicks for {pile:?}");
    }
    b.eval("document.getElementById('volume-go').click()")
        .unwrap();
    let st = b
        .wait_for(
            "myriad.state.volume.measured === 1 && myriad.state.volume",
            Duration::from_secs(60),
        )
        .unwrap();
    let polygon: Vec<String> = (st["polygon"].as_array().unwrap().iter())
        .flat_map(|p| [p[0].to_string(), p[1].to_string()])
        .collect();
    let r = myriad(&["volume", s(&myr), "--polygon", &polygon.join(","), "--json"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let cli: Value = serde_json::from_str(r.stdout.trim()).unwrap();
    let web = &st["result"];
    for k in ["fill", "cut", "area", "cells"] {
        let (a, w) = (web[k].as_f64().unwrap(), cli[k].as_f64().unwrap());
        assert!(
            (a - w).abs() <= 1e-9 * w.abs().max(1.0),
            "{k}: {a} in the browser, {w} by myriad volume"
        );
    }
    assert!(web["fill"].as_f64().unwrap() > 100.0, "{web}");
    let shown = b
        .eval("document.getElementById('volume-result').textContent")
        .unwrap();
    let want = format!("fill {:.3} m³", cli["fill"].as_f64().unwrap());
    assert!(
        shown.as_str().unwrap().starts_with(&want),
        "{shown} against {want}"
    );
    b.eval("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
        .unwrap();
    let cells = b
        .eval("document.querySelectorAll('#labels polygon.fill').length")
        .unwrap();
    assert!(
        cells.as_u64().unwrap() > 10,
        "{cells} squares of fill drawn"
    );
    // The base's outline where its corners project; the polygon's drawn in its yellow.
    let drawn = b
        .eval("document.querySelector('#labels polyline.base').getAttribute('points')")
        .unwrap();
    let drawn: Vec<f64> = (drawn.as_str().unwrap().split([' ', ',']))
        .map(|v| v.parse().unwrap())
        .collect();
    let under = web["base"].as_array().unwrap();
    assert_eq!(drawn.len(), 2 * (under.len() + 1), "{drawn:?}");
    for (k, q) in under.iter().enumerate() {
        let p: [f64; 3] = std::array::from_fn(|a| q[a].as_f64().unwrap());
        let (x, y) = on_screen(&mut b, p);
        assert!(
            (drawn[2 * k] - x).abs() < 1.0 && (drawn[2 * k + 1] - y).abs() < 1.0,
            "base corner {k} drawn at {:?}, projects to ({x}, {y})",
            &drawn[2 * k..2 * k + 2]
        );
    }
    let (_, _, px) = png(&b.screenshot().unwrap());
    let outline = px
        .iter()
        .filter(|p| {
            (p[0] as i32 - 255).abs() <= 10 && (p[1] as i32 - 210).abs() <= 10 && p[2] <= 30
        })
        .count();
    assert!(outline >= 100, "{outline} pixels of the polygon's outline");
    drop(b);
    let _ = std::fs::remove_dir_all(&d);
}

/// Edits in the web viewer (`serve --edit`, issue 70): the dataset's edits (a ground edit, its
/// surface read by range requests) shown as the CLI reads them; a polygon given a class and
/// another's points removed from the page, undo and redo, each giving the same points in
/// `extract`'s output as the same edits made by `classify` on a copy; the points drawn counted
/// after each; the scan and the dataset untouched.
#[test]
fn the_web_viewer_edits_classes_as_the_cli_does() {
    use common::records;
    let Some(exe) = browser::find() else {
        eprintln!("SKIPPED: no Chromium (apt-get install chromium; .ci/run installs it)");
        return;
    };
    let d = tempdir("web-edit");
    let laz = d.join("e.laz");
    let r = myriad(&["synth", "-o", s(&laz), "--points", "80k", "--scene", "city"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let myr = d.join("e.myr");
    ok(&["convert", s(&laz), "-o", s(&myr)]);
    let (laz0, myr0) = (std::fs::read(&laz).unwrap(), std::fs::read(&myr).unwrap());
    ok(&["ground", s(&myr), "--no-count"]);
    // The CLI's copy: the dataset, its edits and the surface they name.
    let cli = d.join("cli");
    std::fs::create_dir_all(&cli).unwrap();
    for f in std::fs::read_dir(&*d).unwrap() {
        let p = f.unwrap().path();
        let n = p.file_name().unwrap().to_string_lossy().to_string();
        if n.starts_with("e.") && !n.ends_with(".laz") {
            std::fs::copy(&p, cli.join(&n)).unwrap();
        }
    }
    let cli_myr = cli.join("e.myr");
    let histogram = |ds: &std::path::Path| {
        let out = d.join("h.las");
        ok(&["extract", s(ds), "-o", s(&out), "--force"]);
        let recs = records(&out);
        let mut h = std::collections::BTreeMap::new();
        for r in &recs {
            *h.entry(r[5].to_string()).or_insert(0u64) += 1;
        }
        (recs, h)
    };
    let server = serve(&[s(&myr), "--edit"], std::process::Stdio::null());
    let mut b = Browser::launch(&exe).unwrap();
    b.open(&format!("{}/view/e.myr#renderer=webgl2", server.base), W, H)
        .unwrap();
    // Every point loaded (80 k under the budget): the classes drawn, counted.
    let drawn = |b: &mut Browser| -> std::collections::BTreeMap<String, u64> {
        converge(b);
        let v = b
            .eval(
                "(() => { const c = {}; for (const n of nodes.values()) for (const [k, v] of \
                 n.classes || []) c[k] = (c[k] || 0) + v; return c; })()",
            )
            .unwrap();
        (v.as_object().unwrap().iter())
            .map(|(k, v)| (k.clone(), v.as_u64().unwrap()))
            .collect()
    };
    let st = b
        .wait_for(
            "window.myriad && myriad.state.editing && myriad.state.editing.loaded && myriad.state.editing",
            Duration::from_secs(60),
        )
        .unwrap();
    assert_eq!(st["editable"], true, "{st}");
    let (_, want) = histogram(&myr);
    assert!(want.get("2").copied().unwrap_or(0) > 10_000, "{want:?}");
    assert_eq!(
        drawn(&mut b),
        want,
        "the ground edit drawn as extract reads it"
    );
    // Coloured by height above its terrain (the workers read the surface by ranges).
    let styled = b
        .eval(
            "(async () => { settings.ramp = { name: 'above_ground', gradient: null, range: null }; \
             return await applyStyle(); })()",
        )
        .unwrap();
    assert_eq!(
        styled,
        true,
        "{}",
        b.eval("myriad.state.styleProblem").unwrap()
    );
    let st = converge(&mut b);
    assert_eq!(st["style"]["gradient"], "turbo", "{st}");
    assert_eq!(st["style"]["range"][0], 0.0, "{st}");
    // The terrain's contours over the view, as the CLI's lines from the same terrain.
    let lines = b.eval("myriad.contours(2)").unwrap().as_u64().unwrap();
    assert!(lines > 0, "{lines} contour lines");
    b.eval("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
        .unwrap();
    let drawn_lines = b
        .eval("document.querySelectorAll('#labels polyline.contour').length")
        .unwrap();
    assert!(drawn_lines.as_u64().unwrap() > 0, "{drawn_lines} drawn");
    let zs = b
        .eval("[...new Set(myriad.state.contours.lines.map((c) => c.z))]")
        .unwrap();
    assert!(
        (zs.as_array().unwrap().iter()).all(|z| (z.as_f64().unwrap() / 2.0).fract() == 0.0),
        "levels at multiples of 2: {zs}"
    );

    // A polygon given class 6 and another's points removed, from the page and by the CLI.
    let bounds = Dataset::open(&myr).unwrap().meta.bounds;
    let at = |fx: f64, fy: f64| {
        [
            bounds.min[0] + fx * (bounds.max[0] - bounds.min[0]),
            bounds.min[1] + fy * (bounds.max[1] - bounds.min[1]),
        ]
    };
    let p1 = [at(0.1, 0.1), at(0.6, 0.2), at(0.4, 0.7), at(0.15, 0.5)];
    let p2 = [at(0.6, 0.6), at(0.9, 0.6), at(0.9, 0.95), at(0.6, 0.9)];
    let js = |p: &[[f64; 2]; 4]| serde_json::to_string(&p.to_vec()).unwrap();
    let arg = |p: &[[f64; 2]; 4]| {
        p.iter()
            .map(|q| format!("{},{}", q[0], q[1]))
            .collect::<Vec<_>>()
            .join(",")
    };
    let done = b.eval(&format!("myriad.edit({}, 6)", js(&p1))).unwrap();
    assert!(done.as_str().unwrap().starts_with("edit 2: "), "{done}");
    ok(&[
        "classify",
        s(&cli_myr),
        "--polygon",
        &arg(&p1),
        "--to",
        "6",
        "--no-count",
    ]);
    b.eval(&format!("myriad.edit({}, 'remove')", js(&p2)))
        .unwrap();
    ok(&[
        "classify",
        s(&cli_myr),
        "--polygon",
        &arg(&p2),
        "--remove",
        "--no-count",
    ]);
    let (served, h) = histogram(&myr);
    let (by_cli, _) = histogram(&cli_myr);
    assert_eq!(served, by_cli, "the page's edits are the CLI's");
    assert!(served.len() < 75_000, "{} points left", served.len());
    assert_eq!(drawn(&mut b), h, "the edited points drawn");
    let st = b.eval("myriad.state").unwrap();
    assert_eq!(st["points"].as_u64(), Some(served.len() as u64), "{st}");

    // Undo (the page) and the CLI's undo: the removal gone; redo brings it back.
    b.eval("myriad.undoEdit()").unwrap();
    ok(&["classify", s(&cli_myr), "--undo"]);
    let (served, h) = histogram(&myr);
    assert_eq!(served, histogram(&cli_myr).0);
    assert_eq!(served.len(), 80_000);
    assert_eq!(drawn(&mut b), h);
    b.eval("myriad.redoEdit()").unwrap();
    assert_eq!(histogram(&myr).0.len(), by_cli.len());
    let st = b.eval("myriad.state.editing").unwrap();
    assert_eq!(st["layer"]["edits"].as_array().unwrap().len(), 3, "{st}");
    assert_eq!(
        (std::fs::read(&laz).unwrap(), std::fs::read(&myr).unwrap()),
        (laz0, myr0),
        "the scan and the dataset untouched"
    );
}

/// Issue 71 in the web viewer: the class scheme kept with the saved work names, colours and
/// hides classes (the class list its legend, the points its colours); a camera path recorded
/// with "add view" (and key J) is saved with the work as `view` and `render --path` read it, and
/// plays.
#[test]
fn the_web_viewer_uses_the_class_scheme_and_records_camera_paths() {
    let Some(exe) = browser::find() else {
        eprintln!("SKIPPED: no Chromium (apt-get install chromium; .ci/run installs it)");
        return;
    };
    let d = tempdir("web-scheme");
    let laz = d.join("w.laz");
    ok(&["synth", "-o", s(&laz), "--points", "100k"]);
    let myr = d.join("w.myr");
    ok(&["convert", s(&laz), "-o", s(&myr)]);
    let scheme = d.join("scheme.json");
    std::fs::write(
        &scheme,
        r##"{"classes": {"6": {"name": "houses", "colour": "#0000ff"}, "5": {"hidden": true}}}"##,
    )
    .unwrap();
    ok(&["annotate", s(&myr), "--classes-scheme", s(&scheme)]);
    let server = serve(&[s(&myr), "--edit"], std::process::Stdio::null());
    let mut b = Browser::launch(&exe).unwrap();
    b.open(
        &format!(
            "{}/view/w.myr#renderer=webgl2&color=classification",
            server.base
        ),
        W,
        H,
    )
    .unwrap();
    converge(&mut b);
    b.eval("document.getElementById('panel').style.display = 'none'; new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
        .unwrap();
    let (_, _, px) = png(&b.screenshot().unwrap());
    b.eval("document.getElementById('panel').style.display = ''")
        .unwrap();
    let near = |p: &[u8; 3], c: [u8; 3]| (0..3).all(|k| (p[k] as i32 - c[k] as i32).abs() <= 4);
    let blue = px.iter().filter(|p| near(p, [0, 0, 255])).count();
    let old = px.iter().filter(|p| near(p, [230, 90, 60])).count();
    let trees = px.iter().filter(|p| near(p, [0, 110, 0])).count();
    assert!(
        blue > 2000 && old == 0 && trees == 0,
        "{blue} blue, {old} of the default building colour, {trees} of trees"
    );
    let rows = b
        .eval("[...document.querySelectorAll('#classes label.class')].map(l => [l.textContent, l.querySelector('input').checked])")
        .unwrap()
        .to_string();
    for want in [
        r#"6 houses: "#,
        r#"5 high vegetation: "#,
        r#"7 low point: 0",false"#,
    ] {
        assert!(rows.contains(want), "{want} in {rows}");
    }
    assert!(rows.contains(r#"5 high vegetation: "#) && !rows.contains(r#"high vegetation: 0"#));
    let link = b.eval("myriad.link()").unwrap();
    assert!(
        !link.as_str().unwrap().contains("hide="),
        "the scheme's hidden classes: {link}"
    );

    // Legends over the view: a gradient colouring's, and the parallel view's scale bar.
    b.eval(
        "(() => { const s = document.getElementById('scheme'); s.value = 'ramp:z'; \
         s.dispatchEvent(new Event('change')); myriad.setParallel(true); })()",
    )
    .unwrap();
    let shown = b
        .wait_for(
            "myriad.state.style && myriad.state.style.color === 'z' && \
             getComputedStyle(document.getElementById('ramp-legend')).display === 'block' && \
             getComputedStyle(document.getElementById('scalebar')).display === 'block' && \
             [document.getElementById('ramp-legend').textContent, \
              document.querySelector('#scalebar .text').textContent, \
              document.querySelector('#scalebar .bar').getBoundingClientRect().width]",
            Duration::from_secs(30),
        )
        .unwrap();
    assert!(
        shown[0].as_str().unwrap().starts_with("elevation"),
        "{shown}"
    );
    assert!(shown[1].as_str().unwrap().ends_with(" m"), "{shown}");
    let bar = shown[2].as_f64().unwrap();
    assert!(bar > W as f64 / 10.0 && bar < W as f64 * 0.3, "{shown}");
    b.eval(
        "(() => { const s = document.getElementById('scheme'); s.value = 'classification'; \
         s.dispatchEvent(new Event('change')); myriad.setParallel(false); })()",
    )
    .unwrap();
    // A profile's picture has its axes labelled (the ink of the labels, in the PNG it saves).
    let b0 = Dataset::open(&myr).unwrap().meta.bounds;
    let (c, x0, x1) = (b0.center(), b0.min[0] + 5.0, b0.max[0] - 5.0);
    let ink = b
        .eval(&format!(
            "myriad.cut([[{x0}, {y}], [{x1}, {y}]], 3).then(() => {{ \
               const c = document.querySelector('#profile canvas'); \
               const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; let n = 0; \
               for (let i = 0; i < d.length; i += 4) if (d[i] === 40 && d[i + 1] === 40 && d[i + 2] === 40) n++; \
               return [n, document.querySelector('#profile a.png').href.length]; }})",
            y = c[1]
        ))
        .unwrap();
    assert!(ink[0].as_u64().unwrap() > 20, "{ink}: the labels' ink");

    // A camera path: two views (the button, then key J after the camera moved), saved, played.
    b.eval("document.getElementById('path-name').value = 'tour'; document.getElementById('path-name').onchange({target: document.getElementById('path-name')}); document.getElementById('path-add').click()")
        .unwrap();
    b.eval("(() => { const c = myriad.camera(); myriad.setCamera({position: c.position.map((v, i) => i === 2 ? v + 50 : v)}); })()")
        .unwrap();
    b.eval("window.dispatchEvent(new KeyboardEvent('keydown', {key: 'j'})); document.getElementById('path-save').click()")
        .unwrap();
    b.wait_for(
        "myriad.state.work.saves > 0 && myriad.state.work.doc.paths",
        Duration::from_secs(30),
    )
    .unwrap();
    let saved: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("w.work.json")).unwrap()).unwrap();
    assert_eq!(saved["paths"][0]["name"], "tour", "{saved}");
    assert_eq!(saved["paths"][0]["views"].as_array().unwrap().len(), 2);
    assert_eq!(saved["paths"][0]["views"][1]["time"], 2.0);
    assert_eq!(
        saved["classes"]["6"]["name"], "houses",
        "the scheme kept: {saved}"
    );
    b.eval("document.getElementById('path-play').click()")
        .unwrap();
    b.wait_for("myriad.state.paths.played === 1", Duration::from_secs(30))
        .unwrap();
    drop(b);
    // `render --path tour` flies what the page saved.
    let out = ok(&[
        "render",
        s(&myr),
        "--path",
        "tour",
        "--fps",
        "2",
        "-o",
        s(&d.join("f")),
        "--raster",
        "cpu",
        "--width",
        "64",
        "--height",
        "48",
    ]);
    assert!(out.contains("5 frames of 64x48"), "{out}");
}

/// Issue 71: the map beside the view. Tiles from a local server (one colour each) are asked at
/// the zoom and place pyproj gives for the dataset's corners; the footprint is drawn over them;
/// a click on the map moves the camera there; a dataset without a CRS says why the map is off.
#[test]
fn the_web_viewer_shows_a_map_beside_the_view() {
    let Some(exe) = browser::find() else {
        eprintln!("SKIPPED: no Chromium (apt-get install chromium; .ci/run installs it)");
        return;
    };
    if !common::proj() {
        return;
    }
    let d = tempdir("web-map");
    let laz = d.join("m.laz");
    ok(&["synth", "-o", s(&laz), "--points", "50k"]);
    let myr = d.join("m.myr");
    ok(&["convert", s(&laz), "-o", s(&myr)]);
    let e57 = d.join("room.e57");
    ok(&[
        "synth",
        "-o",
        s(&e57),
        "--points",
        "20k",
        "--scene",
        "indoor",
    ]);
    let room = d.join("room.myr");
    ok(&["convert", s(&e57), "-o", s(&room)]);
    let tiles = common::tile_server([10, 120, 200]);
    let server = serve(&[s(&myr), s(&room)], std::process::Stdio::null());
    let mut b = Browser::launch(&exe).unwrap();
    let template = tiles.template.replace('{', "%7B").replace('}', "%7D");
    b.open(
        &format!("{}/view/m.myr#renderer=webgl2&map={template}", server.base),
        W,
        H,
    )
    .unwrap();
    converge(&mut b);
    let counts = b
        .wait_for(
            "myriad.state.map.requested.length > 0 && \
             myriad.state.map.requested.every((t) => { const i = myriad.state.map.images.get(t.url); return i.complete; }) && \
             (() => { myriad.state.map.drawn = 0; mapDraw(); \
               const d = document.querySelector('#map canvas').getContext('2d').getImageData(0, 0, 256, 256).data; \
               let tile = 0, line = 0; \
               for (let i = 0; i < d.length; i += 4) { \
                 if (d[i] === 10 && d[i + 1] === 120 && d[i + 2] === 200) tile++; \
                 if (d[i] > 240 && d[i + 1] > 190 && d[i + 1] < 230 && d[i + 2] < 40) line++; } \
               return [tile, line]; })()",
            Duration::from_secs(30),
        )
        .unwrap();
    let (tile, line) = (counts[0].as_u64().unwrap(), counts[1].as_u64().unwrap());
    assert!(tile > 20_000, "{tile} pixels of tiles");
    assert!(line > 150, "{line} pixels of the footprint");
    let asked = tiles.asked.lock().unwrap().clone();
    let bounds = Dataset::open(&myr).unwrap().meta.bounds;
    common::check_tiles(&asked, &bounds);
    // A click at the map's centre: the camera's target moves to the footprint's centre.
    b.eval(
        "(() => { const c = document.querySelector('#map canvas'); const r = c.getBoundingClientRect(); \
         c.dispatchEvent(new MouseEvent('mousemove', {clientX: r.left + 128, clientY: r.top + 128})); \
         c.dispatchEvent(new MouseEvent('click', {clientX: r.left + 128, clientY: r.top + 128})); })()",
    )
    .unwrap();
    let cam = b.eval("myriad.camera()").unwrap();
    let c = bounds.center();
    let (tx, ty) = (
        cam["target"][0].as_f64().unwrap(),
        cam["target"][1].as_f64().unwrap(),
    );
    assert!(
        (tx - c[0]).abs() < 3.0 && (ty - c[1]).abs() < 3.0,
        "target {tx}, {ty} against {c:?}"
    );
    let cursor = b
        .eval("document.querySelector('#map .cursor').textContent")
        .unwrap();
    assert!(cursor.as_str().unwrap().starts_with("39."), "{cursor}");
    drop(b);
    // No CRS: the map says why it is off.
    let mut b = Browser::launch(&exe).unwrap();
    b.open(
        &format!(
            "{}/view/room.myr#renderer=webgl2&map={template}",
            server.base
        ),
        W,
        H,
    )
    .unwrap();
    converge(&mut b);
    let off = b
        .wait_for("myriad.state.map.off", Duration::from_secs(30))
        .unwrap();
    assert!(
        off.as_str().unwrap().contains("no coordinate system"),
        "{off}"
    );
}

/// Issue 71: photos in the web viewer. The server lists a dataset's photos and gives only the
/// images its list names; the page marks the placed ones, opens one, and views from its pose
/// with the photo over the points.
#[test]
fn the_web_viewer_shows_photos_from_their_poses() {
    let Some(exe) = browser::find() else {
        eprintln!("SKIPPED: no Chromium (apt-get install chromium; .ci/run installs it)");
        return;
    };
    let d = tempdir("web-photos");
    let laz = d.join("p.laz");
    ok(&["synth", "-o", s(&laz), "--points", "50k"]);
    let myr = d.join("p.myr");
    ok(&["convert", s(&laz), "-o", s(&myr)]);
    let e57 = d.join("images.e57");
    let eye = [499_900.0, 4_399_960.0, 60.0];
    common::photo_e57(
        &e57,
        (eye, [500_000.0, 4_400_055.0, 5.0], 50.0),
        &common::flat_png(160, 120, [30, 200, 120]),
        (160, 120),
        [500_000.0, 4_400_020.0, 1.6],
    );
    ok(&["photos", s(&myr), "--add", s(&e57)]);
    // The pump E57's visual reference (a 3072x2304 JPEG, no pose): listed and shown.
    let pump = common::shared_data("pye57__pumpAVisualReferenceImage.e57");
    if let Some(pump) = &pump {
        ok(&["photos", s(&myr), "--add", s(pump)]);
    }
    let server = serve(&[s(&myr)], std::process::Stdio::null());
    let list = common::http_get(&server.base, "/photos/p.myr", &[]);
    assert!(
        list.contains("\"camera\"") && list.contains("\"site sketch\""),
        "{list}"
    );
    let image = ureq::get(&format!("{}/photos/p.myr?file=1.png", server.base))
        .call()
        .unwrap()
        .into_body()
        .read_to_vec()
        .unwrap();
    assert_eq!(
        image,
        std::fs::read(d.join("p.photos").join("1.png")).unwrap()
    );
    for other in ["..%2Fp.myr", "p.photos.json", "4.png"] {
        let r = ureq::get(&format!("{}/photos/p.myr?file={other}", server.base)).call();
        assert!(
            matches!(r, Err(ureq::Error::StatusCode(404))),
            "{other}: {r:?}"
        );
    }
    let mut b = Browser::launch(&exe).unwrap();
    b.open(&format!("{}/view/p.myr#renderer=webgl2", server.base), W, H)
        .unwrap();
    converge(&mut b);
    b.wait_for("myriad.state.photos.loaded", Duration::from_secs(30))
        .unwrap();
    let marks = b
        .eval("[...document.querySelectorAll('.photo-mark')].map((m) => m.title)")
        .unwrap();
    let mut want = vec!["camera", "panorama", "site sketch"];
    if pump.is_some() {
        want.push("pumpVisual");
        b.eval("openPhoto(3)").unwrap();
        let shown = b
            .wait_for(
                "(() => { const i = document.querySelector('#photos .shown img'); \
                  return i && i.complete && i.naturalWidth > 0 && \
                  [i.naturalWidth, document.querySelector('#photos .shown button').disabled]; })()",
                Duration::from_secs(30),
            )
            .unwrap();
        assert_eq!(
            shown,
            serde_json::json!([3072, true]),
            "the pump's image shown, not placed"
        );
    }
    assert_eq!(marks, serde_json::json!(want));
    b.eval("openPhoto(0); viewFromPhoto()").unwrap();
    let shown = b
        .wait_for(
            "getComputedStyle(document.getElementById('photo-over')).display === 'block' && \
             document.getElementById('photo-over').complete && \
             [myriad.camera().position, document.querySelector('#photos .shown img').naturalWidth]",
            Duration::from_secs(30),
        )
        .unwrap();
    for k in 0..3 {
        assert!(
            (shown[0][k].as_f64().unwrap() - eye[k]).abs() < 1e-6,
            "{shown}"
        );
    }
    assert_eq!(shown[1], 160);
    // The panorama (one colour) as a sphere around the eye at its pose.
    b.eval("openPhoto(1); viewFromPhoto()").unwrap();
    let sphere = b
        .wait_for(
            "getComputedStyle(document.getElementById('photo-sphere')).display === 'block' && \
             (() => { const c = document.getElementById('photo-sphere'); \
               const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; let n = 0; \
               for (let i = 0; i < d.length; i += 4) if (d[i] === 200 && d[i + 1] === 100 && d[i + 2] === 50) n++; \
               return [n, c.width * c.height]; })()",
            Duration::from_secs(30),
        )
        .unwrap();
    assert_eq!(
        sphere[0], sphere[1],
        "every pixel of the sphere the panorama's: {sphere}"
    );
}

#[test]
fn the_web_viewer_draws_a_lone_point_no_wider_than_the_native_renderer() {
    // A plane 0.5 apart and one red point 20 above it, one node: nothing within two of the
    // spacings its finest level is drawn at, so it is lone and drawn at most 3 x 3 pixels (its
    // node's spacing would make it about 10 wide from 40 away), in WebGL2 and WebGPU as by
    // `myriad render`.
    let Some(exe) = browser::find() else {
        eprintln!("SKIPPED: no Chromium (apt-get install chromium; .ci/run installs it)");
        return;
    };
    let d = tempdir("web-lone");
    let mut text = String::new();
    for i in 0..200 {
        for j in 0..200 {
            text += &format!("{} {} 0 128 128 128\n", i as f64 * 0.5, j as f64 * 0.5);
        }
    }
    text += "50 50 20 255 0 0\n";
    let txt = d.join("lone.txt");
    std::fs::write(&txt, text).unwrap();
    let myr = d.join("lone.myr");
    ok(&[
        "convert",
        s(&txt),
        "--columns",
        "x,y,z,r,g,b",
        "-o",
        s(&myr),
    ]);
    let red = |px: &[[u8; 3]]| {
        px.iter()
            .filter(|c| c[0] > 200 && c[1] < 60 && c[2] < 60)
            .count()
    };
    let grey = |px: &[[u8; 3]]| px.iter().filter(|c| c[0] > 100 && c[0] == c[2]).count();
    let native = d.join("native.png");
    ok(&[
        "render",
        s(&myr),
        "-o",
        s(&native),
        "--width",
        &W.to_string(),
        "--height",
        &H.to_string(),
        "--camera",
        "50,50,60,50,50,0",
        "--up",
        "0,1,0",
        "--passes",
        "none",
    ]);
    let (_, _, px) = png(&std::fs::read(&native).unwrap());
    let cpu = red(&px);
    assert!(
        (1..=9).contains(&cpu),
        "render: the lone point covers {cpu} pixels"
    );
    let server = serve(&[s(&myr)], std::process::Stdio::null());
    for renderer in ["webgl2", "webgpu"] {
        let mut b = Browser::launch(&exe).unwrap();
        let url = format!(
            "{}/view/lone.myr#renderer={renderer}&camera=50,50,60,50,50,0&up=0,1,0&edl=0",
            server.base
        );
        b.open(&url, W, H).unwrap();
        let st = converge(&mut b);
        if st["renderer"] != renderer {
            eprintln!(
                "SKIPPED {renderer}: this browser has none ({})",
                st["renderer"]
            );
            continue;
        }
        b.eval("document.getElementById('panel').style.display = 'none'; new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
            .unwrap();
        let (_, _, px) = png(&b.screenshot().unwrap());
        let (r, g) = (red(&px), grey(&px));
        eprintln!("{renderer}: the lone point {r} pixels (render: {cpu}), the plane {g}");
        assert!(g > 100_000, "{renderer}: the plane covers {g} pixels");
        assert!(
            (1..=9).contains(&r),
            "{renderer}: the lone point covers {r} pixels (at most 3 x 3)"
        );
    }
}
