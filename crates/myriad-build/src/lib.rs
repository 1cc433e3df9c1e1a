//! Level-of-detail builders. So far: [`distribute`], the first phase of the out-of-core pipeline
//! (every input read once, points scattered to octree-cell chunks on disk within a memory budget),
//! and [`mospt`], the Memory Optimized Sequential Point Tree of one node (Scheiblauer 2006,
//! chapter 3), the inner structure of the `nested-octree`. Building chunks, merging the tops and
//! writing the dataset come with `convert`.

pub mod distribute;
pub mod mospt;
pub mod nested;
