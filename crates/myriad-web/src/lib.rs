//! The web viewer's core (issue 16), compiled to WebAssembly (`build.sh`): the same reader
//! (`myriad-format`), selection (`myriad-lod`) and colour schemes (`myriad_core::colour`) as the
//! native renderer, so that the browser draws what `myriad render` draws for the same camera.
//! The viewer's JavaScript (myriad-serve's `viewer/`) runs it in Web Workers: one selects (and
//! reads the hierarchy pages it needs, by synchronous range requests, which workers may make),
//! others decode node pages the worker fetched. [`wasm`] is the boundary: plain exported
//! functions over linear memory, no bindings generator.
//!
//! Everything here also builds natively, where the tests run it.

use myriad_core::colour::{ColorBy, Gradient, colours};
use myriad_core::{Aabb, Attribute, Column, NodeKey, PointBatch};
use myriad_format::{ByteSource, Dataset, NodeEntry, PageRef};
use myriad_lod::{Camera, Clip, DrawnTree, Hierarchy, SelectOptions, robust_bounds, select_where};
use myriad_measure::{Bound, Filter};
use serde_json::{Value, json};
use std::collections::HashSet;
use std::path::Path;
use std::sync::Arc;

#[cfg(target_arch = "wasm32")]
pub mod wasm;

/// Hierarchy pages one selection call reads at most before it answers (the viewer asks again
/// while pages are missing).
pub const PAGES_PER_CALL: usize = 8;

/// An open dataset, its known hierarchy and the bounds the default views frame.
pub struct Viewer {
    pub dataset: Dataset,
    pub hierarchy: Hierarchy,
    /// The root node's points without the outer 0.5 % on each axis (as `Scene::open`).
    pub view_bounds: Aabb,
}

/// What the viewer asks a selection for: the camera, budget and threshold, a clipping box, and
/// the nodes it has drawn (for the adaptive point sizes' tree).
pub struct Ask {
    pub camera: Camera,
    pub options: SelectOptions,
    pub clip: Option<Clip>,
    pub drawn: HashSet<NodeKey>,
}

pub fn key_json(k: &NodeKey) -> Value {
    json!([k.level, k.cell[0], k.cell[1], k.cell[2]])
}

fn aabb_json(b: &Aabb) -> Value {
    json!([b.min[0], b.min[1], b.min[2], b.max[0], b.max[1], b.max[2]])
}

impl Viewer {
    /// Opens a dataset from `bytes` (reads the header, metadata, root hierarchy page and root
    /// node, as the native scene does).
    pub fn open(bytes: Arc<dyn ByteSource>, name: &str) -> myriad_core::Result<Viewer> {
        Viewer::from_dataset(Dataset::from_source(bytes, Path::new(name))?)
    }

    /// [`Viewer::open`] of a dataset opened already.
    pub fn from_dataset(dataset: Dataset) -> myriad_core::Result<Viewer> {
        let meta = &dataset.meta;
        let hierarchy = match dataset.hierarchy_page(&dataset.root_page()) {
            Ok(page) => Hierarchy::from_root_page(meta.root, page, meta.depth),
            Err(d) => return Err(dataset.damage_error(&d)),
        };
        let mut view_bounds = meta.bounds;
        if let Some(root) = hierarchy.get(&NodeKey::ROOT).filter(|n| n.points > 0) {
            let b = dataset
                .read_node(root)
                .map_err(|d| dataset.damage_error(&d))?;
            let sample = robust_bounds(&b.positions, 0.005);
            if !sample.is_empty() {
                view_bounds = sample;
            }
        }
        Ok(Viewer {
            dataset,
            hierarchy,
            view_bounds,
        })
    }

