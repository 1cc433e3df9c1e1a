//! The surveyor's tools as a user runs them: `volume` on the synthetic stockpiles against their
//! analytic volumes (and two epochs against the pile taken away), `profile` to CSV, LAS, DXF
//! and PNG checked against the geometry (and, where `MYRIAD_PYTHON` has them, by laspy and
//! ezdxf), the filters of `extract`, and the one-line errors of bad input.

mod common;
use common::{fails, myriad, ok, python_with, s, shared_data, tempdir};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A pile line of `synth --scene stockpiles`: (volume, polygon).
fn piles(out: &str) -> Vec<(f64, String)> {
    out.lines()
        .filter(|l| l.starts_with("pile "))
        .map(|l| {
            let v = l.split(" m high, ").nth(1).unwrap();
            let v: f64 = v.split(" m3").next().unwrap().parse().unwrap();
            (v, l.split("--polygon ").nth(1).unwrap().trim().to_string())
        })
        .collect()
}

fn json(out: &str) -> serde_json::Value {
    serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}"))
}

fn stockpiles(d: &Path, epoch: &str) -> (PathBuf, Vec<(f64, String)>) {
    let las = d.join(format!("piles{epoch}.las"));
    let myr = d.join(format!("piles{epoch}.myr"));
    let out = ok(&[
        "synth",
        "--scene",
        "stockpiles",
        "--points",
        "1M",
        "--epoch",
        epoch,
        "-o",
        s(&las),
    ]);
    ok(&["convert", s(&las), "-o", s(&myr)]);
    (myr, piles(&out))
}

#[test]
fn stockpile_volumes_within_one_percent() {
    let d = tempdir("measure-volume");
    let (myr, piles) = stockpiles(&d, "1");
    assert!(piles.len() >= 30, "{} piles", piles.len());
    for (analytic, polygon) in piles.iter().take(8) {
        let v = json(&ok(&["volume", s(&myr), "--polygon", polygon, "--json"]));
        let fill = v["fill"].as_f64().unwrap();
        let err = (fill - analytic).abs() / analytic;
        assert!(
            err < 0.01,
            "fill {fill} vs {analytic}: {:.2} %",
            100.0 * err
        );
        assert!(v["cut"].as_f64().unwrap() < 0.005 * analytic, "{v}");
        assert!(v["rim_points"].as_u64().unwrap() > 100, "{v}");
    }
    // The ground under each pile, from the scene's ground points around it (class 2; the
    // material is 1): the pile's volume within 2 %.
    for (analytic, polygon) in piles.iter().take(4) {
        let v = json(&ok(&[
            "volume",
            s(&myr),
            "--polygon",
            polygon,
            "--base",
            "ground",
            "--json",
        ]));
        let fill = v["fill"].as_f64().unwrap();
        assert!(
            (fill - analytic).abs() < 0.02 * analytic,
            "--base ground: fill {fill} vs {analytic}"
        );
    }
    // A given elevation: the plane's slope under the pile counts too, so only sanity here.
    let (analytic, polygon) = &piles[0];
    let v = json(&ok(&[
        "volume",
        s(&myr),
        "--polygon",
        polygon,
        "--base",
        "90",
        "--json",
    ]));
    assert!(v["fill"].as_f64().unwrap() > 10.0 * analytic, "{v}");
    assert_eq!(v["cut"].as_f64().unwrap(), 0.0);

    // A later survey with the first pile gone: cut against the earlier surface is that pile.
    let (later, piles2) = stockpiles(&d, "2");
    assert_eq!(piles2.len(), piles.len());
    let v = json(&ok(&[
        "volume",
        s(&later),
        "--polygon",
        polygon,
        "--base",
        s(&myr),
        "--json",
    ]));
    let cut = v["cut"].as_f64().unwrap();
    assert!(
        (cut - analytic).abs() < 0.01 * analytic,
        "cut {cut} vs {analytic}"
    );
    assert!(v["fill"].as_f64().unwrap() < 0.005 * analytic, "{v}");
    // The other piles stand: neither cut nor fill over the second.
    let (_, polygon2) = &piles[1];
    let v = json(&ok(&[
        "volume",
        s(&later),
        "--polygon",
        polygon2,
        "--base",
        s(&myr),
        "--json",
    ]));
    assert!(v["net"].as_f64().unwrap().abs() < 0.01 * piles[1].0, "{v}");
    // As GeoJSON, read by shapely: the polygon's area, the volumes, the CRS.
    let gj = d.join("pile.geojson");
    ok(&["volume", s(&myr), "--polygon", polygon, "--geojson", s(&gj)]);
    match python_with("shapely") {
        None => eprintln!("SKIPPED: no Python with shapely (MYRIAD_PYTHON); .ci/run installs it"),
        Some(py) => {
            let script = r#"
import json, sys
from shapely.geometry import shape
doc = json.load(open(sys.argv[1]))
assert doc["crs"]["properties"]["name"] == "urn:ogc:def:crs:EPSG::32633", doc.get("crs")
(f,) = doc["features"]
g = shape(f["geometry"])
assert g.is_valid and g.geom_type == "Polygon"
p = f["properties"]
assert abs(g.area - p["area"]) < 1e-6 * p["area"], (g.area, p["area"])
assert p["units"] == "m" and p["fill"] > 0
print(round(p["fill"], 3))
"#;
            let r = Command::new(&py)
                .args(["-c", script, s(&gj)])
                .output()
                .unwrap();
            assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
            let fill: f64 = String::from_utf8_lossy(&r.stdout).trim().parse().unwrap();
            assert!((fill - analytic).abs() < 0.01 * analytic, "{fill}");
        }
    }
    fails(
        &["volume", s(&myr), "--polygon", polygon, "--geojson", s(&gj)],
        "output exists",
    );
    let text = ok(&["volume", s(&myr), "--polygon", polygon]);
    assert!(
        text.contains("fill") && text.contains("m3 above the base"),
        "{text}"
    );

    // Bad polygons and bases: one line each.
    fails(
        &["volume", s(&myr), "--polygon", "0,0,10,10,10,0,0,10"],
        "crosses itself",
    );
    fails(&["volume", s(&myr), "--polygon", "0,0,10,10"], "at least 3");
    fails(
        &["volume", s(&myr), "--polygon", "0,0,10,0,0,10"],
        "holds no point",
    );
    fails(
        &["volume", s(&myr), "--polygon", polygon, "--base", "nowhere"],
        "--base \"nowhere\"",
    );
    fails(
        &["volume", s(&myr), "--polygon", polygon, "--cell", "0"],
        "--cell 0",
    );
    // A cell so small that the cells overflowed any integer: refused, not a panic.
    fails(
        &["volume", s(&myr), "--polygon", polygon, "--cell", "1e-20"],
        "more than 100000000",
    );
    // An earlier survey of another pile alone does not cover this one: an error naming the
    // share, not a volume of 0.
    let xy: Vec<f64> = (polygon2.split(',')).map(|v| v.parse().unwrap()).collect();
    let (xs, ys): (Vec<f64>, Vec<f64>) = xy.chunks(2).map(|p| (p[0], p[1])).unzip();
    let lo = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let other = d.join("other.las");
    let b = format!("{},{},-1e6,{},{},1e6", lo(&xs), lo(&ys), hi(&xs), hi(&ys));
    ok(&["extract", s(&myr), "-o", s(&other), "--box", &b]);
    let other_myr = d.join("other.myr");
    ok(&["convert", s(&other), "-o", s(&other_myr)]);
    let args = [
        "volume",
        s(&later),
        "--polygon",
        polygon,
        "--base",
        s(&other_myr),
    ];
    fails(&args, "the earlier survey does not cover");
    polygons_from_files(&d, &myr, polygon);
}

