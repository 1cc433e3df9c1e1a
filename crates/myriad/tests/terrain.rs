//! Terrain products (issue 70): `raster` writes Cloud-Optimized GeoTIFFs that rasterio reads with
//! the dataset's CRS and transform and the right values (a synthetic city's known ground; KY's
//! labelled ground within 0.1 m RMS where the scan is present); `contours` writes DXF and GeoJSON
//! that ezdxf and shapely read, at the terrain's heights; bad requests are one line, nothing
//! written.

mod common;
use common::{fails, ok, python_with, records, s, shared_data, synth, tempdir};
use std::path::Path;
use std::process::Command;

/// Runs a Python script with `args`; its standard output.
fn python(py: &str, script: &str, args: &[&str]) -> String {
    let out = Command::new(py)
        .arg("-c")
        .arg(script)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The TIFF's first directory: its tags (the COG layout: the directory right after the header).
fn tags(tif: &Path) -> Vec<u16> {
    let b = std::fs::read(tif).unwrap();
    assert_eq!(&b[..4], b"II*\0");
    assert_eq!(
        u32::from_le_bytes(b[4..8].try_into().unwrap()),
        8,
        "directory first"
    );
    let n = u16::from_le_bytes(b[8..10].try_into().unwrap()) as usize;
    (0..n)
        .map(|i| u16::from_le_bytes(b[10 + 12 * i..12 + 12 * i].try_into().unwrap()))
        .collect()
}

const READ: &str = r#"
import sys, json, numpy as np, rasterio
r = rasterio.open(sys.argv[1])
pts = json.loads(open(sys.argv[2]).read())
v = np.array([s[0] for s in r.sample([(p[0], p[1]) for p in pts])])
z = np.array([p[2] for p in pts])
ok = v != r.nodata
d = (z - v)[ok]
try:
    from rio_cogeo.cogeo import cog_validate
    cog = cog_validate(sys.argv[1])[0]
except ImportError:
    cog = None
print(json.dumps({"crs": str(r.crs), "t": list(r.transform)[:6], "shape": list(r.shape),
                  "blocks": list(r.block_shapes[0]), "covered": float(ok.mean()),
                  "rms": float(np.sqrt(np.mean(d * d))), "sum": float(np.sum(np.where(r.read(1) == r.nodata, 0, r.read(1)))),
                  "cog": cog}))
"#;

#[test]
fn rasters_and_contours_of_a_synthetic_city() {
    let d = tempdir("terrain");
    let scan = synth(&d, "city.las", 300_000);
    let ds = d.join("city.myr");
    ok(&["convert", s(&scan), "-o", s(&ds)]);
    let dtm = d.join("dtm.tif");
    let said = ok(&["raster", s(&ds), "-o", s(&dtm), "--cell", "1"]);
    assert!(said.contains("dtm of "), "{said}");
    let t = tags(&dtm);
    for tag in [322, 323, 324, 325, 339, 33550, 33922, 34735, 42113] {
        assert!(t.contains(&tag), "tag {tag} in {t:?}");
    }
    for what in ["dsm", "chm", "intensity", "density"] {
        ok(&[
            "raster",
            s(&ds),
            "-o",
            s(&d.join(format!("{what}.tif"))),
            "--cell",
            "1",
            "--what",
            what,
        ]);
    }
    let c_json = d.join("c.geojson");
    let c_dxf = d.join("c.dxf");
    let said = ok(&[
        "contours",
        s(&ds),
        "-o",
        s(&c_json),
        "--interval",
        "0.5",
        "--cell",
        "1",
    ]);
    assert!(said.contains("contours every 0.5"), "{said}");
    ok(&[
        "contours",
        s(&ds),
        "-o",
        s(&c_dxf),
        "--interval",
        "0.5",
        "--cell",
        "1",
    ]);

    // Errors: no ground, a format it does not write, an existing output, a bad interval.
    fails(&["raster", s(&ds), "-o", s(&dtm)], "exists");
    fails(&["raster", s(&ds), "-o", s(&d.join("x.png"))], "GeoTIFF");
    fails(
        &["contours", s(&ds), "-o", s(&d.join("x.txt"))],
        ".dxf or .geojson",
    );
    fails(
        &[
            "contours",
            s(&ds),
            "-o",
            s(&d.join("x.dxf")),
            "--interval",
            "0",
        ],
        "--interval 0",
    );
    let bare = d.join("bare.myr");
    std::fs::copy(&ds, &bare).unwrap();
    ok(&["classify", s(&bare), "--to", "1", "--no-count"]);
    fails(
        &["raster", s(&bare), "-o", s(&d.join("none.tif"))],
        "myriad ground",
    );
    assert!(!d.join("none.tif").exists());

    let Some(py) = python_with("rasterio, numpy, shapely, ezdxf") else {
        eprintln!("SKIPPED: no Python with rasterio, shapely and ezdxf (.ci/run installs them)");
        return;
    };
    // The synthetic ground (classes 2 and 11) and every point, in metres (records: thousandths).
    let all = records(&scan);
    let xyz = |r: &Vec<i64>| {
        [
            r[0] as f64 / 1000.0,
            r[1] as f64 / 1000.0,
            r[2] as f64 / 1000.0,
        ]
    };
    let ground: Vec<[f64; 3]> = all
        .iter()
        .filter(|r| r[5] == 2 || r[5] == 11)
        .step_by(7)
        .map(xyz)
        .collect();
    let pts = d.join("ground.json");
    std::fs::write(&pts, serde_json::to_string(&ground).unwrap()).unwrap();
    let v: serde_json::Value =
        serde_json::from_str(&python(&py, READ, &[s(&dtm), s(&pts)])).unwrap();
    assert_eq!(v["crs"], "EPSG:32633", "{v}");
    let (min_x, max_y) = all.iter().fold((f64::MAX, f64::MIN), |(a, b), r| {
        (a.min(r[0] as f64 / 1000.0), b.max(r[1] as f64 / 1000.0))
    });
    let t: Vec<f64> = v["t"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!((t[0], t[1], t[3], t[4]), (1.0, 0.0, 0.0, -1.0), "{v}");
    assert!(
        t[2] <= min_x && min_x - t[2] < 1.0 && t[5] > max_y && t[5] - max_y <= 1.0,
        "{v}"
    );
    assert_eq!(v["blocks"], serde_json::json!([512, 512]));
    assert!(v["covered"].as_f64().unwrap() == 1.0, "{v}");
    assert!(
        v["rms"].as_f64().unwrap() < 0.1,
        "terrain at the ground points: {v}"
    );
    if !v["cog"].is_null() {
        assert_eq!(v["cog"], true, "rio-cogeo finds it a valid COG: {v}");
    }
    // Density: points per square metre, so its sum over cells of 1 m² is the count.
    let dens = python(&py, READ, &[s(&d.join("density.tif")), s(&pts)]);
    let dens: serde_json::Value = serde_json::from_str(&dens).unwrap();
    assert_eq!(
        dens["sum"].as_f64().unwrap().round() as usize,
        all.len(),
        "{dens}"
    );

    // Contours: shapely and ezdxf read the same lines, at multiples of the interval, lying where
    // the terrain has their height.
    let check = r#"
import sys, json, numpy as np, rasterio, ezdxf, shapely.geometry as g
d = json.load(open(sys.argv[1]))
lines = [(f["properties"]["elevation"], g.shape(f["geometry"])) for f in d["features"]]
assert all(l.is_valid and l.length > 0 for _, l in lines)
assert all(abs(e / 0.5 - round(e / 0.5)) < 1e-9 for e, _ in lines)
dxf = [e for e in ezdxf.readfile(sys.argv[2]).modelspace() if e.dxftype() == "LWPOLYLINE"]
r = rasterio.open(sys.argv[3])
pts = [(x, y, e) for e, l in lines for (x, y) in list(l.coords)[::5]]
v = np.array([s[0] for s in r.sample([(x, y) for x, y, _ in pts])])
err = np.abs(v - np.array([e for _, _, e in pts]))
print(json.dumps({"lines": len(lines), "dxf": len(dxf), "dxf_elevations": sorted(set(round(e.dxf.elevation, 6) for e in dxf)) == sorted(set(round(e, 6) for e, _ in lines)),
                  "crs": d.get("crs", {}).get("properties", {}).get("name"), "median": float(np.median(err))}))
"#;
    let c: serde_json::Value =
        serde_json::from_str(&python(&py, check, &[s(&c_json), s(&c_dxf), s(&dtm)])).unwrap();
    assert!(c["lines"].as_u64().unwrap() > 5, "{c}");
    assert_eq!(c["lines"], c["dxf"], "{c}");
    assert_eq!(c["dxf_elevations"], true, "{c}");
    assert_eq!(c["crs"], "urn:ogc:def:crs:EPSG::32633", "{c}");
    assert!(
        c["median"].as_f64().unwrap() < 0.25,
        "contours off the terrain: {c}"
    );
}

/// KY's terrain model from its labelled ground: within 0.1 m RMS of the labelled ground points
/// (a sample) at a 2 ft cell; no CRS (the scan names none).
#[test]
fn ky_terrain_within_a_tenth_of_a_metre() {
    let Some(ky) = shared_data("KY_RiverLockDam4_KyFromAbove_merged.laz") else {
        return;
    };
    let Some(py) = python_with("rasterio, numpy, laspy") else {
        eprintln!("SKIPPED: no Python with rasterio and laspy (.ci/run installs them)");
        return;
    };
    let d = tempdir("terrain-ky");
    let ds = d.join("ky.myr");
    ok(&["convert", s(&ky), "-o", s(&ds)]);
    let dtm = d.join("ky.tif");
    ok(&["raster", s(&ds), "-o", s(&dtm), "--cell", "2"]);
    let script = r#"
import sys, json, numpy as np, rasterio, laspy
f = laspy.read(sys.argv[1]); g = f.classification == 2
x, y, z = (np.asarray(a)[g] for a in (f.x, f.y, f.z))
i = np.random.default_rng(1).choice(len(x), 20000, replace=False)
r = rasterio.open(sys.argv[2])
v = np.array([s[0] for s in r.sample(zip(x[i], y[i]))])
d = (z[i] - v)[v != r.nodata]
print(json.dumps({"crs": str(r.crs), "n": int(d.size), "rms_m": float(0.3048 * np.sqrt(np.mean(d * d)))}))
"#;
    let v: serde_json::Value =
        serde_json::from_str(&python(&py, script, &[s(&ky), s(&dtm)])).unwrap();
    assert_eq!(v["n"], 20000, "{v}");
    assert!(v["rms_m"].as_f64().unwrap() < 0.1, "{v}");
    assert_eq!(v["crs"], "None", "{v}");
}