    /// The dataset as the viewer shows it: counts, bounds, attributes.
    pub fn info(&self) -> Value {
        let m = &self.dataset.meta;
        json!({
            "name": self.dataset.path().display().to_string(),
            "points": m.points,
            "nodes": m.nodes,
            "structure": m.structure,
            "bounds": aabb_json(&m.bounds),
            "root": aabb_json(&m.root),
            "view_bounds": aabb_json(&self.view_bounds),
            "attributes": m.schema.names(),
            // What a colour ramp or a `where` condition may name (`myriad_core::Column`).
            "columns": Column::columns(&m.schema).into_iter().map(|(n, _)| n).collect::<Vec<_>>(),
            "gradients": Gradient::ALL.iter().map(|g| gradient_name(*g)).collect::<Vec<_>>(),
            "crs": m.crs,
            // The unit of the CRS's coordinates (for the scale bar).
            "units": myriad_measure::measurement::crs_units(m.crs.as_deref()),
            // The files besides the dataset's own that hold its pages, relative to it.
            "files": m.files.iter().map(|f| f.path.as_str()).collect::<Vec<_>>(),
            // A cloud format read in place ("COPC 1.0", "EPT", "Potree 2.0"): its nodes are read by
            // the decoders themselves, not fetched as pages.
            "foreign": self.dataset.foreign_format(),
            // The classes' names, colours and visibility (the default scheme, as `render` colours
            // them; a style's answer gives a dataset's own), for the class list.
            "classes": myriad_measure::scheme::table(&Default::default()),
        })
    }

    /// The camera `myriad render` starts from: the view bounds framed from above at 45
    /// degrees, near and far around the whole dataset.
    pub fn default_camera(&self, width: u32, height: u32, fov: f64) -> Camera {
        let mut cam = Camera::framing(&self.view_bounds, width, height, fov);
        cam.fit_depth(&self.dataset.meta.bounds);
        cam
    }

    /// Selects the nodes to draw for `ask`, reading up to [`PAGES_PER_CALL`] missing hierarchy
    /// pages first where the selection needs them; the answer lists each node with where its
    /// page lies, the adaptive point sizes' tree over the drawn nodes, and what is still missing.
    pub fn select(&mut self, ask: &Ask) -> Value {
        let keep = |cube: &Aabb| Clip::keeps(ask.clip, cube);
        let mut cam = ask.camera;
        cam.fit_depth(&self.dataset.meta.bounds);
        let mut read = 0;
        let mut errors = Vec::new();
        let selection = loop {
            let s = select_where(&self.hierarchy, &cam, &ask.options, &keep);
            if s.pages.is_empty() || read >= PAGES_PER_CALL {
                break s;
            }
            for p in s.pages.iter().take(PAGES_PER_CALL - read) {
                read += 1;
                match self.dataset.hierarchy_page(p) {
                    Ok(page) => {
                        self.hierarchy.insert_page(p.key, page);
                    }
                    Err(d) => {
                        errors.push(self.dataset.damage_error(&d).to_string());
                        // Never asked for again: an empty page in its place.
                        self.hierarchy.insert_page(p.key, Default::default());
                    }
                }
            }
        };
        let tree = DrawnTree::new(&selection, &self.hierarchy, |k| ask.drawn.contains(k));
        let root = self.hierarchy.root;
        let cells = self.hierarchy.cells();
        let nodes: Vec<Value> = selection
            .nodes
            .iter()
            .filter_map(|n| {
                let e = self.hierarchy.get(&n.key)?;
                let cube = n.key.bounds(&root);
                Some(json!({
                    "key": key_json(&n.key),
                    "points": n.points,
                    "total": e.points,
                    // The spacing its finest level is drawn at: which of its points are lone
                    // (myriad_lod::lone_radius).
                    "finest": myriad_lod::point_spacing(e).last().copied().unwrap_or(0.0),
                    // No descendant: drawn whole, its lone points are drawn small.
                    "leaf": self.hierarchy.is_leaf(&n.key),
                    // At most its drawn ancestors' (the tree's, where it is in it).
                    "spacing": if cells { tree.spacing(&n.key).unwrap_or(n.spacing) } else { n.spacing },
                    "page": [e.page.offset, e.page.length, e.page.crc],
                    "cube": [cube.min[0], cube.min[1], cube.min[2], cube.size()[0]],
                    "tree": if cells { tree.index.get(&n.key).map(|&i| i as i64).unwrap_or(-1) } else { -1 },
                }))
            })
            .collect();
        json!({
            "nodes": nodes,
            "points": selection.points,
            "budget_reached": selection.budget_reached,
            "pages_missing": selection.pages.len(),
            "pages_read": read,
            "pages": self.hierarchy.pages(),
            "tree": tree.entries.iter().flatten().collect::<Vec<_>>(),
            "errors": errors,
        })
    }
}