/// `--polygon @FILE`: GeoJSON, WKT and CSV give the volume the inline polygon gives, a polygon
/// of 100 k vertices over the same ground too; another CRS, far coordinates and what is not a
/// file are one-line errors.
fn polygons_from_files(d: &Path, myr: &Path, polygon: &str) {
    let xy: Vec<f64> = polygon.split(',').map(|v| v.parse().unwrap()).collect();
    let pts: Vec<[f64; 2]> = xy.chunks(2).map(|p| [p[0], p[1]]).collect();
    let inline = json(&ok(&["volume", s(myr), "--polygon", polygon, "--json"]));
    let fill = inline["fill"].as_f64().unwrap();
    let ring = |p: &[[f64; 2]]| {
        let mut v: Vec<String> = p.iter().map(|q| format!("[{},{}]", q[0], q[1])).collect();
        v.push(v[0].clone());
        v.join(",")
    };
    let geojson = |p: &[[f64; 2]], epsg: u32| {
        format!(
            r#"{{"type":"FeatureCollection","crs":{{"type":"name","properties":{{"name":"urn:ogc:def:crs:EPSG::{epsg}"}}}},
            "features":[{{"type":"Feature","properties":{{"name":"pile"}},"geometry":{{"type":"Polygon","coordinates":[[{}]]}}}}]}}"#,
            ring(p)
        )
    };
    let wkt = format!(
        "SRID=32633;POLYGON (({}, {} {}))",
        pts.iter()
            .map(|p| format!("{} {}", p[0], p[1]))
            .collect::<Vec<_>>()
            .join(", "),
        pts[0][0],
        pts[0][1]
    );
    let csv = format!(
        "id,x,y\n{}",
        pts.iter()
            .enumerate()
            .map(|(i, p)| format!("{i},{},{}\n", p[0], p[1]))
            .collect::<String>()
    );
    // 100 k vertices along the same edges.
    let per = 100_000 / pts.len();
    let mut dense = Vec::new();
    for i in 0..pts.len() {
        let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
        for k in 0..per {
            let t = k as f64 / per as f64;
            dense.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
        }
    }
    for (name, text) in [
        ("pile.geojson", geojson(&pts, 32633)),
        ("pile.wkt", wkt),
        ("pile.csv", csv),
        ("dense.geojson", geojson(&dense, 32633)),
    ] {
        let f = d.join(name);
        std::fs::write(&f, text).unwrap();
        let arg = format!("@{}", f.display());
        let v = json(&ok(&["volume", s(myr), "--polygon", &arg, "--json"]));
        let got = v["fill"].as_f64().unwrap();
        assert!(
            (got - fill).abs() <= 1e-4 * fill,
            "{name}: fill {got} vs {fill}"
        );
    }
    let other = d.join("other-crs.geojson");
    std::fs::write(&other, geojson(&pts, 4326)).unwrap();
    fails(
        &[
            "volume",
            s(myr),
            "--polygon",
            &format!("@{}", other.display()),
        ],
        "its CRS is EPSG:4326, the dataset's EPSG:32633",
    );
    let lonlat = d.join("lonlat.csv");
    std::fs::write(&lonlat, "15.1,50.2\n15.2,50.2\n15.2,50.3\n").unwrap();
    fails(
        &[
            "volume",
            s(myr),
            "--polygon",
            &format!("@{}", lonlat.display()),
        ],
        "lies far outside the dataset",
    );
    let bad = d.join("bad.wkt");
    std::fs::write(&bad, "POLYGON ((0 0, 1 0, 1 x, 0 0))").unwrap();
    fails(
        &[
            "volume",
            s(myr),
            "--polygon",
            &format!("@{}", bad.display()),
        ],
        "bad.wkt: byte 22: \"x\" is not a finite number",
    );
    fails(&["volume", s(myr), "--polygon", "@/dev/zero"], "not a file");
    fails(
        &["volume", s(myr), "--polygon", "@/nonexistent/area.geojson"],
        "area.geojson",
    );
}

