//! Navigation: the camera moved by mouse and keyboard, in pixels and seconds. Orbit turns the
//! eye around a pivot (the point picked under the cursor), pan slides the view so the point under
//! the cursor follows it, zoom moves towards the cursor, fly mode moves the eye with WASD and looks
//! around with the mouse. Z is up. Near and far planes follow the data after every move.

use myriad_core::Aabb;
use myriad_lod::Camera;

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// `v` turned by `angle` radians around the unit `axis` (Rodrigues).
fn rotate(v: [f64; 3], axis: [f64; 3], angle: f64) -> [f64; 3] {
    let (s, c) = angle.sin_cos();
    let k = axis;
    let cross = [
        k[1] * v[2] - k[2] * v[1],
        k[2] * v[0] - k[0] * v[2],
        k[0] * v[1] - k[1] * v[0],
    ];
    let kv = dot(k, v);
    std::array::from_fn(|i| v[i] * c + cross[i] * s + k[i] * kv * (1.0 - c))
}

/// Turns `p` and `q` around `centre`: `yaw` radians around the vertical, then `p` up by
/// `elevation` radians (its elevation seen from `centre` kept within 89 degrees of level), `q`
/// with it.
fn turn(
    centre: [f64; 3],
    p: [f64; 3],
    q: [f64; 3],
    yaw: f64,
    elevation: f64,
) -> ([f64; 3], [f64; 3]) {
    let z = [0.0, 0.0, 1.0];
    let v = rotate(sub(p, centre), z, yaw);
    let w = rotate(sub(q, centre), z, yaw);
    let len = norm(v);
    if len == 0.0 {
        return (add(centre, v), add(centre, w));
    }
    let now = (v[2] / len).clamp(-1.0, 1.0).asin();
    let limit = 89f64.to_radians();
    let delta = (now + elevation).clamp(-limit, limit) - now;
    // Around the horizontal axis at right angles to v: positive angles raise v.
    let axis = [v[1], -v[0], 0.0];
    let a = norm(axis);
    if a < 1e-12 {
        return (add(centre, v), add(centre, w));
    }
    let axis = scale(axis, 1.0 / a);
    (
        add(centre, rotate(v, axis, delta)),
        add(centre, rotate(w, axis, delta)),
    )
}

/// The six axis views.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum View {
    /// Straight down (north up).
    Top,
    /// From the south, looking north.
    Front,
    /// From the east, looking west.
    Right,
    /// Straight up from below (north up).
    Bottom,
    /// From the north, looking south.
    Back,
    /// From the west, looking east.
    Left,
}

impl View {
    pub const ALL: [View; 6] = [
        View::Top,
        View::Front,
        View::Right,
        View::Bottom,
        View::Back,
        View::Left,
    ];

    pub fn name(self) -> &'static str {
        match self {
            View::Top => "top",
            View::Front => "front",
            View::Right => "right",
            View::Bottom => "bottom",
            View::Back => "back",
            View::Left => "left",
        }
    }
}

/// The field of view of the parallel (orthographic) view, in degrees: the eye that far away
/// that the view keeps its size at the target, lines of sight parallel to within half of it
/// (and one level of detail across the depth), drawn by the same perspective pipeline.
pub const PARALLEL_FOV: f64 = 1.0;

pub struct Nav {
    pub camera: Camera,
    /// What orbiting turns around.
    pub pivot: [f64; 3],
    pub fly: bool,
    /// Fly speed, units per second.
    pub speed: f64,
    /// Everything there is (for near and far planes).
    all: Aabb,
    /// In the parallel view: the field of view to go back to.
    parallel: Option<f64>,
}

/// Radians per pixel of mouse movement.
const TURN: f64 = 0.005;

impl Nav {
    /// The data framed from above at 45 degrees.
    pub fn framing(bounds: &Aabb, all: &Aabb, fov: f64) -> Nav {
        let camera = Camera::framing(bounds, 1280, 720, fov);
        let s = bounds.size();
        let mut nav = Nav {
            pivot: camera.target,
            camera,
            fly: false,
            speed: s[0].max(s[1]).max(s[2]).max(1e-3) / 10.0,
            all: *all,
            parallel: None,
        };
        nav.fit();
        nav
    }

