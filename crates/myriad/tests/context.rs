//! Context around the points (issue 71): class schemes (names, colours, classes hidden) from a
//! file or kept with the saved work, used by `render`; camera paths flown to frames that are
//! the same bytes every run.

mod common;
use common::{decode_png, fails, myriad, ok, s, synth, tempdir};
use std::path::Path;

fn pixels_of(png: &Path, colour: [u8; 3]) -> usize {
    let (_, _, px) = decode_png(png);
    px.chunks(4).filter(|p| p[..3] == colour).count()
}

fn render(ds: &Path, out: &Path, extra: &[&str]) -> String {
    let mut args = vec![
        "render",
        s(ds),
        "-o",
        s(out),
        "--force",
        "--raster",
        "cpu",
        "--width",
        "320",
        "--height",
        "240",
        "--color",
        "classification",
        "--passes",
        "none",
    ];
    args.extend_from_slice(extra);
    ok(&args)
}

#[test]
fn a_class_scheme_names_colours_and_hides_classes() {
    let d = tempdir("scheme");
    let scan = synth(&d, "city.las", 100_000);
    let ds = d.join("city.myr");
    ok(&["convert", s(&scan), "-o", s(&ds)]);
    let (ground, building, trees) = ([166, 120, 72], [230, 90, 60], [0, 110, 0]);
    let png = d.join("a.png");
    render(&ds, &png, &[]);
    assert!(pixels_of(&png, building) > 1000 && pixels_of(&png, trees) > 200);

    // A scheme: buildings blue, ground yellow, high vegetation hidden.
    let scheme = d.join("scheme.json");
    std::fs::write(
        &scheme,
        r##"{"classes": {"6": {"name": "houses", "colour": "#0000ff"},
            "2": {"colour": [255, 255, 0]}, "5": {"hidden": true}}}"##,
    )
    .unwrap();
    render(&ds, &png, &["--classes-scheme", s(&scheme)]);
    let blue = pixels_of(&png, [0, 0, 255]);
    assert!(blue > 1000, "{blue} pixels of the scheme's building colour");
    assert!(pixels_of(&png, [255, 255, 0]) > 1000);
    for c in [ground, building, trees] {
        assert_eq!(pixels_of(&png, c), 0, "{c:?} drawn");
    }
    let with_flag = std::fs::read(&png).unwrap();
    // `--classes` names what is drawn, hidden or not.
    render(
        &ds,
        &png,
        &["--classes-scheme", s(&scheme), "--classes", "5"],
    );
    assert!(pixels_of(&png, trees) > 200);

    // Kept with the saved work: render, and annotate lists it.
    let listed = ok(&["annotate", s(&ds), "--classes-scheme", s(&scheme)]);
    assert!(
        listed.contains(
            "class scheme: 2 ground #ffff00; 5 high vegetation #006e00, hidden; 6 houses #0000ff"
        ),
        "{listed}"
    );
    render(&ds, &png, &[]);
    assert_eq!(std::fs::read(&png).unwrap(), with_flag);
    ok(&["annotate", s(&ds), "--classes-scheme", "default"]);
    render(&ds, &png, &[]);
    assert!(pixels_of(&png, building) > 1000);

    // Noise (7) is hidden by default; a scheme shows it.
    let poly = "499950,4400020,500050,4400020,500050,4400090,499950,4400090";
    ok(&["classify", s(&ds), "--polygon", poly, "--to", "7"]);
    let noise = [255, 0, 255];
    render(&ds, &png, &[]);
    assert_eq!(pixels_of(&png, noise), 0);
    let shows = d.join("shows.json");
    std::fs::write(&shows, r#"{"classes": {"7": {"hidden": false}}}"#).unwrap();
    render(&ds, &png, &["--classes-scheme", s(&shows)]);
    assert!(pixels_of(&png, noise) > 1000);

    // A bad scheme: one line naming the file and the member.
    std::fs::write(&shows, r#"{"classes": {"7": {"colour": "red"}}}"#).unwrap();
    fails(
        &[
            "render",
            s(&ds),
            "-o",
            s(&png),
            "--force",
            "--classes-scheme",
            s(&shows),
        ],
        "shows.json: classes.7.colour: a colour is",
    );
    std::fs::write(&shows, "{\"classes\": {\n\"300\": {}}}").unwrap();
    fails(
        &["annotate", s(&ds), "--classes-scheme", s(&shows)],
        "shows.json: classes.300: not a class number",
    );
}

#[test]
fn a_camera_path_renders_the_same_frames_every_time() {
    let d = tempdir("camera-path");
    let scan = synth(&d, "city.las", 100_000);
    let ds = d.join("city.myr");
    ok(&["convert", s(&scan), "-o", s(&ds)]);
    let path = d.join("path.json");
    std::fs::write(
        &path,
        r#"{"name": "round", "views": [
            {"position": [499850, 4399950, 120], "target": [500000, 4400055, 0]},
            {"position": [500150, 4399950, 120], "target": [500000, 4400055, 0]},
            {"position": [500150, 4400150, 90], "target": [500000, 4400055, 0], "time": 3}]}"#,
    )
    .unwrap();
    let fly = |out: &Path, extra: &[&str]| {
        let mut args = vec![
            "render",
            s(&ds),
            "--path",
            s(&path),
            "--fps",
            "4",
            "-o",
            s(out),
            "--raster",
            "cpu",
            "--width",
            "160",
            "--height",
            "120",
        ];
        args.extend_from_slice(extra);
        ok(&args)
    };
    let (a, b) = (d.join("a"), d.join("b"));
    let said = fly(&a, &[]);
    assert!(
        said.contains("13 frames of 160x120 (3.00 s at 4 fps"),
        "{said}"
    );
    fly(&b, &[]);
    let names: Vec<String> = (0..13).map(|i| format!("{i:05}.png")).collect();
    let mut listed: Vec<String> = std::fs::read_dir(&a)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    listed.sort();
    assert_eq!(listed, names);
    for n in &names {
        let (x, y) = (
            std::fs::read(a.join(n)).unwrap(),
            std::fs::read(b.join(n)).unwrap(),
        );
        assert!(x == y, "{n} differs between two runs");
        let (_, _, px) = decode_png(&a.join(n));
        let lit = px.chunks(4).filter(|p| p[..3] != [0, 0, 0]).count();
        assert!(lit > 1000, "{n}: {lit} pixels drawn");
    }
    // The views differ along the path: the first and the last frame are not the same image.
    assert_ne!(
        std::fs::read(a.join(&names[0])).unwrap(),
        std::fs::read(a.join(&names[12])).unwrap()
    );

    // Kept with the saved work, flown by name; a .mp4 gets its frames and the ffmpeg line.
    ok(&["annotate", s(&ds), "--add-path", s(&path)]);
    let video = d.join("fly.mp4");
    let out = ok(&[
        "render",
        s(&ds),
        "--path",
        "round",
        "--fps",
        "4",
        "-o",
        s(&video),
        "--raster",
        "cpu",
        "--width",
        "160",
        "--height",
        "120",
    ]);
    assert!(
        out.contains("ffmpeg -framerate 4 -i") && out.contains("fly.frames/%05d.png"),
        "{out}"
    );
    assert_eq!(
        std::fs::read(d.join("fly.frames").join(&names[5])).unwrap(),
        std::fs::read(a.join(&names[5])).unwrap()
    );
    let back = d.join("back.json");
    ok(&[
        "annotate",
        s(&ds),
        "--export-path",
        &format!("1={}", s(&back)),
    ]);
    fly(&d.join("c"), &[]);

    // An output that exists is replaced only with --force and only where it holds frames.
    fails(
        &["render", s(&ds), "--path", s(&path), "-o", s(&a)],
        "output exists",
    );
    fly(&a, &["--force"]);
    std::fs::write(a.join("notes.txt"), "mine").unwrap();
    fails(
        &["render", s(&ds), "--path", s(&path), "-o", s(&a), "--force"],
        "is not a folder of frames: not replaced",
    );
    assert_eq!(std::fs::read(a.join("notes.txt")).unwrap(), b"mine");
    fails(
        &["render", s(&ds), "--path", "nowhere", "-o", s(&d.join("x"))],
        "--path nowhere: no such file, nor a camera path of the saved work (1 \"round\")",
    );
    std::fs::write(
        &path,
        "{\"views\": [\n {\"position\": [1, 2], \"target\": [0, 0, 0]}]}",
    )
    .unwrap();
    fails(
        &["render", s(&ds), "--path", s(&path), "-o", s(&d.join("x"))],
        "path.json: views[0].position: three numbers",
    );
    fails(
        &[
            "render",
            s(&ds),
            "--path",
            s(&back),
            "-o",
            s(&d.join("x.png")),
        ],
        "writes a folder of frames",
    );
    // --fps needs --path (clap's usage error).
    let r = myriad(&["render", s(&ds), "-o", s(&d.join("y.png")), "--fps", "3"]);
    assert_eq!(r.code, 2, "{}", r.stderr);
}