/// Distance along and across a polyline, computed here on its own: the nearest segment.
fn station(line: &[[f64; 2]], p: [f64; 2]) -> (f64, f64, f64) {
    let mut best = (f64::INFINITY, 0.0, 0.0);
    let mut start = 0.0;
    for w in line.windows(2) {
        let (a, b) = (w[0], w[1]);
        let d = [b[0] - a[0], b[1] - a[1]];
        let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
        let t = (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / (len * len)).clamp(0.0, 1.0);
        let f = [a[0] + t * d[0], a[1] + t * d[1]];
        let dist = ((p[0] - f[0]).powi(2) + (p[1] - f[1]).powi(2)).sqrt();
        let side = (d[0] * (p[1] - a[1]) - d[1] * (p[0] - a[0])).signum();
        if dist < best.0 {
            best = (dist, start + t * len, dist * side);
        }
        start += len;
    }
    best
}

#[test]
fn profile_to_csv_las_dxf_png() {
    let d = tempdir("measure-profile");
    let las = d.join("city.las");
    let myr = d.join("city.myr");
    ok(&["synth", "--points", "300k", "-o", s(&las)]);
    ok(&["convert", s(&las), "-o", s(&myr)]);
    let ds = myriad_format::Dataset::open(&myr).unwrap();
    let b = ds.meta.bounds;
    let (w, h) = (b.max[0] - b.min[0], b.max[1] - b.min[1]);
    // An L across the city: 3 m wide.
    let line = [
        [b.min[0] + 0.1 * w, b.min[1] + 0.2 * h],
        [b.min[0] + 0.8 * w, b.min[1] + 0.3 * h],
        [b.min[0] + 0.7 * w, b.min[1] + 0.9 * h],
    ];
    let line_arg = line
        .iter()
        .map(|p| format!("{},{}", p[0], p[1]))
        .collect::<Vec<_>>()
        .join(",");
    let width = 3.0;
    let all = d.join("all.las");
    ok(&["extract", s(&myr), "-o", s(&all)]);
    // Every point of the scan within 1.5 m of the line, found here by brute force.
    let mut expect: Vec<[i64; 3]> = Vec::new();
    let mut src = myriad_io::open(&all, &Default::default()).unwrap();
    while let Some(b) = src.read_batch(myriad_io::DEFAULT_BATCH).unwrap() {
        for p in &b.positions {
            if station(&line, [p[0], p[1]]).0 <= width / 2.0 {
                expect.push(p.map(|v| (v * 1000.0).round() as i64));
            }
        }
    }
    expect.sort();
    assert!(
        expect.len() > 1000,
        "{} points in the corridor",
        expect.len()
    );

    let csv = d.join("profile.csv");
    let out = ok(&[
        "profile",
        s(&myr),
        "--line",
        &line_arg,
        "--width",
        "3",
        "-o",
        s(&csv),
    ]);
    assert!(
        out.contains(&format!(
            "{} points",
            myriad_core::units::thousands(expect.len() as u64)
        )),
        "{out}"
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut rows = text.lines();
    let header: Vec<&str> = rows.next().unwrap().split(',').collect();
    assert_eq!(&header[..5], ["x", "y", "z", "distance", "offset"]);
    assert!(header.contains(&"classification") && header.contains(&"intensity"));
    let mut got = Vec::new();
    let mut last = f64::NEG_INFINITY;
    for r in rows {
        let v: Vec<f64> = r.split(',').map(|t| t.parse().unwrap()).collect();
        let (_, along, across) = station(&line, [v[0], v[1]]);
        assert!((v[3] - along).abs() < 1e-3, "distance {} vs {along}", v[3]);
        assert!((v[4] - across).abs() < 1e-3, "offset {} vs {across}", v[4]);
        assert!(v[3] >= last, "sorted along the line");
        last = v[3];
        got.push([v[0], v[1], v[2]].map(|c| (c * 1000.0).round() as i64));
    }
    got.sort();
    assert_eq!(got, expect, "the CSV holds exactly the corridor's points");
    // The same line from a WKT file, and as a GeoJSON LineString: the same rows.
    let wkt = d.join("road.wkt");
    let pairs: Vec<String> = line.iter().map(|p| format!("{} {}", p[0], p[1])).collect();
    std::fs::write(&wkt, format!("LINESTRING ({})", pairs.join(", "))).unwrap();
    let gj = d.join("road.geojson");
    let coords: Vec<String> = line
        .iter()
        .map(|p| format!("[{},{}]", p[0], p[1]))
        .collect();
    std::fs::write(
        &gj,
        format!(
            r#"{{"type":"Feature","geometry":{{"type":"LineString","coordinates":[{}]}}}}"#,
            coords.join(",")
        ),
    )
    .unwrap();
    for (file, out) in [(&wkt, "wkt.csv"), (&gj, "gj.csv")] {
        let o = d.join(out);
        let arg = format!("@{}", file.display());
        ok(&[
            "profile",
            s(&myr),
            "--line",
            &arg,
            "--width",
            "3",
            "-o",
            s(&o),
        ]);
        assert_eq!(std::fs::read_to_string(&o).unwrap(), text, "{out}");
    }

    let corridor = d.join("profile.laz");
    ok(&[
        "profile",
        s(&myr),
        "--line",
        &line_arg,
        "--width",
        "3",
        "-o",
        s(&corridor),
    ]);
    let mut got = Vec::new();
    let mut src = myriad_io::open(&corridor, &Default::default()).unwrap();
    while let Some(b) = src.read_batch(myriad_io::DEFAULT_BATCH).unwrap() {
        got.extend(
            b.positions
                .iter()
                .map(|p| p.map(|v| (v * 1000.0).round() as i64)),
        );
    }
    got.sort();
    assert_eq!(got, expect, "the LAZ holds exactly the corridor's points");

    let dxf = d.join("profile.dxf");
    ok(&[
        "profile",
        s(&myr),
        "--line",
        &line_arg,
        "--width",
        "3",
        "-o",
        s(&dxf),
    ]);
    let gj = d.join("profile.geojson");
    ok(&[
        "profile",
        s(&myr),
        "--line",
        &line_arg,
        "--width",
        "3",
        "-o",
        s(&gj),
    ]);
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&gj).unwrap()).unwrap();
    let f = &doc["features"][0];
    assert_eq!(f["geometry"]["type"], "LineString");
    assert_eq!(
        f["properties"]["points"].as_u64(),
        Some(expect.len() as u64)
    );
    assert_eq!(
        doc["crs"]["properties"]["name"],
        "urn:ogc:def:crs:EPSG::32633"
    );
    let png = d.join("profile.png");
    let out = ok(&[
        "profile",
        s(&myr),
        "--line",
        &line_arg,
        "--width",
        "3",
        "-o",
        s(&png),
        "--pixels",
        "800",
        "--color",
        "classification",
    ]);
    assert!(out.contains("800 x "), "{out}");
    let (width, _, rgba) = common::decode_png(&png);
    assert_eq!(width, 800);
    let ground = myriad_core::colour::class_colour(2);
    let lit = rgba.chunks(4).filter(|p| p[..3] == ground).count();
    assert!(lit > 200, "{lit} pixels of ground colour in the profile");

    // Read by the field's readers: the corridor by laspy against the whole scan, the drawing
    // by ezdxf.
    match python_with("laspy, lazrs, ezdxf, numpy") {
        None => eprintln!(
            "SKIPPED: no Python with laspy[lazrs] and ezdxf (MYRIAD_PYTHON); .ci/run installs them"
        ),
        Some(py) => {
            let script = format!(
                r#"
import laspy, ezdxf, numpy as np, sys
line = np.array({line:?})
def dist(x, y):
    best = np.full(len(x), np.inf)
    for a, b in zip(line[:-1], line[1:]):
        d = b - a
        t = np.clip(((x - a[0]) * d[0] + (y - a[1]) * d[1]) / d.dot(d), 0, 1)
        best = np.minimum(best, np.hypot(x - a[0] - t * d[0], y - a[1] - t * d[1]))
    return best
full = laspy.read(sys.argv[1]); cut = laspy.read(sys.argv[2])
inside = dist(np.asarray(full.x), np.asarray(full.y)) <= 1.5
key = lambda l, m: sorted(zip(l.X[m].tolist(), l.Y[m].tolist(), l.Z[m].tolist()))
assert key(full, inside) == key(cut, np.ones(len(cut.X), bool)), "laspy: corridor differs"
assert set(np.asarray(cut.classification).tolist()) <= set(np.asarray(full.classification).tolist())
doc = ezdxf.readfile(sys.argv[3])
msp = doc.modelspace()
points = msp.query("POINT"); polys = msp.query("LWPOLYLINE")
assert len(points) == len(cut.X), (len(points), len(cut.X))
assert len(polys) == 2, len(polys)
assert {{p.dxf.layer for p in points}} == {{"POINTS"}}
prof = [p for p in polys if p.dxf.layer == "PROFILE"][0]
xs = [v[0] for v in prof.get_points()]
assert xs == sorted(xs) and xs[-1] <= {length} + 1e-6, "profile line along the section"
print("ok", len(points))
"#,
                line = line.map(|p| p.to_vec()),
                length = {
                    let mut l = 0.0;
                    for w in line.windows(2) {
                        l += ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt();
                    }
                    l
                }
            );
            let r = Command::new(&py)
                .args(["-c", &script, s(&all), s(&corridor), s(&dxf)])
                .output()
                .unwrap();
            assert!(
                r.status.success(),
                "{}{}",
                String::from_utf8_lossy(&r.stdout),
                String::from_utf8_lossy(&r.stderr)
            );
            assert_eq!(
                String::from_utf8_lossy(&r.stdout).trim(),
                format!("ok {}", expect.len())
            );
        }
    }

    // A line away from the data: a valid empty file, and said.
    let empty = d.join("empty.csv");
    let out = ok(&[
        "profile",
        s(&myr),
        "--line",
        "0,0,10,10",
        "--width",
        "2",
        "-o",
        s(&empty),
    ]);
    assert!(out.contains("holds no point"), "{out}");
    assert_eq!(
        std::fs::read_to_string(&empty).unwrap().lines().count(),
        1,
        "the header only"
    );
    fails(
        &[
            "profile",
            s(&myr),
            "--line",
            &line_arg,
            "--width",
            "0",
            "-o",
            s(&d.join("z.csv")),
        ],
        "--width 0",
    );
    fails(
        &[
            "profile",
            s(&myr),
            "--line",
            "1,2,3",
            "--width",
            "2",
            "-o",
            s(&d.join("z.csv")),
        ],
        "odd count",
    );
    fails(
        &[
            "profile",
            s(&myr),
            "--line",
            &line_arg,
            "--width",
            "2",
            "--classes",
            "grond",
            "-o",
            s(&d.join("z.csv")),
        ],
        "\"grond\": no such class",
    );
    fails(
        &[
            "profile",
            s(&myr),
            "--line",
            &line_arg,
            "--width",
            "2",
            "--where",
            "amplitude>2",
            "-o",
            s(&d.join("z.csv")),
        ],
        "no attribute \"amplitude\"",
    );
    assert!(!d.join("z.csv").exists());
}

