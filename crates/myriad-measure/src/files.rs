//! The tools' files on disk, each written atomically (nothing at the path until it is whole):
//! a profile as CSV, PNG or DXF (through the `dxf` crate, DXF R2000 as CAD programs and ezdxf
//! read it); saved work ([`crate::work`]) as its sidecar, GeoJSON or DXF, and read back.

use crate::measurement::Kind;
use crate::profile::Profile;
use crate::shape;
use crate::work::{self, Annotation, Work};
use crate::{Corridor, Polygon};
use dxf::entities::{Entity, EntityType, LwPolyline, MText, ModelPoint, Polyline, Text, Vertex};
use dxf::enums::AcadVersion;
use dxf::tables::Layer;
use dxf::{Color, Drawing, LwPolylineVertex, Point};
use myriad_core::{Error, Result};
use myriad_io::atomic::AtomicFile;
use std::io::{BufWriter, Write};
use std::path::Path;

/// Layer names of a profile's drawing.
pub const PROFILE_LAYER: &str = "PROFILE";
pub const POINTS_LAYER: &str = "POINTS";
pub const LINE_LAYER: &str = "LINE";

fn polyline(layer: &str, pts: &[[f64; 2]], closed: bool, elevation: f64) -> Entity {
    let mut l = LwPolyline {
        vertices: pts
            .iter()
            .map(|p| LwPolylineVertex {
                x: p[0],
                y: p[1],
                ..Default::default()
            })
            .collect(),
        ..Default::default()
    };
    l.set_is_closed(closed);
    let mut e = Entity::new(EntityType::LwPolyline(l));
    e.common.layer = layer.into();
    e.common.elevation = elevation;
    e
}

fn drawing(layers: &[(&str, u8)]) -> Drawing {
    let mut d = Drawing::new();
    d.header.version = AcadVersion::R2000;
    for (name, colour) in layers {
        d.add_layer(Layer {
            name: (*name).into(),
            color: Color::from_index(*colour),
            ..Default::default()
        });
    }
    d
}

/// At most this many points in a drawing (the `dxf` crate holds a drawing in memory, a few
/// hundred bytes a point entity).
pub const MAX_DXF_POINTS: usize = 2_000_000;

/// A profile as a drawing: on `PROFILE` the profile line (the highest point of each step of half
/// the width along the line) as a 2D polyline of (distance along, elevation); on `POINTS` every
/// point of the corridor as a 3D point in the dataset's coordinates; on `LINE` the section
/// line in plan.
pub fn profile_drawing(p: &Profile, corridor: &Corridor) -> Result<Drawing> {
    if p.len() > MAX_DXF_POINTS {
        return Err(Error::Invalid(format!(
            "the corridor holds {} points, more than a DXF takes here ({MAX_DXF_POINTS}): a \
             narrower --width, or a .laz output",
            p.len()
        )));
    }
    let mut d = drawing(&[(PROFILE_LAYER, 1), (POINTS_LAYER, 7), (LINE_LAYER, 3)]);
    let top = p.top_line((p.width / 2.0).max(1e-3));
    if top.len() >= 2 {
        d.add_entity(polyline(PROFILE_LAYER, &top, false, 0.0));
    }
    d.add_entity(polyline(LINE_LAYER, corridor.line(), false, 0.0));
    for q in &p.positions {
        let mut e = Entity::new(EntityType::ModelPoint(ModelPoint::new(Point::new(
            q[0], q[1], q[2],
        ))));
        e.common.layer = POINTS_LAYER.into();
        d.add_entity(e);
    }
    Ok(d)
}

/// A polygon (a volume's footprint) as a closed polyline on layer `name` at `elevation`.
pub fn polygon_entity(polygon: &Polygon, layer: &str, elevation: f64) -> Entity {
    polyline(layer, polygon.vertices(), true, elevation)
}

