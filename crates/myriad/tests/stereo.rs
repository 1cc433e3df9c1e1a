//! `render --stereo` through the CLI: both eyes side by side from one selection.

mod common;
use common::*;

#[test]
fn render_stereo_draws_both_eyes_side_by_side() {
    let d = tempdir("stereo");
    let las = synth(&d, "s.las", 150_000);
    let ds = d.join("s.myr");
    ok(&["convert", s(&las), "-o", s(&ds)]);
    let png_path = d.join("st.png");
    let text = ok(&[
        "render",
        s(&ds),
        "-o",
        s(&png_path),
        "--width",
        "160",
        "--height",
        "120",
        "--stereo",
        "--ipd",
        "4",
        "--hidden-area",
    ]);
    assert!(text.contains("both eyes side by side"), "{text}");
    let (w, h, img) = decode_png(&png_path);
    assert_eq!((w, h), (320, 120));
    let lit = |x0: usize, x1: usize| {
        (0..120usize)
            .flat_map(|y| (x0..x1).map(move |x| (y, x)))
            .filter(|&(y, x)| img[(y * 320 + x) * 4..][..3] != [0, 0, 0])
            .count()
    };
    // Both eyes show the scan; the masked corners are black.
    assert!(lit(0, 160) > 160 * 120 / 10 && lit(160, 320) > 160 * 120 / 10);
    for (y, x) in [(0, 0), (0, 159), (119, 160), (119, 319)] {
        assert_eq!(&img[(y * 320 + x) * 4..][..3], &[0, 0, 0]);
    }
    // The eyes differ (parallax), and two passes draw what one does.
    let left: Vec<u8> = (0..120)
        .flat_map(|y| img[y * 1280..y * 1280 + 640].to_vec())
        .collect();
    let right: Vec<u8> = (0..120)
        .flat_map(|y| img[y * 1280 + 640..y * 1280 + 1280].to_vec())
        .collect();
    assert_ne!(left, right);
    let two = d.join("two.png");
    ok(&[
        "render",
        s(&ds),
        "-o",
        s(&two),
        "--width",
        "160",
        "--height",
        "120",
        "--stereo",
        "--ipd",
        "4",
        "--hidden-area",
        "--two-pass",
    ]);
    let (_, _, img2) = decode_png(&two);
    let differ = img
        .chunks(4)
        .zip(img2.chunks(4))
        .filter(|(a, b)| a != b)
        .count();
    assert!(differ * 100 <= 320 * 120, "{differ} pixels differ");
    // A negative distance between the eyes is refused.
    let r = myriad(&[
        "render",
        s(&ds),
        "-o",
        s(&d.join("x.png")),
        "--stereo",
        "--ipd=-1",
    ]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(r.stderr.contains("--ipd"), "{}", r.stderr);
}

#[test]
fn bench_stereo_times_every_frame_and_on_the_quad_path_both_node_orders() {
    let d = tempdir("stereo-bench");
    let las = synth(&d, "b.las", 60_000);
    let ds = d.join("b.myr");
    ok(&["convert", s(&las), "-o", s(&ds)]);
    let rows = |out: &str| -> Vec<(String, u64)> {
        out.lines()
            .filter_map(|l| {
                let cells: Vec<&str> = l.split('|').map(str::trim).collect();
                let n = cells.get(2)?.replace(',', "").parse().ok()?;
                let ms: f64 = cells.get(3)?.parse().ok()?;
                assert!(ms > 0.0, "{l}");
                Some((cells[1].to_string(), n))
            })
            .collect()
    };
    let args = |raster: &'static str| {
        [
            "bench",
            "stereo",
            s(&ds),
            "--size",
            "64",
            "--frames",
            "1",
            "--raster",
            raster,
        ]
        .map(String::from)
    };
    let cpu = args("cpu");
    let out = ok(&cpu.each_ref().map(String::as_str));
    let r = rows(&out);
    assert_eq!(r.len(), 5, "{out}");
    assert!(
        r[0].0 == "mono" && r[4].0 == "single pass, hidden-area mask",
        "{out}"
    );
    assert!(r.iter().all(|(_, n)| *n > 0), "{out}");
    // The quad path (on any adapter, lavapipe too): each frame front to back and as selected,
    // the same points.
    let quads = args("quads");
    let run = myriad(&quads.each_ref().map(String::as_str));
    if run.code != 0 && run.stderr.contains("adapter") {
        eprintln!("SKIPPED the quad path: {}", run.stderr.trim());
        return;
    }
    assert_eq!(run.code, 0, "{}", run.stderr);
    let r = rows(&run.stdout);
    assert_eq!(r.len(), 10, "{}", run.stdout);
    assert_eq!(r[1].0, "mono, nodes as selected");
    assert_eq!(r[0].1, r[1].1);
    assert_eq!(r[9].0, "single pass, hidden-area mask, nodes as selected");
    assert_eq!(r[5].1, r[9].1);
}