#[test]
fn extract_keeps_exactly_the_filtered_records() {
    let d = tempdir("measure-filter");
    let las = d.join("city.las");
    let myr = d.join("city.myr");
    ok(&["synth", "--points", "200k", "-o", s(&las)]);
    ok(&["convert", s(&las), "-o", s(&myr)]);
    let all = common::records(&las);
    let class = |r: &Vec<i64>| r[5];
    let some = d.join("some.las");
    ok(&["extract", s(&myr), "-o", s(&some), "--classes", "2,6"]);
    let expect: Vec<Vec<i64>> = all
        .iter()
        .filter(|r| matches!(class(r), 2 | 6))
        .cloned()
        .collect();
    assert!(expect.len() > 1000 && expect.len() < all.len());
    assert_eq!(common::records(&some), expect);
    // Names, and a condition on the intensity.
    let bright = d.join("bright.laz");
    ok(&[
        "extract",
        s(&myr),
        "-o",
        s(&bright),
        "--classes",
        "building",
        "--where",
        "intensity>=2000 and return_number=1",
    ]);
    let expect: Vec<Vec<i64>> = all
        .iter()
        .filter(|r| class(r) == 6 && r[4] >= 2000 && r[6] == 1)
        .cloned()
        .collect();
    assert!(!expect.is_empty());
    assert_eq!(common::records(&bright), expect);
    // Drawn on the CPU without passes (no blending of colours): what `render` prints, and the
    // image's pixels.
    let png = d.join("drawn.png");
    let render = |extra: &[&str]| -> (String, Vec<[u8; 3]>) {
        let mut args = vec![
            "render",
            s(&myr),
            "-o",
            s(&png),
            "--force",
            "--passes",
            "none",
            "--raster",
            "cpu",
            "--width",
            "320",
            "--height",
            "200",
        ];
        args.extend(extra);
        let out = ok(&args);
        let (_, _, rgba) = common::decode_png(&png);
        (out, rgba.chunks(4).map(|p| [p[0], p[1], p[2]]).collect())
    };
    // With classes coloured, every lit pixel is ground's.
    let (_, px) = render(&["--classes", "2", "--color", "classification"]);
    let ground = myriad_core::colour::class_colour(2);
    let lit = px.iter().filter(|p| **p == ground).count();
    let other = px
        .iter()
        .filter(|p| **p != ground && **p != [0, 0, 0])
        .count();
    assert!(lit > 5000, "{lit} ground pixels");
    assert_eq!(other, 0, "pixels of other colours than ground's");
    // Unfiltered, buildings show.
    let (_, px) = render(&["--color", "classification"]);
    let building = myriad_core::colour::class_colour(6);
    let n = px.iter().filter(|p| **p == building).count();
    assert!(n > 500, "{n} building pixels unfiltered");
    // Any attribute through a gradient: GPS time in grey, fitted to the overview's range.
    let (_, px) = render(&["--color", "gps_time", "--gradient", "grey"]);
    assert!(px.iter().all(|p| p[0] == p[1] && p[1] == p[2]), "grey only");
    let levels: std::collections::HashSet<u8> = px.iter().map(|p| p[0]).collect();
    assert!(
        levels.len() > 50,
        "{} grey levels of GPS time",
        levels.len()
    );
    // Within a budget, a filtered node draws the share of its level of detail it keeps: ground
    // is about its share of the points drawn unfiltered, not the budget.
    let drawn = |extra: &[&str]| -> f64 {
        let mut args = vec!["--budget", "5k"];
        args.extend(extra);
        let (out, _) = render(&args);
        let n = out
            .split(": ")
            .nth(1)
            .unwrap()
            .split(" points")
            .next()
            .unwrap();
        n.replace(',', "").parse().unwrap()
    };
    let share = all.iter().filter(|r| class(r) == 2).count() as f64 / all.len() as f64;
    let (whole, only) = (drawn(&[]), drawn(&["--classes", "2"]));
    assert!(
        (only / (whole * share) - 1.0).abs() < 0.3,
        "ground drew {only} of {whole}, its share {share:.3}"
    );
    fails(
        &[
            "render",
            s(&myr),
            "-o",
            s(&d.join("x.png")),
            "--color",
            "amplitude",
        ],
        "--color \"amplitude\"",
    );
    fails(
        &[
            "render",
            s(&myr),
            "-o",
            s(&d.join("x.png")),
            "--color",
            "intensity",
            "--range",
            "5,1",
        ],
        "--range 5,1",
    );
    fails(
        &[
            "render",
            s(&myr),
            "-o",
            s(&d.join("x.png")),
            "--where",
            "nir>3",
        ],
        "no attribute \"nir\"",
    );
    fails(
        &[
            "extract",
            s(&myr),
            "-o",
            s(&d.join("x.las")),
            "--where",
            "intensity~2",
        ],
        "expected NAME OP VALUE",
    );
    assert!(!d.join("x.las").exists());
}

