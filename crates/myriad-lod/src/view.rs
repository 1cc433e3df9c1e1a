//! The view: a pinhole camera (position, target, up, vertical field of view, viewport, near and
//! far) and its frustum, in world coordinates (f64: scans live at UTM-sized coordinates).

use myriad_core::Aabb;

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    if l > 0.0 { a.map(|v| v / l) } else { a }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub position: [f64; 3],
    pub target: [f64; 3],
    pub up: [f64; 3],
    /// Vertical field of view in degrees.
    pub fov_y: f64,
    pub width: u32,
    pub height: u32,
    pub near: f64,
    pub far: f64,
}

impl Camera {
    /// Looks at the whole of `bounds` from above at 45 degrees (Z up), from the south.
    pub fn framing(bounds: &Aabb, width: u32, height: u32, fov_y: f64) -> Camera {
        let c = bounds.center();
        let s = bounds.size();
        // A box of one point (a scan's preview of one chunk) is framed from a distance its
        // coordinates' magnitude can still tell from its centre.
        let magnitude = c.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        let radius = (0.5 * dot(s, s).sqrt()).max(1e-6 * magnitude);
        // Far enough that the bounding sphere fits the narrower field of view.
        let aspect = width as f64 / height.max(1) as f64;
        let half_v = (fov_y.to_radians() / 2.0).min(1.5);
        let half = if aspect < 1.0 {
            (half_v.tan() * aspect).atan()
        } else {
            half_v
        };
        let at = |distance: f64| {
            let d = distance / 2f64.sqrt();
            Camera {
                position: [c[0], c[1] - d, c[2] + d],
                target: c,
                up: [0.0, 0.0, 1.0],
                fov_y,
                width,
                height,
                near: (distance - radius).max(distance * 1e-4),
                far: distance + radius,
            }
        };
        // The bounding sphere fits at this distance; the box itself usually fits much nearer:
        // the nearest distance at which every corner is inside the view with a 5 % margin.
        let sphere = radius / half.sin();
        let fits = |distance: f64| {
            let cam = at(distance);
            let (tan_v, aspect) = ((fov_y.to_radians() / 2.0).tan() * 0.95, aspect);
            bounds.corners().iter().all(|&p| {
                let e = cam.to_eye(p);
                e[2] > 0.0 && e[0].abs() <= e[2] * tan_v * aspect && e[1].abs() <= e[2] * tan_v
            })
        };
        let (mut lo, mut hi) = (sphere * 0.05, sphere);
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if fits(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        at(hi)
    }

    /// Right, up and forward unit vectors (a right-handed eye frame looking along forward).
    pub fn basis(&self) -> ([f64; 3], [f64; 3], [f64; 3]) {
        let f = normalize(sub(self.target, self.position));
        let mut r = cross(f, self.up);
        if dot(r, r) < 1e-24 {
            // Looking along `up`: any perpendicular will do.
            r = cross(
                f,
                if f[0].abs() < 0.9 {
                    [1.0, 0.0, 0.0]
                } else {
                    [0.0, 1.0, 0.0]
                },
            );
        }
        let r = normalize(r);
        let u = cross(r, f);
        (r, u, f)
    }

    /// Two eyes `ipd` apart (in the data's units), left and right of this camera's eye along its
    /// right vector, looking in parallel (a headset's eyes): each the camera's field of view and
    /// image size.
    pub fn eyes(&self, ipd: f64) -> [Camera; 2] {
        let (r, _, _) = self.basis();
        [-0.5, 0.5].map(|k| {
            let d = r.map(|v| v * k * ipd);
            Camera {
                position: std::array::from_fn(|a| self.position[a] + d[a]),
                target: std::array::from_fn(|a| self.target[a] + d[a]),
                ..*self
            }
        })
    }

    /// A point in eye coordinates: x right, y up, z the depth along the view direction.
    pub fn to_eye(&self, p: [f64; 3]) -> [f64; 3] {
        let (r, u, f) = self.basis();
        let d = sub(p, self.position);
        [dot(d, r), dot(d, u), dot(d, f)]
    }

    /// Where a box (its 8 corners) lies in the image: its nearest eye depth and the pixel
    /// rectangle `[x0, y0, x1, y1]` its corners span (x right, y down; not clipped to the
    /// image); `None` when a corner is at or before the near plane.
    pub fn box_on_screen(&self, corners: &[[f64; 3]; 8]) -> Option<(f64, [f64; 4])> {
        let (r, u, f) = self.basis();
        let focal = self.focal();
        let (w, h) = (self.width as f64, self.height as f64);
        let mut nearest = f64::INFINITY;
        let mut rect = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for &c in corners {
            let d = sub(c, self.position);
            let (x, y, z) = (dot(d, r), dot(d, u), dot(d, f));
            if z <= self.near {
                return None;
            }
            nearest = nearest.min(z);
            let (px, py) = (w / 2.0 + x * focal / z, h / 2.0 - y * focal / z);
            rect = [
                rect[0].min(px),
                rect[1].min(py),
                rect[2].max(px),
                rect[3].max(py),
            ];
        }
        Some((nearest, rect))
    }

    /// Pixels that one unit of length covers at eye depth `depth` (on the view axis).
    pub fn pixels_per_unit(&self, depth: f64) -> f64 {
        self.focal() / depth.max(self.near)
    }

    /// Pixels that one unit of length covers at depth 1 (the focal length in pixels).
    pub fn focal(&self) -> f64 {
        self.height as f64 / (2.0 * (self.fov_y.to_radians() / 2.0).tan())
    }

    /// The view direction (unit).
    pub fn forward(&self) -> [f64; 3] {
        self.basis().2
    }

    /// The view-projection matrix (column-major, as WGSL's `mat4x4<f32>`) for positions given
    /// relative to `origin` (f32 keeps about 7 digits: points are uploaded relative to a nearby
    /// origin). Clip depth runs from 0 at the near plane to 1 at the far plane, as WebGPU wants.
    pub fn view_proj(&self, origin: [f64; 3]) -> [[f32; 4]; 4] {
        let (r, u, f) = self.basis();
        let eye = sub(self.position, origin);
        let fy = 1.0 / (self.fov_y.to_radians() / 2.0).tan();
        let fx = fy * self.height as f64 / self.width.max(1) as f64;
        let a = self.far / (self.far - self.near);
        let rows = [
            [fx * r[0], fx * r[1], fx * r[2], -fx * dot(r, eye)],
            [fy * u[0], fy * u[1], fy * u[2], -fy * dot(u, eye)],
            [
                a * f[0],
                a * f[1],
                a * f[2],
                -a * dot(f, eye) - a * self.near,
            ],
            [f[0], f[1], f[2], -dot(f, eye)],
        ];
        std::array::from_fn(|c| std::array::from_fn(|r| rows[r][c] as f32))
    }

    pub fn frustum(&self) -> Frustum {
        let (r, u, f) = self.basis();
        let tan_v = (self.fov_y.to_radians() / 2.0).tan();
        let tan_h = tan_v * self.width as f64 / self.height.max(1) as f64;
        let p = self.position;
        // Side planes through the eye, normals pointing inwards.
        let plane = |n: [f64; 3]| {
            let n = normalize(n);
            (n, -dot(n, p))
        };
        let left = plane([
            f[0] * tan_h + r[0],
            f[1] * tan_h + r[1],
            f[2] * tan_h + r[2],
        ]);
        let right = plane([
            f[0] * tan_h - r[0],
            f[1] * tan_h - r[1],
            f[2] * tan_h - r[2],
        ]);
        let bottom = plane([
            f[0] * tan_v + u[0],
            f[1] * tan_v + u[1],
            f[2] * tan_v + u[2],
        ]);
        let top = plane([
            f[0] * tan_v - u[0],
            f[1] * tan_v - u[1],
            f[2] * tan_v - u[2],
        ]);
        let near = (f, -dot(f, p) - self.near);
        let far = (f.map(|v| -v), dot(f, p) + self.far);
        Frustum {
            planes: [left, right, bottom, top, near, far],
        }
    }
}

impl Camera {
    /// Moves the near and far planes to just around `bounds` as seen from here (near at least
    /// 1/10,000 of far, so that depth keeps its precision).
    pub fn fit_depth(&mut self, bounds: &Aabb) {
        let depths = bounds.corners().map(|p| self.to_eye(p)[2]);
        let far = depths.iter().cloned().fold(f64::MIN, f64::max).max(1e-3) * 1.01;
        let near = depths.iter().cloned().fold(f64::MAX, f64::min) * 0.99;
        self.far = far;
        self.near = near.max(far * 1e-4);
    }

