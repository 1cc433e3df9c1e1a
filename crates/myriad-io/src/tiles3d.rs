//! A 3D Tiles writer (what CesiumJS, Cesium for Unreal, ArcGIS and 3d-tiles-renderer open): a
//! folder with `tileset.json` and `tiles/`, one tile per octree node, refined by adding points.
//!
//! - 3D Tiles 1.1 (the default): each tile's content is a binary glTF (`NAME.glb`) of one
//!   point primitive: `POSITION` (float32, relative to the tile's centre, which is the glTF
//!   node's translation), `COLOR_0` (RGBA8, normalized) where the points have colours, and
//!   `_INTENSITY` and `_CLASSIFICATION` (float32: every vertex attribute's element 4-byte
//!   aligned, as glTF asks, and the values exact) declared as property attributes of the class
//!   `point` by `EXT_structural_metadata`. glTF is y-up: a tile's (x, y, z) is written
//!   (x, z, -y), which clients turn back.
//! - 3D Tiles 1.0 (`Version::V1_0`): `NAME.pnts`, positions float32 from the feature table's
//!   `RTC_CENTER`, `RGB` (u8 x 3), and the batch table's `intensity` (u16) and `classification`
//!   (u8).
//!
//! Coordinates: every point moves from the dataset's CRS to Earth-centred ones (EPSG:4978,
//! through PROJ, on all cores), then into the east-north-up frame of the dataset's centre; the
//! root tile's `transform` places that frame on the globe. Bounding volumes are boxes in that
//! frame: each tile's holds its own points and every child's box. Geometric errors are the
//! nodes' point spacing in metres (the root's, halved per level; 0 for leaves); the tileset's
//! is its box's diagonal. Nodes `SUB_LEVELS` levels apart start external tilesets
//! (`tiles/NAME.json`), so that no JSON file grows with the dataset. Node names are Potree's:
//! `r`, then each level's child index 4x + 2y + z.

use crate::atomic::AtomicDir;
use crate::proj::Pool;
use myriad_core::{Aabb, Attribute, Error, NodeKey, PointBatch, Result, Schema};
use rayon::prelude::*;
use serde_json::{Value, json};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// Levels per tileset file: a node this many levels below its file's root starts its own.
pub const SUB_LEVELS: u32 = 6;

/// Which 3D Tiles: 1.1 (glTF contents) or 1.0 (.pnts).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Version {
    V1_0,
    V1_1,
}

impl Version {
    pub fn parse(s: &str) -> std::result::Result<Version, String> {
        match s {
            "1.0" => Ok(Version::V1_0),
            "1.1" => Ok(Version::V1_1),
            _ => Err(format!("\"{s}\": expected 1.0 or 1.1")),
        }
    }

    fn extension(self) -> &'static str {
        match self {
            Version::V1_0 => "pnts",
            Version::V1_1 => "glb",
        }
    }
}

/// Where the octree lies.
#[derive(Debug, Clone)]
pub struct Frame {
    /// The root node's cube, in the dataset's CRS.
    pub cube: Aabb,
    /// A point of the data (the centre of its bounds): the local frame's origin.
    pub centre: [f64; 3],
    /// Point spacing of the root, in the dataset's units.
    pub spacing: f64,
    /// The dataset's CRS (WKT, EPSG:n, a PROJ string).
    pub crs: String,
}

/// What [`TilesSink::finish`] wrote.
#[derive(Debug, Clone, Default)]
pub struct TilesSummary {
    pub points: u64,
    /// Tiles with content.
    pub tiles: u64,
    /// Tileset files (tileset.json and the external ones).
    pub tilesets: u64,
    pub bytes: u64,
    /// Points that did not move into Earth-centred coordinates, left out.
    pub not_transformed: u64,
}

#[derive(Debug, Clone, Copy)]
struct Tile {
    points: u32,
    /// The points' box in the local frame.
    bounds: Aabb,
}

impl Default for Tile {
    fn default() -> Tile {
        Tile {
            points: 0,
            bounds: Aabb::EMPTY,
        }
    }
}

/// WGS 84, for the local frame's up (the ellipsoid's normal).
const A: f64 = 6_378_137.0;
const F: f64 = 1.0 / 298.257_223_563;

