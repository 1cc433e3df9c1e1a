//! Photos and panoramas with a dataset: the images an E57 carries (pinhole and spherical ones
//! with their poses, visual reference images without one) and panorama sets described as
//! Potree does (`coordinates.txt`), kept beside the dataset: `city.photos.json` lists them,
//! `city.photos/` holds their images (their own bytes, JPEG or PNG).
//!
//! ```json
//! {"myriad": "photos", "version": 1, "photos": [
//!   {"name": "cam 1", "kind": "pinhole", "width": 4000, "height": 3000, "file": "1.jpg",
//!    "pose": {"position": [x, y, z], "rotation": [w, x, y, z]},
//!    "focal": [fx, fy], "principal": [cx, cy]},
//!   {"name": "pano 1", "kind": "spherical", "width": 8192, "height": 4096, "file": "2.jpg",
//!    "pose": {...}},
//!   {"name": "reference", "kind": "reference", "width": 3072, "height": 2304, "file": "3.jpg",
//!    "pose": null}]}
//! ```
//!
//! The camera's frame (the pose's rotation takes it to the dataset's axes): a pinhole camera
//! looks along +z, its image's columns grow along +x and its rows along +y (down), a point at
//! (x, y, z) in it on pixel (cx + fx x / z, cy + fy y / z) (`focal` in pixels: E57's focal
//! length over its pixel size); a spherical image spans azimuth (from +x towards +y) from +180
//! degrees at its left edge to -180 at its right, and elevation from +90 at its top to -90 at its
//! bottom (E57's pixel sizes in radians; a full panorama's).

use serde_json::{Value, json};

/// What an image is and how it maps the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    /// A perspective camera: focal lengths and principal point, in pixels.
    Pinhole {
        focal: [f64; 2],
        principal: [f64; 2],
    },
    /// A spherical (equirectangular) panorama.
    Spherical,
    /// An image shown with the data, not placed (E57's visual reference).
    Reference,
}

/// Where a camera was: its centre, and the rotation (a unit quaternion, w x y z) from its frame
/// to the dataset's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub position: [f64; 3],
    pub rotation: [f64; 4],
}

impl Pose {
    /// `v` of the camera's frame in the dataset's axes.
    pub fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        let [w, x, y, z] = self.rotation;
        let n = (w * w + x * x + y * y + z * z).sqrt().max(1e-300);
        let (w, x, y, z) = (w / n, x / n, y / n, z / n);
        let m = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
    }

    /// `p` of the dataset in the camera's frame.
    pub fn to_camera(&self, p: [f64; 3]) -> [f64; 3] {
        let d: [f64; 3] = std::array::from_fn(|i| p[i] - self.position[i]);
        let [w, x, y, z] = self.rotation;
        Pose {
            position: [0.0; 3],
            rotation: [w, -x, -y, -z],
        }
        .rotate(d)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Photo {
    pub name: String,
    pub kind: Kind,
    pub width: u32,
    pub height: u32,
    /// The image, relative to the photos' folder.
    pub file: String,
    pub pose: Option<Pose>,
}

/// A camera looking from a photo's pose: eye, target, up, vertical field of view (degrees).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhotoView {
    pub eye: [f64; 3],
    pub target: [f64; 3],
    pub up: [f64; 3],
    pub fov_y: f64,
}

impl Photo {
    /// The pixel (column, row, from the top left) where `p` of the dataset shows, where it is in
    /// front of a placed pinhole camera, or anywhere on a placed panorama.
    pub fn project(&self, p: [f64; 3]) -> Option<[f64; 2]> {
        let pose = self.pose?;
        let c = pose.to_camera(p);
        match self.kind {
            Kind::Pinhole { focal, principal } => (c[2] > 1e-9).then(|| {
                [
                    principal[0] + focal[0] * c[0] / c[2],
                    principal[1] + focal[1] * c[1] / c[2],
                ]
            }),
            Kind::Spherical => {
                let az = c[1].atan2(c[0]);
                let el = c[2].atan2(c[0].hypot(c[1]));
                let (w, h) = (self.width as f64, self.height as f64);
                Some([
                    (std::f64::consts::PI - az) / std::f64::consts::TAU * w,
                    (std::f64::consts::FRAC_PI_2 - el) / std::f64::consts::PI * h,
                ])
            }
            Kind::Reference => None,
        }
    }

