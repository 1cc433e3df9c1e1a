//! How the renderer's options are written on a command line (`render`, `view`, `mesh` and the
//! benchmarks share these): each parser takes the text and says what it expected when it is
//! not that.

#[cfg(feature = "clap")]
use crate::surface::{self, Density, Kind, Normals, Surface};
use crate::{ColorBy, Passes, Path, PointSize, Shape};

/// A colour scheme by name.
pub fn parse_color(s: &str) -> Result<ColorBy, String> {
    ColorBy::parse(s).ok_or_else(|| {
        format!("\"{s}\": one of rgb, intensity, elevation, classification, return, source, level, uniform")
    })
}

/// A comma-separated list of post passes ([`Passes::parse`]).
pub fn parse_passes(s: &str) -> Result<Passes, String> {
    Passes::parse(s)
}

/// `adaptive`, `adaptive:SCALE` or `fixed:PX`.
pub fn parse_point_size(s: &str) -> Result<PointSize, String> {
    if s == "adaptive" {
        return Ok(PointSize::adaptive());
    }
    if let Some(scale) = s.strip_prefix("adaptive:") {
        return match scale.parse::<f32>() {
            Ok(v) if (0.1..=10.0).contains(&v) => Ok(PointSize::Adaptive {
                scale: v,
                max: 32.0,
            }),
            _ => Err(format!(
                "\"{s}\": the scale of adaptive:SCALE is from 0.1 to 10"
            )),
        };
    }
    s.strip_prefix("fixed:")
        .and_then(|v| v.parse::<f32>().ok())
        .filter(|v| (1.0..=64.0).contains(v))
        .map(PointSize::Fixed)
        .ok_or_else(|| {
            format!("\"{s}\": expected adaptive, adaptive:SCALE or fixed:PX with PX from 1 to 64")
        })
}

/// The level of detail's threshold: pixels above 0 and at most 64.
pub fn parse_lod_threshold(s: &str) -> Result<f64, String> {
    s.parse::<f64>()
        .ok()
        .filter(|v| *v > 0.0 && *v <= 64.0)
        .ok_or_else(|| format!("\"{s}\": pixels above 0 and at most 64"))
}

/// A point shape by name.
pub fn parse_shape(s: &str) -> Result<Shape, String> {
    Shape::parse(s).ok_or_else(|| format!("\"{s}\": one of square, round, paraboloid"))
}

/// A point path by name: compute, quads or cpu.
pub fn parse_path(s: &str) -> Result<Path, String> {
    match s {
        "compute" => Ok(Path::Compute),
        "quads" => Ok(Path::Quads),
        "cpu" => Ok(Path::Cpu),
        _ => Err(format!("\"{s}\": compute, quads or cpu")),
    }
}

/// Neighbours a point may move to: 0, 1 or 3.
pub fn parse_neighbours(s: &str) -> Result<u32, String> {
    match s {
        "0" => Ok(0),
        "1" => Ok(1),
        "3" => Ok(3),
        _ => Err(format!("\"{s}\": 0, 1 or 3")),
    }
}

/// The options of a surface, as `render`, `view` and `mesh` take them.
#[cfg(feature = "clap")]
#[derive(clap::Args, Clone, Debug)]
pub struct SurfaceArgs {
    /// Columns, rows and depth layers of the view-frustum grid
    #[arg(long, value_parser = surface::parse_grid, default_value = "150x150x50")]
    pub grid: [u32; 3],
    /// Cell normals: tensor (the point distribution tensor's minor eigenvector) or cells (towards
    /// the empty neighbour cells, faster, rougher)
    #[arg(long, value_parser = Normals::parse, default_value = "tensor")]
    pub normals: Normals,
    /// Neighbours a point may move to, per point: 0 (no move), 1 (along its largest offset) or
    /// 3 (along each axis)
    #[arg(long, value_parser = parse_neighbours, default_value = "3")]
    pub neighbours: u32,
    /// Cluster only: the same as --neighbours 0
    #[arg(long)]
    pub no_move: bool,
    /// The density that moves points: count (points per cell) or planarity (of the cell's
    /// point distribution tensor)
    #[arg(long, value_parser = Density::parse, default_value = "count")]
    pub density: Density,
    /// The exponent of the move's weights
    #[arg(long, default_value_t = 2.0)]
    pub gamma: f64,
    /// The lower bound of the move's weights, 0 to 0.5
    #[arg(long, default_value_t = 0.1)]
    pub lb: f64,
}

#[cfg(feature = "clap")]
impl SurfaceArgs {
    /// The surface of this kind with these options.
    pub fn surface(&self, kind: Kind) -> Result<Surface, String> {
        if !(self.gamma > 0.0 && self.gamma <= 16.0) {
            return Err("--gamma must be above 0 and at most 16".into());
        }
        if !(0.0..0.5).contains(&self.lb) {
            return Err("--lb must be from 0 to below 0.5".into());
        }
        Ok(Surface {
            kind,
            grid: self.grid,
            normals: self.normals,
            neighbours: if self.no_move { 0 } else { self.neighbours },
            density: self.density,
            gamma: self.gamma,
            lb: self.lb,
        })
    }
}