/// A node entry from what a selection answer says of it (enough to check and decode its page).
pub fn entry(key: NodeKey, page: PageRef, points: u32) -> NodeEntry {
    NodeEntry::new(key, page, points, vec![points], vec![0.0])
}

/// A decoded node for the GPU: positions relative to `origin` (f32: no jitter at UTM or ECEF
/// magnitudes when the origin is the node's) and RGBA8 colours by `scheme`.
pub struct Decoded {
    pub positions: Vec<f32>,
    pub colours: Vec<[u8; 4]>,
    /// The node's points per class, hidden ones included: (class, count) for each class present.
    pub classes: Vec<(u8, u32)>,
}

/// Classes hidden: a flag per ASPRS class number.
pub type Hidden = [bool; 256];

/// What the viewer shows of `ds`: the points of the classes not hidden that meet the
/// conditions `wheres` (`--where`'s syntax: `intensity>100 and return_number=1`), against the
/// dataset's attributes (an unknown name is an error naming it).
pub fn shown(ds: &Dataset, hidden: &Hidden, wheres: &str) -> Result<Bound, String> {
    let schema = &ds.meta.schema;
    let classes = (hidden.iter().any(|&h| h) && schema.has(&Attribute::Classification))
        .then(|| (0..=255u8).filter(|&c| !hidden[c as usize]).collect());
    let conditions = match wheres.trim() {
        "" => Vec::new(),
        w => Filter::parse_where(w).map_err(|e| e.replace("--where: ", ""))?,
    };
    Filter {
        classes,
        conditions,
    }
    .bind(schema)
    .map_err(|e| e.replace("--where: ", "where: "))
}

pub fn gradient_name(g: Gradient) -> String {
    format!("{g:?}").to_ascii_lowercase()
}

/// The viewer's colours as `--color NAME [--gradient G] [--range LOW,HIGH]` choose them
/// (`myriad_core::colour::choose`): a scheme by its name, else a ramp over the attribute `NAME`
/// with its range fitted to the overview where none is given. With it, what the panel shows:
/// the colour's name and a ramp's gradient and range.
pub fn style(
    ds: &Dataset,
    name: &str,
    gradient: Option<&str>,
    range: Option<[f64; 2]>,
) -> Result<(ColorBy, Value), String> {
    let gradient =
        match gradient {
            Some(g) => Some(Gradient::parse(g).ok_or_else(|| {
                format!("gradient \"{g}\": none such (one of {})", Gradient::NAMES)
            })?),
            None => None,
        };
    if let Some([lo, hi]) = range
        && !(lo.is_finite() && hi.is_finite() && lo < hi)
    {
        return Err(format!("range {lo},{hi}: two numbers, low then high"));
    }
    let colour =
        (ds.choose_colour(name, gradient, range)).map_err(|e| e.replace("--color ", "colour "))?;
    let ramp = match colour {
        // Its colours at eleven stops, for the legend.
        ColorBy::Ramp(r) => json!({
            "gradient": gradient_name(r.gradient), "range": r.range,
            "stops": (0..=10).map(|i| r.gradient.at(i as f64 / 10.0)).collect::<Vec<_>>(),
        }),
        _ => Value::Null,
    };
    Ok((colour, json!({ "color": name, "ramp": ramp })))
}

/// Drops the points `shown` leaves out, and counts each class's points before (a batch without
/// classes counts none).
pub fn keep_shown(b: &mut PointBatch, shown: &Bound) -> Vec<(u8, u32)> {
    let mut counts = [0u32; 256];
    for &k in b.classification.iter().flatten() {
        counts[k as usize] += 1;
    }
    shown.retain(b);
    (0..=255u8)
        .filter(|&k| counts[k as usize] > 0)
        .map(|k| (k, counts[k as usize]))
        .collect()
}

