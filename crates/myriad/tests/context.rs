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

#[test]
fn photos_are_shown_from_their_poses() {
    let d = tempdir("photos");
    let scan = synth(&d, "city.las", 100_000);
    let ds = d.join("city.myr");
    ok(&["convert", s(&scan), "-o", s(&ds)]);
    // The "photo": what Myriad draws from a known camera.
    let (eye, target) = (
        [499_900.0, 4_399_960.0, 60.0],
        [500_000.0, 4_400_055.0, 5.0],
    );
    let (w, h, fov) = (320u32, 240u32, 50.0f64);
    let photo = d.join("photo.png");
    let camera = format!(
        "{},{},{},{},{},{}",
        eye[0], eye[1], eye[2], target[0], target[1], target[2]
    );
    let base = [
        "--raster",
        "cpu",
        "--passes",
        "none",
        "--color",
        "classification",
        "--width",
        "320",
    ];
    let mut args = vec![
        "render",
        s(&ds),
        "-o",
        s(&photo),
        "--camera",
        &camera,
        "--fov",
        "50",
        "--height",
        "240",
    ];
    args.extend_from_slice(&base);
    ok(&args);
    // An E57 carrying it as a pinhole image, a panorama and a visual reference.
    let e57 = d.join("images.e57");
    common::photo_e57(
        &e57,
        (eye, target, fov),
        &std::fs::read(&photo).unwrap(),
        (w, h),
        [500_000.0, 4_400_020.0, 1.6],
    );
    let info = ok(&["info", s(&e57), "--header-only"]);
    assert!(
        info.contains("image 1     \"camera\": pinhole 320x240 PNG"),
        "{info}"
    );
    assert!(
        info.contains("\"site sketch\": visual reference 40x30 PNG") && info.contains("no pose"),
        "{info}"
    );
    let listed = ok(&["photos", s(&ds), "--add", s(&e57)]);
    assert!(listed.contains("3 photos"), "{listed}");
    assert!(
        listed.contains("photo 1 \"camera\": pinhole 320x240, at 499900.000, 4399960.000, 60.000"),
        "{listed}"
    );
    assert!(
        listed.contains("photo 3 \"site sketch\": reference 40x30, not placed"),
        "{listed}"
    );
    assert_eq!(
        std::fs::read(d.join("city.photos").join("1.png")).unwrap(),
        std::fs::read(&photo).unwrap()
    );

    // The view from the photo's pose is the photo, within a few pixels.
    let from = d.join("from.png");
    let mut args = vec!["render", s(&ds), "-o", s(&from), "--photo", "1"];
    args.extend_from_slice(&base);
    ok(&args);
    let ((fw, fh, a), (_, _, b)) = (decode_png(&from), decode_png(&photo));
    assert_eq!((fw, fh), (w, h));
    let differ = a.chunks(4).zip(b.chunks(4)).filter(|(x, y)| x != y).count();
    assert!(
        differ < (w * h / 50) as usize,
        "{differ} pixels differ from the photo"
    );
    // The dataset's points land on the photo where its camera model puts them.
    let set = myriad_measure::photos::parse(
        &std::fs::read_to_string(d.join("city.photos.json")).unwrap(),
    )
    .unwrap();
    let px = set[0].project(target).unwrap();
    assert!(
        (px[0] - 160.0).abs() < 0.5 && (px[1] - 120.0).abs() < 0.5,
        "{px:?}"
    );
    // The panorama: the view along its centre column; under the points, the photo's pixels.
    let mut args = vec![
        "render",
        s(&ds),
        "-o",
        s(&from),
        "--photo",
        "2",
        "--over-photo",
        "--force",
    ];
    args.extend_from_slice(&base);
    ok(&args);
    let (_, _, p) = decode_png(&from);
    let photo_px = p.chunks(4).filter(|c| c[..3] == [200, 100, 50]).count();
    let points = p.chunks(4).filter(|c| c[..3] != [200, 100, 50]).count();
    assert!(
        photo_px > 1000 && points > 1000,
        "{photo_px} of the panorama, {points} of points"
    );
    fails(
        &["render", s(&ds), "-o", s(&from), "--photo", "3", "--force"],
        "\"site sketch\" is not placed",
    );
    fails(
        &["render", s(&ds), "-o", s(&from), "--photo", "9", "--force"],
        "keeps 3 photos",
    );

    // The pump E57's visual reference image: listed and kept, not placed.
    if let Some(pump) = common::shared_data("pye57__pumpAVisualReferenceImage.e57") {
        let info = ok(&["info", s(&pump), "--header-only"]);
        assert!(
            info.contains("visual reference 3072x2304 JPEG") && info.contains("no pose"),
            "{info}"
        );
        let listed = ok(&["photos", s(&ds), "--add", s(&pump)]);
        assert!(
            listed.contains("photo 4 ")
                && listed.contains("reference 3072x2304, not placed (no pose) (4.jpg)"),
            "{listed}"
        );
        let jpg = std::fs::read(d.join("city.photos").join("4.jpg")).unwrap();
        assert_eq!(&jpg[..2], &[0xff, 0xd8], "a JPEG");
    }
}

