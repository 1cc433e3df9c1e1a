//! Edits as a layer: classes set and points removed, kept beside a dataset and never written
//! into it (`myriad classify`), applied by every reader of the dataset's points.
//!
//! An edit is a region, a filter and a rule: the points in the region (a polygon in plan with an
//! optional elevation range, a box, a corridor, the spheres a brush painted, or everywhere) that
//! the filter keeps (`--classes`, `--where`, as the tools read them) are given a class or
//! removed. A layer is a list of edits applied in order, each seeing the classes the ones
//! before it set and not the points they removed; undone edits are kept after them for redo. An
//! edit over a whole tile or a billion points costs its few numbers, never a list of points;
//! applying it costs one test per point of the nodes its region meets (nodes it does not meet
//! are read as stored, [`myriad_format::edits`]).
//!
//! The file, next to the dataset ([`sidecar_for`]: `city.myr` → `city.edits.json`):
//! ```json
//! { "myriad": "edits", "version": 1, "crs": "EPSG:2193",
//!   "edits": [ { "polygon": [[x, y], ...], "z": [z0, z1], "to": 7 },
//!              { "box": [[x0, y0, z0], [x1, y1, z1]], "classes": "1", "remove": true },
//!              { "corridor": [[x, y], ...], "width": 4.0, "where": ["intensity<20"], "to": 18 },
//!              { "brush": [[x, y, z, radius], ...], "to": 6 },
//!              { "where": ["z>350"], "remove": true } ],
//!   "undone": [] }
//! ```

use crate::filter::{Bound, Filter};
use crate::ground::Rule;
use crate::ground::surface::Surface;
use crate::work::{MAX_COORD, finite, list, short};
use crate::{Corridor, Polygon, Region};
use myriad_core::{Aabb, PointBatch, Schema};
use serde_json::{Map, Value, json};
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[cfg(not(target_arch = "wasm32"))]
mod kept;
#[cfg(not(target_arch = "wasm32"))]
pub use kept::{Change, Refused, admit, change};

/// An edits file larger than this is refused (brush strokes are the largest edits).
pub const MAX_BYTES: usize = 16 << 20;
/// Most spheres of one brush edit.
pub const MAX_SPHERES: usize = 100_000;

/// Where an edit applies.
#[derive(Debug, Clone, PartialEq)]
pub enum Area {
    /// Everywhere: the filter alone chooses.
    All,
    /// A polygon in plan, between two elevations where `z` is given.
    Polygon {
        ring: Vec<[f64; 2]>,
        z: Option<[f64; 2]>,
    },
    Box(Aabb),
    /// Within half `width` of a line in plan.
    Corridor {
        line: Vec<[f64; 2]>,
        width: f64,
    },
    /// Spheres a brush painted: centre and radius.
    Brush(Vec<[f64; 4]>),
}

/// What an edit does to the points it selects.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    Class(u8),
    Remove,
    /// Ground against a terrain surface (`myriad ground`): class 2 near it, 7 far below it, 1
    /// for points labelled 2 that are neither; noise (7, 18) left as it is.
    Ground {
        /// The surface's file, beside the edits file.
        surface: String,
        rule: Rule,
    },
}

/// One edit: a region, a filter (as the user wrote it) and a rule.
#[derive(Debug, Clone, PartialEq)]
pub struct Edit {
    pub area: Area,
    /// `--classes`, as given.
    pub classes: Option<String>,
    /// `--where`, as given.
    pub wheres: Vec<String>,
    pub action: Action,
}

/// A dataset's edits.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Layer {
    /// The dataset's CRS when the edits were made.
    pub crs: Option<String>,
    pub edits: Vec<Edit>,
    /// Edits undone, the last undone last: what redo gives back.
    pub undone: Vec<Edit>,
}