    fn fit(&mut self) {
        self.camera.fit_depth(&self.all);
    }

    /// Eye and target as given; the pivot at the target.
    pub fn look(&mut self, eye: [f64; 3], target: [f64; 3]) {
        self.camera.position = eye;
        self.camera.target = target;
        self.pivot = target;
        self.fit();
    }

    /// Back to the whole of `bounds`, from above at 45 degrees.
    pub fn frame(&mut self, bounds: &Aabb) {
        let (w, h) = (self.camera.width, self.camera.height);
        let c = Camera::framing(bounds, w, h, self.camera.fov_y);
        self.camera = Camera {
            up: [0.0, 0.0, 1.0],
            ..c
        };
        self.pivot = c.target;
        self.fit();
    }

    /// Along an axis at the data's centre, at the framing distance.
    pub fn standard(&mut self, view: View, bounds: &Aabb) {
        self.frame(bounds);
        let c = bounds.center();
        let d = norm(sub(self.camera.position, self.camera.target));
        let (eye, up) = match view {
            View::Top => ([c[0], c[1], c[2] + d], [0.0, 1.0, 0.0]),
            View::Bottom => ([c[0], c[1], c[2] - d], [0.0, 1.0, 0.0]),
            View::Front => ([c[0], c[1] - d, c[2]], [0.0, 0.0, 1.0]),
            View::Back => ([c[0], c[1] + d, c[2]], [0.0, 0.0, 1.0]),
            View::Right => ([c[0] + d, c[1], c[2]], [0.0, 0.0, 1.0]),
            View::Left => ([c[0] - d, c[1], c[2]], [0.0, 0.0, 1.0]),
        };
        self.camera.position = eye;
        self.camera.target = c;
        self.camera.up = up;
        self.pivot = c;
        self.fit();
    }

    /// Whether the view is parallel (orthographic).
    pub fn parallel(&self) -> bool {
        self.parallel.is_some()
    }

    /// The parallel (orthographic) view on or off, what is seen at the target kept the same
    /// size: the eye moves along the line of sight to where [`PARALLEL_FOV`] (or, back, the
    /// field of view it had) sees as much.
    pub fn set_parallel(&mut self, on: bool) {
        match (on, self.parallel) {
            (true, None) => {
                self.parallel = Some(self.camera.fov_y);
                self.refocus(PARALLEL_FOV);
            }
            (false, Some(fov)) => {
                self.parallel = None;
                self.refocus(fov);
            }
            _ => {}
        }
    }

    fn refocus(&mut self, fov: f64) {
        let t = self.camera.target;
        let v = sub(self.camera.position, t);
        let d = norm(v).max(1e-9);
        let half = d * (self.camera.fov_y.to_radians() / 2.0).tan();
        let far = half / (fov.to_radians() / 2.0).tan();
        self.camera.position = add(t, scale(v, far / d));
        self.camera.fov_y = fov;
        self.fit();
    }

    /// Turns eye and target around the pivot: `dx` pixels around the vertical, `dy` pixels up
    /// or down over it (dragging down raises the eye; never over the top or under the bottom).
    pub fn orbit(&mut self, dx: f64, dy: f64) {
        let (eye, target) = turn(
            self.pivot,
            self.camera.position,
            self.camera.target,
            -dx * TURN,
            dy * TURN,
        );
        self.camera.position = eye;
        self.camera.target = target;
        self.camera.up = [0.0, 0.0, 1.0];
        self.fit();
    }

    /// Fly mode: turns the view around the eye (dragging right looks right, up looks up).
    pub fn look_around(&mut self, dx: f64, dy: f64) {
        let eye = self.camera.position;
        let (target, _) = turn(
            eye,
            self.camera.target,
            self.camera.target,
            -dx * TURN,
            -dy * TURN,
        );
        self.camera.target = target;
        self.camera.up = [0.0, 0.0, 1.0];
        self.fit();
    }

    /// World units per pixel at the depth of `p`.
    fn units_per_pixel(&self, p: [f64; 3]) -> f64 {
        self.camera.to_eye(p)[2].max(1e-6) / self.camera.focal()
    }

