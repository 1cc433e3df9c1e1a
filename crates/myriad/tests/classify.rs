//! Edits as a layer (issue 70): `classify` reclassifies and removes the points in a region as
//! edits kept beside the dataset; `extract`, `render` and the tools read the points edited; undo
//! and redo; `--apply` writes a dataset equal to extracting the edited points; the scan and the
//! dataset are never touched; bad edits are one line.

mod common;
use common::{decode_png, fails, myriad, ok, records, s, synth, tempdir};
use std::path::Path;

fn digest(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap()
}

fn extracted(ds: &Path, out: &Path) -> Vec<Vec<i64>> {
    ok(&["extract", s(ds), "-o", s(out), "--force"]);
    records(out)
}

/// Ray casting, independent of Myriad's polygon.
fn inside(poly: &[[f64; 2]], x: f64, y: f64) -> bool {
    let mut c = false;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        if (a[1] > y) != (b[1] > y) && x < a[0] + (y - a[1]) * (b[0] - a[0]) / (b[1] - a[1]) {
            c = !c;
        }
    }
    c
}

/// The place `f` of the way along axis `a` of the records' extent (records in thousandths).
fn within(records: &[Vec<i64>]) -> impl Fn(usize, f64) -> f64 {
    let (lo, hi) = records
        .iter()
        .fold(([i64::MAX; 3], [i64::MIN; 3]), |(lo, hi), r| {
            (
                std::array::from_fn::<i64, 3, _>(|a| lo[a].min(r[a])),
                std::array::from_fn::<i64, 3, _>(|a| hi[a].max(r[a])),
            )
        });
    move |a: usize, f: f64| (lo[a] as f64 + f * (hi[a] - lo[a]) as f64) / 1000.0
}

fn number_after(out: &str, before: &str) -> u64 {
    let t = out.split(before).next().unwrap();
    let n = t.rsplit(' ').next().unwrap().replace(',', "");
    n.parse().unwrap_or_else(|_| panic!("{before:?} in {out}"))
}