/// `annotate`: work kept beside the dataset (what `view` and `serve` read), exported to
/// GeoJSON (read by shapely with its CRS) and DXF (by ezdxf), imported back into another
/// dataset's work as it was, and bad input refused in one line with the sidecar untouched.
#[test]
fn annotations_are_kept_exported_and_imported() {
    let d = tempdir("annotate");
    let laz = common::synth(&d, "site.laz", 20_000);
    let myr = d.join("site.myr");
    ok(&["convert", s(&laz), "-o", s(&myr)]);
    let sidecar = d.join("site.work.json");
    let out = ok(&[
        "annotate",
        s(&myr),
        "--add",
        "500010.5,4400020.25,12.125",
        "--title",
        "gate",
        "--text",
        "north side\nsee photo 12",
        "--camera",
        "500000,4399990,60,500010.5,4400020.25,12.125",
        "--measure",
        "distance:500000,4400000,10,500003,4400004,10,500003,4400004,22",
        "--measure",
        "area:500000,4400000,0,500010,4400000,0,500010,4400010,0",
        "--measure",
        "azimuth:500000,4400000,0,500001,4400001,0",
    ]);
    assert!(
        out.contains("site.work.json: 1 annotations, 3 measurements, CRS EPSG:32633"),
        "{out}"
    );
    assert!(
        out.contains("measurement 1 distance: 17.000 m (3 points)"),
        "{out}"
    );
    assert!(out.contains("measurement 2 area: 50.00 m² area"), "{out}");
    assert!(out.contains("45.00° from north"), "{out}");
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&sidecar).unwrap()).unwrap();
    assert_eq!(saved["annotations"][0]["text"], "north side\nsee photo 12");
    assert_eq!(saved["annotations"][0]["camera"]["position"][2], 60.0);
    // A number that is not finite is a usage error, and nothing is saved: one NaN kept as
    // JSON's null made the work unreadable everywhere.
    let kept = std::fs::read(&sidecar).unwrap();
    for bad in [
        &["--add", "NaN,1,2", "--title", "x"][..],
        &["--add", "1,inf,2"],
        &["--add", "1e400,1,2"],
        &["--add", "1,2,3", "--camera", "0,0,0,1,1,NaN"],
    ] {
        let r = myriad(&[&["annotate", s(&myr)][..], bad].concat());
        assert_eq!(r.code, 2, "{bad:?}: {}", r.stderr);
        assert!(r.stderr.contains("finite"), "{bad:?}: {}", r.stderr);
    }
    assert_eq!(std::fs::read(&sidecar).unwrap(), kept);
    fails(
        &["annotate", s(&myr), "--measure", "distance:0,0,0,NaN,1,1"],
        "not a number",
    );
    assert_eq!(std::fs::read(&sidecar).unwrap(), kept);
    // Finite but far: a camera between ±1e308 looked along infinities, a distance between such
    // points was saved as null.
    for bad in [
        &["--add", "1,2,3", "--camera", "-1e308,0,0,1e308,0,0"][..],
        &["--measure", "distance:-1e308,0,0,1e308,0,0"],
        &["--add", "1,2,3", "--camera", "5,5,5,5,5,5"],
    ] {
        let r = myriad(&[&["annotate", s(&myr)][..], bad].concat());
        assert_eq!(r.code, 1, "{bad:?}: {}", r.stderr);
        assert!(
            r.stderr.contains("beyond ±1e12") || r.stderr.contains("its target is its position"),
            "{bad:?}: {}",
            r.stderr
        );
        assert!(r.stderr.contains("not saved"), "{bad:?}: {}", r.stderr);
    }
    assert_eq!(std::fs::read(&sidecar).unwrap(), kept);
    // An import read with a bound: a GeoJSON name for /dev/zero grew to gigabytes.
    let zero = d.join("zero.geojson");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    fails(
        &["annotate", s(&myr), "--import", s(&zero)],
        "a device, not a file",
    );
    assert_eq!(std::fs::read(&sidecar).unwrap(), kept);
    // The scan shares the dataset's work (the same name beside it).
    let again = ok(&["annotate", s(&laz)]);
    assert!(again.contains("1 annotations, 3 measurements"), "{again}");

    let geojson = d.join("work.geojson");
    let dxf = d.join("work.dxf");
    ok(&["annotate", s(&myr), "--export", s(&geojson)]);
    ok(&["annotate", s(&myr), "--export", s(&dxf)]);
    fails(&["annotate", s(&myr), "--export", s(&dxf)], "work.dxf");
    match python_with("ezdxf, shapely") {
        None => eprintln!(
            "SKIPPED: no Python with ezdxf and shapely (MYRIAD_PYTHON); .ci/run installs them"
        ),
        Some(py) => {
            let script = r#"
import ezdxf, json, sys, shapely.geometry as g
j = json.load(open(sys.argv[1]))
print(j["crs"]["properties"]["name"])
for f in j["features"]:
    s = g.shape(f["geometry"])
    print(f["properties"]["myriad"], s.geom_type, round(s.length, 6), round(s.area, 6), list(s.coords)[0] if s.geom_type != "Polygon" else "")
m = ezdxf.readfile(sys.argv[2]).modelspace()
for e in m:
    print("dxf", e.dxftype(), e.dxf.layer, e.dxf.text if e.dxftype() == "TEXT" else (len(list(e.points())) if e.dxftype() == "POLYLINE" else ""))
"#;
            let r = Command::new(py)
                .args(["-c", script, s(&geojson), s(&dxf)])
                .output()
                .unwrap();
            let out = String::from_utf8_lossy(&r.stdout);
            assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
            eprintln!("{out}");
            let lines: Vec<&str> = out.lines().collect();
            assert_eq!(lines[0], "urn:ogc:def:crs:EPSG::32633");
            assert_eq!(
                lines[1],
                "annotation Point 0.0 0.0 (500010.5, 4400020.25, 12.125)"
            );
            // shapely's lengths are in plan: 5 m, then 12 m straight up.
            assert!(
                lines[2].starts_with("measurement LineString 5.0 0.0"),
                "{out}"
            );
            assert!(
                lines[3].starts_with("measurement Polygon 34.142136 50.0"),
                "{out}"
            );
            assert!(
                lines[4].starts_with("measurement LineString 1.414214"),
                "{out}"
            );
            let dxf: Vec<&str> = lines
                .iter()
                .filter(|l| l.starts_with("dxf"))
                .copied()
                .collect();
            assert_eq!(
                dxf,
                [
                    "dxf TEXT ANNOTATIONS gate",
                    "dxf MTEXT ANNOTATION_TEXT ",
                    "dxf POLYLINE MEASURE_DISTANCE 3",
                    "dxf POLYLINE MEASURE_AREA 3",
                    "dxf POLYLINE MEASURE_AZIMUTH 2",
                ]
            );
        }
    }

    // Imported into another dataset of the same CRS: the same work (DXF keeps no camera).
    let other = d.join("other.myr");
    std::fs::copy(&myr, &other).unwrap();
    ok(&["annotate", s(&other), "--import", s(&geojson)]);
    let a: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("other.work.json")).unwrap()).unwrap();
    assert_eq!(a["annotations"], saved["annotations"]);
    assert_eq!(a["measurements"], saved["measurements"]);
    ok(&["annotate", s(&other), "--clear", "--import", s(&dxf)]);
    let b: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("other.work.json")).unwrap()).unwrap();
    assert_eq!(b["measurements"], saved["measurements"]);
    assert_eq!(b["annotations"][0]["text"], "north side\nsee photo 12");
    assert_eq!(b["annotations"][0]["camera"], serde_json::Value::Null);

    // Bad input: one line naming the value, exit 1, the sidecar as it was.
    let before = std::fs::read(&sidecar).unwrap();
    fails(
        &["annotate", s(&myr), "--measure", "volume:1,2,3"],
        "unknown measurement \"volume\"",
    );
    fails(
        &["annotate", s(&myr), "--measure", "circle:1,2,3,4,5,6"],
        "a circle takes 3 points, not 2",
    );
    fails(
        &["annotate", s(&myr), "--measure", "distance:1,2,x"],
        "\"x\" is not a number",
    );
    fails(
        &["annotate", s(&myr), "--remove", "nothing"],
        "no annotation of that title",
    );
    let foreign = d.join("foreign.geojson");
    std::fs::write(
        &foreign,
        r#"{"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"urn:ogc:def:crs:EPSG::2992"}},"features":[]}"#,
    )
    .unwrap();
    fails(
        &["annotate", s(&myr), "--import", s(&foreign)],
        "foreign.geojson: its CRS is EPSG:2992, the dataset's EPSG:32633",
    );
    // Longitude and latitude without a CRS member (GeoJSON's default), into a dataset in
    // metres: refused by where its points lie, whatever the CRSs' codes say (issue 67).
    let lonlat = d.join("lonlat.geojson");
    std::fs::write(
        &lonlat,
        r#"{"type":"FeatureCollection","features":[{"type":"Feature","geometry":{"type":"Point","coordinates":[15.0,39.7,20.0]},"properties":{"myriad":"annotation","title":"gate"}}]}"#,
    )
    .unwrap();
    fails(
        &["annotate", s(&myr), "--import", s(&lonlat)],
        "lonlat.geojson: its point 15.000, 39.700 lies far outside the dataset",
    );
    let broken = d.join("broken.geojson");
    std::fs::write(
        &broken,
        "{\"type\":\n\"FeatureCollection\",\n\"features\": [1,\n",
    )
    .unwrap();
    fails(
        &["annotate", s(&myr), "--import", s(&broken)],
        "broken.geojson: line 4",
    );
    assert_eq!(std::fs::read(&sidecar).unwrap(), before);
    // A broken sidecar is said with its line, and left as it is.
    std::fs::write(
        &sidecar,
        "{\n  \"myriad\": \"work\",\n  \"version\": 1,\n  oops\n}",
    )
    .unwrap();
    fails(
        &["annotate", s(&myr), "--add", "1,2,3"],
        "site.work.json: line 4",
    );
    assert!(std::fs::read_to_string(&sidecar).unwrap().contains("oops"));
    // Removing by title.
    std::fs::write(&sidecar, &before).unwrap();
    let out = ok(&["annotate", s(&myr), "--remove", "gate"]);
    assert!(out.contains("0 annotations, 3 measurements"), "{out}");
}

