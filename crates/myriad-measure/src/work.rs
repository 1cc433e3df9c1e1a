//! Saved work: a dataset's annotations (a point, a title, a text, a camera) and measurements,
//! kept in a sidecar file next to what the user opened ([`sidecar_for`]: `city.myr` →
//! `city.work.json`; a scan and the dataset converted from it in the same folder share one),
//! as JSON with the dataset's CRS. `view`, `serve`'s web viewer and `myriad annotate` read and
//! write the same file; GeoJSON and DXF ([`crate::files`]) carry it to GIS and CAD programs and
//! back.
//!
//! The file:
//! ```json
//! { "myriad": "work", "version": 1, "crs": "PROJCS[...]",
//!   "annotations": [ { "position": [x, y, z], "title": "...", "text": "...",
//!                      "camera": { "position": [x, y, z], "target": [x, y, z] } } ],
//!   "measurements": [ { "kind": "distance", "points": [[x, y, z], ...],
//!                       "value": 17.0, "label": "17.000 m" } ],
//!   "classes": { "2": { "name": "terrain", "colour": "#8b5a2b", "hidden": false } },
//!   "paths": [ { "name": "...", "views": [ { "position": [x, y, z], "target": [x, y, z],
//!                                            "time": 0 } ] } ] }
//! ```
//! `classes` (a class scheme, [`crate::scheme`]) and `paths` (camera paths,
//! [`crate::camera_path`]) may be left out.
//! `value` and `label` are written for readers (the web viewer shows the label) and ignored on
//! reading: the figure is always computed again from the points.

use crate::crs::metres_per_unit;
use crate::geojson::{self, epsg_code};
use crate::measurement::{Kind, Measurement, Units};
use serde_json::{Map, Value, json};

/// A sidecar file larger than this is refused (a few thousand annotations fit in far less).
pub const MAX_BYTES: usize = 4 << 20;
/// Most annotations, and most measurements, a file holds.
pub const MAX_ITEMS: usize = 10_000;
/// Most points of one measurement.
pub const MAX_POINTS: usize = 10_000;
/// Most characters of a title, and of a text.
pub const MAX_TITLE: usize = 200;
pub const MAX_TEXT: usize = 10_000;

/// Where a dataset's camera was when an annotation was made (and the largest coordinate saved
/// work holds).
pub use crate::camera_path::{MAX_COORD, View};

#[derive(Debug, Clone, PartialEq)]
pub struct Annotation {
    pub position: [f64; 3],
    pub title: String,
    pub text: String,
    pub camera: Option<View>,
}

/// A dataset's saved work.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Work {
    /// The dataset's CRS (WKT, or `EPSG:n`), as it was when the work was saved.
    pub crs: Option<String>,
    pub annotations: Vec<Annotation>,
    /// Complete measurements only.
    pub measurements: Vec<Measurement>,
    /// The class scheme the viewers and `render` use for the dataset (`None`: the default).
    pub classes: Option<myriad_core::classes::Scheme>,
    /// Camera paths recorded in the viewers (`render --path NAME` flies one).
    pub paths: Vec<crate::camera_path::CameraPath>,
}

/// The sidecar of `opened` (a dataset, a scan, a folder of tiles): beside it, its name with
/// the extension replaced by `.work.json` (a folder's whole name followed by it).
pub fn sidecar_for(opened: &std::path::Path) -> std::path::PathBuf {
    let is_dir = opened.is_dir();
    let name = if is_dir {
        opened.file_name()
    } else {
        opened.file_stem()
    };
    let name = name.map_or_else(|| "work".into(), |n| n.to_string_lossy().into_owned());
    opened.with_file_name(format!("{name}.work.json"))
}

/// The units a CRS's lengths are labelled in (its own, where it names one).
pub fn units_of(crs: Option<&str>) -> (Units, Option<f64>) {
    let m = crs.and_then(metres_per_unit);
    let units = match m {
        Some(v) if (v - 1.0).abs() < 1e-9 => Units::Metres,
        Some(v) if (v - 0.3048).abs() < 1e-9 => Units::Feet,
        Some(v) if (v - 1200.0 / 3937.0).abs() < 1e-9 => Units::UsFeet,
        _ => Units::Data,
    };
    (units, m)
}

fn xyz(p: [f64; 3]) -> Value {
    json!([p[0], p[1], p[2]])
}