    /// The view from the photo's pose: a pinhole camera's own (along its axis, its vertical
    /// field of view); a panorama's centre column (its +x), 90 degrees.
    pub fn view(&self) -> Option<PhotoView> {
        let pose = self.pose?;
        let (forward, up, fov_y) = match self.kind {
            Kind::Pinhole { focal, .. } => (
                pose.rotate([0.0, 0.0, 1.0]),
                pose.rotate([0.0, -1.0, 0.0]),
                2.0 * (self.height as f64 / 2.0 / focal[1]).atan().to_degrees(),
            ),
            Kind::Spherical => (
                pose.rotate([1.0, 0.0, 0.0]),
                pose.rotate([0.0, 0.0, 1.0]),
                90.0,
            ),
            Kind::Reference => return None,
        };
        let e = pose.position;
        Some(PhotoView {
            eye: e,
            target: std::array::from_fn(|i| e[i] + forward[i]),
            up,
            fov_y,
        })
    }

    pub fn kind_name(&self) -> &'static str {
        match self.kind {
            Kind::Pinhole { .. } => "pinhole",
            Kind::Spherical => "spherical",
            Kind::Reference => "reference",
        }
    }

    pub fn to_json(&self) -> Value {
        let mut v = json!({
            "name": self.name, "kind": self.kind_name(), "width": self.width,
            "height": self.height, "file": self.file,
            "pose": self.pose.map(|p| json!({"position": p.position, "rotation": p.rotation})),
        });
        if let Kind::Pinhole { focal, principal } = self.kind {
            v["focal"] = json!(focal);
            v["principal"] = json!(principal);
        }
        v
    }

    pub fn from_json(v: &Value, at: &str) -> Result<Photo, String> {
        let text = |k: &str| {
            v.get(k)
                .and_then(Value::as_str)
                .map(str::to_string)
                .ok_or_else(|| format!("{at}.{k}: not a text"))
        };
        let num = |x: &Value| x.as_f64().filter(|f| f.is_finite() && f.abs() <= 1e12);
        let nums = |k: &str, n: usize, x: &Value| -> Result<Vec<f64>, String> {
            match x.as_array() {
                Some(a) if a.len() == n && a.iter().all(|e| num(e).is_some()) => {
                    Ok(a.iter().filter_map(num).collect())
                }
                _ => Err(format!("{at}.{k}: {n} numbers")),
            }
        };
        let size = |k: &str| {
            v.get(k)
                .and_then(Value::as_u64)
                .filter(|&s| (1..=1 << 20).contains(&s))
                .map(|s| s as u32)
                .ok_or_else(|| format!("{at}.{k}: 1 to 1048576 pixels"))
        };
        let file = text("file")?;
        if file.is_empty() || file.contains("..") || file.contains('/') || file.contains('\\') {
            return Err(format!("{at}.file: a name in the photos' folder"));
        }
        let kind = match text("kind")?.as_str() {
            "pinhole" => {
                let f = nums("focal", 2, v.get("focal").unwrap_or(&Value::Null))?;
                let c = nums("principal", 2, v.get("principal").unwrap_or(&Value::Null))?;
                if !(f[0] > 0.0 && f[1] > 0.0) {
                    return Err(format!("{at}.focal: positive"));
                }
                Kind::Pinhole {
                    focal: [f[0], f[1]],
                    principal: [c[0], c[1]],
                }
            }
            "spherical" => Kind::Spherical,
            "reference" => Kind::Reference,
            k => {
                return Err(format!(
                    "{at}.kind: \"{k}\": pinhole, spherical or reference"
                ));
            }
        };
        let pose = match v.get("pose") {
            None | Some(Value::Null) => None,
            Some(p) => {
                let position = nums(
                    "pose.position",
                    3,
                    p.get("position").unwrap_or(&Value::Null),
                )?;
                let r = nums(
                    "pose.rotation",
                    4,
                    p.get("rotation").unwrap_or(&Value::Null),
                )?;
                if r.iter().map(|x| x * x).sum::<f64>() < 1e-12 {
                    return Err(format!("{at}.pose.rotation: a unit quaternion"));
                }
                Some(Pose {
                    position: [position[0], position[1], position[2]],
                    rotation: [r[0], r[1], r[2], r[3]],
                })
            }
        };
        Ok(Photo {
            name: text("name")?,
            kind,
            width: size("width")?,
            height: size("height")?,
            file,
            pose,
        })
    }
}

/// The photos list's file beside a dataset: `city.myr` → `city.photos.json`.
pub fn sidecar_for(dataset: &std::path::Path) -> std::path::PathBuf {
    let stem = dataset
        .file_stem()
        .map_or_else(|| "photos".into(), |n| n.to_string_lossy().into_owned());
    dataset.with_file_name(format!("{stem}.photos.json"))
}