/// The edits file of the dataset at `dataset`: `city.myr` → `city.edits.json` (a folder
/// dataset's next to the folder).
pub fn sidecar_for(dataset: &Path) -> PathBuf {
    // An EPT or Potree 2.0 dataset given by its metadata file is its folder.
    let folder = dataset.parent().filter(|_| {
        dataset
            .file_name()
            .is_some_and(|n| n == "ept.json" || n == "metadata.json")
    });
    let dataset = folder.unwrap_or(dataset);
    let name = if folder.is_some() || dataset.is_dir() {
        dataset.file_name()
    } else {
        dataset.file_stem()
    };
    let name = name.map_or_else(|| "dataset".into(), |n| n.to_string_lossy().into_owned());
    dataset.with_file_name(format!("{name}.edits.json"))
}

impl Edit {
    /// The edit's filter (an error names what does not parse).
    pub fn filter(&self) -> Result<Filter, String> {
        Filter::parse(self.classes.as_deref(), &self.wheres)
    }

    /// The edit's region (`None`: everywhere); an error says why its shape is not one.
    pub fn region(&self) -> Result<Option<Box<dyn Region>>, String> {
        Ok(match &self.area {
            Area::All => None,
            Area::Polygon { ring, z } => Some(Box::new(Prism {
                polygon: Polygon::new(ring)?,
                z: z.unwrap_or([f64::NEG_INFINITY, f64::INFINITY]),
            })),
            Area::Box(b) => Some(Box::new(*b)),
            Area::Corridor { line, width } => Some(Box::new(Corridor::new(line, *width)?)),
            Area::Brush(s) => Some(Box::new(Spheres::new(s.clone())?)),
        })
    }

    /// A short description: "polygon of 5 points → class 7".
    pub fn describe(&self) -> String {
        let mut s = match &self.area {
            Area::All => "everywhere".to_string(),
            Area::Polygon { ring, z: None } => format!("polygon of {} points", ring.len()),
            Area::Polygon { ring, z: Some(z) } => {
                format!("polygon of {} points, z {} to {}", ring.len(), z[0], z[1])
            }
            Area::Box(b) => format!(
                "box {},{},{} to {},{},{}",
                b.min[0], b.min[1], b.min[2], b.max[0], b.max[1], b.max[2]
            ),
            Area::Corridor { line, width } => {
                format!("corridor of {} points, {width} wide", line.len())
            }
            Area::Brush(s) => format!("brush of {} spheres", s.len()),
        };
        if let Some(c) = &self.classes {
            s += &format!(", classes {c}");
        }
        for w in &self.wheres {
            s += &format!(", where {w}");
        }
        match &self.action {
            Action::Class(c) => s + &format!(" → class {c}"),
            Action::Remove => s + " → removed",
            Action::Ground { surface, rule } => {
                s + &format!(
                    " → ground within {} + {} x slope of {surface}, low noise {} below",
                    rule.threshold, rule.scalar, rule.low
                )
            }
        }
    }

    /// The edit as the file keeps it.
    pub fn to_json(&self) -> Value {
        let mut o = Map::new();
        match &self.area {
            Area::All => {}
            Area::Polygon { ring, z } => {
                o.insert("polygon".into(), json!(ring));
                if let Some(z) = z {
                    o.insert("z".into(), json!(z));
                }
            }
            Area::Box(b) => {
                o.insert("box".into(), json!([b.min, b.max]));
            }
            Area::Corridor { line, width } => {
                o.insert("corridor".into(), json!(line));
                o.insert("width".into(), json!(width));
            }
            Area::Brush(s) => {
                o.insert("brush".into(), json!(s));
            }
        }
        if let Some(c) = &self.classes {
            o.insert("classes".into(), json!(c));
        }
        if !self.wheres.is_empty() {
            o.insert("where".into(), json!(self.wheres));
        }
        match &self.action {
            Action::Class(c) => o.insert("to".into(), json!(c)),
            Action::Remove => o.insert("remove".into(), json!(true)),
            Action::Ground { surface, rule } => o.insert(
                "ground".into(),
                json!({"surface": surface, "threshold": rule.threshold, "scalar": rule.scalar,
                       "low": rule.low}),
            ),
        };
        Value::Object(o)
    }