/// Every figure of `volume` in the dataset's unit: autzen is in US feet, and the rim plane's
/// height was printed in metres beside volumes in feet (issue 67).
#[test]
fn volume_speaks_the_datasets_unit() {
    let Some(laz) = shared_data("PDAL__laz_autzen_trim.laz") else {
        return;
    };
    let d = tempdir("volume-units");
    let myr = d.join("autzen.myr");
    ok(&["convert", s(&laz), "-o", s(&myr)]);
    let v: serde_json::Value = serde_json::from_str(&ok(&["info", "--json", s(&myr)])).unwrap();
    let (min, max) = (&v["bounds"]["min"], &v["bounds"]["max"]);
    let f = |v: &serde_json::Value, i: usize| v[i].as_f64().unwrap();
    let (cx, cy) = ((f(min, 0) + f(max, 0)) / 2.0, (f(min, 1) + f(max, 1)) / 2.0);
    let r = 60.0;
    let polygon = format!(
        "{},{},{},{},{},{},{},{}",
        cx - r,
        cy - r,
        cx + r,
        cy - r,
        cx + r,
        cy + r,
        cx - r,
        cy + r
    );
    let out = ok(&["volume", s(&myr), "--polygon", &polygon]);
    let fill = out
        .lines()
        .find(|l| l.trim_start().starts_with("fill"))
        .unwrap();
    let unit = fill
        .split_whitespace()
        .nth(2)
        .unwrap()
        .trim_end_matches('3');
    assert_ne!(unit, "m", "autzen is in feet: {out}");
    assert!(
        out.contains(&format!("{unit} at the first vertex")),
        "the rim plane in the dataset's unit: {out}"
    );
}