#[test]
fn pictures_say_their_scale() {
    let d = tempdir("legends");
    let scan = synth(&d, "city.las", 100_000);
    let ds = d.join("city.myr");
    ok(&["convert", s(&scan), "-o", s(&ds)]);
    // The profile's axes labelled below and to the left of the picture, its width as asked.
    let png = d.join("p.png");
    ok(&[
        "profile",
        s(&ds),
        "--line",
        "499950,4400050,500050,4400050",
        "--width",
        "3",
        "-o",
        s(&png),
        "--pixels",
        "800",
        "--color",
        "classification",
    ]);
    let (w, h, px) = decode_png(&png);
    assert_eq!(w, 800);
    let dark = |x0: u32, x1: u32, y0: u32, y1: u32| {
        (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .filter(|&(x, y)| px[((y * w + x) * 4) as usize] < 180)
            .count()
    };
    let (gx, gy) = myriad_render::legend::PROFILE_GUTTER;
    assert!(dark(0, gx + 10, 20, h - gy) > 100, "elevation labels");
    assert!(dark(gx, w, h - gy, h) > 200, "distance labels and the unit");

    // A parallel view with --legend: a scale bar and the gradient's legend.
    let png = d.join("r.png");
    let out = ok(&[
        "render",
        s(&ds),
        "-o",
        s(&png),
        "--raster",
        "cpu",
        "--view",
        "top",
        "--parallel",
        "--legend",
        "--color",
        "z",
        "--width",
        "640",
        "--height",
        "360",
    ]);
    assert!(out.contains("r.png"), "{out}");
    let (w, h, px) = decode_png(&png);
    let bar = (0..w)
        .filter(|&x| px[(((h - 18) * w + x) * 4) as usize..][..3] == [20, 20, 20])
        .count() as u32;
    assert!(
        bar > w / 10 && bar < w * 3 / 10,
        "a scale bar of {bar} pixels"
    );
    let low = myriad_core::colour::Gradient::Spectral.at(0.0);
    let high = myriad_core::colour::Gradient::Spectral.at(1.0);
    let row = |y: u32| (0..w).map(move |x| ((y * w + x) * 4) as usize);
    let legend: Vec<[u8; 3]> = row(h - 25).map(|i| [px[i], px[i + 1], px[i + 2]]).collect();
    assert!(
        legend.contains(&low) && legend.contains(&high),
        "the gradient's ends in its legend"
    );
    // Without --legend none of it.
    ok(&[
        "render",
        s(&ds),
        "-o",
        s(&png),
        "--raster",
        "cpu",
        "--view",
        "top",
        "--parallel",
        "--color",
        "z",
        "--width",
        "640",
        "--height",
        "360",
        "--force",
    ]);
    let (_, _, px) = decode_png(&png);
    let bar = (0..w)
        .filter(|&x| px[(((h - 18) * w + x) * 4) as usize..][..3] == [20, 20, 20])
        .count();
    assert_eq!(bar, 0);
}