/// Writes `write`'s bytes to `path` atomically.
pub fn write_atomic(
    path: &Path,
    force: bool,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let f = AtomicFile::create(path, force)?;
    let mut w = BufWriter::new(f.open_write()?);
    write(&mut w)
        .and_then(|_| w.flush())
        .map_err(|e| Error::io(path, e))?;
    drop(w);
    f.commit()
}

/// Layers of a contour drawing: every contour, and every fifth (index contours) apart.
pub const CONTOURS_LAYER: &str = "CONTOURS";
pub const INDEX_CONTOURS_LAYER: &str = "CONTOURS_INDEX";

/// Contours as a drawing: each a 2D polyline at its elevation (closed where it closes), those at
/// multiples of five intervals on their own layer.
pub fn contours_drawing(lines: &[crate::contours::Contour], interval: f64) -> Drawing {
    let mut d = drawing(&[(CONTOURS_LAYER, 8), (INDEX_CONTOURS_LAYER, 1)]);
    for c in lines {
        let k = (c.elevation / interval).round() as i64;
        let layer = if k % 5 == 0 {
            INDEX_CONTOURS_LAYER
        } else {
            CONTOURS_LAYER
        };
        d.add_entity(polyline(layer, &c.points, c.closed, c.elevation));
    }
    d
}

/// Writes a drawing to `path` atomically.
pub fn save_drawing(d: &Drawing, path: &Path, force: bool) -> Result<()> {
    write_atomic(path, force, |w| {
        let mut w = w;
        d.save(&mut w).map_err(std::io::Error::other)
    })
}

/// Layers of saved work's drawing: annotations' titles (TEXT) and texts (MTEXT) at their
/// points, and each kind of measurement's points as a 3D polyline (`MEASURE_DISTANCE`, ...;
/// closed for an area) or, for a point, a POINT.
pub const ANNOTATIONS_LAYER: &str = "ANNOTATIONS";
pub const ANNOTATION_TEXT_LAYER: &str = "ANNOTATION_TEXT";

fn measure_layer(kind: Kind) -> String {
    format!("MEASURE_{}", kind.name().to_ascii_uppercase())
}

/// DXF keeps at most 250 characters a group: a longer text goes in pieces.
const DXF_STRING: usize = 250;

/// Saved work as a drawing (cameras are not kept: DXF has no place for them).
pub fn work_drawing(w: &Work) -> Drawing {
    let mut layers = vec![
        (ANNOTATIONS_LAYER.to_string(), 2u8),
        (ANNOTATION_TEXT_LAYER.to_string(), 2),
    ];
    layers.extend(Kind::ALL.iter().map(|&k| (measure_layer(k), 3u8)));
    let named: Vec<(&str, u8)> = layers.iter().map(|(n, c)| (n.as_str(), *c)).collect();
    let mut d = drawing(&named);
    for a in &w.annotations {
        let at = Point::new(a.position[0], a.position[1], a.position[2]);
        let mut t = Entity::new(EntityType::Text(Text {
            location: at.clone(),
            value: a.title.clone(),
            ..Default::default()
        }));
        t.common.layer = ANNOTATIONS_LAYER.into();
        d.add_entity(t);
        if !a.text.is_empty() {
            // MTEXT's paragraphs are `\P`.
            let body = a.text.replace('\n', "\\P");
            let chars: Vec<char> = body.chars().collect();
            let mut pieces: Vec<String> = chars
                .chunks(DXF_STRING)
                .map(|c| c.iter().collect())
                .collect();
            let last = pieces.pop().unwrap_or_default();
            let mut m = Entity::new(EntityType::MText(MText {
                insertion_point: at,
                extended_text: pieces,
                text: last,
                ..Default::default()
            }));
            m.common.layer = ANNOTATION_TEXT_LAYER.into();
            d.add_entity(m);
        }
    }
    for m in &w.measurements {
        let layer = measure_layer(m.kind);
        if m.kind == Kind::Point {
            let p = m.points[0];
            let mut e = Entity::new(EntityType::ModelPoint(ModelPoint::new(Point::new(
                p[0], p[1], p[2],
            ))));
            e.common.layer = layer;
            d.add_entity(e);
            continue;
        }
        let mut poly = Polyline::default();
        for p in &m.points {
            poly.add_vertex(
                &mut d,
                Vertex {
                    location: Point::new(p[0], p[1], p[2]),
                    ..Default::default()
                },
            );
        }
        poly.set_is_3d_polyline(true);
        poly.set_is_closed(m.kind == Kind::Area);
        let mut e = Entity::new(EntityType::Polyline(poly));
        e.common.layer = layer;
        d.add_entity(e);
    }
    d
}

