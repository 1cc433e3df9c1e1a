//! How points are drawn: their size, shape, the post passes and the background.

use crate::Clip;
use crate::post::Passes;
use myriad_lod::Camera;

/// How big a point is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PointSize {
    /// This many pixels on a side.
    Fixed(f32),
    /// The spacing of the point's level of detail (pulled up, see `myriad_lod::select`) as seen
    /// at the point's depth, times `scale`, at most `max` pixels. Points one spacing apart
    /// leave holes between them (a level's points are one per cell, anywhere in it): the
    /// default scale closes them.
    Adaptive { scale: f32, max: f32 },
}

impl PointSize {
    pub const ADAPTIVE_SCALE: f32 = 1.5;

    /// Adaptive with the default scale, at most 32 pixels.
    pub fn adaptive() -> PointSize {
        PointSize::Adaptive {
            scale: PointSize::ADAPTIVE_SCALE,
            max: 32.0,
        }
    }
}

/// The shape of a point on screen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    Square,
    /// A disc: the pixels whose centres lie within the point's size.
    Round,
    /// A disc whose centre stands out towards the eye (by half its size), so that overlapping
    /// points meet in curved seams, as splats would.
    Paraboloid,
}

impl Shape {
    pub fn parse(s: &str) -> Option<Shape> {
        Some(match s {
            "square" => Shape::Square,
            "round" | "circle" => Shape::Round,
            "paraboloid" => Shape::Paraboloid,
            _ => return None,
        })
    }
}

/// How points are drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Style {
    pub size: PointSize,
    pub shape: Shape,
    /// The post passes over the g-buffer (eye-dome lighting among them).
    pub passes: Passes,
    pub background: [u8; 4],
    pub clip: Option<Clip>,
}

impl Default for Style {
    fn default() -> Style {
        Style {
            size: PointSize::adaptive(),
            shape: Shape::Square,
            passes: Passes::default(),
            background: [0, 0, 0, 255],
            clip: None,
        }
    }
}

/// The camera and style of a frame supersampled `f` times: `f` times the pixels on each side,
/// fixed point sizes and the largest adaptive size `f` times as many pixels.
pub(crate) fn supersampled(camera: &Camera, style: &Style, f: u32) -> (Camera, Style) {
    let mut c = *camera;
    c.width = camera.width.max(1) * f;
    c.height = camera.height.max(1) * f;
    let mut s = *style;
    let k = f as f32;
    s.size = match style.size {
        PointSize::Fixed(px) => PointSize::Fixed(px * k),
        PointSize::Adaptive { scale, max } => PointSize::Adaptive {
            scale,
            max: max * k,
        },
    };
    (c, s)
}