pub(crate) fn finite(v: &Value, at: &str) -> Result<f64, String> {
    match v.as_f64() {
        Some(x) if x.abs() <= MAX_COORD => Ok(x),
        Some(x) if x.is_finite() => Err(format!("{at}: {x:e} is beyond ±{MAX_COORD:e}")),
        _ => Err(format!("{at}: not a finite number: {}", short(v))),
    }
}

/// Why a saved point cannot be kept: a number that is not finite, or one beyond [`MAX_COORD`].
fn out_of_range(p: &[f64; 3]) -> Option<&'static str> {
    if p.iter().any(|x| !x.is_finite()) {
        Some("not a finite number")
    } else if p.iter().any(|x| x.abs() > MAX_COORD) {
        Some("a coordinate beyond ±1e12")
    } else {
        None
    }
}

/// At most 60 characters of a value, for an error.
pub(crate) fn short(v: &Value) -> String {
    let s = v.to_string();
    if s.chars().count() > 60 {
        format!("{}…", s.chars().take(60).collect::<String>())
    } else {
        s
    }
}

fn point(v: &Value, at: &str) -> Result<[f64; 3], String> {
    let a = v
        .as_array()
        .filter(|a| a.len() == 2 || a.len() == 3)
        .ok_or_else(|| format!("{at}: not a point [x, y, z]: {}", short(v)))?;
    let z = match a.get(2) {
        Some(z) => finite(z, at)?,
        None => 0.0,
    };
    Ok([finite(&a[0], at)?, finite(&a[1], at)?, z])
}

fn text(v: Option<&Value>, at: &str, most: usize) -> Result<String, String> {
    match v {
        None | Some(Value::Null) => Ok(String::new()),
        Some(Value::String(s)) if s.chars().count() <= most => Ok(s.clone()),
        Some(Value::String(_)) => Err(format!("{at}: longer than {most} characters")),
        Some(v) => Err(format!("{at}: not a text: {}", short(v))),
    }
}

impl Kind {
    /// The kind of a name ([`Kind::name`]).
    pub fn from_name(name: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// A measurement of `kind` through `points`, or why not.
pub fn measurement(kind: Kind, points: Vec<[f64; 3]>, at: &str) -> Result<Measurement, String> {
    if points.len() > MAX_POINTS {
        return Err(format!("{at}: more than {MAX_POINTS} points"));
    }
    let m = Measurement { kind, points };
    if !m.complete() {
        let want = match kind.points() {
            Some(n) => format!("{n}"),
            None if kind == Kind::Area => "3 or more".into(),
            None => "2 or more".into(),
        };
        let article = if kind.name().starts_with(['a', 'e', 'i', 'o', 'u']) {
            "an"
        } else {
            "a"
        };
        return Err(format!(
            "{at}: {article} {} takes {want} points, not {}",
            kind.name(),
            m.points.len()
        ));
    }
    Ok(m)
}

impl Annotation {
    fn to_json(&self) -> Value {
        let mut o =
            json!({ "position": xyz(self.position), "title": self.title, "text": self.text });
        if let Some(c) = self.camera {
            o["camera"] = json!({ "position": xyz(c.position), "target": xyz(c.target) });
        }
        o
    }

    fn from_json(v: &Value, at: &str) -> Result<Annotation, String> {
        let o = v
            .as_object()
            .ok_or_else(|| format!("{at}: not an object: {}", short(v)))?;
        let position = point(
            o.get("position")
                .ok_or_else(|| format!("{at}: no \"position\""))?,
            &format!("{at}.position"),
        )?;
        let camera = match o.get("camera") {
            None | Some(Value::Null) => None,
            Some(c) => {
                let view = View {
                    position: point(&c["position"], &format!("{at}.camera.position"))?,
                    target: point(&c["target"], &format!("{at}.camera.target"))?,
                };
                if view.position == view.target {
                    return Err(format!("{at}.camera: its target is its position"));
                }
                Some(view)
            }
        };
        Ok(Annotation {
            position,
            title: text(o.get("title"), &format!("{at}.title"), MAX_TITLE)?,
            text: text(o.get("text"), &format!("{at}.text"), MAX_TEXT)?,
            camera,
        })
    }
}

fn measurement_json(m: &Measurement, units: Units, metres: Option<f64>) -> Value {
    json!({
        "kind": m.kind.name(),
        "points": m.points.iter().map(|&p| xyz(p)).collect::<Vec<_>>(),
        "value": m.value(),
        "label": m.label(units, metres),
    })
}

fn measurement_from_json(v: &Value, at: &str) -> Result<Measurement, String> {
    let kind = v["kind"]
        .as_str()
        .ok_or_else(|| format!("{at}.kind: not a text: {}", short(&v["kind"])))?;
    let kind = Kind::from_name(kind).ok_or_else(|| {
        let names: Vec<&str> = Kind::ALL.iter().map(|k| k.name()).collect();
        format!(
            "{at}.kind: unknown measurement \"{kind}\" (one of {})",
            names.join(", ")
        )
    })?;
    let pts = v["points"]
        .as_array()
        .ok_or_else(|| format!("{at}.points: not a list of points"))?;
    let points = pts
        .iter()
        .enumerate()
        .map(|(i, p)| point(p, &format!("{at}.points[{i}]")))
        .collect::<Result<Vec<_>, _>>()?;
    measurement(kind, points, at)
}

pub(crate) fn list<'a>(o: &'a Map<String, Value>, key: &str) -> Result<&'a [Value], String> {
    match o.get(key) {
        None | Some(Value::Null) => Ok(&[]),
        Some(Value::Array(a)) if a.len() <= MAX_ITEMS => Ok(a),
        Some(Value::Array(_)) => Err(format!("{key}: more than {MAX_ITEMS}")),
        Some(v) => Err(format!("{key}: not a list: {}", short(v))),
    }
}