    /// An edit from its JSON (`at`: where it is, for errors).
    pub fn from_json(v: &Value, at: &str) -> Result<Edit, String> {
        let o = v
            .as_object()
            .ok_or_else(|| format!("{at}: not an object: {}", short(v)))?;
        let points = |key: &str, n: usize| -> Result<Vec<Vec<f64>>, String> {
            let a = match o.get(key) {
                Some(Value::Array(a)) if a.len() <= crate::shape::MAX_VERTICES => a,
                Some(v) => return Err(format!("{at}.{key}: not a list of points: {}", short(v))),
                None => return Ok(Vec::new()),
            };
            a.iter()
                .enumerate()
                .map(|(i, p)| match p.as_array() {
                    Some(c) if c.len() == n => (c.iter())
                        .map(|x| finite(x, &format!("{at}.{key}[{i}]")))
                        .collect(),
                    _ => Err(format!("{at}.{key}[{i}]: not {n} numbers: {}", short(p))),
                })
                .collect()
        };
        let xy = |key: &str| -> Result<Vec<[f64; 2]>, String> {
            Ok(points(key, 2)?.into_iter().map(|p| [p[0], p[1]]).collect())
        };
        let shapes = ["polygon", "box", "corridor", "brush"];
        let given: Vec<&str> = shapes.into_iter().filter(|k| o.contains_key(*k)).collect();
        if given.len() > 1 {
            return Err(format!("{at}: both {} and {}", given[0], given[1]));
        }
        let area = match given.first().copied() {
            None => Area::All,
            Some("polygon") => Area::Polygon {
                ring: xy("polygon")?,
                z: match o.get("z") {
                    None | Some(Value::Null) => None,
                    Some(v) => {
                        let z = (v.as_array().filter(|a| a.len() == 2))
                            .ok_or_else(|| format!("{at}.z: not two numbers: {}", short(v)))?;
                        let z = [
                            finite(&z[0], &format!("{at}.z"))?,
                            finite(&z[1], &format!("{at}.z"))?,
                        ];
                        if z[0] > z[1] {
                            return Err(format!("{at}.z: {} is above {}", z[0], z[1]));
                        }
                        Some(z)
                    }
                },
            },
            Some("box") => {
                let c = points("box", 3)?;
                if c.len() != 2 {
                    return Err(format!("{at}.box: not two corners"));
                }
                let (lo, hi) = ([c[0][0], c[0][1], c[0][2]], [c[1][0], c[1][1], c[1][2]]);
                if (0..3).any(|a| lo[a] > hi[a]) {
                    return Err(format!("{at}.box: its first corner is not its lowest"));
                }
                Area::Box(Aabb::new(lo, hi))
            }
            Some("corridor") => Area::Corridor {
                line: xy("corridor")?,
                width: o
                    .get("width")
                    .and_then(Value::as_f64)
                    .filter(|w| w.is_finite() && *w > 0.0 && *w <= MAX_COORD)
                    .ok_or_else(|| format!("{at}.width: not a positive number"))?,
            },
            _ => {
                let s = points("brush", 4)?;
                if s.len() > MAX_SPHERES {
                    return Err(format!("{at}.brush: more than {MAX_SPHERES} spheres"));
                }
                Area::Brush(s.into_iter().map(|p| [p[0], p[1], p[2], p[3]]).collect())
            }
        };
        let classes = match o.get("classes") {
            None | Some(Value::Null) => None,
            Some(Value::String(s)) => Some(s.clone()),
            Some(v) => return Err(format!("{at}.classes: not a text: {}", short(v))),
        };
        let wheres = match o.get("where") {
            None | Some(Value::Null) => Vec::new(),
            Some(Value::Array(a)) if a.len() <= 100 => a
                .iter()
                .map(|w| {
                    w.as_str()
                        .map(str::to_string)
                        .ok_or_else(|| format!("{at}.where: not a text: {}", short(w)))
                })
                .collect::<Result<_, _>>()?,
            Some(v) => return Err(format!("{at}.where: not a list of texts: {}", short(v))),
        };
        let action = match (o.get("to"), o.get("remove")) {
            (None, None) if o.contains_key("ground") => ground_from_json(&o["ground"], at)?,
            _ if o.contains_key("ground") => {
                return Err(format!("{at}: \"ground\" with \"to\" or \"remove\""));
            }
            (Some(c), None) => match c.as_u64() {
                Some(c) if c <= 255 => Action::Class(c as u8),
                _ => return Err(format!("{at}.to: not a class from 0 to 255: {}", short(c))),
            },
            (None, Some(Value::Bool(true))) => Action::Remove,
            (Some(_), Some(_)) => return Err(format!("{at}: both \"to\" and \"remove\"")),
            _ => return Err(format!("{at}: neither \"to\": CLASS nor \"remove\": true")),
        };
        let e = Edit {
            area,
            classes,
            wheres,
            action,
        };
        // What would fail when applied fails now, naming the edit.
        e.filter().map_err(|m| format!("{at}: {m}"))?;
        e.region().map_err(|m| format!("{at}: {m}"))?;
        Ok(e)
    }
}

