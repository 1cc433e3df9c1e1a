//! The dataset's metadata: what it holds (structure, counts, bounds, quantization, CRS,
//! schema, sources, the input's LAS header, the per-level table), stored as JSON after the node
//! pages.

use crate::NodeEntry;
use crate::page::Quantization;
use myriad_core::{Aabb, Attribute, ExtraDim, ExtraType, Schema};
use serde_json::{Value, json};
use std::collections::BTreeMap;

/// What the dataset holds, stored as JSON after the node pages.
#[derive(Debug, Clone, PartialEq)]
pub struct Metadata {
    /// The hierarchy's kind, e.g. "nested-octree", and its parameters.
    pub structure: String,
    pub parameters: Value,
    pub points: u64,
    pub nodes: u64,
    /// Deepest node level.
    pub depth: u32,
    /// Bounds of the points.
    pub bounds: Aabb,
    /// The root node's cube.
    pub root: Aabb,
    pub quantization: Quantization,
    /// OGC WKT (or "EPSG:n").
    pub crs: Option<String>,
    pub schema: Schema,
    /// The inputs: path, format, points taken from each.
    pub sources: Vec<Value>,
    /// A LAS header (with its VLRs) of the input, so that extraction writes the input's point
    /// format, version and VLRs; `None` when no input was LAS/LAZ.
    pub las_header: Option<Vec<u8>>,
    pub software: String,
    /// Nodes and points per level, written by [`DatasetWriter::finish`] so that whole-dataset
    /// statistics need no walk of the hierarchy; empty in datasets written before it was.
    pub levels: Vec<Level>,
    /// Files other than the dataset's own that hold some of its node pages (a merge's parts):
    /// empty for a dataset of one file. See [`crate::linked`].
    pub files: Vec<crate::linked::LinkedFile>,
}

/// One level of the hierarchy: its nodes, their points (aggregates included), and the finest
/// spacing of a node's first level of detail there (infinite: no node with points).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Level {
    pub level: u32,
    pub nodes: u64,
    pub points: u64,
    pub spacing: f64,
}

impl Level {
    /// The table of `entries`, by level.
    pub fn table<'a>(entries: impl IntoIterator<Item = &'a NodeEntry>) -> Vec<Level> {
        let mut by: BTreeMap<u32, Level> = BTreeMap::new();
        for e in entries {
            let l = by.entry(e.key.level).or_insert(Level {
                level: e.key.level,
                nodes: 0,
                points: 0,
                spacing: f64::INFINITY,
            });
            l.nodes += 1;
            l.points += e.points as u64;
            if let Some(&s) = e.spacing.first() {
                l.spacing = l.spacing.min(s);
            }
        }
        by.into_values().collect()
    }
}

fn aabb_json(b: &Aabb) -> Value {
    json!({"min": b.min, "max": b.max})
}

fn schema_json(s: &Schema) -> Value {
    let mut names = Vec::new();
    let mut extra = Vec::new();
    for a in &s.attributes {
        match a {
            Attribute::Extra(d) => {
                let (code, len) = d.data_type.las_code();
                extra.push(json!({
                    "name": d.name, "type": code, "bytes": len, "offset": d.offset,
                    "description": d.description, "scale": d.scale, "add_offset": d.add_offset,
                }));
            }
            a => names.push(Value::from(a.name())),
        }
    }
    json!({"attributes": names, "extra_bytes": s.extra_bytes, "extra_dims": extra})
}

impl Metadata {
    pub fn to_json(&self) -> Value {
        let q = &self.quantization;
        let mut v = json!({
            "structure": self.structure,
            "parameters": self.parameters,
            "points": self.points,
            "nodes": self.nodes,
            "depth": self.depth,
            "bounds": aabb_json(&self.bounds),
            "root": aabb_json(&self.root),
            "scale": q.scale,
            "offset": q.offset,
            "crs": self.crs,
            "schema": schema_json(&self.schema),
            "sources": self.sources,
            "las_header": self.las_header.as_deref().map(myriad_core::units::hex),
            "software": self.software,
            "levels": self.levels.iter().map(|l| json!({
                "level": l.level, "nodes": l.nodes, "points": l.points,
                "spacing": l.spacing.is_finite().then_some(l.spacing),
            })).collect::<Vec<_>>(),
        });
        // Absent from datasets of one file, as before there were others.
        if !self.files.is_empty() {
            v["files"] = self.files.iter().map(|f| f.to_json()).collect();
        }
        v
    }