/// Geodetic longitude and latitude (radians) of an Earth-centred point.
fn geodetic(p: [f64; 3]) -> (f64, f64) {
    let e2 = F * (2.0 - F);
    let lon = p[1].atan2(p[0]);
    let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
    let mut lat = p[2].atan2(r * (1.0 - e2));
    for _ in 0..6 {
        let n = A / (1.0 - e2 * lat.sin().powi(2)).sqrt();
        let h = r / lat.cos() - n;
        lat = p[2].atan2(r * (1.0 - e2 * n / (n + h)));
    }
    (lon, lat)
}

/// East, north and up at `p` (Earth-centred unit vectors).
fn east_north_up(p: [f64; 3]) -> [[f64; 3]; 3] {
    let (lon, lat) = geodetic(p);
    let (so, co) = lon.sin_cos();
    let (sa, ca) = lat.sin_cos();
    [
        [-so, co, 0.0],
        [-sa * co, -sa * so, ca],
        [ca * co, ca * so, sa],
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Potree's name of a node: `r` and the child index of each level.
pub fn node_name(k: NodeKey) -> String {
    let mut s = String::with_capacity(1 + k.level as usize);
    s.push('r');
    for l in (0..k.level).rev() {
        let shift = l;
        let c = (0..3).fold(0, |m, a| m | (((k.cell[a] >> shift) & 1) << (2 - a)));
        s.push(char::from(b'0' + c as u8));
    }
    s
}

/// Whether `dir` holds a 3D Tiles export only (tileset.json and tiles/ of tiles and tilesets).
fn is_tiles(dir: &Path) -> bool {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return false;
    };
    entries.flatten().all(|e| match e.file_name().to_str() {
        Some("tileset.json") => true,
        Some("tiles") => std::fs::read_dir(e.path()).is_ok_and(|t| {
            t.flatten().all(|f| {
                let n = f.file_name().to_string_lossy().into_owned();
                [".glb", ".pnts", ".json"].iter().any(|x| n.ends_with(x))
            })
        }),
        _ => false,
    })
}

/// Streams the nodes of an octree into a 3D Tiles folder.
pub struct TilesSink {
    dir: AtomicDir,
    version: Version,
    pool: Pool,
    /// The local frame: its origin (Earth-centred) and east, north, up.
    origin: [f64; 3],
    axes: [[f64; 3]; 3],
    /// Metres per dataset unit along the ground, at the centre.
    metres: f64,
    spacing: f64,
    intensity: bool,
    classification: bool,
    tiles: BTreeMap<NodeKey, Tile>,
    bytes: u64,
    not_transformed: u64,
    path: PathBuf,
}

impl TilesSink {
    /// Returns the sink and what it cannot keep of `schema`.
    pub fn create(
        dir: &Path,
        schema: &Schema,
        frame: Frame,
        version: Version,
        force: bool,
    ) -> Result<(TilesSink, Vec<String>)> {
        let fail = |m: String| Error::unsupported(dir, m);
        let pool = Pool::new(&frame.crs, "EPSG:4978").map_err(fail)?;
        let c = frame.centre;
        let step = (frame.cube.size()[0] / 1e3).max(1e-9);
        let (origin, east) = {
            let mut t = pool.get();
            let o = t.point(c);
            let e = t.point([c[0] + step, c[1], c[2]]);
            match (o, e) {
                (Some(o), Some(e)) => (o, e),
                _ => {
                    return Err(fail(format!(
                        "the dataset's centre {c:?} does not move into Earth-centred \
                         coordinates (EPSG:4978)"
                    )));
                }
            }
        };
        let metres = (0..3)
            .map(|a| (east[a] - origin[a]).powi(2))
            .sum::<f64>()
            .sqrt()
            / step;
        let lost: Vec<String> = schema
            .attributes
            .iter()
            .filter(|a| {
                !matches!(
                    a,
                    Attribute::Rgb | Attribute::Intensity | Attribute::Classification
                )
            })
            .map(|a| a.name())
            .collect();
        let lost = if lost.is_empty() {
            vec![]
        } else {
            vec![format!(
                "{} (3D Tiles point clouds carry colours, intensity and classification)",
                lost.join(", ")
            )]
        };
        let ad = AtomicDir::create(dir, force, is_tiles, "a 3D Tiles folder")?;
        let tiles = ad.temp().join("tiles");
        std::fs::create_dir_all(&tiles).map_err(|e| Error::io(&tiles, e))?;
        Ok((
            TilesSink {
                dir: ad,
                version,
                pool,
                origin,
                axes: east_north_up(origin),
                metres,
                spacing: frame.spacing,
                intensity: schema.has(&Attribute::Intensity),
                classification: schema.has(&Attribute::Classification),
                tiles: BTreeMap::new(),
                bytes: 0,
                not_transformed: 0,
                path: dir.to_path_buf(),
            },
            lost,
        ))
    }

    /// Moves, encodes and writes `nodes` on all cores.
    pub fn write_nodes(&mut self, nodes: &[(NodeKey, PointBatch)]) -> Result<()> {
        for (key, batch) in nodes {
            if !batch.is_consistent() || self.tiles.contains_key(key) {
                return Err(Error::Invalid(format!(
                    "{}: node {key:?} written twice or inconsistent",
                    self.path.display()
                )));
            }
        }
        let folder = self.dir.temp().join("tiles");
        let written: Vec<Result<(NodeKey, Tile, u64, u64)>> = nodes
            .par_iter()
            .filter(|(_, b)| !b.is_empty())
            .map(|(key, b)| {
                let mut local = b.positions.clone();
                let failed = self.pool.get().apply(&mut local);
                // The points that did not transform (NaN) left out, the batch copied only then.
                let b = if failed > 0 {
                    let keep: Vec<bool> = local.iter().map(|p| p[0].is_finite()).collect();
                    local.retain(|p| p[0].is_finite());
                    let mut kept = b.clone();
                    kept.retain_mask(&keep);
                    std::borrow::Cow::Owned(kept)
                } else {
                    std::borrow::Cow::Borrowed(b)
                };
                let mut bounds = Aabb::EMPTY;
                for p in local.iter_mut() {
                    let d: [f64; 3] = std::array::from_fn(|a| p[a] - self.origin[a]);
                    *p = self.axes.map(|axis| dot(axis, d));
                    bounds.extend(*p);
                }
                let tile = Tile {
                    points: local.len() as u32,
                    bounds,
                };
                if local.is_empty() {
                    return Ok((*key, tile, 0, failed as u64));
                }
                let centre: [f64; 3] =
                    std::array::from_fn(|a| (bounds.min[a] + bounds.max[a]) / 2.0);
                let bytes = match self.version {
                    Version::V1_1 => self.glb(&b, &local, centre),
                    Version::V1_0 => self.pnts(&b, &local, centre),
                };
                let path = folder.join(format!("{}.{}", node_name(*key), self.version.extension()));
                std::fs::write(&path, &bytes).map_err(|e| Error::io(&path, e))?;
                Ok((*key, tile, bytes.len() as u64, failed as u64))
            })
            .collect();
        for w in written {
            let (key, tile, bytes, failed) = w?;
            self.bytes += bytes;
            self.not_transformed += failed;
            if tile.points > 0 {
                self.tiles.insert(key, tile);
            }
        }
        Ok(())
    }

    /// RGBA8 of the batch's colours (8-bit values in 16-bit fields taken as they are).
    fn colours(b: &PointBatch) -> Option<Vec<[u8; 4]>> {
        b.rgb.as_ref()?;
        Some(myriad_core::colour::colours(
            b,
            b.len(),
            myriad_core::colour::ColorBy::Rgb,
            (0.0, 1.0),
            0,
        ))
    }

    /// A binary glTF of the points (`local`: their places in the local frame).
    fn glb(&self, b: &PointBatch, local: &[[f64; 3]], centre: [f64; 3]) -> Vec<u8> {
        let n = local.len();
        let mut bin: Vec<u8> = Vec::with_capacity(n * 24);
        let mut views = Vec::new();
        let mut accessors = Vec::new();
        let mut attributes = serde_json::Map::new();
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for p in local {
            // y-up: (x, y, z) is written (x, z, -y).
            let q = [
                (p[0] - centre[0]) as f32,
                (p[2] - centre[2]) as f32,
                -(p[1] - centre[1]) as f32,
            ];
            for a in 0..3 {
                lo[a] = lo[a].min(q[a]);
                hi[a] = hi[a].max(q[a]);
                bin.extend_from_slice(&q[a].to_le_bytes());
            }
        }
        let mut view = |bin: &Vec<u8>, start: usize| {
            views.push(json!({"buffer": 0, "byteOffset": start, "byteLength": bin.len() - start, "target": 34962}));
            views.len() - 1
        };
        let v = view(&bin, 0);
        accessors.push(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi}));
        attributes.insert("POSITION".into(), json!(0));
        if let Some(c) = Self::colours(b) {
            let start = bin.len();
            for rgba in &c {
                bin.extend_from_slice(rgba);
            }
            let v = view(&bin, start);
            accessors.push(json!({"bufferView": v, "componentType": 5121, "normalized": true, "count": n, "type": "VEC4"}));
            attributes.insert("COLOR_0".into(), json!(accessors.len() - 1));
        }
        let mut properties = serde_json::Map::new();
        let mut scalar = |name: &str, values: Vec<f32>, bin: &mut Vec<u8>| {
            let start = bin.len();
            for x in values {
                bin.extend_from_slice(&x.to_le_bytes());
            }
            let v = view(bin, start);
            accessors.push(
                json!({"bufferView": v, "componentType": 5126, "count": n, "type": "SCALAR"}),
            );
            let attr = format!("_{}", name.to_ascii_uppercase());
            attributes.insert(attr.clone(), json!(accessors.len() - 1));
            properties.insert(name.into(), json!({"attribute": attr}));
        };
        if let (true, Some(i)) = (self.intensity, &b.intensity) {
            scalar("intensity", i.iter().map(|&x| x as f32).collect(), &mut bin);
        }
        if let (true, Some(c)) = (self.classification, &b.classification) {
            scalar(
                "classification",
                c.iter().map(|&x| x as f32).collect(),
                &mut bin,
            );
        }
        let mut primitive = json!({"mode": 0, "attributes": attributes});
        let mut gltf = json!({
            "asset": {"version": "2.0", "generator": concat!("Myriad ", env!("CARGO_PKG_VERSION"))},
            "scene": 0,
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0, "translation": [centre[0], centre[2], -centre[1]]}],
            "accessors": accessors,
            "bufferViews": views,
            "buffers": [{"byteLength": bin.len()}],
        });
        if !properties.is_empty() {
            let class: serde_json::Map<String, Value> = properties
                .keys()
                .map(|k| {
                    (
                        k.clone(),
                        json!({"type": "SCALAR", "componentType": "FLOAT32"}),
                    )
                })
                .collect();
            primitive["extensions"] =
                json!({"EXT_structural_metadata": {"propertyAttributes": [0]}});
            gltf["extensionsUsed"] = json!(["EXT_structural_metadata"]);
            gltf["extensions"] = json!({"EXT_structural_metadata": {
                "schema": {"id": "myriad", "classes": {"point": {"properties": class}}},
                "propertyAttributes": [{"class": "point", "properties": properties}],
            }});
        }
        gltf["meshes"] = json!([{"primitives": [primitive]}]);
        crate::mesh::glb(&gltf, bin)
    }

    /// A .pnts tile of the points (3D Tiles 1.0).
    fn pnts(&self, b: &PointBatch, local: &[[f64; 3]], centre: [f64; 3]) -> Vec<u8> {
        let n = local.len();
        let mut ft_bin: Vec<u8> = Vec::with_capacity(n * 15);
        for p in local {
            for a in 0..3 {
                ft_bin.extend_from_slice(&((p[a] - centre[a]) as f32).to_le_bytes());
            }
        }
        let mut ft =
            json!({"POINTS_LENGTH": n, "RTC_CENTER": centre, "POSITION": {"byteOffset": 0}});
        if let Some(c) = Self::colours(b) {
            ft["RGB"] = json!({"byteOffset": ft_bin.len()});
            for rgba in &c {
                ft_bin.extend_from_slice(&rgba[..3]);
            }
        }
        let mut bt = serde_json::Map::new();
        let mut bt_bin: Vec<u8> = Vec::new();
        if let (true, Some(i)) = (self.intensity, &b.intensity) {
            bt.insert(
                "intensity".into(),
                json!({"byteOffset": 0, "componentType": "UNSIGNED_SHORT", "type": "SCALAR"}),
            );
            for x in i {
                bt_bin.extend_from_slice(&x.to_le_bytes());
            }
        }
        if let (true, Some(c)) = (self.classification, &b.classification) {
            bt.insert(
                "classification".into(),
                json!({"byteOffset": bt_bin.len(), "componentType": "UNSIGNED_BYTE", "type": "SCALAR"}),
            );
            bt_bin.extend_from_slice(c);
        }
        // Each part padded to 8 bytes (JSON with spaces), from the 28-byte header on.
        let json_part = |v: &Value, at: usize| {
            let mut t = serde_json::to_vec(v).expect("JSON of numbers and strings");
            while !(at + t.len()).is_multiple_of(8) {
                t.push(b' ');
            }
            t
        };
        let pad = |mut v: Vec<u8>| {
            while !v.len().is_multiple_of(8) {
                v.push(0);
            }
            v
        };
        let ft_json = json_part(&ft, 28);
        let ft_bin = pad(ft_bin);
        let (bt_json, bt_bin) = if bt.is_empty() {
            (vec![], vec![])
        } else {
            (json_part(&Value::Object(bt), 0), pad(bt_bin))
        };
        let total = 28 + ft_json.len() + ft_bin.len() + bt_json.len() + bt_bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"pnts");
        for x in [
            1,
            total,
            ft_json.len(),
            ft_bin.len(),
            bt_json.len(),
            bt_bin.len(),
        ] {
            out.extend_from_slice(&(x as u32).to_le_bytes());
        }
        for part in [ft_json, ft_bin, bt_json, bt_bin] {
            out.extend_from_slice(&part);
        }
        out
    }

    /// Writes tileset.json (and the external tilesets), then moves the folder to its name.
    pub fn finish(self) -> Result<TilesSummary> {
        let all = crate::with_ancestors(&self.tiles);
        // Each tile's box: its points' and its children's (parents come first in key order).
        let mut boxes: HashMap<NodeKey, Aabb> = all.iter().map(|(k, t)| (*k, t.bounds)).collect();
        let mut children: HashMap<NodeKey, Vec<NodeKey>> = HashMap::new();
        for k in all.keys().rev().filter(|k| k.level > 0) {
            let b = boxes[k];
            let parent = boxes.get_mut(&k.parent()).expect("ancestors are there");
            for a in 0..3 {
                parent.min[a] = parent.min[a].min(b.min[a]);
                parent.max[a] = parent.max[a].max(b.max[a]);
            }
            if !b.is_empty() {
                children.entry(k.parent()).or_default().push(*k);
            }
        }
        for v in children.values_mut() {
            v.sort();
        }
        let root_box = boxes[&NodeKey::ROOT];
        let mut out = Writer {
            sink: &self,
            all: &all,
            boxes: &boxes,
            children: &children,
            files: 0,
            bytes: 0,
        };
        let folder = self.dir.temp().to_path_buf();
        if !root_box.is_empty() {
            let mut root = out.tile(NodeKey::ROOT, "tiles/", true)?;
            let [e, n, u] = self.axes;
            let o = self.origin;
            root["transform"] = json!([
                e[0], e[1], e[2], 0.0, n[0], n[1], n[2], 0.0, u[0], u[1], u[2], 0.0, o[0], o[1],
                o[2], 1.0
            ]);
            let d = root_box.size();
            let diagonal = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            out.write(&folder.join("tileset.json"), root, diagonal.max(1.0))?;
        } else {
            // Nothing selected: an empty tileset CesiumJS still opens.
            let root = json!({
                "boundingVolume": {"box": [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1]},
                "geometricError": 0.0, "refine": "ADD",
            });
            out.write(&folder.join("tileset.json"), root, 0.0)?;
        }
        let summary = TilesSummary {
            points: self.tiles.values().map(|t| t.points as u64).sum(),
            tiles: self.tiles.len() as u64,
            tilesets: out.files,
            bytes: self.bytes + out.bytes,
            not_transformed: self.not_transformed,
        };
        self.dir.commit()?;
        Ok(summary)
    }
}

