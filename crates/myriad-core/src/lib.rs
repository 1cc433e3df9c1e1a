//! Myriad's shared vocabulary: f64 geometry ([`Aabb`], [`Obb`]), the attribute schema that covers
//! every LAS 1.4 point field plus normals ([`Schema`], [`Attribute`]), the columnar [`PointBatch`]
//! that readers yield and builders consume, the colour schemes that show a point's attributes
//! ([`colour`]: one implementation for the renderer and the web viewer), the class schemes that
//! name, colour and hide classes ([`classes`]), and the typed [`Error`]
//! every library crate returns.
//!
//! Nothing here does I/O, spawns threads or touches a GPU.

pub mod batch;
pub mod classes;
pub mod colour;
pub mod column;
pub mod error;
pub mod geometry;
pub mod ground;
pub mod guard;
pub mod mesh;
pub mod pca;
pub mod schema;
pub mod units;

pub use batch::{Numbers, PointBatch, PointRecord, RowBytes, WavePacket};
pub use column::Column;
pub use error::{Error, Location, Result};
pub use geometry::{Aabb, Affine, NodeKey, Obb};
pub use mesh::Mesh;
pub use schema::{Attribute, ExtraDim, ExtraType, Schema};