/// The folder of the photos' images beside a dataset: `city.photos/`.
pub fn folder_for(dataset: &std::path::Path) -> std::path::PathBuf {
    let stem = dataset
        .file_stem()
        .map_or_else(|| "photos".into(), |n| n.to_string_lossy().into_owned());
    dataset.with_file_name(format!("{stem}.photos"))
}

/// The largest photos list (and Potree panorama list) read, bytes.
pub const MAX_BYTES: usize = 64 << 20;

/// The most photos a dataset keeps.
pub const MAX_PHOTOS: usize = 100_000;

/// The photos list's text.
pub fn to_text(photos: &[Photo]) -> String {
    let lines: Vec<String> = photos
        .iter()
        .map(|p| format!("    {}", p.to_json()))
        .collect();
    format!(
        "{{\n  \"myriad\": \"photos\",\n  \"version\": 1,\n  \"photos\": [\n{}\n  ]\n}}\n",
        lines.join(",\n")
    )
}

/// A photos list from its text; an error names the line or the member.
pub fn parse(text: &str) -> Result<Vec<Photo>, String> {
    let v: Value = serde_json::from_str(text)
        .map_err(|e| format!("line {} column {}: {e}", e.line(), e.column()))?;
    if v.get("myriad").and_then(Value::as_str) != Some("photos") {
        return Err("not a Myriad photos list (no \"myriad\": \"photos\")".into());
    }
    let list = v
        .get("photos")
        .and_then(Value::as_array)
        .ok_or("photos: not a list")?;
    if list.len() > MAX_PHOTOS {
        return Err(format!("photos: more than {MAX_PHOTOS}"));
    }
    (list.iter().enumerate())
        .map(|(i, p)| Photo::from_json(p, &format!("photos[{i}]")))
        .collect()
}