impl Work {
    /// Empty work for a dataset of `crs`.
    pub fn new(crs: Option<&str>) -> Work {
        Work {
            crs: crs.map(str::to_string),
            ..Default::default()
        }
    }

    pub fn is_empty(&self) -> bool {
        self.annotations.is_empty()
            && self.measurements.is_empty()
            && self.classes.is_none()
            && self.paths.is_empty()
    }

    /// The sidecar's JSON.
    pub fn to_json(&self) -> Value {
        let (units, metres) = units_of(self.crs.as_deref());
        let mut v = json!({
            "myriad": "work",
            "version": 1,
            "crs": self.crs,
            "annotations": self.annotations.iter().map(Annotation::to_json).collect::<Vec<_>>(),
            "measurements": self.measurements.iter().map(|m| measurement_json(m, units, metres)).collect::<Vec<_>>(),
        });
        if let Some(s) = &self.classes {
            v["classes"] = crate::scheme::to_json(s);
        }
        if !self.paths.is_empty() {
            v["paths"] = self.paths.iter().map(|p| p.to_json()).collect();
        }
        v
    }

    /// The sidecar's text: an annotation or a measurement a line (for people, and for
    /// version control's differences).
    pub fn to_text(&self) -> String {
        let v = self.to_json();
        let mut s = format!(
            "{{\n  \"myriad\": \"work\",\n  \"version\": 1,\n  \"crs\": {},\n",
            v["crs"]
        );
        let mut keys = vec!["annotations", "measurements"];
        keys.extend(
            ["classes", "paths"]
                .into_iter()
                .filter(|k| v.get(*k).is_some()),
        );
        for (i, &key) in keys.iter().enumerate() {
            let end = if i + 1 < keys.len() { ",\n" } else { "\n" };
            if let Some(o) = v[key].as_object() {
                let lines: Vec<String> = (o.iter())
                    .map(|(k, e)| format!("    {}: {e}", Value::from(k.as_str())))
                    .collect();
                s.push_str(&format!(
                    "  \"{key}\": {{\n{}\n  }}{end}",
                    lines.join(",\n")
                ));
                continue;
            }
            let items = v[key].as_array().map_or(&[][..], |a| a.as_slice());
            if items.is_empty() {
                s.push_str(&format!("  \"{key}\": []{end}"));
            } else {
                let lines: Vec<String> = items.iter().map(|i| format!("    {i}")).collect();
                s.push_str(&format!("  \"{key}\": [\n{}\n  ]{end}", lines.join(",\n")));
            }
        }
        s.push_str("}\n");
        s
    }

    /// Work from a sidecar's text; an error names the line (broken JSON) or the member.
    pub fn parse(text: &str) -> Result<Work, String> {
        if text.len() > MAX_BYTES {
            return Err(format!("larger than {MAX_BYTES} bytes"));
        }
        let v: Value = serde_json::from_str(text)
            .map_err(|e| format!("line {} column {}: {e}", e.line(), e.column()))?;
        Work::from_json(&v)
    }