#[test]
fn edits_are_a_layer_every_reader_applies() {
    let d = tempdir("classify");
    let scan = synth(&d, "city.las", 200_000);
    let ds = d.join("city.myr");
    ok(&["convert", s(&scan), "-o", s(&ds)]);
    let (scan0, ds0) = (digest(&scan), digest(&ds));
    let out = d.join("x.las");
    let r0 = extracted(&ds, &out);
    assert_eq!(r0.len(), 200_000);

    // The bounds, in thousandths, give a polygon over a part and a box over another.
    let at = within(&r0);
    let poly = [
        [at(0, 0.1), at(1, 0.1)],
        [at(0, 0.5), at(1, 0.2)],
        [at(0, 0.4), at(1, 0.6)],
        [at(0, 0.15), at(1, 0.5)],
    ];
    let poly_arg = poly
        .iter()
        .map(|p| format!("{},{}", p[0], p[1]))
        .collect::<Vec<_>>()
        .join(",");
    let printed = ok(&["classify", s(&ds), "--polygon", &poly_arg, "--to", "noise"]);
    assert!(printed.contains("edit 1 kept in"), "{printed}");
    let selected = number_after(&printed, " points selected");
    let xy = |r: &Vec<i64>| (r[0] as f64 / 1000.0, r[1] as f64 / 1000.0);
    let mut want: Vec<Vec<i64>> = r0
        .iter()
        .map(|r| {
            let mut r = r.clone();
            let (x, y) = xy(&r);
            if inside(&poly, x, y) {
                r[5] = 7;
            }
            r
        })
        .collect();
    let n_in = r0
        .iter()
        .filter(|r| inside(&poly, xy(r).0, xy(r).1))
        .count() as u64;
    assert!(n_in > 10_000, "{n_in} points in the polygon");
    assert_eq!(selected, n_in);
    want.sort();
    let r1 = extracted(&ds, &out);
    assert_eq!(r1, want, "extract gives the points reclassified");

    // Remove the points in a box that overlaps the polygon, of class 7 only: what is left of
    // the polygon's points in the box goes.
    let b = [
        at(0, 0.3),
        at(1, 0.0),
        at(2, 0.0) - 1.0,
        at(0, 0.9),
        at(1, 0.4),
        at(2, 1.0) + 1.0,
    ];
    let in_box = |r: &Vec<i64>| {
        (0..3).all(|a| {
            let v = r[a] as f64 / 1000.0;
            v >= b[a] && v <= b[a + 3]
        })
    };
    let box_arg = b.map(|v| v.to_string()).join(",");
    let printed = ok(&[
        "classify",
        s(&ds),
        "--box",
        &box_arg,
        "--classes",
        "7",
        "--remove",
    ]);
    let removed = number_after(&printed, " points removed");
    let want2: Vec<Vec<i64>> = want
        .iter()
        .filter(|r| !(in_box(r) && r[5] == 7))
        .cloned()
        .collect();
    assert!(
        removed > 1000 && removed as usize == want.len() - want2.len(),
        "{printed}"
    );
    let r2 = extracted(&ds, &out);
    assert_eq!(r2, want2, "extract leaves the removed points out");
    let list = ok(&["classify", s(&ds), "--list"]);
    assert_eq!(list.lines().count(), 2, "{list}");
    assert!(
        list.contains("→ removed") && list.contains("→ class 7"),
        "{list}"
    );

    // --apply writes a dataset whose points are the edited ones, and which verifies.
    let applied = d.join("applied.myr");
    let said = ok(&["classify", s(&ds), "--apply", "-o", s(&applied)]);
    assert_eq!(number_after(&said, " points removed"), removed, "{said}");
    assert_eq!(extracted(&applied, &d.join("y.las")), want2);
    ok(&["verify", s(&applied)]);
    fails(
        &["classify", s(&ds), "--apply", "-o", s(&applied)],
        "exists",
    );

    // Rendered: removing every point leaves the background alone.
    let png = d.join("a.png");
    let render = |p: &Path| {
        ok(&[
            "render",
            s(&ds),
            "-o",
            s(p),
            "--width",
            "96",
            "--height",
            "64",
            "--force",
            "--raster",
            "cpu",
        ]);
        let (_, _, px) = decode_png(p);
        px.chunks(4).filter(|c| c[..3] != px[..3]).count()
    };
    assert!(render(&png) > 500);
    ok(&[
        "classify",
        s(&ds),
        "--where",
        "z>-1e9",
        "--remove",
        "--no-count",
    ]);
    assert_eq!(render(&png), 0, "no point drawn once all are removed");

    // Undo all three; redo gives them back; the scan and the dataset were never touched.
    for _ in 0..3 {
        assert!(ok(&["classify", s(&ds), "--undo"]).starts_with("undone: "));
    }
    fails(&["classify", s(&ds), "--undo"], "no edit to undo");
    assert_eq!(extracted(&ds, &out), r0);
    ok(&["classify", s(&ds), "--redo"]);
    ok(&["classify", s(&ds), "--redo"]);
    assert_eq!(extracted(&ds, &out), want2);
    assert_eq!(digest(&scan), scan0);
    assert_eq!(digest(&ds), ds0);

    // Eight editors at once: none loses another's edit (the file is held while it changes).
    let edits = |list: &str| list.lines().filter(|l| l.contains(" → ")).count();
    let before = edits(&ok(&["classify", s(&ds), "--list"]));
    let editors: Vec<_> = (0..8)
        .map(|i| {
            std::process::Command::new(env!("CARGO_BIN_EXE_myriad"))
                .args([
                    "classify",
                    s(&ds),
                    "--where",
                    &format!("intensity=={}", 60_000 + i),
                ])
                .args(["--to", "3", "--no-count"])
                .stdout(std::process::Stdio::null())
                .spawn()
                .unwrap()
        })
        .collect();
    for mut e in editors {
        assert!(e.wait().unwrap().success());
    }
    let list = ok(&["classify", s(&ds), "--list"]);
    assert_eq!(edits(&list), before + 8, "{list}");
    assert_eq!(list.matches("→ class 3").count(), 8, "{list}");
    for _ in 0..8 {
        ok(&["classify", s(&ds), "--undo"]);
    }

    // Bad edits are one line: a polygon that crosses itself, one of two points, a class past
    // 255, a damaged edits file (named, with its line) for every command that reads points.
    fails(
        &[
            "classify",
            s(&ds),
            "--polygon",
            &format!(
                "{},{},{},{},{},{},{},{}",
                poly[0][0],
                poly[0][1],
                poly[2][0],
                poly[2][1],
                poly[1][0],
                poly[1][1],
                poly[3][0],
                poly[3][1]
            ),
            "--to",
            "2",
        ],
        "crosses itself",
    );
    fails(
        &[
            "classify",
            s(&ds),
            "--polygon",
            &format!(
                "{},{},{},{}",
                poly[0][0], poly[0][1], poly[1][0], poly[1][1]
            ),
            "--to",
            "2",
        ],
        "at least 3",
    );
    fails(&["classify", s(&ds), "--to", "256"], "0 to 255");
    fails(
        &["classify", s(&ds), "--where", "nosuch>1", "--remove"],
        "nosuch",
    );
    // A scan has no dataset of its own to keep edits beside.
    fails(&["classify", s(&scan), "--to", "2"], "convert it first");
    let r = myriad(&["classify", s(&ds)]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    let sidecar = d.join("city.edits.json");
    std::fs::write(
        &sidecar,
        "{\"myriad\": \"edits\",\n \"version\": 1, \"edits\": [ {\"to\": 2} ",
    )
    .unwrap();
    fails(
        &["extract", s(&ds), "-o", s(&out), "--force"],
        "city.edits.json: line 2",
    );
    // verify and info read the pages as stored, whatever the edits file holds.
    ok(&["verify", s(&ds)]);
    assert!(ok(&["info", s(&ds)]).contains("200,000"));
    fails(
        &[
            "render",
            s(&ds),
            "-o",
            s(&png),
            "--force",
            "--raster",
            "cpu",
        ],
        "city.edits.json",
    );
    std::fs::write(
        &sidecar,
        r#"{"myriad":"edits","version":1,"edits":[{"to":2},{"box":[[0,0,0],[1,1,1]]}]}"#,
    )
    .unwrap();
    fails(
        &["extract", s(&ds), "-o", s(&out), "--force"],
        "edits[1]: neither",
    );
}

/// `ground` on a synthetic city whose ground `synth` knows (classes 2 and 11, roads): the points
/// it calls ground within 2 % of the truth; in 15 tiles of 64 cells the same classes as in one
/// (no seam); an edit like any other (undo gives the labels back).
#[test]
fn ground_is_found_in_tiles_without_a_seam() {
    let d = tempdir("ground");
    let scan = synth(&d, "city.las", 300_000);
    let (a, b) = (d.join("a.myr"), d.join("b.myr"));
    ok(&["convert", s(&scan), "-o", s(&a)]);
    std::fs::copy(&a, &b).unwrap();
    let truth = records(&scan);
    // Take the labels away first: every point unclassified.
    for ds in [&a, &b] {
        ok(&["classify", s(ds), "--to", "1", "--no-count"]);
    }
    let said = ok(&["ground", s(&a), "--tile", "2048"]);
    assert!(said.contains("in 1 tiles"), "{said}");
    let tiled = ok(&["ground", s(&b), "--tile", "64"]);
    assert!(tiled.contains("in 15 tiles of 64"), "{tiled}");
    let out = d.join("x.las");
    let got = extracted(&a, &out);
    assert_eq!(extracted(&b, &d.join("y.las")), got, "tiles show no seam");
    // Coloured by height above the terrain: most of the scene (its ground) at the gradient's low
    // end, roofs and trees above it; where there is no terrain, one line says so.
    let png = d.join("hag.png");
    let mut args = common::render_cpu(s(&b), s(&png), ("320", "240"));
    args.extend([
        "--view",
        "top",
        "--passes",
        "none",
        "--color",
        "above-ground",
    ]);
    ok(&args);
    let (_, _, img) = decode_png(&png);
    let turbo = |t: f64| myriad_core::colour::Gradient::Turbo.at(t);
    let ts: Vec<f64> = (img.chunks(4))
        .filter(|p| p[..3] != [0, 0, 0])
        .map(|p| {
            let d = |k: usize| -> i32 {
                let c = turbo(k as f64 / 100.0);
                (0..3).map(|i| (c[i] as i32 - p[i] as i32).abs()).sum()
            };
            (0..=100).min_by_key(|&k| d(k)).unwrap() as f64 / 100.0
        })
        .collect();
    let share =
        |f: &dyn Fn(f64) -> bool| ts.iter().filter(|&&t| f(t)).count() as f64 / ts.len() as f64;
    assert!(ts.len() > 15_000, "{} pixels", ts.len());
    assert!(
        share(&|t| t < 0.1) > 0.4,
        "{} at the ground",
        share(&|t| t < 0.1)
    );
    assert!(
        share(&|t| t > 0.3) > 0.03,
        "{} above it",
        share(&|t| t > 0.3)
    );
    let no_terrain = d.join("c.myr");
    std::fs::copy(&a, &no_terrain).unwrap();
    let png = d.join("none.png");
    let mut args = common::render_cpu(s(&no_terrain), s(&png), ("320", "240"));
    args.extend(["--color", "above-ground"]);
    fails(&args, "has no terrain");
    // Records sort by position first: the same points in the same order.
    assert_eq!(got.len(), truth.len());
    let is_ground = |c: i64| c == 2 || c == 11;
    let wrong = (got.iter().zip(&truth))
        .filter(|(g, t)| is_ground(g[5]) != is_ground(t[5]))
        .count();
    assert!(
        wrong * 50 <= truth.len(),
        "{wrong} of {} points misclassified",
        truth.len()
    );
    let ground = got.iter().filter(|g| g[5] == 2).count();
    assert!(
        said.contains(
            &format!("({:.1} %)", 100.0 * ground as f64 / got.len() as f64)
                .replace("(", "(class 2, ")
        ),
        "{said}"
    );
    ok(&["classify", s(&a), "--undo"]);
    ok(&["classify", s(&a), "--undo"]);
    assert_eq!(extracted(&a, &out), truth);
    // Bad options and a damaged surface are one line.
    fails(&["ground", s(&a), "--cell", "0"], "--cell 0");
    fails(&["ground", s(&a), "--slope=-1"], "--slope -1");
    ok(&["classify", s(&a), "--redo"]);
    ok(&["classify", s(&a), "--redo"]);
    let surface = d.join("a.ground-1.surface");
    let mut bytes = std::fs::read(&surface).unwrap();
    bytes[20] ^= 0xff;
    std::fs::write(&surface, &bytes).unwrap();
    fails(
        &["extract", s(&a), "-o", s(&out), "--force"],
        "checksum mismatch",
    );
    std::fs::write(&surface, b"nothing").unwrap();
    fails(
        &["extract", s(&a), "-o", s(&out), "--force"],
        "a.ground-1.surface",
    );
}

/// Edits from the viewers' server (`serve --edit`, as the web viewer sends them): kept beside
/// the dataset like the CLI's, the same points changed; eight clients and a `classify` at once
/// lose nothing; undo and redo; read-only without `--edit`; bad changes refused with their
/// status, the file as it was; a ground edit's surface served to the viewer, nothing else beside
/// the dataset.
#[test]
fn edits_from_the_server_are_kept_and_lose_nothing() {
    use common::{http_send, serve};
    use std::process::Stdio;
    let d = tempdir("classify-serve");
    let scan = synth(&d, "site.las", 60_000);
    let served = d.join("site.myr");
    ok(&["convert", s(&scan), "-o", s(&served)]);
    std::fs::create_dir_all(d.join("cli")).unwrap();
    let cli = d.join("cli/site.myr");
    std::fs::copy(&served, &cli).unwrap();
    let (scan0, ds0) = (digest(&scan), digest(&served));
    let r0 = records(&scan);
    let at = within(&r0);
    // Nine slabs across x, each a box given its own class.
    let slab = |i: usize| {
        let (x0, x1) = (at(0, i as f64 / 9.0), at(0, (i as f64 + 0.7) / 9.0));
        [
            x0,
            at(1, 0.0) - 1.0,
            at(2, 0.0) - 1.0,
            x1,
            at(1, 1.0) + 1.0,
            at(2, 1.0) + 1.0,
        ]
    };
    let json_box = |i: usize| {
        let b = slab(i);
        format!(
            r#"{{"add": {{"box": [[{},{},{}],[{},{},{}]], "to": {}}}}}"#,
            b[0],
            b[1],
            b[2],
            b[3],
            b[4],
            b[5],
            20 + i
        )
    };
    let path = "/edits/site.myr";
    let json_headers = ["Content-Type: application/json"];

    // Read-only: the (empty) layer shown, no change taken.
    let ro = serve(&[s(&served)], Stdio::null());
    let (code, body) = http_send(&ro.base, "GET", path, &[], "");
    assert_eq!(code, 200, "{body}");
    let v: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(
        (v["editable"].clone(), v["edits"].clone()),
        (false.into(), serde_json::json!([]))
    );
    let (code, _) = http_send(&ro.base, "POST", path, &json_headers, &json_box(0));
    assert_eq!(code, 403);
    drop(ro);
    let sidecar = d.join("site.edits.json");
    assert!(!sidecar.exists());

    // Eight clients of the server and one classify, at once: nine edits kept.
    let rw = serve(&[s(&served), "--edit"], Stdio::null());
    std::thread::scope(|scope| {
        for i in 0..8 {
            let (base, body) = (rw.base.clone(), json_box(i));
            scope.spawn(move || {
                let (code, answer) = http_send(&base, "POST", path, &json_headers, &body);
                assert_eq!(code, 200, "{answer}");
            });
        }
        let b = slab(8);
        let arg = b.map(|v| v.to_string()).join(",");
        ok(&[
            "classify",
            s(&served),
            "--box",
            &arg,
            "--to",
            "28",
            "--no-count",
        ]);
    });
    let (_, body) = http_send(&rw.base, "GET", path, &[], "");
    let v: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(v["editable"], true);
    let mut kept: Vec<u64> = (v["edits"].as_array().unwrap().iter())
        .map(|e| e["to"].as_u64().unwrap())
        .collect();
    kept.sort();
    assert_eq!(kept, (20..29).collect::<Vec<u64>>(), "no edit lost");
    // The same points as the CLI's edits give.
    for i in 0..9 {
        let arg = slab(i).map(|v| v.to_string()).join(",");
        ok(&[
            "classify",
            s(&cli),
            "--box",
            &arg,
            "--to",
            &(20 + i).to_string(),
            "--no-count",
        ]);
    }
    let (a, b) = (d.join("a.las"), d.join("b.las"));
    let served_records = extracted(&served, &a);
    assert_eq!(served_records, extracted(&cli, &b));
    let changed = (served_records.iter().zip(&r0))
        .filter(|(x, y)| x != y)
        .count();
    assert!(
        changed > 30_000,
        "{changed} points given the slabs' classes"
    );

    // Undo and redo, as the CLI's; nothing to redo is 409.
    let (code, body) = http_send(&rw.base, "POST", path, &json_headers, r#"{"undo": true}"#);
    assert_eq!(code, 200, "{body}");
    let v: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(v["edits"].as_array().unwrap().len(), 8);
    assert!(v["done"].as_str().unwrap().starts_with("undone: "), "{v}");
    ok(&["classify", s(&cli), "--undo"]);
    let undone_cli = extracted(&cli, &b);
    // (Undone on each side: the last edit of each, which may differ; redo gives both back.)
    let (code, _) = http_send(&rw.base, "POST", path, &json_headers, r#"{"redo": true}"#);
    assert_eq!(code, 200);
    assert_eq!(extracted(&served, &a), served_records);
    let (code, body) = http_send(&rw.base, "POST", path, &json_headers, r#"{"redo": true}"#);
    assert_eq!(code, 409, "{body}");
    assert_ne!(undone_cli, served_records);

    // Bad changes: their status, one line, the file as it was.
    let before = digest(&sidecar);
    for (body, code, says) in [
        (
            r#"{"add": {"polygon": [[0,0],[1,0]], "to": 7}}"#,
            400,
            "polygon",
        ),
        (
            r#"{"add": {"where": ["nothing>1"], "to": 7}}"#,
            400,
            "nothing",
        ),
        (r#"{"add": {"to": 300}}"#, 400, "300"),
        (r#"{"delete": true}"#, 400, "one of"),
        (
            r#"{"add": {"ground": {"surface": "site.ground-1.surface", "threshold": 0.5, "scalar": 1.25, "low": 1}}}"#,
            400,
            "myriad ground",
        ),
        ("{\n\"add\": ", 400, "line 2"),
    ] {
        let (got, answer) = http_send(&rw.base, "POST", path, &json_headers, body);
        assert_eq!(got, code, "{body}: {answer}");
        assert!(answer.contains(says), "{body}: {answer}");
        assert_eq!(answer.trim().lines().count(), 1, "{answer}");
    }
    let big = format!(
        r#"{{"add": {{"brush": [{}], "to": 7}}}}"#,
        "[1,2,3,4],".repeat(120_000)
    );
    let (code, _) = http_send(&rw.base, "POST", path, &json_headers, &big);
    assert_eq!(code, 413);
    let foreign = [
        "Content-Type: application/json",
        "Origin: https://elsewhere.example",
    ];
    let (code, _) = http_send(&rw.base, "POST", path, &foreign, &json_box(0));
    assert_eq!(code, 403, "a page of another origin does not edit");
    let (code, _) = http_send(
        &rw.base,
        "POST",
        "/edits/nothing.myr",
        &json_headers,
        &json_box(0),
    );
    assert_eq!(code, 404);
    assert_eq!(digest(&sidecar), before);

    // A ground edit's surface is served to the viewer; nothing else beside the dataset is.
    ok(&["ground", s(&served), "--no-count"]);
    let (_, body) = http_send(&rw.base, "GET", path, &[], "");
    let v: serde_json::Value = serde_json::from_str(&body).unwrap();
    let name = v["edits"][9]["ground"]["surface"]
        .as_str()
        .unwrap()
        .to_string();
    let answer = common::http_get(&rw.base, &format!("{path}?surface={name}"), &[]).to_lowercase();
    let len = std::fs::metadata(d.join(&name)).unwrap().len();
    assert!(answer.starts_with("http/1.1 200"), "{}", &answer[..40]);
    assert!(
        answer.contains(&format!("content-length: {len}\r\n")),
        "{len}"
    );
    for other in [
        "site.edits.json",
        "site.myr",
        "..%2Fsite.las",
        ".site.edits.json.lock",
    ] {
        let (code, _) = http_send(&rw.base, "GET", &format!("{path}?surface={other}"), &[], "");
        assert_eq!(code, 404, "{other}");
    }
    assert_eq!(
        (digest(&scan), digest(&served)),
        (scan0, ds0),
        "the scan and dataset untouched"
    );
}

/// `ground` finds isolated points (fewer than `--isolated` others in the cubes of a cell around
/// them) and makes them noise, class 7, as it does low points; a small cluster in the air is not
/// isolated, nor is the ground; `--isolated 0` finds none.
#[test]
fn isolated_points_are_noise() {
    let d = tempdir("isolated");
    let xyz = d.join("plane.xyz");
    let mut text = String::from("x y z classification\n");
    for i in 0..200 {
        for j in 0..200 {
            let z = 0.02 * ((i * 7 + j * 13) % 5) as f64;
            text += &format!("{} {} {z} 1\n", i as f64 * 0.5, j as f64 * 0.5);
        }
    }
    let lonely = [[20.0, 20.0, 20.0], [60.0, 35.0, 35.0], [80.0, 80.0, 50.0]];
    for p in lonely {
        text += &format!("{} {} {} 1\n", p[0], p[1], p[2]);
    }
    for k in 0..10 {
        text += &format!("{} 50 30 1\n", 40.0 + 0.1 * k as f64);
    }
    std::fs::write(&xyz, text).unwrap();
    let classes = |ds: &Path| -> Vec<([f64; 3], u8)> {
        let out = d.join("out.las");
        ok(&["extract", s(ds), "-o", s(&out), "--force"]);
        let mut src = myriad_io::open(&out, &myriad_io::OpenOptions::default()).unwrap();
        let mut all = Vec::new();
        while let Some(b) = src.read_batch(myriad_io::DEFAULT_BATCH).unwrap() {
            let c = b.classification.clone().unwrap();
            all.extend(b.positions.iter().copied().zip(c));
        }
        all
    };
    for (name, isolated, found) in [("a.myr", "2", 3), ("b.myr", "0", 0)] {
        let ds = d.join(name);
        ok(&["convert", s(&xyz), "-o", s(&ds)]);
        let said = ok(&["ground", s(&ds), "--isolated", isolated]);
        assert!(said.contains("noise (class 7"), "{said}");
        let got = classes(&ds);
        assert_eq!(got.len(), 40_013);
        let noise: Vec<[f64; 3]> = (got.iter().filter(|(_, c)| *c == 7))
            .map(|(p, _)| *p)
            .collect();
        assert_eq!(noise.len(), found, "{noise:?}");
        for p in &noise {
            assert!(
                lonely
                    .iter()
                    .any(|q| (0..3).all(|a| (p[a] - q[a]).abs() < 0.01)),
                "{p:?}"
            );
        }
        let ground = got.iter().filter(|(p, c)| *c == 2 && p[2] < 1.0).count();
        assert!(ground > 39_000, "{ground} of the plane's 40,000 ground");
        let cluster = got.iter().filter(|(p, c)| p[2] == 30.0 && *c == 1).count();
        assert_eq!(cluster, 10, "the cluster in the air is not isolated");
    }
}