fn ground_from_json(v: &Value, at: &str) -> Result<Action, String> {
    let surface = v["surface"]
        .as_str()
        .filter(|s| {
            !s.is_empty()
                && Path::new(s)
                    .file_name()
                    .is_some_and(|n| n == std::ffi::OsStr::new(s))
        })
        .ok_or_else(|| format!("{at}.ground.surface: not the name of a file beside the edits"))?;
    let num = |k: &str| {
        v[k].as_f64()
            .filter(|x| x.is_finite() && *x >= 0.0 && *x <= MAX_COORD)
            .ok_or_else(|| format!("{at}.ground.{k}: not a number 0 or more"))
    };
    Ok(Action::Ground {
        surface: surface.to_string(),
        rule: Rule {
            threshold: num("threshold")?,
            scalar: num("scalar")?,
            low: num("low")?,
        },
    })
}

impl Layer {
    /// Adds an edit (what was undone can no longer be redone).
    pub fn push(&mut self, e: Edit) {
        self.edits.push(e);
        self.undone.clear();
    }

    /// Undoes the last edit: the edit undone, or `None` when there is none.
    pub fn undo(&mut self) -> Option<&Edit> {
        let e = self.edits.pop()?;
        self.undone.push(e);
        self.undone.last()
    }

    /// Redoes the last edit undone.
    pub fn redo(&mut self) -> Option<&Edit> {
        let e = self.undone.pop()?;
        self.edits.push(e);
        self.edits.last()
    }

    pub fn to_json(&self) -> String {
        let v = json!({
            "myriad": "edits",
            "version": 1,
            "crs": self.crs,
            "edits": self.edits.iter().map(Edit::to_json).collect::<Vec<_>>(),
            "undone": self.undone.iter().map(Edit::to_json).collect::<Vec<_>>(),
        });
        serde_json::to_string_pretty(&v).expect("JSON of numbers and texts") + "\n"
    }

