//! `myriad view` in a real window: under Xvfb (a virtual X server) the viewer opens on a converted
//! scan, orbits a few frames, waits until the view has converged, writes a screenshot of the
//! window and exits; the scan is in the screenshot. Skipped with a message where `xvfb-run` is
//! missing (CI installs it, see .ci/run).

mod common;
use common::decode_png;
use myriad_core::colour::class_colour;
use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

fn myriad() -> Command {
    Command::new(env!("CARGO_BIN_EXE_myriad"))
}

fn tempdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("myriad-view-test-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `myriad view ARGS` under Xvfb until it exits by itself (a hang past 240 s fails the test
/// instead of blocking CI): whether it succeeded, its stdout and stderr; None, saying so, where
/// the window has no Vulkan driver.
fn view_under_xvfb(args: &[&str]) -> Option<(bool, String, String)> {
    let mut child = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1024x768x24"])
        .arg(env!("CARGO_BIN_EXE_myriad"))
        .arg("view")
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let t = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t.elapsed() > Duration::from_secs(240) {
            let _ = child.kill();
            panic!("the viewer did not exit within 240 s");
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    if !status.success() && stderr.contains("No suitable graphics adapter") {
        eprintln!("SKIPPED: no Vulkan driver for the window (CI installs lavapipe)");
        return None;
    }
    Some((status.success(), stdout, stderr))
}

#[test]
fn the_viewer_opens_converges_and_shows_the_scan() {
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        eprintln!("SKIPPED: xvfb-run is not installed (apt-get install xvfb xauth)");
        return;
    }
    let d = tempdir("xvfb");
    let las = d.join("s.las");
    let st = myriad()
        .args([
            "synth",
            "-o",
            las.to_str().unwrap(),
            "--points",
            "300k",
            "--seed",
            "3",
        ])
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let ds = d.join("s.myr");
    let st = myriad()
        .args(["convert", las.to_str().unwrap(), "-o", ds.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    // As a user opens it (on this machine the CPU path draws), then on the window's own GPU
    // adapter (lavapipe: `--gpu`), drawing straight into the window's texture.
    let run = |extra: &[&str]| -> bool {
        let shot = d.join(format!("shot{}.png", extra.len()));
        let mut args = vec![
            ds.to_str().unwrap(),
            "--width",
            "900",
            "--height",
            "600",
            "--orbit-frames",
            "10",
            "--screenshot",
            shot.to_str().unwrap(),
            "--exit-after-converged",
        ];
        args.extend(extra);
        let Some((ok, stdout, stderr)) = view_under_xvfb(&args) else {
            return false;
        };
        assert!(ok, "{extra:?}: {stdout}\n{stderr}");
        assert!(stdout.contains("orbiting 10 frames"), "{stdout}");
        // Once the orbit ends the view rests: drawn again at the full resolution.
        assert!(stdout.contains("at rest: "), "{stdout}");
        // A surface on the window's GPU adapter (lavapipe here) is made there, as the frames.
        if extra.contains(&"--surface") {
            let on_gpu = extra.contains(&"--gpu");
            assert!(stdout.contains("cells made on"), "{stdout}");
            assert_eq!(!stdout.contains("made on the CPU"), on_gpu, "{stdout}");
        }
        assert!(stdout.contains("screenshot written"), "{stdout}");
        // The window as shown: panels on the left, the scan in the view. The view (right of the
        // panel) is mostly the scan: not black.
        let (w, h, img) = decode_png(&shot);
        assert!(w >= 800 && h >= 500, "{w}x{h}");
        let mut lit = 0;
        let mut total = 0;
        for y in 0..h as usize {
            for x in (w as usize / 2)..w as usize {
                let p = &img[(y * w as usize + x) * 4..][..3];
                total += 1;
                if p != [0, 0, 0] {
                    lit += 1;
                }
            }
        }
        // (Filtered to the ground without hole filling, fewer pixels show: checked below.)
        let filtered = extra.contains(&"--classes");
        assert!(
            lit * 4 > total || (filtered && lit * 20 > total),
            "{extra:?}: {lit} of {total} pixels of the view show the scan"
        );
        true
    };
    // On the GPU also with hardware occlusion queries, read a frame or more late.
    // And the surface the points make (Schiffner et al. 2015), which the window shows from the CPU
    // even where the points went straight to its texture.
    if run(&[]) && run(&["--gpu"]) {
        run(&["--gpu", "--occlusion", "queries"]);
        run(&["--gpu", "--surface", "quads", "--grid", "100x80x30"]);
        // Both eyes side by side (Discher et al. 2018).
        run(&["--stereo", "--ipd", "5"]);
    }
    // Any attribute through a gradient (the panel then offers the gradient and the range).
    run(&["--color", "gps_time", "--gradient", "turbo"]);
    // Straight down in the parallel (orthographic) view.
    run(&["--view", "top", "--parallel"]);
    // Filtered: ground only, coloured by class, no pass blending colours: no building drawn.
    if run(&[
        "--classes",
        "2",
        "--color",
        "classification",
        "--passes",
        "none",
    ]) {
        let (w, h, img) = decode_png(&d.join("shot6.png"));
        let (ground, building) = (class_colour(2), class_colour(6));
        let (mut g, mut b) = (0, 0);
        for y in 0..h as usize {
            for x in (w as usize / 2)..w as usize {
                let p = &img[(y * w as usize + x) * 4..][..3];
                g += (p == ground) as usize;
                b += (p == building) as usize;
            }
        }
        assert!(g > 10_000 && b == 0, "{g} ground and {b} building pixels");
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// The window shows the CPU path's frame pixel for pixel (the blit pass that hands it to the
/// window changes nothing): the screenshot's view equals `render`'s image from the same camera
/// at the view's size. And `--moving-scale` outside 0.1..1 is refused.
#[test]
fn the_window_shows_the_cpu_frame_pixel_for_pixel() {
    let d = tempdir("blit");
    let las = d.join("s.laz");
    let ds = d.join("s.myr");
    for args in [
        vec![
            "synth",
            "-o",
            las.to_str().unwrap(),
            "--points",
            "200k",
            "--seed",
            "5",
        ],
        vec!["convert", las.to_str().unwrap(), "-o", ds.to_str().unwrap()],
    ] {
        let st = myriad().args(&args).output().unwrap();
        assert!(
            st.status.success(),
            "{}",
            String::from_utf8_lossy(&st.stderr)
        );
    }
    let st = myriad()
        .args(["view", ds.to_str().unwrap(), "--moving-scale", "3"])
        .output()
        .unwrap();
    assert_eq!(st.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&st.stderr).contains("--moving-scale must be from 0.1 to 1"));
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        eprintln!("SKIPPED: xvfb-run is not installed (apt-get install xvfb xauth)");
        return;
    }
    // With a hardware GPU the window draws there (straight into its texture), not through the
    // CPU path this test compares.
    if !myriad_render::Gpu::best().0.is_cpu() {
        eprintln!("SKIPPED: a hardware GPU draws the window here, not the CPU path");
        return;
    }
    let camera = "--camera=499950,4399950,60,500050,4400050,5";
    let same = ["--passes", "none", "--occlusion", "off", camera];
    let shot = d.join("view.png");
    let mut args = vec![ds.to_str().unwrap(), "--width", "900", "--height", "600"];
    args.extend(same);
    args.extend([
        "--screenshot",
        shot.to_str().unwrap(),
        "--exit-after-converged",
    ]);
    let Some((ok, stdout, stderr)) = view_under_xvfb(&args) else {
        return;
    };
    assert!(ok, "{stdout}\n{stderr}");
    // "...: screenshot written (the view WxH at X,Y)"
    let at = stdout.split("(the view ").nth(1).expect(&stdout);
    let nums: Vec<u32> = at
        .split(|c: char| !c.is_ascii_digit())
        .filter(|s| !s.is_empty())
        .take(4)
        .map(|s| s.parse().unwrap())
        .collect();
    let [vw, vh, vx, vy] = nums[..] else {
        panic!("{stdout}")
    };
    let rendered = d.join("render.png");
    let (w, h) = (vw.to_string(), vh.to_string());
    let mut args = vec![
        "render",
        ds.to_str().unwrap(),
        "-o",
        rendered.to_str().unwrap(),
    ];
    args.extend(["--width", &w, "--height", &h]);
    args.extend(same);
    let st = myriad().args(&args).output().unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let (sw, _, window) = decode_png(&shot);
    let (rw, rh, image) = decode_png(&rendered);
    assert_eq!((rw, rh), (vw, vh));
    let (mut differ, mut lit) = (0, 0);
    for y in 0..vh as usize {
        for x in 0..vw as usize {
            let a = &window[((y + vy as usize) * sw as usize + x + vx as usize) * 4..][..3];
            let b = &image[(y * vw as usize + x) * 4..][..3];
            differ += (a != b) as usize;
            lit += (b != [0, 0, 0]) as usize;
        }
    }
    assert!(lit * 4 > (vw * vh) as usize, "{lit} pixels of the scan");
    assert_eq!(differ, 0, "{differ} of {} pixels differ", vw * vh);
    let _ = std::fs::remove_dir_all(&d);
}

/// Scans without their datasets: the window opens on their previews at once, the datasets are
/// built behind them and drawn once in (the screenshot waits for them), and kept next to the
/// scans.
#[test]
fn the_viewer_shows_a_scans_preview_while_its_dataset_is_built() {
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        eprintln!("SKIPPED: xvfb-run is not installed (apt-get install xvfb xauth)");
        return;
    }
    let d = tempdir("xvfb-preview");
    // Two scans: two previews side by side, each replaced by its own dataset.
    let (laz, other) = (d.join("s.laz"), d.join("t.laz"));
    for (p, seed) in [(&laz, "1"), (&other, "2")] {
        let st = myriad()
            .args([
                "synth",
                "-o",
                p.to_str().unwrap(),
                "--points",
                "300k",
                "--seed",
                seed,
            ])
            .output()
            .unwrap();
        assert!(
            st.status.success(),
            "{}",
            String::from_utf8_lossy(&st.stderr)
        );
    }
    let shot = d.join("shot.png");
    let Some((ok, stdout, stderr)) = view_under_xvfb(&[
        laz.to_str().unwrap(),
        other.to_str().unwrap(),
        "--width",
        "900",
        "--height",
        "600",
        "--screenshot",
        shot.to_str().unwrap(),
        "--exit-after-converged",
    ]) else {
        return;
    };
    assert!(ok, "{stdout}\n{stderr}");
    assert_eq!(
        stderr
            .matches("showing its preview while its dataset is built")
            .count(),
        2,
        "{stderr}"
    );
    for name in ["s.laz", "t.laz"] {
        assert!(
            stdout.contains(&format!("{name}: its dataset is built, drawn from now on")),
            "{stdout}"
        );
    }
    assert!(stdout.contains("screenshot written"), "{stdout}");
    let datasets = std::fs::read_dir(&d)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().ends_with(".myr"))
        .count();
    assert_eq!(datasets, 2, "each dataset kept next to its scan");
    let (w, h, img) = decode_png(&shot);
    let lit = (0..h as usize)
        .flat_map(|y| ((w as usize / 2)..w as usize).map(move |x| (y, x)))
        .filter(|&(y, x)| img[(y * w as usize + x) * 4..][..3] != [0, 0, 0])
        .count();
    assert!(
        lit * 4 > (h as usize) * (w as usize / 2),
        "{lit} pixels lit"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// Saved work in the window: the annotation and the measurement that `myriad annotate` kept
/// beside the dataset are drawn over the view (the annotation's mark, the measurement's
/// lines), and closing the window leaves the sidecar as it was; without them, neither colour
/// is drawn. (The window's own editing, written back as it changes, is tested in
/// myriad-viewer's `tools/annotate.rs`.)
#[test]
fn the_viewer_shows_the_saved_annotations_and_measurements() {
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        eprintln!("SKIPPED: xvfb-run is not installed (apt-get install xvfb xauth)");
        return;
    }
    let d = tempdir("work");
    let las = common::synth(&d, "w.las", 100_000);
    let ds = d.join("w.myr");
    let r = common::myriad(&["convert", las.to_str().unwrap(), "-o", ds.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let b = myriad_format::Dataset::open(&ds).unwrap().meta.bounds;
    let c = b.center();
    let (x0, x1, y) = (
        b.min[0] + 0.3 * (b.max[0] - b.min[0]),
        b.min[0] + 0.7 * (b.max[0] - b.min[0]),
        c[1],
    );
    let at = format!("{},{},{}", c[0], c[1], b.max[2]);
    let line = format!("distance:{x0},{y},{},{x1},{y},{}", b.max[2], b.max[2]);
    let r = common::myriad(&[
        "annotate",
        ds.to_str().unwrap(),
        "--add",
        &at,
        "--title",
        "here",
        "--measure",
        &line,
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let sidecar = d.join("w.work.json");
    let before = std::fs::read(&sidecar).unwrap();
    let shot_with = |name: &str, extra: &[&str]| -> Option<(usize, usize, usize)> {
        let png = d.join(name);
        let mut args = vec![
            ds.to_str().unwrap(),
            "--width",
            "1000",
            "--height",
            "650",
            "--screenshot",
            png.to_str().unwrap(),
            "--exit-after-converged",
        ];
        args.extend(extra);
        let (ok, stdout, stderr) = view_under_xvfb(&args)?;
        assert!(ok, "{stdout}\n{stderr}");
        let (_, _, img) = decode_png(&png);
        let count = |c: [u8; 3]| img.chunks(4).filter(|p| p[..3] == c).count();
        Some((
            count([255, 64, 200]),
            count([255, 210, 0]),
            count([250, 250, 250]),
        ))
    };
    let shot = |name: &str| shot_with(name, &[]).map(|(m, l, _)| (m, l));
    let Some((marks, lines)) = shot("with.png") else {
        return;
    };
    assert!(marks >= 60, "{marks} pixels of the annotation's mark");
    assert!(lines >= 100, "{lines} pixels of the measurement's line");
    assert_eq!(
        std::fs::read(&sidecar).unwrap(),
        before,
        "the sidecar as it was"
    );
    let r = common::myriad(&["annotate", ds.to_str().unwrap(), "--clear"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let (marks, lines) = shot("without.png").unwrap();
    assert!(
        marks < 10 && lines < 10,
        "{marks} and {lines} without any work"
    );
    // A cross-section cut on opening: its profile's window, the picture's background.
    let section = format!("{},{y},{},{y}", b.min[0], b.max[0]);
    let (_, _, paper) = shot_with("section.png", &["--section", &section]).unwrap();
    let (_, _, none) = shot_with("nosection.png", &[]).unwrap();
    assert!(
        paper >= 40_000 && none < 1000,
        "{paper} pixels of the profile's picture ({none} without)"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// A volume in the window (`--volume`, as key V and clicks make one): the figure `myriad
/// volume` gives for the same polygon, printed, and the base drawn over the view.
#[test]
fn the_viewer_measures_a_volume_and_draws_its_base() {
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        eprintln!("SKIPPED: xvfb-run is not installed (apt-get install xvfb xauth)");
        return;
    }
    let d = tempdir("volume");
    let las = d.join("p.las");
    let r = common::myriad(&[
        "synth",
        "--scene",
        "stockpiles",
        "-o",
        las.to_str().unwrap(),
        "--points",
        "200k",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let polygon = (r.stdout.lines().chain(r.stderr.lines()))
        .find(|l| l.starts_with("pile 1:"))
        .and_then(|l| l.split("--polygon ").nth(1))
        .unwrap()
        .trim()
        .to_string();
    let ds = d.join("p.myr");
    let r = common::myriad(&["convert", las.to_str().unwrap(), "-o", ds.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let r = common::myriad(&[
        "volume",
        ds.to_str().unwrap(),
        "--polygon",
        &polygon,
        "--json",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let v: serde_json::Value = serde_json::from_str(r.stdout.trim()).unwrap();
    let png = d.join("v.png");
    let Some((ok, stdout, stderr)) = view_under_xvfb(&[
        ds.to_str().unwrap(),
        "--width",
        "1000",
        "--height",
        "650",
        "--volume",
        &polygon,
        "--screenshot",
        png.to_str().unwrap(),
        "--exit-after-converged",
    ]) else {
        return;
    };
    assert!(ok, "{stdout}\n{stderr}");
    let want = format!(
        "volume: fill {:.3} m³, cut {:.3} m³",
        v["fill"].as_f64().unwrap(),
        v["cut"].as_f64().unwrap()
    );
    assert!(stdout.contains(&want), "{want} in {stdout}");
    let (_, _, img) = decode_png(&png);
    let base = img.chunks(4).filter(|p| p[..3] == [255, 140, 0]).count();
    assert!(base >= 100, "{base} pixels of the base's outline");
    let _ = std::fs::remove_dir_all(&d);
}

/// Issue 41's faults: a scan shown in the window that changes on disk is noticed (its size and
/// modification time) and built again, and its new dataset replaces what is shown.
#[test]
fn the_viewer_builds_a_scan_again_when_it_changes_on_disk() {
    use std::io::BufRead;
    use std::os::unix::process::CommandExt;
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        eprintln!("SKIPPED: xvfb-run is not installed (apt-get install xvfb xauth)");
        return;
    }
    let d = tempdir("xvfb-changed");
    let (laz, other) = (d.join("s.laz"), d.join("t.laz"));
    for (p, points, seed) in [(&laz, "200k", "1"), (&other, "150k", "2")] {
        let st = myriad()
            .args(["synth", "-o", p.to_str().unwrap(), "--points", points])
            .args(["--seed", seed])
            .output()
            .unwrap();
        assert!(st.status.success());
    }
    let mut child = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1024x768x24"])
        .arg(env!("CARGO_BIN_EXE_myriad"))
        .args([
            "view",
            laz.to_str().unwrap(),
            "--width",
            "640",
            "--height",
            "480",
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .process_group(0)
        .spawn()
        .unwrap();
    let (tx, rx) = std::sync::mpsc::channel::<String>();
    let out = std::io::BufReader::new(child.stdout.take().unwrap());
    let err = std::io::BufReader::new(child.stderr.take().unwrap());
    let t2 = tx.clone();
    std::thread::spawn(move || {
        out.lines()
            .map_while(Result::ok)
            .for_each(|l| drop(tx.send(l)))
    });
    std::thread::spawn(move || {
        err.lines()
            .map_while(Result::ok)
            .for_each(|l| drop(t2.send(l)))
    });
    let mut seen = Vec::new();
    let wait_for = |what: &str, seen: &mut Vec<String>| -> bool {
        let t = Instant::now();
        while t.elapsed() < Duration::from_secs(120) {
            if let Ok(l) = rx.recv_timeout(Duration::from_millis(200)) {
                let hit = l.contains(what);
                seen.push(l);
                if hit {
                    return true;
                }
            }
        }
        false
    };
    let built = wait_for("s.laz: its dataset is built", &mut seen);
    let skipped = seen
        .iter()
        .any(|l| l.contains("No suitable graphics adapter"));
    if built {
        std::fs::rename(&other, &laz).unwrap();
    }
    let noticed = built && wait_for("changed on disk: building its dataset again", &mut seen);
    let again = noticed && wait_for("s.laz: its dataset is built", &mut seen);
    let _ = Command::new("kill")
        .args(["-TERM", "--", &format!("-{}", child.id())])
        .status();
    let _ = child.wait();
    if skipped {
        eprintln!("SKIPPED: no Vulkan driver for the window (CI installs lavapipe)");
        return;
    }
    assert!(built && noticed && again, "{seen:#?}");
    // The dataset kept beside the scan is the new scan's (the old one's went).
    let kept = common::datasets_in(&d);
    assert_eq!(kept.len(), 1, "{kept:?}");
    let info = myriad()
        .args(["info", kept[0].to_str().unwrap()])
        .output()
        .unwrap();
    let info = String::from_utf8_lossy(&info.stdout);
    assert!(info.contains("150,000"), "{info}");
}

/// Edits in the window (issue 70; `--classify`, as key K and clicks make one, and
/// `--undo-edits`, as Ctrl+Z): each printed, kept beside the dataset, the same points in
/// `extract`'s output as `classify` gives on a copy, and drawn edited (the class given shows
/// in the screenshot, where the data had none).
#[test]
fn the_viewer_edits_classes_as_the_cli_does() {
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        eprintln!("SKIPPED: xvfb-run is not installed (apt-get install xvfb xauth)");
        return;
    }
    let d = tempdir("edit");
    let las = d.join("c.las");
    let r = common::myriad(&["synth", "-o", las.to_str().unwrap(), "--points", "150k"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let (ds, copy) = (d.join("c.myr"), d.join("cli.myr"));
    common::ok(&["convert", las.to_str().unwrap(), "-o", ds.to_str().unwrap()]);
    std::fs::copy(&ds, &copy).unwrap();
    let before = std::fs::read(&ds).unwrap();
    // A terrain for the contours (its edit the first of each).
    for d in [&ds, &copy] {
        common::ok(&["ground", d.to_str().unwrap(), "--no-count"]);
    }
    let r0 = common::records(&las);
    assert!(r0.iter().all(|r| r[5] != 9), "no water in the scene");
    let (lo, hi) = r0
        .iter()
        .fold(([i64::MAX; 2], [i64::MIN; 2]), |(lo, hi), r| {
            (
                [lo[0].min(r[0]), lo[1].min(r[1])],
                [hi[0].max(r[0]), hi[1].max(r[1])],
            )
        });
    let at = |fx: f64, fy: f64| {
        format!(
            "{},{}",
            (lo[0] as f64 + fx * (hi[0] - lo[0]) as f64) / 1000.0,
            (lo[1] as f64 + fy * (hi[1] - lo[1]) as f64) / 1000.0
        )
    };
    let ring = |c: [(f64, f64); 4]| c.map(|(x, y)| at(x, y)).join(",");
    let p1 = ring([(0.2, 0.2), (0.7, 0.25), (0.65, 0.7), (0.25, 0.6)]);
    let p2 = ring([(0.75, 0.1), (0.95, 0.1), (0.95, 0.3), (0.75, 0.3)]);
    let p3 = ring([(0.05, 0.8), (0.3, 0.8), (0.3, 0.95), (0.05, 0.95)]);
    let png = d.join("e.png");
    let Some((ok, stdout, stderr)) = view_under_xvfb(&[
        ds.to_str().unwrap(),
        "--width",
        "800",
        "--height",
        "600",
        "--view",
        "top",
        "--color",
        "classification",
        "--classify",
        &format!("{p1}=9"),
        "--classify",
        &format!("{p2}=remove"),
        "--classify",
        &format!("{p3}=17"),
        "--undo-edits",
        "1",
        "--contours",
        "2",
        "--screenshot",
        png.to_str().unwrap(),
        "--exit-after-converged",
    ]) else {
        return;
    };
    assert!(ok, "{stdout}\n{stderr}");
    for said in ["edit 2: ", "edit 3: ", "edit 4: ", "undone: ", "contours: "] {
        assert!(stdout.contains(said), "{said} in {stdout}");
    }
    let lines: usize = (stdout.split("contours: ").nth(1).unwrap().split(' '))
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(lines > 0, "{stdout}");
    common::ok(&[
        "classify",
        copy.to_str().unwrap(),
        "--polygon",
        &p1,
        "--to",
        "9",
    ]);
    common::ok(&[
        "classify",
        copy.to_str().unwrap(),
        "--polygon",
        &p2,
        "--remove",
    ]);
    let (a, b) = (d.join("a.las"), d.join("b.las"));
    common::ok(&["extract", ds.to_str().unwrap(), "-o", a.to_str().unwrap()]);
    common::ok(&["extract", copy.to_str().unwrap(), "-o", b.to_str().unwrap()]);
    let (ra, rb) = (common::records(&a), common::records(&b));
    assert_eq!(ra, rb, "the window's edits are the CLI's");
    let water = ra.iter().filter(|r| r[5] == 9).count();
    assert!(
        water > 10_000 && ra.len() < r0.len(),
        "{water} of {}",
        ra.len()
    );
    let (_, _, img) = decode_png(&png);
    let shown = img.chunks(4).filter(|p| p[..3] == class_colour(9)).count();
    assert!(shown > 5_000, "{shown} pixels of water drawn");
    let near = |p: &[u8], c: [u8; 3]| (0..3).all(|i| (p[i] as i32 - c[i] as i32).abs() <= 12);
    let contour = (img.chunks(4))
        .filter(|p| near(p, [230, 170, 90]) || near(p, [255, 225, 150]))
        .count();
    assert!(contour > 30, "{contour} pixels of contours drawn");
    assert_eq!(std::fs::read(&ds).unwrap(), before, "the dataset untouched");
    let _ = std::fs::remove_dir_all(&d);
}

/// Issue 71 in the window: a class scheme (`--classes-scheme`) colours and hides classes; views
/// recorded (`--path-view`, as key J adds them) are saved with the work as a camera path
/// (`--record-path`, the panel's "save") that `render --path` flies, and a path plays
/// (`--play-path`) before the screenshot.
#[test]
fn the_viewer_uses_the_class_scheme_and_records_camera_paths() {
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        eprintln!("SKIPPED: xvfb-run is not installed (apt-get install xvfb xauth)");
        return;
    }
    let d = tempdir("scheme-window");
    let las = d.join("c.las");
    common::ok(&["synth", "-o", las.to_str().unwrap(), "--points", "100k"]);
    let ds = d.join("c.myr");
    common::ok(&["convert", las.to_str().unwrap(), "-o", ds.to_str().unwrap()]);
    let scheme = d.join("scheme.json");
    std::fs::write(
        &scheme,
        r##"{"classes": {"6": {"name": "houses", "colour": "#0000ff"}, "5": {"hidden": true}}}"##,
    )
    .unwrap();
    let b = myriad_format::Dataset::open(&ds).unwrap().meta.bounds;
    let c = b.center();
    let view = |dx: f64| {
        format!(
            "{},{},{},{},{},{}",
            c[0] + dx,
            c[1] - 150.0,
            c[2] + 150.0,
            c[0],
            c[1],
            c[2]
        )
    };
    let (v1, v2) = (view(-60.0), view(60.0));
    let png = d.join("s.png");
    let Some((ok, stdout, stderr)) = view_under_xvfb(&[
        ds.to_str().unwrap(),
        "--width",
        "640",
        "--height",
        "480",
        "--color",
        "classification",
        "--classes-scheme",
        scheme.to_str().unwrap(),
        "--path-view",
        &v1,
        "--path-view",
        &v2,
        "--record-path",
        "tour",
        "--play-path",
        "tour",
        "--screenshot",
        png.to_str().unwrap(),
        "--exit-after-converged",
    ]) else {
        return;
    };
    assert!(ok, "{stdout}\n{stderr}");
    assert!(
        stdout.contains("camera path saved \"tour\": 2 views, 2.0 s"),
        "{stdout}"
    );
    assert!(
        stdout.contains("played camera path \"tour\" (2.0 s)"),
        "{stdout}"
    );
    let work: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("c.work.json")).unwrap()).unwrap();
    assert_eq!(work["paths"][0]["name"], "tour", "{work}");
    assert_eq!(work["paths"][0]["views"].as_array().unwrap().len(), 2);
    let (_, _, img) = decode_png(&png);
    let count = |c: [u8; 3]| img.chunks(4).filter(|p| p[..3] == c).count();
    let (blue, old, trees) = (
        count([0, 0, 255]),
        count(class_colour(6)),
        count(class_colour(5)),
    );
    assert!(
        blue > 1000 && old == 0 && trees == 0,
        "{blue} blue, {old} of the default building colour, {trees} of trees"
    );
    let out = common::ok(&[
        "render",
        ds.to_str().unwrap(),
        "--path",
        "tour",
        "--fps",
        "2",
        "-o",
        d.join("f").to_str().unwrap(),
        "--raster",
        "cpu",
        "--width",
        "64",
        "--height",
        "48",
    ]);
    assert!(out.contains("5 frames of 64x48"), "{out}");
    let _ = std::fs::remove_dir_all(&d);
}

/// Issue 71 in the window: the map in the view's top right corner, its tiles asked at the zoom
/// and place pyproj gives for the dataset's corners, the footprint drawn over them.
#[test]
fn the_viewer_shows_a_map_beside_the_view() {
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        eprintln!("SKIPPED: xvfb-run is not installed (apt-get install xvfb xauth)");
        return;
    }
    if !common::proj() {
        return;
    }
    let d = tempdir("map-window");
    let las = d.join("c.las");
    common::ok(&["synth", "-o", las.to_str().unwrap(), "--points", "50k"]);
    let ds = d.join("c.myr");
    common::ok(&["convert", las.to_str().unwrap(), "-o", ds.to_str().unwrap()]);
    let tiles = common::tile_server([10, 120, 200]);
    let png = d.join("m.png");
    let Some((ok, stdout, stderr)) = view_under_xvfb(&[
        ds.to_str().unwrap(),
        "--width",
        "800",
        "--height",
        "600",
        "--map-tiles",
        &tiles.template,
        "--screenshot",
        png.to_str().unwrap(),
        "--exit-after-converged",
    ]) else {
        return;
    };
    assert!(ok, "{stdout}\n{stderr}");
    let asked = tiles.asked.lock().unwrap().clone();
    assert!(stdout.contains("map tile: http://127.0.0.1:"), "{stdout}");
    let bounds = myriad_format::Dataset::open(&ds).unwrap().meta.bounds;
    common::check_tiles(&asked, &bounds);
    let (w, _, img) = decode_png(&png);
    let (mut tile, mut line) = (0, 0);
    for (i, p) in img.chunks(4).enumerate() {
        let x = (i as u32) % w;
        if x < w / 2 {
            continue;
        }
        tile += (p[..3] == [10, 120, 200]) as usize;
        line += (p[0] > 240 && p[1] > 190 && p[1] < 230 && p[2] < 40) as usize;
    }
    assert!(tile > 20_000, "{tile} pixels of tiles");
    assert!(line > 150, "{line} pixels of the footprint");
    let _ = std::fs::remove_dir_all(&d);
}

/// Issue 71 in the window: photos kept with the dataset (an E57's pinhole photo and panorama),
/// `--photo N` puts the camera at the photo's pose and draws it over the view (the panorama as a
/// sphere around the eye).
#[test]
fn the_viewer_shows_photos_from_their_poses() {
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        eprintln!("SKIPPED: xvfb-run is not installed (apt-get install xvfb xauth)");
        return;
    }
    let d = tempdir("photos-window");
    let las = d.join("c.las");
    common::ok(&["synth", "-o", las.to_str().unwrap(), "--points", "50k"]);
    let ds = d.join("c.myr");
    common::ok(&["convert", las.to_str().unwrap(), "-o", ds.to_str().unwrap()]);
    let e57 = d.join("images.e57");
    let photo = common::flat_png(160, 120, [30, 200, 120]);
    common::photo_e57(
        &e57,
        (
            [499_900.0, 4_399_960.0, 60.0],
            [500_000.0, 4_400_055.0, 5.0],
            50.0,
        ),
        &photo,
        (160, 120),
        [500_000.0, 4_400_020.0, 1.6],
    );
    common::ok(&[
        "photos",
        ds.to_str().unwrap(),
        "--add",
        e57.to_str().unwrap(),
    ]);
    for (n, colour) in [("1", [30u8, 200, 120]), ("2", [200, 100, 50])] {
        let png = d.join(format!("p{n}.png"));
        let Some((ok, stdout, stderr)) = view_under_xvfb(&[
            ds.to_str().unwrap(),
            "--width",
            "640",
            "--height",
            "480",
            "--photo",
            n,
            "--screenshot",
            png.to_str().unwrap(),
            "--exit-after-converged",
        ]) else {
            return;
        };
        assert!(ok, "{stdout}\n{stderr}");
        assert!(
            stdout.contains(&format!("photo {n} \"")) && stdout.contains("viewed from its pose"),
            "{stdout}"
        );
        // The photo at 0.6 over the view: its colour where the view is black.
        let (_, _, img) = decode_png(&png);
        let want = colour.map(|c| (c as f32 * 0.6).round() as i32);
        let near = (img.chunks(4))
            .filter(|p| (0..3).all(|k| (p[k] as i32 - want[k]).abs() <= 6))
            .count();
        assert!(
            near > 5_000,
            "photo {n}: {near} pixels of its colour over the view"
        );
    }
    let _ = std::fs::remove_dir_all(&d);
}