/// A panorama set made by Myriad (`render --panorama` from a synthetic city, its Potree
/// `coordinates.txt` line as printed): added with `photos`, the panorama is where its pose says:
/// the view from it (`render --photo`) and the panorama sampled along each of that view's rays
/// agree pixel for pixel, but for the resampling's edges.
#[test]
fn a_panorama_set_is_placed_where_it_was_taken() {
    let d = tempdir("panoramas");
    let scan = synth(&d, "city.las", 200_000);
    let ds = d.join("city.myr");
    ok(&["convert", s(&scan), "-o", s(&ds)]);
    let set = d.join("set");
    std::fs::create_dir_all(&set).unwrap();
    let pano = set.join("p1.png");
    let said = ok(&[
        "render",
        s(&ds),
        "-o",
        s(&pano),
        "--panorama",
        "--camera",
        "499990,4400040,12,500010,4400050,12",
        "--width",
        "512",
        "--raster",
        "cpu",
        "--passes",
        "none",
        "--color",
        "classification",
    ]);
    let line = said
        .lines()
        .find_map(|l| l.strip_prefix("coordinates.txt: "))
        .unwrap();
    std::fs::write(
        set.join("coordinates.txt"),
        format!("File\tTime\tX\tY\tZ\tcourse\tpitch\troll\n{line}\n"),
    )
    .unwrap();
    let listed = ok(&["photos", s(&ds), "--add", s(&set.join("coordinates.txt"))]);
    assert!(
        listed
            .contains("photo 1 \"p1.png\": spherical 512x256, at 499990.000, 4400040.000, 12.000"),
        "{listed}"
    );
    let from = d.join("from.png");
    ok(&[
        "render",
        s(&ds),
        "-o",
        s(&from),
        "--photo",
        "1",
        "--width",
        "256",
        "--raster",
        "cpu",
        "--passes",
        "none",
        "--color",
        "classification",
    ]);
    let (w, h, view) = decode_png(&from);
    let (pw, ph, pano_px) = decode_png(&pano);
    let photos = myriad_measure::photos::parse(
        &std::fs::read_to_string(d.join("city.photos.json")).unwrap(),
    )
    .unwrap();
    let p = &photos[0];
    let v = p.view().unwrap();
    let cam = myriad_lod::Camera {
        position: v.eye,
        target: v.target,
        up: v.up,
        fov_y: v.fov_y,
        width: w,
        height: h,
        near: 0.1,
        far: 1000.0,
    };
    let (r, u, f) = cam.basis();
    let focal = cam.focal();
    let (mut same, mut drawn) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let a = ((y * w + x) * 4) as usize;
            if view[a..a + 3] == [0, 0, 0] {
                continue;
            }
            drawn += 1;
            let (dx, dy) = (
                (x as f64 + 0.5 - w as f64 / 2.0) / focal,
                -(y as f64 + 0.5 - h as f64 / 2.0) / focal,
            );
            let at: [f64; 3] = std::array::from_fn(|i| v.eye[i] + f[i] + r[i] * dx + u[i] * dy);
            let q = p.project(at).unwrap();
            let (qx, qy) = (
                (q[0].floor() as u32).min(pw - 1),
                (q[1].floor() as u32).min(ph - 1),
            );
            let b = ((qy * pw + qx) * 4) as usize;
            same += (view[a..a + 3] == pano_px[b..b + 3]) as usize;
        }
    }
    assert!(drawn > 10_000, "{drawn} pixels drawn");
    assert!(
        same as f64 > 0.85 * drawn as f64,
        "{same} of {drawn} pixels agree with the panorama"
    );
}
