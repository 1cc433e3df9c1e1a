//! While the camera moves, the view is drawn at a lower resolution and the budget holds the
//! frame rate; once it rests, at the full resolution and the whole budget; once a resting
//! view has converged and nothing was touched, the last image is shown again rather than
//! drawn again.
//!
//! On the CPU path a frame's cost is mostly per pixel (the point pass's squares, the post passes,
//! the finish; issue 45 item 10): at half the width and height it costs about a quarter, and
//! the frame-rate budget then controls the rate. Drawn at rest, the view refines to the whole
//! budget, as Potree's viewer refines a still view.

use myriad_lod::Camera;
use std::time::{Duration, Instant};

/// The camera counts as moving this long after it last changed (drags do not move it every
/// frame).
pub const SETTLE: Duration = Duration::from_millis(300);

/// What a frame is drawn with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Drawn {
    /// Fraction of the view's width and height drawn.
    pub scale: f32,
    /// The camera moves: the frame-rate budget applies.
    pub moving: bool,
}

#[derive(Debug, Clone)]
pub struct Motion {
    /// Fraction of the width and height drawn while moving (1: always the full resolution).
    pub scale: f32,
    last: Option<Camera>,
    moved: Option<Instant>,
}

impl Motion {
    pub fn new(scale: f32) -> Motion {
        Motion {
            scale: scale.clamp(0.1, 1.0),
            last: None,
            moved: None,
        }
    }

    /// This frame's camera (at the view's full size) at `now`; `scripted`: a scripted move
    /// (`--orbit-frames`) is under way.
    pub fn frame(&mut self, camera: &Camera, now: Instant, scripted: bool) -> Drawn {
        if self.last.as_ref().is_none_or(|c| !same(c, camera)) {
            // The first frame is not a move: it is drawn at the full resolution.
            if self.last.is_some() {
                self.moved = Some(now);
            }
            self.last = Some(*camera);
        }
        let moving = scripted || self.moved.is_some_and(|t| now.duration_since(t) < SETTLE);
        Drawn {
            scale: if moving { self.scale } else { 1.0 },
            moving,
        }
    }
}

fn same(a: &Camera, b: &Camera) -> bool {
    a.position == b.position
        && a.target == b.target
        && a.up == b.up
        && a.fov_y == b.fov_y
        && a.width == b.width
        && a.height == b.height
}

/// The camera `camera` drawn at `scale` of its size: the same view (the focal length scales
/// with the height), fewer pixels.
pub fn scaled(camera: &Camera, scale: f32) -> Camera {
    if scale >= 1.0 {
        return *camera;
    }
    let s = |v: u32| ((v as f32 * scale).round() as u32).max(1);
    Camera {
        width: s(camera.width),
        height: s(camera.height),
        ..*camera
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        let b = myriad_core::Aabb {
            min: [0.0; 3],
            max: [10.0, 10.0, 2.0],
        };
        Camera::framing(&b, 1050, 720, 60.0)
    }

    #[test]
    fn half_resolution_while_moving_and_full_once_at_rest() {
        let mut m = Motion::new(0.5);
        let t0 = Instant::now();
        let mut c = camera();
        // Opening: at rest.
        assert_eq!(
            m.frame(&c, t0, false),
            Drawn {
                scale: 1.0,
                moving: false
            }
        );
        c.position[0] += 1.0;
        let t1 = t0 + Duration::from_millis(16);
        assert_eq!(
            m.frame(&c, t1, false),
            Drawn {
                scale: 0.5,
                moving: true
            }
        );
        // A drag that skips a frame still moves.
        let t2 = t1 + Duration::from_millis(100);
        assert!(m.frame(&c, t2, false).moving);
        // Still for longer than SETTLE: at rest again.
        let t3 = t1 + SETTLE + Duration::from_millis(1);
        assert_eq!(
            m.frame(&c, t3, false),
            Drawn {
                scale: 1.0,
                moving: false
            }
        );
        // A scripted orbit moves whatever the camera does; a resize is a change.
        assert!(m.frame(&c, t3, true).moving);
        c.width = 800;
        assert!(m.frame(&c, t3, false).moving);
        // Scale 1: moving, but at the full resolution.
        let mut full = Motion::new(1.0);
        full.frame(&c, t0, false);
        c.position[1] += 1.0;
        assert_eq!(
            full.frame(&c, t1, false),
            Drawn {
                scale: 1.0,
                moving: true
            }
        );
    }

    #[test]
    fn a_scaled_camera_sees_the_same_view() {
        let c = camera();
        let h = scaled(&c, 0.5);
        assert_eq!((h.width, h.height), (525, 360));
        // A point lands at the same fraction of the image.
        let p = [3.0, 7.0, 1.0];
        let at = |c: &Camera| {
            let e = c.to_eye(p);
            let f = c.focal();
            (
                (c.width as f64 / 2.0 + e[0] * f / e[2]) / c.width as f64,
                (c.height as f64 / 2.0 - e[1] * f / e[2]) / c.height as f64,
            )
        };
        let (a, b) = (at(&c), at(&h));
        assert!(
            (a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9,
            "{a:?} {b:?}"
        );
        assert_eq!(scaled(&c, 1.0).width, 1050);
    }
}