    /// Three views that tests and benchmarks share: the whole of `bounds` from above at 45
    /// degrees; straight down; and a close view across the middle from a tenth of the extent
    /// away, slightly above (where level of detail matters most).
    pub fn standard_views(bounds: &Aabb, width: u32, height: u32) -> [(&'static str, Camera); 3] {
        let overview = Camera::framing(bounds, width, height, 60.0);
        let c = bounds.center();
        let s = bounds.size();
        let extent = s[0].max(s[1]).max(1e-9);
        let distance = dot(sub(overview.position, c), sub(overview.position, c)).sqrt();
        let mut top = Camera {
            position: [c[0], c[1], c[2] + distance],
            target: c,
            up: [0.0, 1.0, 0.0],
            ..overview
        };
        top.fit_depth(bounds);
        let ground = [c[0], c[1], bounds.min[2] + 0.25 * s[2]];
        let mut close = Camera {
            position: [
                ground[0] - 0.06 * extent,
                ground[1] - 0.08 * extent,
                ground[2] + 0.03 * extent,
            ],
            target: ground,
            ..overview
        };
        close.fit_depth(bounds);
        [("overview", overview), ("top", top), ("close", close)]
    }

    /// The standard view `name` of `view` (see [`Camera::standard_views`]), or the overview
    /// (`framing` at 60 degrees) when None, its depth fitted to `all`: what the benchmarks and
    /// `mesh --view` look from. None: no view of that name.
    pub fn view(
        name: Option<&str>,
        view: &Aabb,
        all: &Aabb,
        width: u32,
        height: u32,
    ) -> Option<Camera> {
        let mut cam = match name {
            Some(v) => {
                Camera::standard_views(view, width, height)
                    .into_iter()
                    .find(|(n, _)| *n == v)?
                    .1
            }
            None => Camera::framing(view, width, height, 60.0),
        };
        cam.fit_depth(all);
        Some(cam)
    }
}

/// The box holding all but `fraction` of `points` at each end of each axis (outliers, such as
/// the stray returns far above a scan, would otherwise decide the framing and colour ramps).
pub fn robust_bounds(points: &[[f64; 3]], fraction: f64) -> Aabb {
    if points.is_empty() {
        return Aabb::EMPTY;
    }
    let mut b = Aabb::EMPTY;
    let k = ((points.len() as f64 * fraction) as usize).min((points.len() - 1) / 2);
    for axis in 0..3 {
        let mut v: Vec<f64> = points.iter().map(|p| p[axis]).collect();
        v.sort_unstable_by(f64::total_cmp);
        b.min[axis] = v[k];
        b.max[axis] = v[v.len() - 1 - k];
    }
    b
}

/// Six planes `n · p + d >= 0` inside.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frustum {
    pub planes: [([f64; 3], f64); 6],
}

impl Frustum {
    /// Does the box meet the frustum? (Conservative: a box near an edge may pass.)
    pub fn intersects(&self, b: &Aabb) -> bool {
        self.planes.iter().all(|(n, d)| {
            // The box corner furthest along the normal.
            let p: [f64; 3] =
                std::array::from_fn(|a| if n[a] >= 0.0 { b.max[a] } else { b.min[a] });
            dot(*n, p) + d >= 0.0
        })
    }