/// Saved work from a drawing: TEXT on `ANNOTATIONS` (with the MTEXT on `ANNOTATION_TEXT` at
/// the same point as its text), and the points and polylines on `MEASURE_*` layers.
pub fn work_from_drawing(d: &Drawing) -> std::result::Result<Work, String> {
    let mut w = Work::default();
    let mut texts: Vec<([f64; 3], String)> = Vec::new();
    for (i, e) in d.entities().enumerate() {
        let at = format!("entity {i} on layer {}", e.common.layer);
        let layer = e.common.layer.to_ascii_uppercase();
        let kind = layer
            .strip_prefix("MEASURE_")
            .and_then(|k| Kind::from_name(&k.to_ascii_lowercase()));
        match (&e.specific, layer.as_str(), kind) {
            (EntityType::Text(t), ANNOTATIONS_LAYER, _) => w.annotations.push(Annotation {
                position: [t.location.x, t.location.y, t.location.z],
                title: t.value.chars().take(work::MAX_TITLE).collect(),
                text: String::new(),
                camera: None,
            }),
            (EntityType::MText(m), ANNOTATION_TEXT_LAYER, _) => {
                let mut s: String = m.extended_text.concat();
                s.push_str(&m.text);
                let p = &m.insertion_point;
                texts.push(([p.x, p.y, p.z], s.replace("\\P", "\n")));
            }
            (EntityType::ModelPoint(p), _, Some(Kind::Point)) => {
                let l = &p.location;
                w.measurements
                    .push(work::measurement(Kind::Point, vec![[l.x, l.y, l.z]], &at)?);
            }
            (EntityType::Polyline(p), _, Some(k)) => {
                let pts = p
                    .vertices()
                    .map(|v| [v.location.x, v.location.y, v.location.z])
                    .collect();
                w.measurements.push(work::measurement(k, pts, &at)?);
            }
            (EntityType::LwPolyline(p), _, Some(k)) => {
                let z = e.common.elevation;
                let pts = p.vertices.iter().map(|v| [v.x, v.y, z]).collect();
                w.measurements.push(work::measurement(k, pts, &at)?);
            }
            _ => {}
        }
        if w.annotations.len() > work::MAX_ITEMS || w.measurements.len() > work::MAX_ITEMS {
            return Err(format!(
                "more than {} annotations or measurements",
                work::MAX_ITEMS
            ));
        }
    }
    for (p, s) in texts {
        if let Some(a) = w
            .annotations
            .iter_mut()
            .find(|a| a.position == p && a.text.is_empty())
        {
            a.text = s.chars().take(work::MAX_TEXT).collect();
        }
    }
    Ok(w)
}

/// The saved work of a dataset from its sidecar (none there: empty work of `crs`).
pub fn load_work(sidecar: &Path, crs: Option<&str>) -> Result<Work> {
    match std::fs::metadata(sidecar) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Work::new(crs)),
        Err(e) => return Err(Error::io(sidecar, e)),
        Ok(m) if m.len() > work::MAX_BYTES as u64 => {
            return Err(Error::Invalid(format!(
                "{}: larger than {} bytes: not a work file",
                sidecar.display(),
                work::MAX_BYTES
            )));
        }
        Ok(_) => {}
    }
    let text = std::fs::read_to_string(sidecar).map_err(|e| Error::io(sidecar, e))?;
    let mut w =
        Work::parse(&text).map_err(|e| Error::Invalid(format!("{}: {e}", sidecar.display())))?;
    if w.crs.is_none() {
        w.crs = crs.map(str::to_string);
    }
    Ok(w)
}

