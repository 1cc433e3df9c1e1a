//! An image of points that are in no dataset yet, such as a scan's preview (a sample read
//! without decoding the scan): drawn as one coarse level whose spacing is the sample's, and
//! where whole chunks were decoded too, those points as a finer level over it.

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
    /// The leading points that sample the scan evenly; those after are denser where they are
    /// (whole chunks decoded), each standing for `detail_share` of an even one's points.
    pub even: usize,
    pub detail_share: f64,
}

impl Sample {
    /// The points of `batches` (one sample per file, say) coloured by `colour`, elevation
    /// ramps over all of them.
    pub fn new(batches: &[PointBatch], colour: ColorBy) -> Sample {
        let even: Vec<usize> = batches.iter().map(|b| b.len()).collect();
        Sample::layered(batches, &even, 1.0, colour)
    }

    /// As [`Sample::new`], the first `even[i]` points of batch `i` sampling its file evenly
    /// and the rest denser patches, each standing for `detail_share` of an even one's points.
    pub fn layered(
        batches: &[PointBatch],
        even: &[usize],
        detail_share: f64,
        colour: ColorBy,
    ) -> Sample {
        let split = |i: usize, b: &PointBatch| even.get(i).copied().unwrap_or(b.len()).min(b.len());
        let mut positions: Vec<[f64; 3]> = Vec::new();
        for (i, b) in batches.iter().enumerate() {
            positions.extend_from_slice(&b.positions[..split(i, b)]);
        }
        let n_even = positions.len();
        for (i, b) in batches.iter().enumerate() {
            positions.extend_from_slice(&b.positions[split(i, b)..]);
        }
        let all = robust_bounds(&positions, 0.0);
        let view = robust_bounds(&positions, 0.005);
        let c: Vec<Vec<[u8; 4]>> = batches
            .iter()
            .map(|b| colours(b, b.len(), colour, (view.min[2], view.max[2]), 0))
            .collect();
        let mut rgba = Vec::with_capacity(positions.len());
        for (i, b) in batches.iter().enumerate() {
            rgba.extend_from_slice(&c[i][..split(i, b)]);
        }
        for (i, b) in batches.iter().enumerate() {
            rgba.extend_from_slice(&c[i][split(i, b)..]);
        }
        Sample {
            positions,
            rgba,
            all,
            view,
            even: n_even,
            detail_share: detail_share.clamp(1e-9, 1.0),
        }
    }

    /// The spacing of the sample's even points over its view bounds: the side of the square
    /// each has on the bounds' largest face (a scan is mostly a surface seen from above or the
    /// side).
    pub fn spacing(&self) -> f64 {
        let s = self.view.size();
        let mut sides = [s[0], s[1], s[2]];
        sides.sort_by(f64::total_cmp);
        let area = (sides[1] * sides[2]).max(1e-12);
        (area / self.even.max(1) as f64).sqrt()
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
        let e = self.even.min(self.positions.len());
        let coarse = Points::upload(gpu, origin, &self.positions[..e], &self.rgba[..e]);
        if e == self.positions.len() {
            return raster.render(gpu, camera, &[coarse.all(self.spacing())], &[], &style);
        }
        // The decoded patches as a finer level: each point stands for a share of an even
        // one's points, so its square is that much smaller.
        let fine = Points::upload(gpu, origin, &self.positions[e..], &self.rgba[e..]);
        let draws = [
            coarse.all(self.spacing()),
            fine.all(self.spacing() * self.detail_share.sqrt()),
        ];
        raster.render(gpu, camera, &draws, &[], &style)
    }
}