    /// Slides the view so that the point at the pivot's depth follows the cursor.
    pub fn pan(&mut self, dx: f64, dy: f64) {
        let (right, up, _) = self.camera.basis();
        let u = self.units_per_pixel(self.pivot);
        let m = add(scale(right, -dx * u), scale(up, dy * u));
        self.camera.position = add(self.camera.position, m);
        self.camera.target = add(self.camera.target, m);
        self.pivot = add(self.pivot, m);
        self.fit();
    }

    /// The unit ray from the eye through pixel (`x`, `y`).
    pub fn ray(&self, x: f64, y: f64) -> [f64; 3] {
        let (right, up, forward) = self.camera.basis();
        let f = self.camera.focal();
        let px = (x - self.camera.width as f64 / 2.0) / f;
        let py = (self.camera.height as f64 / 2.0 - y) / f;
        let d = add(forward, add(scale(right, px), scale(up, py)));
        scale(d, 1.0 / norm(d))
    }

    /// Moves towards the point under pixel (`x`, `y`) at the pivot's depth: `scroll` pixels of
    /// wheel, a tenth of the way per 50 (negative: away).
    pub fn zoom_towards(&mut self, x: f64, y: f64, scroll: f64) {
        let ray = self.ray(x, y);
        // (Not below the near plane's distance from the data: fit_depth puts it just short of
        // the nearest corner.)
        let depth = self.camera.to_eye(self.pivot)[2].max(1e-6);
        let (_, _, forward) = self.camera.basis();
        let along = depth / dot(ray, forward).max(1e-6);
        let f = (1.0 - 0.9f64.powf(scroll / 50.0)).clamp(-2.0, 0.9);
        let m = scale(ray, along * f);
        self.camera.position = add(self.camera.position, m);
        self.camera.target = add(self.camera.target, m);
        self.fit();
    }