    /// Work from the sidecar's JSON.
    pub fn from_json(v: &Value) -> Result<Work, String> {
        let o = v
            .as_object()
            .ok_or_else(|| "not a JSON object".to_string())?;
        if o.get("myriad").and_then(Value::as_str) != Some("work") {
            return Err("not a Myriad work file (no \"myriad\": \"work\")".into());
        }
        match o.get("version").and_then(Value::as_u64) {
            Some(1) => {}
            v => return Err(format!("version {v:?}: this Myriad reads version 1")),
        }
        let crs = match o.get("crs") {
            None | Some(Value::Null) => None,
            Some(Value::String(s)) => Some(s.clone()),
            Some(v) => return Err(format!("crs: not a text: {}", short(v))),
        };
        let annotations = (list(o, "annotations")?.iter().enumerate())
            .map(|(i, a)| Annotation::from_json(a, &format!("annotations[{i}]")))
            .collect::<Result<_, _>>()?;
        let measurements = (list(o, "measurements")?.iter().enumerate())
            .map(|(i, m)| measurement_from_json(m, &format!("measurements[{i}]")))
            .collect::<Result<_, _>>()?;
        let classes = match o.get("classes") {
            None | Some(Value::Null) => None,
            Some(c) => Some(crate::scheme::from_json(c)?),
        };
        let paths = (list(o, "paths")?.iter().enumerate())
            .map(|(i, p)| crate::camera_path::CameraPath::from_json(p, &format!("paths[{i}].")))
            .collect::<Result<_, _>>()?;
        Ok(Work {
            crs,
            annotations,
            measurements,
            classes,
            paths,
        })
    }

    /// The first number of the work that is not finite (NaN, an infinity) or beyond
    /// [`MAX_COORD`], or a camera looking nowhere (its target its position), named as the
    /// sidecar names it (`annotations[2].position`): JSON has no NaN, so work holding one would
    /// be saved as `null` and read back nowhere, and a camera between coordinates of 1e308 has a
    /// direction of infinities.
    pub fn finite(&self) -> Result<(), String> {
        for (i, a) in self.annotations.iter().enumerate() {
            let views = a.camera.iter().flat_map(|c| {
                [
                    ("camera.position", &c.position),
                    ("camera.target", &c.target),
                ]
            });
            for (what, p) in std::iter::once(("position", &a.position)).chain(views) {
                if let Some(why) = out_of_range(p) {
                    return Err(format!("annotations[{i}].{what}: {why}: {p:?}"));
                }
            }
            if let Some(c) = a.camera
                && c.position == c.target
            {
                return Err(format!(
                    "annotations[{i}].camera: its target is its position"
                ));
            }
        }
        for (i, m) in self.measurements.iter().enumerate() {
            for (j, p) in m.points.iter().enumerate() {
                if let Some(why) = out_of_range(p) {
                    return Err(format!("measurements[{i}].points[{j}]: {why}: {p:?}"));
                }
            }
        }
        for (i, path) in self.paths.iter().enumerate() {
            for (j, k) in path.keys.iter().enumerate() {
                for (what, p) in [("position", &k.view.position), ("target", &k.view.target)] {
                    if let Some(why) = out_of_range(p) {
                        return Err(format!("paths[{i}].views[{j}].{what}: {why}: {p:?}"));
                    }
                }
            }
        }
        Ok(())
    }

    /// Adds `other`'s annotations and measurements (an import), refusing work of another CRS
    /// or with a number that is not finite.
    pub fn merge(&mut self, other: Work) -> Result<(), String> {
        other.finite()?;
        let code = |c: &Option<String>| c.as_deref().and_then(epsg_code);
        if let (Some(a), Some(b)) = (code(&self.crs), code(&other.crs))
            && a != b
        {
            return Err(format!(
                "its CRS is EPSG:{b}, the dataset's EPSG:{a}: reproject it first"
            ));
        }
        if self.annotations.len() + other.annotations.len() > MAX_ITEMS
            || self.measurements.len() + other.measurements.len() > MAX_ITEMS
        {
            return Err(format!("more than {MAX_ITEMS} annotations or measurements"));
        }
        if self.paths.len() + other.paths.len() > MAX_ITEMS {
            return Err(format!("more than {MAX_ITEMS} camera paths"));
        }
        self.annotations.extend(other.annotations);
        self.measurements.extend(other.measurements);
        self.paths.extend(other.paths);
        if self.classes.is_none() {
            self.classes = other.classes;
        }
        Ok(())
    }