    /// A layer from the file's text; an error names the line or the edit.
    pub fn parse(text: &str) -> Result<Layer, String> {
        if text.len() > MAX_BYTES {
            return Err(format!("larger than {MAX_BYTES} bytes"));
        }
        let v: Value = serde_json::from_str(text)
            .map_err(|e| format!("line {} column {}: {e}", e.line(), e.column()))?;
        let o = v
            .as_object()
            .ok_or_else(|| "not a JSON object".to_string())?;
        if o.get("myriad").and_then(Value::as_str) != Some("edits") {
            return Err("not a Myriad edits file (no \"myriad\": \"edits\")".into());
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
        let edits = |key: &str| -> Result<Vec<Edit>, String> {
            (list(o, key)?.iter().enumerate())
                .map(|(i, e)| Edit::from_json(e, &format!("{key}[{i}]")))
                .collect()
        };
        Ok(Layer {
            crs,
            edits: edits("edits")?,
            undone: edits("undone")?,
        })
    }

    /// The edits bound to a dataset's columns, ready to apply (`dir`: the folder of the edits
    /// file, where the surfaces they name are); an error names the edit whose filter asks for a
    /// column the dataset lacks, which sets classes it has none of, or whose surface is missing.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn compile(&self, schema: &Schema, dir: &Path) -> Result<Compiled, String> {
        self.compile_with(schema, &|name| {
            Surface::open(&dir.join(name))
                .map(Arc::new)
                .map_err(|e| e.to_string())
        })
    }

    /// [`Layer::compile`] with the surfaces ground edits name opened by `surface` (the web
    /// viewer reads them from its server).
    pub fn compile_with(
        &self,
        schema: &Schema,
        surface: &dyn Fn(&str) -> Result<Arc<Surface>, String>,
    ) -> Result<Compiled, String> {
        let edits = (self.edits.iter().enumerate())
            .map(|(i, e)| compile(e, schema, surface).map_err(|m| format!("edits[{i}]: {m}")))
            .collect::<Result<_, _>>()?;
        Ok(Compiled { edits })
    }
}

fn compile(
    e: &Edit,
    schema: &Schema,
    surface: &dyn Fn(&str) -> Result<Arc<Surface>, String>,
) -> Result<CompiledEdit, String> {
    let classes = schema.has(&myriad_core::Attribute::Classification);
    if !matches!(e.action, Action::Remove) && !classes {
        return Err("the dataset has no classes to set (remove points instead)".into());
    }
    Ok(CompiledEdit {
        region: e.region()?,
        bound: e.filter()?.bind(schema)?,
        surface: match &e.action {
            Action::Ground { surface: name, .. } => Some(surface(name)?),
            _ => None,
        },
        action: e.action.clone(),
    })
}

/// One edit bound to a dataset's columns.
#[derive(Debug)]
struct CompiledEdit {
    region: Option<Box<dyn Region>>,
    bound: Bound,
    /// The surface a ground edit reads.
    surface: Option<Arc<Surface>>,
    action: Action,
}

impl CompiledEdit {
    fn selects(&self, b: &PointBatch, i: usize) -> bool {
        self.region
            .as_ref()
            .is_none_or(|r| r.contains(b.positions[i]))
            && self.bound.keeps(b, i)
    }
}

/// A layer bound to a dataset's columns: what readers apply.
#[derive(Debug)]
pub struct Compiled {
    edits: Vec<CompiledEdit>,
}

impl myriad_format::edits::Edits for Compiled {
    fn ground(&self) -> Option<Arc<dyn myriad_core::ground::GroundHeight>> {
        let s = self.edits.iter().rev().find_map(|e| e.surface.clone())?;
        Some(s)
    }

    fn meets(&self, cube: &Aabb) -> bool {
        self.edits
            .iter()
            .any(|e| e.region.as_ref().is_none_or(|r| r.meets(cube)))
    }