/// Writes the sidecar atomically (replacing the one there).
pub fn save_work(sidecar: &Path, w: &Work) -> Result<()> {
    w.finite().map_err(|e| {
        Error::Invalid(format!("{}: {e}: the work is not saved", sidecar.display()))
    })?;
    let text = w.to_text();
    write_atomic(sidecar, true, |out| out.write_all(text.as_bytes()))
}

/// Saved work to `path`: `.geojson`/`.json` (GeoJSON) or `.dxf`.
pub fn export_work(w: &Work, path: &Path, force: bool) -> Result<()> {
    match extension(path).as_str() {
        "geojson" | "json" => {
            let text = serde_json::to_string_pretty(&w.to_geojson()).expect("JSON of JSON values");
            write_atomic(path, force, |out| out.write_all(text.as_bytes()))
        }
        "dxf" => save_drawing(&work_drawing(w), path, force),
        _ => Err(Error::Invalid(format!(
            "{}: the work goes to .geojson or .dxf",
            path.display()
        ))),
    }
}

/// A drawing from DXF bytes. The dxf crate panics on some values it reads (a header date
/// beyond chrono's range, found by fuzzing): such a file is an error like any other.
fn load_dxf(bytes: &[u8]) -> std::result::Result<Drawing, String> {
    match myriad_core::guard::catching(|| Drawing::load(&mut &bytes[..])) {
        Ok(Ok(d)) => Ok(d),
        Ok(Err(e)) => Err(e.to_string()),
        Err(m) => Err(format!("not a DXF this reads ({m})")),
    }
}

/// Saved work from a `.geojson`/`.json` file (GeoJSON, or a work sidecar) or a `.dxf`.
pub fn import_work(path: &Path) -> Result<Work> {
    let bad = |e: String| Error::Invalid(format!("{}: {e}", path.display()));
    // Read with a bound (a device such as /dev/zero is refused); a DXF as a GeoJSON (the dxf
    // crate holds about 30 times a drawing's size while it reads one).
    let max = work::MAX_BYTES as u64 * 4;
    match extension(path).as_str() {
        "geojson" | "json" => {
            let text = String::from_utf8(myriad_io::read_small(path, max)?)
                .map_err(|_| bad("not UTF-8 text".into()))?;
            let v: serde_json::Value = serde_json::from_str(&text)
                .map_err(|e| bad(format!("line {} column {}: {e}", e.line(), e.column())))?;
            if v["myriad"] == "work" {
                Work::from_json(&v).map_err(bad)
            } else {
                Work::from_geojson(&v).map_err(bad)
            }
        }
        "dxf" => {
            let bytes = myriad_io::read_small(path, max)?;
            let d = load_dxf(&bytes).map_err(bad)?;
            work_from_drawing(&d).map_err(bad)
        }
        _ => Err(bad("work comes from .geojson, .json or .dxf".into())),
    }
}

/// Files of vertices are read up to this size (a 10 M vertex CSV).
pub const MAX_SHAPE_BYTES: u64 = 512 << 20;

