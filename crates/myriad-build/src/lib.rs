//! Level-of-detail builders. So far: [`mospt`], the Memory Optimized Sequential Point Tree of one
//! node (Scheiblauer 2006, chapter 3), the inner structure of the `nested-octree`. The out-of-core
//! pipeline (distribute, build chunks, merge tops) comes with the converter.

pub mod mospt;