    fn apply(&self, cube: &Aabb, b: &mut PointBatch) -> Result<Option<Vec<bool>>, String> {
        let n = b.len();
        let mut keep: Option<Vec<bool>> = None;
        for e in &self.edits {
            if !e.region.as_ref().is_none_or(|r| r.meets(cube)) {
                continue;
            }
            let chosen: Vec<usize> = (0..n)
                .filter(|&i| keep.as_ref().is_none_or(|k| k[i]) && e.selects(b, i))
                .collect();
            match &e.action {
                Action::Class(c) => {
                    if let Some(cl) = b.classification.as_mut() {
                        for i in chosen {
                            cl[i] = *c;
                        }
                    }
                }
                Action::Remove => {
                    let k = keep.get_or_insert_with(|| vec![true; n]);
                    for i in chosen {
                        k[i] = false;
                    }
                }
                Action::Ground { rule, .. } => {
                    let surface = e.surface.as_ref().expect("compiled with its surface");
                    ground(surface, rule, b, chosen)?;
                }
            }
        }
        if let Some(k) = &keep {
            b.retain_mask(k);
        }
        Ok(keep)
    }
}

/// A ground edit on the points `chosen` of `b`, tile by tile of the surface.
fn ground(
    surface: &Surface,
    rule: &Rule,
    b: &mut PointBatch,
    chosen: Vec<usize>,
) -> Result<(), String> {
    let Some(classes) = b.classification.as_mut() else {
        return Ok(());
    };
    let mut by_tile: Vec<(usize, usize)> = chosen
        .into_iter()
        .filter(|&i| !crate::ground::is_noise(classes[i]))
        .filter_map(|i| Some((surface.tile_of(b.positions[i][0], b.positions[i][1])?, i)))
        .collect();
    by_tile.sort_unstable();
    for run in by_tile.chunk_by(|a, c| a.0 == c.0) {
        let t = run[0].0;
        let Some(cells) = surface.tile(t)? else {
            continue;
        };
        for &(_, i) in run {
            let [x, y, z] = b.positions[i];
            if surface.is_isolated(x, y, z) {
                classes[i] = 7;
                continue;
            }
            if let Some(h) = surface.height(t, &cells, x, y)
                && let Some(c) = rule.class(classes[i], z - h.z, h.slope)
            {
                classes[i] = c;
            }
        }
    }
    Ok(())
}

/// A polygon in plan between two elevations.
#[derive(Debug)]
struct Prism {
    polygon: Polygon,
    z: [f64; 2],
}

impl Region for Prism {
    fn meets(&self, b: &Aabb) -> bool {
        b.min[2] <= self.z[1] && self.z[0] <= b.max[2] && self.polygon.meets(b)
    }
    fn contains(&self, p: [f64; 3]) -> bool {
        p[2] >= self.z[0] && p[2] <= self.z[1] && self.polygon.contains_xy(p[0], p[1])
    }
}

/// The spheres a brush painted, with their bounds (a point's test looks at the spheres whose
/// boxes hold it).
#[derive(Debug)]
struct Spheres {
    s: Vec<[f64; 4]>,
    bounds: Aabb,
}

impl Spheres {
    fn new(s: Vec<[f64; 4]>) -> Result<Spheres, String> {
        if s.is_empty() {
            return Err("a brush of no spheres".into());
        }
        if let Some(q) = s.iter().find(|q| !(q[3] > 0.0)) {
            return Err(format!("a brush sphere of radius {}: not positive", q[3]));
        }
        let mut bounds = Aabb::EMPTY;
        for q in &s {
            bounds.extend([q[0] - q[3], q[1] - q[3], q[2] - q[3]]);
            bounds.extend([q[0] + q[3], q[1] + q[3], q[2] + q[3]]);
        }
        Ok(Spheres { s, bounds })
    }
}

impl Region for Spheres {
    fn meets(&self, b: &Aabb) -> bool {
        Region::meets(&self.bounds, b)
            && self.s.iter().any(|q| {
                let d2: f64 = (0..3)
                    .map(|a| (q[a] - q[a].clamp(b.min[a], b.max[a])).powi(2))
                    .sum();
                d2 <= q[3] * q[3]
            })
    }
    fn contains(&self, p: [f64; 3]) -> bool {
        Aabb::contains(&self.bounds, p)
            && self.s.iter().any(|q| {
                let d2: f64 = (0..3).map(|a| (p[a] - q[a]).powi(2)).sum();
                d2 <= q[3] * q[3]
            })
    }
}