/// A `--polygon` or `--line` argument: `X1,Y1,X2,Y2,...`, or `@FILE` (GeoJSON, WKT or CSV;
/// [`crate::shape`]), a regular file read with a bound. `what` names the option in errors.
pub fn xy_arg(s: &str, what: &str, want: shape::Want) -> std::result::Result<shape::Shape, String> {
    let least = if want == shape::Want::Polygon { 3 } else { 2 };
    let Some(file) = s.strip_prefix('@') else {
        return Ok(shape::Shape {
            points: crate::corridor::parse_xy_list(s, what, least)?,
            epsg: None,
        });
    };
    let path = Path::new(file);
    let bytes = myriad_io::read_small(path, MAX_SHAPE_BYTES).map_err(|e| format!("{what}: {e}"))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        format!(
            "{what}: {file}: not UTF-8 text (byte {})",
            e.utf8_error().valid_up_to()
        )
    })?;
    shape::parse(&text, file, want).map_err(|e| format!("{what}: {e}"))
}

/// A shape from a file checked against the dataset it measures: the same EPSG code where both
/// name one, and its vertices near the data whatever the codes say.
pub fn check_shape(
    s: &shape::Shape,
    arg: &str,
    what: &str,
    crs: Option<&str>,
    bounds: &myriad_core::Aabb,
) -> std::result::Result<(), String> {
    if !arg.starts_with('@') {
        return Ok(());
    }
    let file = &arg[1..];
    if let (Some(a), Some(b)) = (crs.and_then(crate::geojson::epsg_code), s.epsg)
        && a != b
    {
        return Err(format!(
            "{what}: {file}: its CRS is EPSG:{b}, the dataset's EPSG:{a}: reproject it first"
        ));
    }
    shape::near_the_data(s.points.iter().copied(), bounds)
        .map_err(|e| format!("{what}: {file}: {e}"))
}

fn extension(p: &Path) -> String {
    p.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::work::View;

    /// Work holding a NaN is refused before anything is written: the sidecar there stays.
    #[test]
    fn work_that_is_not_finite_is_not_saved() {
        let dir = std::env::temp_dir().join(format!("myriad-work-nan-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let sidecar = dir.join("a.work.json");
        let good = Work::default();
        save_work(&sidecar, &good).unwrap();
        let before = std::fs::read(&sidecar).unwrap();
        let mut bad = Work::default();
        bad.annotations.push(Annotation {
            position: [1.0, f64::NAN, 2.0],
            title: "x".into(),
            text: String::new(),
            camera: None,
        });
        let e = save_work(&sidecar, &bad).unwrap_err().to_string();
        assert!(
            e.contains("not a finite number") && e.contains("a.work.json"),
            "{e}"
        );
        assert_eq!(std::fs::read(&sidecar).unwrap(), before);
        assert!(load_work(&sidecar, None).is_ok());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn work_round_trips_through_dxf() {
        let mut w = Work::default();
        w.annotations.push(Annotation {
            position: [500100.25, 4400200.5, 31.125],
            title: "gate".into(),
            text: format!("line one\nline two {}", "x".repeat(600)),
            camera: Some(View {
                position: [0.0; 3],
                target: [1.0; 3],
            }),
        });
        for (k, pts) in [
            (Kind::Distance, vec![[1.0, 2.0, 3.0], [4.0, 6.0, 3.0]]),
            (
                Kind::Area,
                vec![[0.0, 0.0, 1.0], [9.0, 0.0, 2.0], [9.0, 9.0, 3.0]],
            ),
            (Kind::Point, vec![[7.0, 8.0, 9.0]]),
        ] {
            w.measurements.push(work::measurement(k, pts, "t").unwrap());
        }
        let dir = std::env::temp_dir().join(format!("myriad-work-dxf-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("w.dxf");
        export_work(&w, &path, true).unwrap();
        let back = import_work(&path).unwrap();
        assert_eq!(back.measurements, w.measurements);
        assert_eq!(back.annotations.len(), 1);
        let a = &back.annotations[0];
        assert_eq!(
            (a.position, a.title.as_str()),
            (w.annotations[0].position, "gate")
        );
        assert_eq!(a.text, w.annotations[0].text);
        assert_eq!(a.camera, None, "DXF keeps no camera");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
