//! View-dependent level of detail, on the CPU alone: the camera and its frustum ([`view`]) and
//! the per-frame selection of nodes and prefixes within a point budget ([`select`]; for mwkd
//! trees, whose nodes replace their parents, the rendering front: [`front`]), and
//! streaming: loader threads and an LRU cache of decoded nodes ([`stream`], [`cache`]). The renderer builds
//! on these.

pub mod cache;
pub mod drawn;
pub mod front;
pub mod hierarchy;
pub mod occlusion;
pub mod pace;
pub mod prefetch;
pub mod select;
pub mod selection;
pub mod stream;
pub mod view;

pub use cache::Lru;
pub use drawn::DrawnTree;
pub use front::{backfacing, select_front};
pub use hierarchy::Hierarchy;
pub use hierarchy::PageCache;
pub use occlusion::{DepthMap, Occluder, Occlusion};
pub use pace::Pace;
pub use prefetch::prefetch;
pub use select::{
    lone_radius, merge, point_spacing, select, select_many, select_occluded, select_occluded_from,
    select_where,
};
pub use selection::{SelectOptions, Selected, Selection};
pub use stream::{Loader, PageReader};
pub use view::{Camera, Clip, Frustum, robust_bounds};