/// The edits of the dataset at `dataset`, read from [`sidecar_for`] it (`None`: no file, or no
/// edit in it); an error names the file. What [`install`] gives the dataset reader.
#[cfg(not(target_arch = "wasm32"))]
pub fn load(
    dataset: &Path,
    meta: &myriad_format::Metadata,
) -> myriad_core::Result<Option<Compiled>> {
    let schema = &meta.schema;
    let file = sidecar_for(dataset);
    let Some(layer) = read(&file)? else {
        return Ok(None);
    };
    if layer.edits.is_empty() {
        return Ok(None);
    }
    if let Some(i) = refused_removal(&layer, meta) {
        return Err(myriad_core::Error::Invalid(format!(
            "{}: edits[{i}]: {}",
            file.display(),
            NO_REMOVAL
        )));
    }
    let dir = file.parent().unwrap_or(Path::new("."));
    let c = layer
        .compile(schema, dir)
        .map_err(|m| myriad_core::Error::Invalid(format!("{}: {m}", file.display())))?;
    Ok(Some(c))
}

/// Why an mwkd dataset's points cannot be removed.
pub const NO_REMOVAL: &str = "an mwkd dataset's points cannot be removed (its splats are made \
    of them): reclassify them, or extract and convert";

/// The first edit that removes points where the dataset cannot lose any (mwkd: its splat pages
/// hold a splat per stored point).
pub fn refused_removal(layer: &Layer, meta: &myriad_format::Metadata) -> Option<usize> {
    (meta.structure == "mwkd")
        .then(|| layer.edits.iter().position(|e| e.action == Action::Remove))
        .flatten()
}

/// The layer in `file` (`None`: no such file); an error names the file and the line or edit.
pub fn read(file: &Path) -> myriad_core::Result<Option<Layer>> {
    let text = match std::fs::read(file) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(myriad_core::Error::io(file, e)),
        Ok(b) if b.len() > MAX_BYTES => {
            return Err(myriad_core::Error::Invalid(format!(
                "{}: larger than {MAX_BYTES} bytes",
                file.display()
            )));
        }
        Ok(b) => b,
    };
    let text = String::from_utf8(text).map_err(|e| {
        myriad_core::Error::Invalid(format!(
            "{}: byte {}: not UTF-8 text",
            file.display(),
            e.utf8_error().valid_up_to()
        ))
    })?;
    Layer::parse(&text)
        .map(Some)
        .map_err(|m| myriad_core::Error::Invalid(format!("{}: {m}", file.display())))
}