/// Writes the tileset files of [`TilesSink::finish`].
struct Writer<'a> {
    sink: &'a TilesSink,
    all: &'a BTreeMap<NodeKey, Tile>,
    boxes: &'a HashMap<NodeKey, Aabb>,
    children: &'a HashMap<NodeKey, Vec<NodeKey>>,
    files: u64,
    bytes: u64,
}

impl Writer<'_> {
    fn write(&mut self, path: &Path, root: Value, error: f64) -> Result<()> {
        let v = json!({
            "asset": {"version": match self.sink.version { Version::V1_0 => "1.0", Version::V1_1 => "1.1" },
                      "generator": concat!("Myriad ", env!("CARGO_PKG_VERSION"))},
            "geometricError": error,
            "root": root,
        });
        let text = serde_json::to_vec(&v).expect("JSON of numbers and strings");
        std::fs::write(path, &text).map_err(|e| Error::io(path, e))?;
        self.files += 1;
        self.bytes += text.len() as u64;
        Ok(())
    }

    /// The geometric error of a node: its spacing in metres, 0 for a leaf.
    fn error(&self, k: NodeKey) -> f64 {
        if self.children.contains_key(&k) {
            self.sink.spacing * self.sink.metres / f64::powi(2.0, k.level as i32)
        } else {
            0.0
        }
    }

    /// The JSON of tile `k` and its subtree; `prefix` leads the URIs (relative to the file it
    /// goes into); `top`: the tile is its file's root.
    fn tile(&mut self, k: NodeKey, prefix: &str, top: bool) -> Result<Value> {
        let b = self.boxes[&k];
        let half: [f64; 3] = std::array::from_fn(|a| ((b.max[a] - b.min[a]) / 2.0).max(0.005));
        let c: [f64; 3] = std::array::from_fn(|a| (b.min[a] + b.max[a]) / 2.0);
        let mut t = json!({
            "boundingVolume": {"box": [c[0], c[1], c[2], half[0], 0.0, 0.0, 0.0, half[1], 0.0, 0.0, 0.0, half[2]]},
            "geometricError": self.error(k),
            "refine": "ADD",
        });
        let kids = self.children.get(&k).cloned().unwrap_or_default();
        let name = node_name(k);
        if !top && k.level.is_multiple_of(SUB_LEVELS) && !kids.is_empty() {
            let root = self.tile(k, "", true)?;
            let path = self
                .sink
                .dir
                .temp()
                .join("tiles")
                .join(format!("{name}.json"));
            self.write(&path, root, self.error(k))?;
            t["content"] = json!({"uri": format!("{prefix}{name}.json")});
            return Ok(t);
        }
        if self.all.get(&k).is_some_and(|t| t.points > 0) {
            t["content"] =
                json!({"uri": format!("{prefix}{name}.{}", self.sink.version.extension())});
        }
        if !kids.is_empty() {
            let v: Vec<Value> = kids
                .iter()
                .map(|c| self.tile(*c, prefix, false))
                .collect::<Result<_>>()?;
            t["children"] = Value::Array(v);
        }
        Ok(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_potrees() {
        assert_eq!(node_name(NodeKey::ROOT), "r");
        // Level 2, cell (3, 0, 2): x's bits 1 1, y's 0 0, z's 1 0 -> children 5 then 4.
        let k = NodeKey {
            level: 2,
            cell: [3, 0, 2],
        };
        assert_eq!(node_name(k), "r54");
    }

    #[test]
    fn the_local_frame_is_east_north_up() {
        // 45 degrees north, 90 degrees east, on the ellipsoid.
        let (lat, lon) = (45f64.to_radians(), 90f64.to_radians());
        let e2 = F * (2.0 - F);
        let n = A / (1.0 - e2 * lat.sin().powi(2)).sqrt();
        let p = [
            n * lat.cos() * lon.cos(),
            n * lat.cos() * lon.sin(),
            n * (1.0 - e2) * lat.sin(),
        ];
        let (lo, la) = geodetic(p);
        assert!((lo - lon).abs() < 1e-12 && (la - lat).abs() < 1e-12);
        let [e, no, u] = east_north_up(p);
        // East at 90 degrees east is -x; up leans north by the latitude; all orthonormal.
        assert!((e[0] + 1.0).abs() < 1e-12);
        assert!((u[2] - lat.sin()).abs() < 1e-12 && (no[2] - lat.cos()).abs() < 1e-12);
        for (a, b) in [(e, no), (no, u), (u, e)] {
            assert!(dot(a, b).abs() < 1e-12);
            assert!((dot(a, a) - 1.0).abs() < 1e-12);
        }
    }
}
