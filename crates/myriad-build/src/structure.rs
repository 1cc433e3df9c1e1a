//! The hierarchies a dataset can be built as.

/// The hierarchy a dataset is built as (`convert --structure`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Structure {
    /// Nested octree of MOSPTs (Scheiblauer 2006).
    Octree,
    /// Octree whose nodes' representatives come from an adaptive n-tree, with contours
    /// (Kanzok et al. 2015).
    Layered,
    /// Balanced binary kd-tree with median splits (Discher et al. 2018).
    Kd,
    /// Multi-way kd-tree of aggregates drawn as splats (Goswami et al. 2010).
    Mwkd,
}

impl Structure {
    pub const ALL: [Structure; 4] = [
        Structure::Octree,
        Structure::Layered,
        Structure::Kd,
        Structure::Mwkd,
    ];

    /// The name `--structure` takes and the metadata stores.
    pub fn name(self) -> &'static str {
        match self {
            Structure::Octree => "octree",
            Structure::Layered => "layered",
            Structure::Kd => "kd",
            Structure::Mwkd => "mwkd",
        }
    }

    /// The name the dataset's metadata stores: the octree's is "nested-octree".
    pub fn stored_name(self) -> &'static str {
        match self {
            Structure::Octree => "nested-octree",
            s => s.name(),
        }
    }

    pub fn parse(s: &str) -> std::result::Result<Structure, String> {
        Structure::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("unknown structure {s:?} (octree, layered, kd, mwkd)"))
    }
}