    /// Fly mode: W S forward and back, A D left and right, Q E down and up, for `dt` seconds.
    pub fn fly_step(&mut self, keys: [bool; 6], dt: f64) {
        let (right, _, forward) = self.camera.basis();
        let z = [0.0, 0.0, 1.0];
        let mut m = [0.0; 3];
        let dirs = [
            forward,
            scale(forward, -1.0),
            scale(right, -1.0),
            right,
            scale(z, -1.0),
            z,
        ];
        for (on, d) in keys.iter().zip(dirs) {
            if *on {
                m = add(m, d);
            }
        }
        if norm(m) == 0.0 {
            return;
        }
        let m = scale(m, self.speed * dt / norm(m));
        self.camera.position = add(self.camera.position, m);
        self.camera.target = add(self.camera.target, m);
        self.pivot = add(self.pivot, m);
        self.fit();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nav() -> Nav {
        let b = Aabb::new([0.0, 0.0, 0.0], [100.0, 100.0, 10.0]);
        let mut n = Nav::framing(&b, &b, 60.0);
        n.camera.width = 800;
        n.camera.height = 600;
        n
    }

    fn close(a: [f64; 3], b: [f64; 3], eps: f64) -> bool {
        norm(sub(a, b)) < eps
    }

    #[test]
    fn orbit_keeps_the_distance_to_the_pivot_and_stays_upright() {
        let mut n = nav();
        let d0 = norm(sub(n.camera.position, n.pivot));
        n.orbit(120.0, 0.0);
        assert!((norm(sub(n.camera.position, n.pivot)) - d0).abs() < 1e-6);
        // Turned around the vertical: the height stays.
        let h = n.camera.position[2];
        n.orbit(300.0, 0.0);
        assert!((n.camera.position[2] - h).abs() < 1e-6);
        // Dragging down a long way stops short of straight down, never flips.
        for _ in 0..100 {
            n.orbit(0.0, 50.0);
        }
        let f = n.camera.forward();
        assert!(f[2] > -1.0 && f[2] < -0.99, "{f:?}");
        assert!((norm(sub(n.camera.position, n.pivot)) - d0).abs() < 1e-6);
    }

    #[test]
    fn pan_moves_the_pivot_with_the_cursor() {
        let mut n = nav();
        let project = |n: &Nav, p: [f64; 3]| {
            let e = n.camera.to_eye(p);
            let f = n.camera.focal();
            (400.0 + e[0] * f / e[2], 300.0 - e[1] * f / e[2])
        };
        let p = n.pivot;
        let before = project(&n, p);
        n.pan(40.0, -25.0);
        // The world point that was at the pivot moved 40 px right and 25 px up on screen.
        let after = project(&n, p);
        assert!(
            (after.0 - before.0 - 40.0).abs() < 1e-6,
            "{before:?} {after:?}"
        );
        assert!(
            (after.1 - before.1 + 25.0).abs() < 1e-6,
            "{before:?} {after:?}"
        );
    }

    #[test]
    fn zoom_goes_towards_the_cursor() {
        let mut n = nav();
        let d0 = norm(sub(n.camera.position, n.pivot));
        n.zoom_towards(400.0, 300.0, 100.0);
        let d1 = norm(sub(n.camera.position, n.pivot));
        assert!(d1 < d0 * 0.9, "{d0} {d1}");
        // Towards a point right of the centre: the eye moves right as well.
        let x0 = n.camera.to_eye(n.pivot)[0];
        n.zoom_towards(700.0, 300.0, 100.0);
        assert!(n.camera.to_eye(n.pivot)[0] < x0);
        // Zooming out is the way back.
        n.zoom_towards(400.0, 300.0, -400.0);
        assert!(norm(sub(n.camera.position, n.pivot)) > d1);
    }

    #[test]
    fn standard_views_and_flying() {
        let b = Aabb::new([0.0, 0.0, 0.0], [100.0, 100.0, 10.0]);
        let mut n = nav();
        n.standard(View::Top, &b);
        assert!(close(n.camera.forward(), [0.0, 0.0, -1.0], 1e-9));
        n.standard(View::Front, &b);
        assert!(close(n.camera.forward(), [0.0, 1.0, 0.0], 1e-9));
        for (v, f) in [
            (View::Bottom, [0.0, 0.0, 1.0]),
            (View::Back, [0.0, -1.0, 0.0]),
            (View::Left, [1.0, 0.0, 0.0]),
            (View::Right, [-1.0, 0.0, 0.0]),
        ] {
            n.standard(v, &b);
            assert!(close(n.camera.forward(), f, 1e-9), "{v:?}");
        }
        // W for half a second at 10 units per second: 5 units forward.
        n.speed = 10.0;
        let p = n.camera.position;
        n.fly_step([true, false, false, false, false, false], 0.5);
        assert!(close(n.camera.position, add(p, [-5.0, 0.0, 0.0]), 1e-9));
        // Looking around turns the view, not the eye.
        let p = n.camera.position;
        n.look_around(100.0, 0.0);
        assert!(close(n.camera.position, p, 1e-9));
        assert!(!close(n.camera.forward(), [-1.0, 0.0, 0.0], 1e-3));
    }

    #[test]
    fn the_parallel_view_keeps_the_size_at_the_target() {
        let b = Aabb::new([0.0, 0.0, 0.0], [100.0, 100.0, 10.0]);
        let mut n = nav();
        n.standard(View::Top, &b);
        let seen = |n: &Nav| {
            let c = &n.camera;
            let d = norm(sub(c.position, c.target));
            2.0 * d * (c.fov_y.to_radians() / 2.0).tan()
        };
        let (before, fov) = (seen(&n), n.camera.fov_y);
        n.set_parallel(true);
        assert!(n.parallel() && n.camera.fov_y == PARALLEL_FOV);
        assert!((seen(&n) - before).abs() < 1e-6 * before);
        assert!(close(n.camera.forward(), [0.0, 0.0, -1.0], 1e-9));
        // Lines of sight within half the field of view of parallel (at the top edge; across
        // the width, the aspect ratio times that).
        let edge = n.ray(n.camera.width as f64 / 2.0, 0.0);
        let angle = dot(edge, n.camera.forward())
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        assert!(angle <= PARALLEL_FOV / 2.0 + 1e-9, "{angle}");
        // The six views keep it; off gives the field of view back, the size as it was.
        n.standard(View::Front, &b);
        assert_eq!(n.camera.fov_y, PARALLEL_FOV);
        n.set_parallel(false);
        assert_eq!(n.camera.fov_y, fov);
        n.standard(View::Top, &b);
        assert!((seen(&n) - before).abs() < 1e-6 * before);
    }
}
