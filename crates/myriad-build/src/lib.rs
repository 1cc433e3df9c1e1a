//! Level-of-detail builders and the out-of-core pipeline. [`distribute`] reads every input once
//! and scatters its points to octree-cell chunks on disk within a memory budget; [`mospt`] is the
//! Memory Optimized Sequential Point Tree of one node (Scheiblauer 2006, chapter 3); [`nested`]
//! builds the `nested-octree` of a chunk and the levels above the chunks; [`convert`] runs the
//! whole build in parallel and writes the dataset; [`partition`] splits it into parts that run
//! on other machines and merges them.

mod above;
pub mod append;
pub mod cached;
pub mod convert;
pub mod distribute;
pub mod edited;
pub mod export;
pub mod extract;
pub mod growing;
pub mod kd;
pub mod mospt;
pub mod mwkd;
pub mod nested;
mod nodes;
pub mod ntree;
pub mod open;
mod order;
pub mod partition;
mod radix;
pub mod report;
pub mod sides;
mod spill;
pub mod staged;
pub mod structure;
