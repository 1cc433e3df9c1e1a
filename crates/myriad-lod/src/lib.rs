//! View-dependent level of detail, on the CPU alone: the camera and its frustum ([`view`]) and
//! the per-frame selection of nodes and prefixes within a point budget ([`select`]). Loading,
//! caches and the renderer build on these.

pub mod select;
pub mod view;

pub use select::{Hierarchy, SelectOptions, Selected, Selection, select};
pub use view::{Camera, Frustum};