    /// Every number that JSON must carry is finite (JSON has no NaN or infinity: serde_json
    /// writes them as null, which would leave a dataset that does not open). Names the field.
    pub fn check_finite(&self) -> std::result::Result<(), String> {
        let q = &self.quantization;
        let fields = [
            ("bounds.min", self.bounds.min),
            ("bounds.max", self.bounds.max),
            ("root.min", self.root.min),
            ("root.max", self.root.max),
            ("scale", q.scale),
            ("offset", q.offset),
        ];
        for (name, v) in fields {
            if v.iter().any(|c| !c.is_finite()) {
                return Err(format!("{name} is {v:?}, not finite"));
            }
        }
        if q.scale.iter().any(|s| *s <= 0.0) {
            return Err(format!("scale is {:?}, not positive", q.scale));
        }
        for a in &self.schema.attributes {
            if let Attribute::Extra(d) = a
                && [d.scale, d.add_offset]
                    .iter()
                    .flatten()
                    .any(|v| !v.is_finite())
            {
                return Err(format!(
                    "extra dimension \"{}\" has a scale or offset that is not finite",
                    d.name
                ));
            }
        }
        Ok(())
    }

    pub fn from_json(v: &Value) -> std::result::Result<Metadata, String> {
        let field = |k: &str| v.get(k).ok_or_else(|| format!("metadata lacks \"{k}\""));
        let f3 = |x: &Value| -> std::result::Result<[f64; 3], String> {
            let a = x
                .as_array()
                .filter(|a| a.len() == 3)
                .ok_or("expected 3 numbers")?;
            let mut out = [0.0; 3];
            for (o, e) in out.iter_mut().zip(a) {
                *o = e.as_f64().ok_or("expected a number")?;
            }
            Ok(out)
        };
        let aabb = |k: &str| -> std::result::Result<Aabb, String> {
            let b = field(k)?;
            Ok(Aabb::new(
                f3(b.get("min").ok_or("no min")?)?,
                f3(b.get("max").ok_or("no max")?)?,
            ))
        };
        let u = |k: &str| {
            field(k)?
                .as_u64()
                .ok_or_else(|| format!("\"{k}\" is not a count"))
        };
        let s = field("schema")?;
        let mut attributes = Vec::new();
        for n in s["attributes"]
            .as_array()
            .ok_or("schema has no attributes")?
        {
            let name = n.as_str().ok_or("attribute name is not a string")?;
            attributes.push(
                Attribute::from_name(name).ok_or_else(|| format!("unknown attribute {name}"))?,
            );
        }
        for d in s["extra_dims"]
            .as_array()
            .ok_or("schema has no extra_dims")?
        {
            let code = d["type"].as_u64().unwrap_or(u64::MAX) as u8;
            let len = d["bytes"].as_u64().unwrap_or(0) as u8;
            attributes.push(Attribute::Extra(ExtraDim {
                name: d["name"].as_str().unwrap_or_default().to_string(),
                data_type: ExtraType::from_las_code(code, len).ok_or("bad extra dimension type")?,
                offset: d["offset"].as_u64().unwrap_or(0) as usize,
                description: d["description"].as_str().unwrap_or_default().to_string(),
                scale: d["scale"].as_f64(),
                add_offset: d["add_offset"].as_f64(),
            }));
        }
        let mut levels = Vec::new();
        for l in v
            .get("levels")
            .and_then(|l| l.as_array())
            .into_iter()
            .flatten()
        {
            let n = |k: &str| l.get(k).and_then(|x| x.as_u64()).ok_or("levels: bad entry");
            levels.push(Level {
                level: n("level")? as u32,
                nodes: n("nodes")?,
                points: n("points")?,
                spacing: l["spacing"].as_f64().unwrap_or(f64::INFINITY),
            });
        }
        let scale = f3(field("scale")?)?;
        if scale.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return Err("scale must be positive".into());
        }
        Ok(Metadata {
            structure: field("structure")?.as_str().unwrap_or_default().to_string(),
            parameters: field("parameters")?.clone(),
            points: u("points")?,
            nodes: u("nodes")?,
            depth: u("depth")? as u32,
            bounds: aabb("bounds")?,
            root: aabb("root")?,
            quantization: Quantization {
                scale,
                offset: f3(field("offset")?)?,
            },
            crs: v.get("crs").and_then(|c| c.as_str()).map(str::to_string),
            schema: Schema {
                attributes,
                extra_bytes: s["extra_bytes"].as_u64().unwrap_or(0) as usize,
            },
            sources: v
                .get("sources")
                .and_then(|s| s.as_array())
                .cloned()
                .unwrap_or_default(),
            las_header: match v.get("las_header").and_then(|h| h.as_str()) {
                Some(h) => Some(myriad_core::units::unhex(h).ok_or("las_header is not hex")?),
                None => None,
            },
            software: v
                .get("software")
                .and_then(|s| s.as_str())
                .unwrap_or_default()
                .to_string(),
            levels,
            files: match v.get("files") {
                Some(f) => (f.as_array().ok_or("files is not a list")?.iter())
                    .map(crate::linked::LinkedFile::from_json)
                    .collect::<std::result::Result<_, _>>()?,
                None => Vec::new(),
            },
        })
    }
}