/// The quaternion (w x y z) of a rotation whose columns are `m`'s (the camera's axes in the
/// dataset's).
pub fn quaternion(m: [[f64; 3]; 3]) -> [f64; 4] {
    let t = m[0][0] + m[1][1] + m[2][2];
    if t > 0.0 {
        let s = (t + 1.0).sqrt() * 2.0;
        [
            0.25 * s,
            (m[2][1] - m[1][2]) / s,
            (m[0][2] - m[2][0]) / s,
            (m[1][0] - m[0][1]) / s,
        ]
    } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
        let s = (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt() * 2.0;
        [
            (m[2][1] - m[1][2]) / s,
            0.25 * s,
            (m[0][1] + m[1][0]) / s,
            (m[0][2] + m[2][0]) / s,
        ]
    } else if m[1][1] > m[2][2] {
        let s = (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt() * 2.0;
        [
            (m[0][2] - m[2][0]) / s,
            (m[0][1] + m[1][0]) / s,
            0.25 * s,
            (m[1][2] + m[2][1]) / s,
        ]
    } else {
        let s = (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt() * 2.0;
        [
            (m[1][0] - m[0][1]) / s,
            (m[0][2] + m[2][0]) / s,
            (m[1][2] + m[2][1]) / s,
            0.25 * s,
        ]
    }
}

/// Panoramas as Potree lists them (`coordinates.txt`): a header line, then a line a panorama,
/// tab-separated (spaces where a line has no tab), names quoted or not: file, time, x, y, z, course, pitch, roll (degrees; the course is
/// the heading of the panorama's centre column, clockwise from +y). Each a spherical photo of
/// `size` (its width and height).
pub fn potree_panoramas(
    text: &str,
    size: impl Fn(&str) -> Option<(u32, u32)>,
) -> Result<Vec<Photo>, String> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = if line.contains('\t') {
            line.split('\t')
                .map(|s| s.trim().trim_matches('"'))
                .collect()
        } else {
            line.split_whitespace()
                .map(|s| s.trim_matches('"'))
                .collect()
        };
        let f: Vec<&str> = f.into_iter().filter(|s| !s.is_empty()).collect();
        if f.is_empty() {
            continue;
        }
        let at = format!("line {}", i + 1);
        if f.len() < 8 {
            return Err(format!("{at}: file, time, x, y, z, course, pitch, roll"));
        }
        let n = |k: usize| {
            f[k].parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("{at}: \"{}\" is not a number", f[k]))
        };
        let (x, y, z, course, pitch, roll) = (n(2)?, n(3)?, n(4)?, n(5)?, n(6)?, n(7)?);
        let (w, h) = size(f[0]).ok_or_else(|| format!("{at}: {}: no such image", f[0]))?;
        // Heading about +z (course clockwise from +y: the centre column's azimuth from +x is
        // 90 - course), then pitch about the camera's y, roll about its x.
        let half = |a: f64| (a.to_radians() / 2.0).sin_cos();
        let (sz, cz) = half(90.0 - course);
        let (sy, cy) = half(-pitch);
        let (sx, cx) = half(roll);
        let q = [
            cz * cy * cx + sz * sy * sx,
            cz * cy * sx - sz * sy * cx,
            cz * sy * cx + sz * cy * sx,
            sz * cy * cx - cz * sy * sx,
        ];
        out.push(Photo {
            name: f[0].to_string(),
            kind: Kind::Spherical,
            width: w,
            height: h,
            file: f[0].to_string(),
            pose: Some(Pose {
                position: [x, y, z],
                rotation: q,
            }),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pinhole_camera_sees_its_axis_at_its_principal_point() {
        // A camera at (10, 0, 5) looking along +y, up +z: its axes x = +x, y (down) = -z,
        // z (forward) = +y.
        let m = [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]];
        let p = Photo {
            name: "c".into(),
            kind: Kind::Pinhole {
                focal: [100.0, 100.0],
                principal: [160.0, 120.0],
            },
            width: 320,
            height: 240,
            file: "c.png".into(),
            pose: Some(Pose {
                position: [10.0, 0.0, 5.0],
                rotation: quaternion(m),
            }),
        };
        let px = p.project([10.0, 50.0, 5.0]).unwrap();
        assert!(
            (px[0] - 160.0).abs() < 1e-9 && (px[1] - 120.0).abs() < 1e-9,
            "{px:?}"
        );
        // Up and to the right: above (row smaller), right (column larger).
        let px = p.project([11.0, 50.0, 6.0]).unwrap();
        assert!(
            (px[0] - 162.0).abs() < 1e-9 && (px[1] - 118.0).abs() < 1e-9,
            "{px:?}"
        );
        assert!(p.project([10.0, -50.0, 5.0]).is_none(), "behind");
        let v = p.view().unwrap();
        assert!((v.target[1] - 1.0).abs() < 1e-12 && (v.up[2] - 1.0).abs() < 1e-12);
        assert!((v.fov_y - 2.0 * (1.2f64).atan().to_degrees()).abs() < 1e-9);
        let back = parse(&to_text(std::slice::from_ref(&p))).unwrap();
        assert_eq!(back, vec![p]);
        assert!(parse(r#"{"myriad": "photos", "photos": [{"name": "a", "kind": "fish", "width": 1, "height": 1, "file": "a"}]}"#)
            .unwrap_err().contains("photos[0].kind"));
        assert!(parse(r#"{"myriad": "photos", "photos": [{"name": "a", "kind": "reference", "width": 1, "height": 1, "file": "../a"}]}"#)
            .unwrap_err().contains("photos[0].file"));
    }

    #[test]
    fn a_panorama_maps_azimuth_and_elevation() {
        let p = Photo {
            name: "p".into(),
            kind: Kind::Spherical,
            width: 360,
            height: 180,
            file: "p.jpg".into(),
            pose: Some(Pose {
                position: [0.0; 3],
                rotation: [1.0, 0.0, 0.0, 0.0],
            }),
        };
        // +x: the centre; +y (azimuth 90): a quarter to the left; straight up: the top row.
        assert_eq!(p.project([5.0, 0.0, 0.0]).unwrap(), [180.0, 90.0]);
        let l = p.project([0.0, 5.0, 0.0]).unwrap();
        assert!((l[0] - 90.0).abs() < 1e-9 && (l[1] - 90.0).abs() < 1e-9);
        assert!(p.project([0.0, 0.0, 5.0]).unwrap()[1].abs() < 1e-9);
        // Potree's course 0 looks north (+y): the centre column.
        let set = potree_panoramas(
            "File\tTime\tX\tY\tZ\tcourse\tpitch\troll\np.jpg\t0\t1\t2\t3\t0\t0\t0\n",
            |_| Some((360, 180)),
        )
        .unwrap();
        let c = set[0].project([1.0, 12.0, 3.0]).unwrap();
        assert!(
            (c[0] - 180.0).abs() < 1e-6 && (c[1] - 90.0).abs() < 1e-6,
            "{c:?}"
        );
        assert!(
            potree_panoramas("h\nq.jpg 0 1 2\n", |_| Some((1, 1)))
                .unwrap_err()
                .starts_with("line 2")
        );
    }
}