/// Checks and decodes the page of node `e` (bytes as fetched) but for the points `shown`
/// leaves out, coloured by `colour` as `myriad render` colours it.
pub fn decode(
    ds: &Dataset,
    e: &NodeEntry,
    bytes: &[u8],
    origin: [f64; 3],
    colour: ColorBy,
    z_range: (f64, f64),
    shown: &Bound,
) -> Result<Decoded, String> {
    let b = ds
        .decode_node_edited(e, bytes, &ds.meta.schema)
        .map_err(|d| ds.damage_error(&d).to_string())?;
    Ok(decoded(b, e, origin, colour, z_range, shown))
}

/// A node's points (decoded from a page, or read in place from a cloud format) for the GPU, as
/// [`decode`] makes them.
pub fn decoded(
    mut b: PointBatch,
    e: &NodeEntry,
    origin: [f64; 3],
    colour: ColorBy,
    z_range: (f64, f64),
    shown: &Bound,
) -> Decoded {
    let classes = keep_shown(&mut b, shown);
    let positions = b
        .positions
        .iter()
        .flat_map(|p| (0..3).map(move |a| (p[a] - origin[a]) as f32))
        .collect();
    let mut colours = colours(&b, b.len(), colour, z_range, e.key.level);
    // Lone points (no other of the node's within `myriad_lod::lone_radius`) marked by their
    // colour's alpha 0: the viewer's shaders draw them at most 3 pixels wide, as the native
    // renderer's LONE_BIT does.
    let lone = myriad_core::geometry::lone_points(&b.positions, myriad_lod::lone_radius(e));
    for (c, _) in colours.iter_mut().zip(lone).filter(|(_, l)| *l) {
        c[3] = 0;
    }
    Decoded {
        positions,
        colours,
        classes,
    }
}

/// Every attribute of point `i` of a decoded node, world coordinates in full.
pub fn point_json(b: &PointBatch, i: usize) -> Value {
    let mut out = serde_json::Map::new();
    for (a, v) in ["x", "y", "z"].iter().zip(b.positions[i]) {
        out.insert(a.to_string(), json!(v));
    }
    for (a, v) in b.values(i) {
        let v = match v.as_slice() {
            [one] => json!(one),
            many => json!(many),
        };
        out.insert(a.name(), v);
    }
    Value::Object(out)
}

/// A measurement in the viewer (`myriad_measure::measurement`, as `view` and `annotate` make it):
/// kind `kind` (its index in `Kind::ALL`) through `points` (x, y, z each), lengths in `units`
/// (0 the data's, 1 m, 2 ft, 3 US ft) converted from the CRS's unit: whether it is complete, its
/// figure, its label and its segments.
pub fn measure_json(kind: u32, points: &[f64], units: u32, crs: Option<&str>) -> Value {
    use myriad_measure::measurement::{Kind, Measurement, Units, metres_per_unit};
    let Some(&kind) = Kind::ALL.get(kind as usize) else {
        return json!({ "error": format!("no measurement {kind}") });
    };
    let units = [Units::Data, Units::Metres, Units::Feet, Units::UsFeet]
        .get(units as usize)
        .copied()
        .unwrap_or(Units::Data);
    let m = Measurement {
        kind,
        points: points.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
    };
    // A geographic CRS measures on its ellipsoid (geodesics, metres), others straight.
    let earth = myriad_measure::measurement::earth(crs);
    let (value, segments) = match earth {
        Some(e) => (m.value_on(e), m.segments_on(e)),
        None => (m.value(), m.segments()),
    };
    json!({
        "kind": kind.name(),
        "complete": m.complete(),
        "value": value,
        "label": m.label_for(units, crs.and_then(metres_per_unit), earth),
        "segments": segments,
        "geodesic": earth.is_some(),
    })
}

