//! The surveyor's tools over datasets, one implementation of each tool's geometry for the CLI,
//! the viewer and (compiled to WebAssembly) the web viewer:
//! - [`filter`]: classes and attribute ranges (`--classes`, `--where`);
//! - [`corridor`] and [`profile`]: cross-sections along a polyline, to CSV, DXF and PNG (LAS and
//!   LAZ through `myriad_build::extract` with the corridor as its region);
//! - [`measurement`]: point, distance, height, area, angle, circle, azimuth, in m / ft / US ft;
//! - [`polygon`] and [`volume`]: volumes over a polygon above a base (a plane fitted to the rim,
//!   an elevation, or an earlier dataset), cut and fill apart.
//!
//! - [`geojson`]: the results for GIS programs, with the CRS named;
//! - [`edits`]: classes set and points removed, kept beside the dataset as a layer that every
//!   reader applies;
//! - [`work`]: saved work, annotations and measurements in a sidecar next to the dataset
//!   (GeoJSON and DXF through [`files`]), with the dataset's class scheme ([`scheme`]) and
//!   camera paths ([`camera_path`]).
//!
//! Every tool reads the original points, at full resolution, from the pages whose nodes meet
//! its region ([`read_region`]), whatever a view draws.

pub mod camera_path;
pub mod contours;
pub mod corridor;
pub mod crs;
pub mod edges;
pub mod edits;
#[cfg(not(target_arch = "wasm32"))]
pub mod files;
pub mod filter;
pub mod geojson;
pub mod ground;
pub mod map;
pub mod measurement;
pub mod photos;
pub mod polygon;
pub mod profile;
#[cfg(not(target_arch = "wasm32"))]
pub mod raster;
pub mod scheme;
pub mod shape;
pub mod volume;
pub mod work;

pub use corridor::Corridor;
pub use filter::{Bound, Filter};
pub use polygon::Polygon;

use myriad_core::{Aabb, PointBatch};
use myriad_format::Dataset;

/// A part of space a tool reads: a corridor, a polygon, a box.
pub trait Region: Send + Sync + std::fmt::Debug {
    /// Whether the box (a node's cube) may hold points of the region.
    fn meets(&self, b: &Aabb) -> bool;
    /// Whether the point is in the region.
    fn contains(&self, p: [f64; 3]) -> bool;
}

impl Region for Aabb {
    fn meets(&self, b: &Aabb) -> bool {
        (0..3).all(|a| b.min[a] <= self.max[a] && self.min[a] <= b.max[a])
    }
    fn contains(&self, p: [f64; 3]) -> bool {
        Aabb::contains(self, p)
    }
}

/// What [`read_region`] read.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Read {
    pub nodes: u64,
    /// Points in the nodes read, before the region and the filter.
    pub points_read: u64,
    /// Points kept.
    pub points: u64,
}

/// Hands `visit` the original points of `ds` in `region` that `filter` keeps, node by node
/// (only the hierarchy pages and node pages whose cubes meet the region are read). A damaged
/// page is an error: a measurement must not silently lack points.
pub fn read_region(
    ds: &Dataset,
    region: &dyn Region,
    filter: &Bound,
    mut visit: impl FnMut(&PointBatch),
) -> Result<Read, String> {
    let (nodes, damage) = ds.nodes_where(&|cube| region.meets(cube));
    if let Some(d) = damage.first() {
        return Err(ds.damage_error(d).to_string());
    }
    let mut read = Read::default();
    for n in nodes {
        // Aggregates (mwkd's inner nodes) were made for drawing: not the user's points.
        if n.points == 0 || n.aggregate() || !region.meets(&n.bounds_in(&ds.meta.root)) {
            continue;
        }
        let mut b = ds
            .read_node(&n)
            .map_err(|d| ds.damage_error(&d).to_string())?;
        read.nodes += 1;
        read.points_read += b.len() as u64;
        let keep: Vec<bool> = (0..b.len())
            .map(|i| region.contains(b.positions[i]) && filter.keeps(&b, i))
            .collect();
        b.retain_mask(&keep);
        if !b.is_empty() {
            read.points += b.len() as u64;
            visit(&b);
        }
    }
    ds.check_unchanged().map_err(|e| e.to_string())?;
    Ok(read)
}