    /// The work as GeoJSON: annotations as points (properties `myriad: annotation`, title,
    /// text, camera), measurements as points, lines or polygons (`myriad: measurement`, kind,
    /// value, label), in the dataset's coordinates with its CRS named.
    pub fn to_geojson(&self) -> Value {
        let (units, metres) = units_of(self.crs.as_deref());
        let mut features = Vec::new();
        for a in &self.annotations {
            let mut props = json!({ "myriad": "annotation", "title": a.title, "text": a.text });
            if let Some(c) = a.camera {
                props["camera_position"] = xyz(c.position);
                props["camera_target"] = xyz(c.target);
            }
            features.push(geojson::feature(
                json!({ "type": "Point", "coordinates": xyz(a.position) }),
                props,
            ));
        }
        for m in &self.measurements {
            let coords: Vec<Value> = m.points.iter().map(|&p| xyz(p)).collect();
            let geometry = match m.kind {
                Kind::Point => json!({ "type": "Point", "coordinates": coords[0] }),
                Kind::Area => {
                    let mut ring = coords.clone();
                    ring.push(coords[0].clone());
                    json!({ "type": "Polygon", "coordinates": [ring] })
                }
                _ => json!({ "type": "LineString", "coordinates": coords }),
            };
            features.push(geojson::feature(
                geometry,
                json!({
                    "myriad": "measurement",
                    "kind": m.kind.name(),
                    "value": m.value(),
                    "label": m.label(units, metres),
                }),
            ));
        }
        geojson::collection(features, self.crs.as_deref())
    }

