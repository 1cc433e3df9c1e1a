//! The tools' files on disk, each written atomically (nothing at the path until it is whole):
//! a profile as CSV, PNG or DXF (through the `dxf` crate, DXF R2000 as CAD programs and ezdxf
//! read it).

use crate::profile::Profile;
use crate::{Corridor, Polygon};
use dxf::entities::{Entity, EntityType, LwPolyline, ModelPoint};
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

/// Writes a drawing to `path` atomically.
pub fn save_drawing(d: &Drawing, path: &Path, force: bool) -> Result<()> {
    write_atomic(path, force, |w| {
        let mut w = w;
        d.save(&mut w).map_err(std::io::Error::other)
    })
}