/// A cross-section for the web viewer (`myriad_measure::profile`, as `myriad profile` and `view`
/// cut it): the original points within `width / 2` of `line` that `shown` keeps, coloured by
/// `colour`, drawn `picture` pixels wide. A JSON summary (points, length, width, elevations,
/// the picture's frame, units) with the RGBA picture and the points as CSV.
pub fn cut_profile(
    ds: &Dataset,
    line: &[[f64; 2]],
    width: f64,
    picture: u32,
    colour: ColorBy,
    shown: &Bound,
) -> Result<(Value, Vec<u8>, Vec<u8>), String> {
    let corridor = myriad_measure::Corridor::new(line, width)?;
    let p = myriad_measure::profile::profile(ds, &corridor, shown, colour)?;
    let units = myriad_measure::measurement::crs_units(ds.meta.crs.as_deref());
    let (z0, z1) = p.z_range();
    let mut summary = json!({
        "points": p.len(), "length": p.length, "width": p.width, "z": [z0, z1],
        "nodes_read": p.nodes_read, "units": units,
    });
    if p.is_empty() {
        return Ok((summary, Vec::new(), Vec::new()));
    }
    let (w, h, rgba, _) = p.plot(picture.clamp(64, 4096));
    let f = p.frame(w);
    summary["frame"] = json!({
        "margin": f.margin, "per_m": f.per_m, "exaggeration": f.exaggeration,
        "inner_h": f.inner_h, "z0": f.z0, "width": w, "height": h,
    });
    // The grid lines the picture draws, for the page to label.
    let (along, heights) = p.grid(w);
    summary["grid"] = json!({
        "along": along, "z": heights,
        "steps": [myriad_measure::profile::nice_step(p.length / 10.0),
                  myriad_measure::profile::nice_step((z1 - z0).max(1e-3) / 5.0)],
    });
    let mut csv = Vec::new();
    p.write_csv(&mut csv).map_err(|e| e.to_string())?;
    Ok((summary, rgba, csv))
}

/// Squares of cells a volume's grid is drawn in at most (as `view` draws it).
pub const VOLUME_BLOCKS: usize = 3000;

/// A volume for the web viewer (`myriad_measure::volume`, as `myriad volume` and `view` measure
/// it) of the points `shown` keeps over `polygon` (plan points), above the rim's plane or
/// `elevation`, on cells of `cell` (or chosen from the spacing): the figures, the label, the
/// base under each vertex and the grid in squares of cells ([`VOLUME_BLOCKS`] at most: centre
/// x, y, half the side, the surface's height, 1 for fill or 0 for cut).
pub fn volume_json(
    ds: &Dataset,
    polygon: &[[f64; 2]],
    elevation: Option<f64>,
    cell: Option<f64>,
    shown: &Bound,
) -> Result<Value, String> {
    use myriad_measure::volume::{Base, volume_and_cells};
    let polygon = myriad_measure::Polygon::new(polygon)?;
    let base = match elevation {
        Some(z) => Base::Elevation(z),
        None => Base::Rim,
    };
    let (v, cells) = volume_and_cells(ds, &polygon, base, cell, shown)?;
    let units = myriad_measure::measurement::crs_units(ds.meta.crs.as_deref());
    let under: Vec<Value> = (polygon.vertices().iter())
        .map(|q| {
            json!(
                v.base_at(&polygon, elevation, q[0], q[1])
                    .map(|z| [q[0], q[1], z])
            )
        })
        .collect();
    let blocks: Vec<[f64; 5]> = (cells.iter().flat_map(|c| c.blocks(VOLUME_BLOCKS)))
        .map(|b| [b.centre[0], b.centre[1], b.half, b.top, b.fill as u8 as f64])
        .collect();
    Ok(json!({
        "fill": v.fill, "cut": v.cut, "net": v.net(), "area": v.area, "cells": v.cells,
        "cell": v.cell, "empty_cells": v.empty_cells, "points": v.points,
        "nodes_read": v.nodes_read, "plane": v.plane, "units": units,
        "label": v.summary(units), "base": under, "blocks": blocks,
    }))
}