/// Makes every dataset this program opens from disk carry the edits kept beside it.
#[cfg(not(target_arch = "wasm32"))]
pub fn install() {
    myriad_format::edits::set_loader(|path, meta| {
        Ok(load(path, meta)?
            .map(|c| std::sync::Arc::new(c) as std::sync::Arc<dyn myriad_format::edits::Edits>))
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_core::Attribute;
    use myriad_format::edits::Edits;

    fn batch() -> PointBatch {
        let s = Schema::new(vec![Attribute::Classification, Attribute::Intensity]);
        let mut b = PointBatch::with_schema(&s, 4);
        for (i, p) in [
            [1.0, 1.0, 0.0],
            [5.0, 5.0, 0.0],
            [5.0, 5.0, 10.0],
            [20.0, 1.0, 0.0],
        ]
        .iter()
        .enumerate()
        {
            b.positions.push(*p);
            b.classification.as_mut().unwrap().push(1);
            b.intensity.as_mut().unwrap().push(10 * i as u16);
        }
        b
    }

    fn square() -> Vec<[f64; 2]> {
        vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]
    }

    #[test]
    fn edits_apply_in_order_and_round_trip() {
        let mut layer = Layer::default();
        layer.push(Edit {
            area: Area::Polygon {
                ring: square(),
                z: Some([-1.0, 1.0]),
            },
            classes: None,
            wheres: vec![],
            action: Action::Class(7),
        });
        // Sees the class the first set: removes the two low points in the square.
        layer.push(Edit {
            area: Area::All,
            classes: Some("7".into()),
            wheres: vec!["intensity>5".into()],
            action: Action::Remove,
        });
        layer.push(Edit {
            area: Area::Brush(vec![[20.0, 1.0, 0.0, 0.5]]),
            classes: None,
            wheres: vec![],
            action: Action::Class(2),
        });
        let back = Layer::parse(&layer.to_json()).unwrap();
        assert_eq!(back, layer);
        let b0 = batch();
        let c = back.compile(&b0.schema(), Path::new(".")).unwrap();
        let mut b = b0.clone();
        let cube = Aabb::new([0.0; 3], [32.0; 3]);
        let keep = c.apply(&cube, &mut b).unwrap().unwrap();
        assert_eq!(keep, vec![true, false, true, true]);
        assert_eq!(b.classification.as_deref(), Some(&[7, 1, 2][..]));
        assert_eq!(b.positions[1], [5.0, 5.0, 10.0]);
        // Undo the brush and the removal: nothing removed, two points in class 7.
        let mut l = back.clone();
        l.undo();
        assert_eq!(l.undo().map(|e| e.action.clone()), Some(Action::Remove));
        let mut b = b0.clone();
        assert!(
            l.compile(&b0.schema(), Path::new("."))
                .unwrap()
                .apply(&cube, &mut b)
                .unwrap()
                .is_none()
        );
        assert_eq!(b.classification.as_deref(), Some(&[7, 7, 1, 1][..]));
        assert_eq!(Layer::parse(&l.to_json()).unwrap(), l);
        l.redo();
        l.redo();
        assert_eq!(l, back);
        assert!(l.redo().is_none());
        // A box far away does not meet the cube.
        let mut far = Layer::default();
        far.push(Edit {
            area: Area::Box(Aabb::new([100.0; 3], [101.0; 3])),
            classes: None,
            wheres: vec![],
            action: Action::Remove,
        });
        assert!(
            !far.compile(&b0.schema(), Path::new("."))
                .unwrap()
                .meets(&cube)
        );
    }

    #[test]
    fn bad_edits_are_named() {
        let bad = |edit: &str| {
            Layer::parse(&format!(
                r#"{{"myriad":"edits","version":1,"edits":[{{"to":1}},{edit}]}}"#
            ))
            .unwrap_err()
        };
        assert!(
            bad(r#"{"polygon":[[0,0],[1,1],[0,1],[1,0]],"to":2}"#)
                .contains("edits[1]: --polygon: it crosses itself")
        );
        assert!(bad(r#"{"polygon":[[0,0],[1,1]],"to":2}"#).contains("at least 3"));
        assert!(bad(r#"{"to":256}"#).contains("edits[1].to"));
        assert!(bad(r#"{"box":[[1,1,1],[0,0,0]],"remove":true}"#).contains("lowest"));
        assert!(bad(r#"{"where":["nosuch>1"],"to":1,"remove":true}"#).contains("both"));
        assert!(bad(r#"{"brush":[[0,0,0,-1]],"to":1}"#).contains("radius"));
        assert!(bad(r#"{"polygon":[[0,0],[1e13,0],[0,1]],"to":1}"#).contains("beyond"));
        // A column the dataset lacks is named when the edits are bound to it.
        let l = Layer::parse(
            r#"{"myriad":"edits","version":1,"edits":[{"where":["gps_time>1"],"remove":true}]}"#,
        )
        .unwrap();
        assert!(
            l.compile(&batch().schema(), Path::new("."))
                .unwrap_err()
                .starts_with("edits[0]:")
        );
    }
}