    /// Work from GeoJSON: Myriad's own features as they were written; other programs'
    /// points become annotations (titled by their `title` or `name`), lines distances and
    /// polygons areas. Its CRS, where named, is kept as `EPSG:n` for [`Work::merge`] to check.
    pub fn from_geojson(v: &Value) -> Result<Work, String> {
        let features: Vec<&Value> = match v["type"].as_str() {
            Some("FeatureCollection") => (v["features"].as_array())
                .ok_or("features: not a list")?
                .iter()
                .collect(),
            Some("Feature") => vec![v],
            _ => return Err("not a GeoJSON FeatureCollection or Feature".into()),
        };
        let crs = v["crs"]["properties"]["name"]
            .as_str()
            .and_then(|n| n.rsplit(':').next())
            .and_then(|c| c.parse::<u32>().ok())
            .map(|c| format!("EPSG:{c}"));
        let mut w = Work::new(crs.as_deref());
        for (i, f) in features.iter().enumerate() {
            let at = format!("features[{i}]");
            let g = &f["geometry"];
            let props = &f["properties"];
            let coords = &g["coordinates"];
            let points = |c: &Value, at: &str| -> Result<Vec<[f64; 3]>, String> {
                (c.as_array().ok_or_else(|| format!("{at}: not a list"))?)
                    .iter()
                    .enumerate()
                    .map(|(k, p)| point(p, &format!("{at}[{k}]")))
                    .collect()
            };
            let given = props["kind"].as_str().and_then(Kind::from_name);
            match (g["type"].as_str(), props["myriad"].as_str()) {
                (Some("Point"), Some("measurement")) => {
                    w.measurements
                        .push(measurement(Kind::Point, vec![point(coords, &at)?], &at)?)
                }
                (Some("Point"), _) => {
                    let title = props["title"].as_str().or(props["name"].as_str());
                    let camera = match (props.get("camera_position"), props.get("camera_target")) {
                        (Some(p), Some(t)) => Some(View {
                            position: point(p, &format!("{at}.camera_position"))?,
                            target: point(t, &format!("{at}.camera_target"))?,
                        }),
                        _ => None,
                    };
                    w.annotations.push(Annotation {
                        position: point(coords, &format!("{at}.coordinates"))?,
                        title: text(title.map(|t| json!(t)).as_ref(), &at, MAX_TITLE)?,
                        text: text(props.get("text"), &at, MAX_TEXT)?,
                        camera,
                    });
                }
                (Some("LineString"), _) => w.measurements.push(measurement(
                    given.unwrap_or(Kind::Distance),
                    points(coords, &format!("{at}.coordinates"))?,
                    &at,
                )?),
                (Some("Polygon"), _) => {
                    let mut ring = points(&coords[0], &format!("{at}.coordinates[0]"))?;
                    if ring.len() > 1 && ring.first() == ring.last() {
                        ring.pop();
                    }
                    w.measurements.push(measurement(Kind::Area, ring, &at)?);
                }
                (t, _) => {
                    return Err(format!(
                        "{at}: a {} geometry: points, lines and polygons only",
                        t.unwrap_or("missing")
                    ));
                }
            }
            if w.annotations.len() > MAX_ITEMS || w.measurements.len() > MAX_ITEMS {
                return Err(format!("more than {MAX_ITEMS} features"));
            }
        }
        Ok(w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Work {
        let utm = r#"PROJCS["WGS 84 / UTM zone 33N",UNIT["metre",1],AUTHORITY["EPSG","32633"]]"#;
        let mut w = Work::new(Some(utm));
        w.annotations.push(Annotation {
            position: [500100.25, 4400200.5, 31.125],
            title: "Gate \"north\"".into(),
            text: "cracked pillar\nsee photo 12".into(),
            camera: Some(View {
                position: [500080.0, 4400180.0, 60.0],
                target: [500100.25, 4400200.5, 31.125],
            }),
        });
        w.annotations.push(Annotation {
            position: [500000.0, 4400000.0, 10.0],
            title: "benchmark".into(),
            text: String::new(),
            camera: None,
        });
        for (kind, pts) in [
            (
                Kind::Distance,
                vec![[0.0, 0.0, 0.0], [3.0, 4.0, 0.0], [3.0, 4.0, 12.0]],
            ),
            (
                Kind::Area,
                vec![[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [10.0, 10.0, 0.0]],
            ),
            (Kind::Point, vec![[1.0, 2.0, 3.0]]),
            (
                Kind::Angle,
                vec![[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            ),
        ] {
            let pts = pts
                .iter()
                .map(|p| [p[0] + 500000.0, p[1] + 4400000.0, p[2]])
                .collect();
            w.measurements.push(measurement(kind, pts, "test").unwrap());
        }
        w
    }

    /// A NaN or an infinity (from a command line, a DXF, a viewer) is named and never merged:
    /// saved, it would be JSON's null, and the sidecar unreadable everywhere.
    #[test]
    fn work_with_a_number_that_is_not_finite_is_named_and_not_merged() {
        let mut w = sample();
        assert_eq!(w.finite(), Ok(()));
        let mut bad = Work::new(w.crs.as_deref());
        bad.annotations.push(Annotation {
            position: [f64::NAN, 1.0, 2.0],
            title: "x".into(),
            text: String::new(),
            camera: None,
        });
        let e = bad.finite().unwrap_err();
        assert!(
            e.starts_with("annotations[0].position: not a finite number"),
            "{e}"
        );
        assert!(w.merge(bad.clone()).is_err());
        assert_eq!(w.annotations.len(), 2, "nothing merged");
        bad.annotations[0].position = [0.0; 3];
        bad.annotations[0].camera = Some(View {
            position: [0.0; 3],
            target: [0.0, f64::INFINITY, 0.0],
        });
        let e = bad.finite().unwrap_err();
        assert!(e.starts_with("annotations[0].camera.target"), "{e}");
        let mut m = Work::new(None);
        m.measurements.push(Measurement {
            kind: Kind::Distance,
            points: vec![[0.0; 3], [f64::NEG_INFINITY, 0.0, 0.0]],
        });
        assert!(
            m.finite()
                .unwrap_err()
                .starts_with("measurements[0].points[1]")
        );
        // Finite but far: a camera between ±1e308 would look along infinities, a distance
        // between them would be saved as null.
        m.measurements[0].points[1] = [1e308, 0.0, 0.0];
        let e = m.finite().unwrap_err();
        assert!(e.contains("beyond ±1e12"), "{e}");
        bad.annotations[0].camera = Some(View {
            position: [-1e308, 0.0, 0.0],
            target: [1e308, 0.0, 0.0],
        });
        assert!(bad.finite().unwrap_err().contains("beyond"));
        bad.annotations[0].camera = Some(View {
            position: [1.0; 3],
            target: [1.0; 3],
        });
        assert!(
            bad.finite()
                .unwrap_err()
                .contains("its target is its position")
        );
        let text = r#"{"myriad":"work","version":1,"annotations":[{"position":[1e300,0,0]}]}"#;
        let e = Work::parse(text).unwrap_err();
        assert!(
            e.starts_with("annotations[0].position: 1e300 is beyond"),
            "{e}"
        );
        assert!(Work::parse(&text.replace("1e300", "999999999999")).is_ok());
    }

    #[test]
    fn the_sidecar_round_trips_and_labels_in_the_crs_units() {
        let w = sample();
        let text = w.to_text();
        assert_eq!(Work::parse(&text).unwrap(), w);
        let v: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["measurements"][0]["value"], 17.0);
        assert_eq!(v["measurements"][0]["label"], "17.000 m");
        assert_eq!(v["measurements"][1]["label"], "50.00 m² area");
    }

    #[test]
    fn geojson_round_trips_with_the_crs() {
        let w = sample();
        let g = w.to_geojson();
        assert_eq!(
            g["crs"]["properties"]["name"],
            "urn:ogc:def:crs:EPSG::32633"
        );
        assert_eq!(g["features"].as_array().unwrap().len(), 6);
        assert_eq!(g["features"][3]["geometry"]["type"], "Polygon");
        let back = Work::from_geojson(&g).unwrap();
        assert_eq!(back.crs.as_deref(), Some("EPSG:32633"));
        assert_eq!(back.annotations, w.annotations);
        assert_eq!(back.measurements, w.measurements);
        // Into the dataset's work: the same CRS merges, another is refused.
        let mut mine = Work::new(w.crs.as_deref());
        mine.merge(back.clone()).unwrap();
        assert_eq!(mine.annotations.len(), 2);
        let mut other = Work::new(Some("EPSG:2992"));
        let e = other.merge(back).unwrap_err();
        assert!(e.contains("EPSG:32633") && e.contains("EPSG:2992"), "{e}");
    }

    #[test]
    fn bad_files_say_where() {
        let e = Work::parse("{\n \"myriad\": \"work\",\n \"version\": 1,\n").unwrap_err();
        assert!(e.starts_with("line 4"), "{e}");
        let e = Work::parse(r#"{"myriad":"work","version":1,"annotations":[{"position":[1,2]},{"position":[1,"x",3]}]}"#).unwrap_err();
        assert!(
            e.starts_with("annotations[1].position: not a finite"),
            "{e}"
        );
        let e = Work::parse(r#"{"myriad":"work","version":1,"measurements":[{"kind":"area","points":[[0,0,0],[1,0,0]]}]}"#).unwrap_err();
        assert_eq!(e, "measurements[0]: an area takes 3 or more points, not 2");
        let e = Work::parse(
            r#"{"myriad":"work","version":1,"measurements":[{"kind":"volume","points":[]}]}"#,
        )
        .unwrap_err();
        assert!(e.contains("unknown measurement \"volume\""), "{e}");
        assert!(Work::parse(r#"{"type":"FeatureCollection"}"#).is_err());
        let long = format!(
            r#"{{"myriad":"work","version":1,"annotations":[{{"position":[0,0,0],"title":"{}"}}]}}"#,
            "x".repeat(MAX_TITLE + 1)
        );
        assert!(Work::parse(&long).unwrap_err().contains("longer than"));
    }

    #[test]
    fn other_programs_geojson_becomes_annotations_and_measurements() {
        let g: Value = serde_json::from_str(
            r#"{"type":"FeatureCollection","features":[
              {"type":"Feature","geometry":{"type":"Point","coordinates":[1,2,3]},"properties":{"name":"well"}},
              {"type":"Feature","geometry":{"type":"LineString","coordinates":[[0,0],[3,4]]},"properties":{}},
              {"type":"Feature","geometry":{"type":"Polygon","coordinates":[[[0,0],[2,0],[2,2],[0,2],[0,0]]]},"properties":null}]}"#,
        )
        .unwrap();
        let w = Work::from_geojson(&g).unwrap();
        assert_eq!(w.annotations[0].title, "well");
        assert_eq!(w.measurements[0].value(), Some(5.0));
        assert_eq!(w.measurements[1].value(), Some(4.0));
        assert_eq!(w.crs, None);
    }

    #[test]
    fn sidecars_sit_beside_what_was_opened() {
        use std::path::Path;
        assert_eq!(
            sidecar_for(Path::new("/data/city.myr")),
            Path::new("/data/city.work.json")
        );
        assert_eq!(
            sidecar_for(Path::new("/data/scan.v2.laz")),
            Path::new("/data/scan.v2.work.json")
        );
    }
}
