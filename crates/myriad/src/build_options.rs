//! The options a build takes, as `convert` and `plan` share them.

use anyhow::{Result, bail};
use clap::Args;
use myriad_build::convert;

/// The options a build takes, in `convert` and `plan`.
#[derive(Args)]
pub struct BuildArgs {
    /// Hierarchy to build: octree (nested octree of MOSPTs), layered (octree with adaptive
    /// n-tree representatives and contours), kd (balanced kd-tree), mwkd (multi-way kd-tree of
    /// aggregates drawn as splats)
    #[arg(long, default_value = "octree")]
    pub(crate) structure: String,
    /// Memory budget: 512MB, 2GB, or bytes [default: 1GB, or a quarter of RAM if less; --append: a quarter of RAM, at most 8GB]
    #[arg(long, value_parser = convert::parse_size)]
    pub(crate) memory: Option<u64>,
    /// Worker threads [default: all cores]
    #[arg(long, value_parser = parse_threads)]
    pub(crate) threads: Option<usize>,
    /// Most points per node
    #[arg(help_heading = "Hierarchy", long, default_value_t = convert::DEFAULT_CAPACITY)]
    pub(crate) capacity: usize,
    /// --structure mwkd: children per node, 2 to 8 [default: the one that makes the tree's
    /// depth whole]
    #[arg(help_heading = "Hierarchy", long, value_parser = clap::value_parser!(u32).range(2..=8))]
    pub(crate) fanout: Option<u32>,
    /// --structure mwkd: cells per side of the grid an inner node's representatives are
    /// clustered in, 2 to 256 (Goswami et al. 2010 used 35) [default: the square root of their
    /// count]
    #[arg(help_heading = "Hierarchy", long, value_parser = clap::value_parser!(u32).range(2..=256))]
    pub(crate) grid: Option<u32>,
    /// Quantization step of float inputs (PLY, PCD, E57, text), in their units (the target's with --to-crs); LAS/LAZ keep their scale
    #[arg(help_heading = "Inputs", long, default_value_t = 0.0001)]
    pub(crate) precision: f64,
    /// Column layout of text inputs, e.g. x,y,z,intensity,r,g,b
    #[arg(help_heading = "Inputs", long)]
    pub(crate) columns: Option<String>,
    /// Ignore SCAN.placement files next to inputs (see README)
    #[arg(help_heading = "Inputs", long)]
    pub(crate) no_placement: bool,
    /// Move every point into this coordinate system: EPSG:NNNN, EPSG:H+V, WKT or a PROJ string
    /// (through PROJ; a target without heights keeps the inputs' vertical part)
    #[arg(help_heading = "Coordinates", long, value_name = "CRS")]
    pub(crate) to_crs: Option<String>,
    /// The coordinate system of inputs whose files name none (with --to-crs)
    #[arg(
        help_heading = "Coordinates",
        long,
        value_name = "CRS",
        requires = "to_crs"
    )]
    pub(crate) from_crs: Option<String>,
}

impl BuildArgs {
    /// The structure named, and the capacity checked.
    pub(crate) fn structure(&self) -> Result<convert::Structure> {
        if self.capacity < 64 {
            bail!("--capacity {} is too small (at least 64)", self.capacity);
        }
        // A node's points are counted in u32s, and budgets of a few times capacity x record
        // size must stay within u64.
        if self.capacity > 1 << 24 {
            bail!(
                "--capacity {} is too large (at most {})",
                self.capacity,
                1u64 << 24
            );
        }
        let s = match self.structure.as_str() {
            "nested-octree" => convert::Structure::Octree,
            s => convert::Structure::parse(s).map_err(|e| anyhow::anyhow!("--structure: {e}"))?,
        };
        if s != convert::Structure::Mwkd && (self.fanout.is_some() || self.grid.is_some()) {
            bail!("--fanout and --grid are for --structure mwkd");
        }
        Ok(s)
    }

    /// How the inputs are opened.
    pub(crate) fn open_options(&self) -> myriad_io::OpenOptions {
        myriad_io::OpenOptions {
            columns: self.columns.clone(),
            sidecar_placements: !self.no_placement,
            reproject: self
                .to_crs
                .as_ref()
                .map(|to| myriad_io::reproject::Reproject {
                    to: to.clone(),
                    from: self.from_crs.clone(),
                }),
            ..Default::default()
        }
    }
}

/// `--threads`: 1 to 1024 (more asked thread pools for tens of thousands of threads).
pub(crate) fn parse_threads(s: &str) -> std::result::Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n) if (1..=1024).contains(&n) => Ok(n),
        _ => Err(format!("\"{s}\": a number of threads from 1 to 1024")),
    }
}
