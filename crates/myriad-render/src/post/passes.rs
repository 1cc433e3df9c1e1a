//! Which post passes a frame runs, parsed from their names, and their order.

use super::{blur::Blur, edl::Edl, fill::Fill, shade::Shade, ssao::Ssao};

/// The passes of a frame, in the pipeline's order (blend, fill, normals, shade, ssao, edl, blur,
/// aa), each on when set.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Passes {
    /// Blending (the deferred blending of Goswami et al. 2010 with the EWA kernels of
    /// Schiffner et al. 2015): the point pass keeps each pixel's nearest depth, then every point's
    /// fragments within its own size of that depth add their colour weighted by the point's
    /// Gaussian footprint; the pixel shows the weighted mean (`blend.rs`).
    pub blend: bool,
    pub fill: Option<Fill>,
    pub shade: Option<Shade>,
    pub ssao: Option<Ssao>,
    pub edl: Option<Edl>,
    pub blur: Option<Blur>,
    /// Supersampling factor: 0 or 1 off, 2 draws four samples per pixel.
    pub aa: u32,
}

/// The default chain of `render` and `view`, chosen by `myriad bench passes` (README).
pub const DEFAULT_PASSES: &str = "fill,blur";

/// The names `Passes::parse` takes, in the pipeline's order.
pub const PASS_NAMES: [&str; 7] = ["blend", "fill", "shade", "ssao", "edl", "blur", "aa"];

impl Passes {
    /// [`DEFAULT_PASSES`].
    pub fn default_chain() -> Passes {
        Passes::parse(DEFAULT_PASSES).expect("valid names")
    }

    /// A comma-separated list of pass names (any order; `none` for no pass), each with its
    /// default parameters; an unknown name is the error.
    pub fn parse(s: &str) -> Result<Passes, String> {
        let mut p = Passes::default();
        for name in s.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            match name {
                "none" => {}
                "blend" => p.blend = true,
                "fill" => p.fill = Some(Fill::default()),
                "shade" => p.shade = Some(Shade::default()),
                "ssao" => p.ssao = Some(Ssao::default()),
                "edl" => p.edl = Some(Edl::default()),
                "blur" => p.blur = Some(Blur::default()),
                "aa" => p.aa = 2,
                _ => {
                    return Err(format!(
                        "unknown pass {name:?} (passes: {}, or none)",
                        PASS_NAMES.join(", ")
                    ));
                }
            }
        }
        Ok(p)
    }

    /// The passes' dispatches in the pipeline's order, by their entry points' names (the
    /// g-buffer's and the finish pass around them): one list for the CPU and the GPU.
    pub(crate) fn steps(&self) -> Vec<&'static str> {
        let mut steps = Vec::new();
        if self.fill.is_some() {
            steps.extend(["fill_rows", "fill_columns"]);
        }
        if self.normals() {
            steps.push("normals");
        }
        for (name, on) in [
            ("shade", self.shade.is_some()),
            ("ssao", self.ssao.is_some()),
            ("edl", self.edl.is_some_and(|e| e.strength > 0.0)),
            ("blur", self.blur.is_some()),
        ] {
            if on {
                steps.push(name);
            }
        }
        steps
    }

    /// Towards the sun in world coordinates, where shading is on.
    pub fn sun(&self) -> Option<[f64; 3]> {
        self.shade.map(|s| s.sun_direction)
    }

    /// Whether a pass needs normals.
    pub fn normals(&self) -> bool {
        self.shade.is_some() || self.ssao.is_some()
    }

    /// The supersampling factor (at least 1).
    pub fn factor(&self) -> u32 {
        self.aa.clamp(1, 4)
    }
}