    pub fn contains(&self, p: [f64; 3]) -> bool {
        self.planes.iter().all(|(n, d)| dot(*n, p) + d >= 0.0)
    }

    /// Whether an oriented box may be in view (no plane has all its corners outside).
    pub fn intersects_obb(&self, b: &myriad_core::Obb) -> bool {
        let corners = b.corners();
        self.planes
            .iter()
            .all(|(n, d)| corners.iter().any(|&p| dot(*n, p) + d >= 0.0))
    }
}

/// A clipping box: only the points inside it are drawn, or only those outside.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Clip {
    pub bounds: Aabb,
    /// Keep the inside (else the outside).
    pub inside: bool,
}

impl Clip {
    /// Whether a node's cube can hold points the box lets through (for the selection: nodes it
    /// hides entirely take no budget).
    pub fn keeps(clip: Option<Clip>, cube: &Aabb) -> bool {
        let Some(c) = clip else { return true };
        let b = &c.bounds;
        if c.inside {
            (0..3).all(|a| cube.max[a] >= b.min[a] && cube.min[a] <= b.max[a])
        } else {
            !(0..3).all(|a| cube.min[a] >= b.min[a] && cube.max[a] <= b.max[a])
        }
    }

    /// The box relative to `origin` as the shaders take it: min with the mode (1 inside,
    /// 2 outside), max; all zero without a box.
    pub fn uniforms(clip: Option<Clip>, origin: [f64; 3]) -> [[f32; 4]; 2] {
        match clip {
            None => [[0.0; 4]; 2],
            Some(c) => {
                let r =
                    |v: [f64; 3]| std::array::from_fn::<f32, 3, _>(|a| (v[a] - origin[a]) as f32);
                let (lo, hi) = (r(c.bounds.min), r(c.bounds.max));
                [
                    [lo[0], lo[1], lo[2], if c.inside { 1.0 } else { 2.0 }],
                    [hi[0], hi[1], hi[2], 0.0],
                ]
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Camera {
        Camera {
            position: [0.0, -10.0, 0.0],
            target: [0.0, 0.0, 0.0],
            up: [0.0, 0.0, 1.0],
            fov_y: 90.0,
            width: 200,
            height: 100,
            near: 0.5,
            far: 100.0,
        }
    }

    #[test]
    fn eye_frame_and_frustum() {
        let c = cam();
        assert_eq!(c.to_eye([0.0, 0.0, 0.0]), [0.0, 0.0, 10.0]);
        let e = c.to_eye([1.0, 0.0, 2.0]);
        assert!((e[0] - 1.0).abs() < 1e-12 && (e[1] - 2.0).abs() < 1e-12);
        let f = c.frustum();
        assert!(f.contains([0.0, 0.0, 0.0]));
        assert!(!f.contains([0.0, -20.0, 0.0]), "behind the camera");
        assert!(!f.contains([0.0, 200.0, 0.0]), "beyond far");
        // 90 degrees vertical: at depth 10 the view reaches z = ±10, and x = ±20 (aspect 2).
        assert!(f.contains([19.0, 0.0, 9.0]));
        assert!(!f.contains([21.0, 0.0, 0.0]));
        assert!(!f.contains([0.0, 0.0, 11.0]));
        assert!(!f.contains([0.0, 0.0, -11.0]));
        assert!(!f.intersects(&Aabb::new([22.0, -0.5, -1.0], [25.0, 0.5, 1.0])));
        assert!(f.intersects(&Aabb::new([15.0, -0.5, -1.0], [25.0, 0.5, 1.0])));
        // One unit at depth 10 covers 100 / (2 tan 45°) / 10 = 5 pixels.
        assert!((c.pixels_per_unit(10.0) - 5.0).abs() < 1e-9);
    }

    #[test]
    fn view_projection_maps_to_clip_space() {
        let c = cam();
        let m = c.view_proj([0.0, -10.0, 0.0]);
        let clip = |p: [f64; 3]| {
            let q = [p[0], p[1] + 10.0, p[2], 1.0];
            let v: [f64; 4] =
                std::array::from_fn(|r| (0..4).map(|k| m[k][r] as f64 * q[k]).sum::<f64>());
            [v[0] / v[3], v[1] / v[3], v[2] / v[3]]
        };
        let centre = clip([0.0, 0.0, 0.0]);
        assert!(centre[0].abs() < 1e-6 && centre[1].abs() < 1e-6);
        assert!(
            (clip([0.0, -9.5, 0.0])[2]).abs() < 1e-5,
            "near plane at depth 0"
        );
        assert!(
            (clip([0.0, 90.0, 0.0])[2] - 1.0).abs() < 1e-5,
            "far plane at depth 1"
        );
        // At depth 10 the view reaches z = ±10 (top = +1) and x = ±20 (right = +1).
        assert!((clip([0.0, 0.0, 10.0])[1] - 1.0).abs() < 1e-5);
        assert!((clip([20.0, 0.0, 0.0])[0] - 1.0).abs() < 1e-5);
    }

    #[test]
    fn framing_sees_the_whole_box() {
        let b = Aabb::new([500000.0, 4400000.0, 0.0], [501000.0, 4400600.0, 40.0]);
        let c = Camera::framing(&b, 1280, 720, 60.0);
        let f = c.frustum();
        for p in b.corners() {
            assert!(f.contains(p), "{p:?} outside");
        }
        assert!(c.position[2] > b.max[2]);
    }

    #[test]
    fn one_point_is_framed_too() {
        let p = [500000.25, 4400000.5, 12.0];
        let c = Camera::framing(&Aabb::new(p, p), 640, 480, 60.0);
        assert!(c.position != c.target, "{c:?}");
        assert!(c.frustum().contains(p));
    }

    #[test]
    fn standard_views_look_at_the_data() {
        let b = Aabb::new([500000.0, 4400000.0, 0.0], [501000.0, 4401000.0, 40.0]);
        let views = Camera::standard_views(&b, 1280, 720);
        let names: Vec<&str> = views.iter().map(|v| v.0).collect();
        assert_eq!(names, ["overview", "top", "close"]);
        for (name, c) in &views {
            let f = c.frustum();
            assert!(f.contains(b.center()), "{name}: centre in view");
            // Near and far planes hold the whole box (no corner clipped in depth).
            for p in b.corners() {
                let d = c.to_eye(p)[2];
                assert!(d <= c.far, "{name}: corner beyond far");
            }
        }
        // Top: straight down; close: inside the extent, nearer than the overview.
        assert!(views[1].1.forward()[2] < -0.999);
        let dist = |c: &Camera| {
            let d = sub(c.position, c.target);
            dot(d, d).sqrt()
        };
        assert!(dist(&views[2].1) < dist(&views[0].1) / 5.0);
        assert!(b.contains(views[2].1.position));
    }

    #[test]
    fn robust_bounds_ignore_outliers() {
        let mut p: Vec<[f64; 3]> = (0..1000)
            .map(|i| [(i % 10) as f64, (i / 10 % 10) as f64, (i / 100) as f64])
            .collect();
        p.push([1e6, -1e6, 5e5]);
        let b = robust_bounds(&p, 0.005);
        assert_eq!((b.min, b.max), ([0.0; 3], [9.0; 3]));
        // Without trimming: everything.
        assert_eq!(robust_bounds(&p, 0.0).max, [1e6, 9.0, 5e5]);
        assert_eq!(robust_bounds(&[[1.0, 2.0, 3.0]], 0.1).min, [1.0, 2.0, 3.0]);
        assert!(robust_bounds(&[], 0.1).is_empty());
    }
}
