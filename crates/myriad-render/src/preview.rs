//! An image of points that are in no dataset yet, such as a scan's preview (a sample read
//! without decoding the scan): drawn as one coarse level whose spacing is the sample's.

use crate::{ColorBy, Gpu, PointSize, Points, Rasterizer, Style, colours};
use myriad_core::{Aabb, PointBatch};
use myriad_lod::{Camera, robust_bounds};

/// A sample's points as they are drawn: positions and colours, and its bounds (all of it, and
/// without the outer 0.5 % on each side of each axis, to frame).
pub struct Sample {
    pub positions: Vec<[f64; 3]>,
    pub rgba: Vec<[u8; 4]>,
    pub all: Aabb,
    pub view: Aabb,
}

impl Sample {
    /// The points of `batches` (one sample per file, say) coloured by `colour`, elevation
    /// ramps over all of them.
    pub fn new(batches: &[PointBatch], colour: ColorBy) -> Sample {
        let positions: Vec<[f64; 3]> = batches
            .iter()
            .flat_map(|b| b.positions.iter().copied())
            .collect();
        let all = robust_bounds(&positions, 0.0);
        let view = robust_bounds(&positions, 0.005);
        let rgba = batches
            .iter()
            .flat_map(|b| colours(b, b.len(), colour, (view.min[2], view.max[2]), 0))
            .collect();
        Sample {
            positions,
            rgba,
            all,
            view,
        }
    }

    /// The spacing of the sample's points over its view bounds: the side of the square each
    /// has on the bounds' largest face (a scan is mostly a surface seen from above or the side).
    pub fn spacing(&self) -> f64 {
        let s = self.view.size();
        let mut sides = [s[0], s[1], s[2]];
        sides.sort_by(f64::total_cmp);
        let area = (sides[1] * sides[2]).max(1e-12);
        (area / self.positions.len().max(1) as f64).sqrt()
    }

    /// Draws the sample seen by `camera`. Adaptive sizes may grow to a quarter of the image's
    /// smaller side: a sparse sample (a point a LAZ chunk) is drawn as large as its spacing
    /// asks, not as specks with gaps between them.
    pub fn draw(&self, gpu: &Gpu, raster: &Rasterizer, camera: &Camera, style: &Style) -> Vec<u8> {
        let mut style = *style;
        if let PointSize::Adaptive { scale, max } = style.size {
            style.size = PointSize::Adaptive {
                scale,
                max: max.max((camera.width.min(camera.height) / 4) as f32),
            };
        }
        let origin = self.positions.first().copied().unwrap_or(camera.target);
        let points = Points::upload(gpu, origin, &self.positions, &self.rgba);
        raster.render(gpu, camera, &[points.all(self.spacing())], &[], &style)
    }
}
