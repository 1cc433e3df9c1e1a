//! Placement of a scan in the project (Scheiblauer 2006, section 5.3): an oriented box that trims
//! the scan to the points that matter, and a transform from the scanner's own coordinate system
//! (SOCS) into the project's (PRCS). Read from a small text file, one keyword per line; `#` starts
//! a comment. All keywords are optional; numbers are separated by white space.
//!
//! | line | meaning |
//! |---|---|
//! | `TRANSFORM r00 r01 r02 tx r10 r11 r12 ty r20 r21 r22 tz` | PRCS from SOCS as a 3x4 matrix, by rows |
//! | `ROTATE-DEG ax ay az` | rotation, degrees, matrices multiplied Rx·Ry·Rz (not with TRANSFORM) |
//! | `TRANSLATE tx ty tz` | translation applied after the rotation (not with TRANSFORM) |
//! | `OBB-ANGLES SOCS\|PRCS cx cy cz hu hv hw ax ay az` | trimming box: centre, half lengths, axes = columns of Rx·Ry·Rz (degrees) |
//! | `OBB-NORMALS SOCS\|PRCS cx cy cz hu hv hw ux uy uz vx vy vz wx wy wz` | trimming box with its axis directions (made orthonormal) |
//!
//! The box is given in SOCS (tested on the points as read) or in PRCS (tested after the transform).
//! Points outside it are dropped and counted; the rest are transformed (normals rotated).

use crate::{PointSource, SourceInfo};
use myriad_core::{Affine, Error, Obb, PointBatch, Result};
use std::path::{Path, PathBuf};

/// Which coordinate system a trimming box is given in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Frame {
    /// The scanner's own coordinate system: the points as read.
    Scanner,
    /// The project coordinate system: the points after the transform.
    Project,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Placement {
    pub path: PathBuf,
    pub project_from_scanner: Affine,
    pub trim: Option<(Obb, Frame)>,
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn normalized(a: [f64; 3]) -> Option<[f64; 3]> {
    let l = dot(a, a).sqrt();
    (l > 1e-12).then(|| a.map(|c| c / l))
}

impl Placement {
    /// The sidecar placement of a scan: `scan.e57` -> `scan.e57.placement`, if that file exists.
    pub fn sidecar(scan: &Path) -> Option<PathBuf> {
        let mut name = scan.file_name()?.to_os_string();
        name.push(".placement");
        let p = scan.with_file_name(name);
        p.is_file().then_some(p)
    }

    pub fn read(path: &Path) -> Result<Placement> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Placement::parse(path, &text)
    }

    pub fn parse(path: &Path, text: &str) -> Result<Placement> {
        let (mut matrix, mut rotate, mut translate, mut trim) = (None, None, None, None);
        let combined = "TRANSFORM cannot be combined with ROTATE-DEG or TRANSLATE";
        for (i, raw) in text.lines().enumerate() {
            let line_no = i as u64 + 1;
            let bad = |m: String| Error::at_line(path, line_no, m);
            let line = raw.split('#').next().unwrap_or("").trim();
            let mut words = line.split_whitespace();
            let Some(key) = words.next() else { continue };
            let key = key.to_ascii_uppercase();
            let frame = if key.starts_with("OBB-") {
                match words.next().map(str::to_ascii_uppercase).as_deref() {
                    Some("SOCS") => Some(Frame::Scanner),
                    Some("PRCS") => Some(Frame::Project),
                    other => {
                        return Err(bad(format!(
                            "{key} needs SOCS or PRCS first, found {:?}",
                            other.unwrap_or("")
                        )));
                    }
                }
            } else {
                None
            };
            let nums = words
                .map(|w| {
                    w.parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| bad(format!("not a number: \"{w}\"")))
                })
                .collect::<Result<Vec<f64>>>()?;
            let want = |n: usize| -> Result<()> {
                if nums.len() == n {
                    Ok(())
                } else {
                    Err(bad(format!(
                        "{key} takes {n} numbers, found {}",
                        nums.len()
                    )))
                }
            };
            let v3 = |k: usize| [nums[k], nums[k + 1], nums[k + 2]];
            match key.as_str() {
                "TRANSFORM" => {
                    want(12)?;
                    let m = Affine {
                        rows: std::array::from_fn(|r| std::array::from_fn(|c| nums[r * 4 + c])),
                    };
                    let l = m.linear();
                    let det = dot(l[0], cross(l[1], l[2]));
                    // Relative to the rows' lengths, so that the test does not depend on units.
                    let size = (0..3).map(|r| dot(l[r], l[r]).sqrt()).product::<f64>();
                    if !(det.abs() > 1e-9 * size) || !det.is_finite() {
                        return Err(bad(format!(
                            "TRANSFORM is not invertible (determinant {det:e}): it would flatten the scan"
                        )));
                    }
                    if rotate.is_some() || translate.is_some() {
                        return Err(bad(combined.into()));
                    }
                    matrix = Some(m);
                }
                "ROTATE-DEG" => {
                    want(3)?;
                    if matrix.is_some() {
                        return Err(bad(combined.into()));
                    }
                    rotate = Some(Affine::rotation_xyz_degrees(v3(0)));
                }
                "TRANSLATE" => {
                    want(3)?;
                    if matrix.is_some() {
                        return Err(bad(combined.into()));
                    }
                    translate = Some(Affine::translation(v3(0)));
                }
                "OBB-ANGLES" | "OBB-NORMALS" => {
                    if trim.is_some() {
                        return Err(bad("only one trimming box per placement".into()));
                    }
                    let axes = if key == "OBB-ANGLES" {
                        want(9)?;
                        let m = Affine::rotation_xyz_degrees(v3(6)).linear();
                        // The box's axes are the rotation's columns.
                        std::array::from_fn(|c| [m[0][c], m[1][c], m[2][c]])
                    } else {
                        want(15)?;
                        let (u, v) = (v3(6), v3(9));
                        let w = v3(12);
                        let det = dot(u, cross(v, w));
                        if det.abs() < 1e-9 {
                            return Err(bad("OBB-NORMALS directions are coplanar".into()));
                        }
                        // Gram-Schmidt from u; the containment test ignores the axes' signs.
                        let u = normalized(u).expect("non-zero: det != 0");
                        let d = dot(v, u);
                        let v = normalized([v[0] - d * u[0], v[1] - d * u[1], v[2] - d * u[2]])
                            .expect("non-zero: det != 0");
                        let w = cross(u, v);
                        [u, v, w]
                    };
                    let half = v3(3);
                    if half.iter().any(|h| *h < 0.0) {
                        return Err(bad("half lengths must not be negative".into()));
                    }
                    trim = Some((
                        Obb {
                            center: v3(0),
                            axes,
                            half_extents: half,
                        },
                        frame.expect("OBB keyword"),
                    ));
                }
                other => return Err(bad(format!("unknown keyword \"{other}\""))),
            }
        }
        let project_from_scanner = matrix.unwrap_or_else(|| {
            translate
                .unwrap_or(Affine::IDENTITY)
                .then_after(&rotate.unwrap_or(Affine::IDENTITY))
        });
        Ok(Placement {
            path: path.to_path_buf(),
            project_from_scanner,
            trim,
        })
    }
}

/// A source with its placement applied: points outside the trimming box dropped, the rest in
/// project coordinates.
pub struct Placed {
    inner: Box<dyn PointSource>,
    placement: Placement,
    info: SourceInfo,
    trimmed: u64,
    /// Points whose transformed coordinates overflowed.
    non_finite: u64,
}

impl Placed {
    pub fn new(inner: Box<dyn PointSource>, placement: Placement) -> Placed {
        let mut info = inner.info().clone();
        // The header's bounds and count describe the scan before trimming and transforming.
        info.bounds = None;
        // The scanner positions move with the points.
        for o in &mut info.origins {
            *o = placement.project_from_scanner.apply(*o);
        }
        if placement.trim.is_some() {
            info.points = None;
        }
        Placed {
            inner,
            placement,
            info,
            trimmed: 0,
            non_finite: 0,
        }
    }

    pub fn placement(&self) -> &Placement {
        &self.placement
    }
}

impl PointSource for Placed {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn las_header(&self) -> Option<&::las::Header> {
        self.inner.las_header()
    }

    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>> {
        let t = &self.placement.project_from_scanner;
        while let Some(mut b) = self.inner.read_batch(max)? {
            if let Some((obb, frame)) = &self.placement.trim {
                let keep: Vec<bool> = b
                    .positions
                    .iter()
                    .map(|p| {
                        obb.contains(if *frame == Frame::Scanner {
                            *p
                        } else {
                            t.apply(*p)
                        })
                    })
                    .collect();
                let before = b.len();
                b.retain_mask(&keep);
                self.trimmed += (before - b.len()) as u64;
            }
            for p in &mut b.positions {
                *p = t.apply(*p);
            }
            // A transform of huge (finite) numbers can still overflow a coordinate.
            if b.positions.iter().any(|p| !p.iter().all(|c| c.is_finite())) {
                let keep: Vec<bool> = b
                    .positions
                    .iter()
                    .map(|p| p.iter().all(|c| c.is_finite()))
                    .collect();
                let before = b.len();
                b.retain_mask(&keep);
                self.non_finite += (before - b.len()) as u64;
            }
            if let Some(normals) = &mut b.normal {
                for n in normals {
                    *n = t.apply_vector(n.map(f64::from)).map(|c| c as f32);
                }
            }
            if !b.is_empty() {
                return Ok(Some(b));
            }
        }
        Ok(None)
    }

    fn skipped_non_finite(&self) -> u64 {
        self.inner.skipped_non_finite() + self.non_finite
    }

    fn trimmed(&self) -> u64 {
        self.trimmed
    }

    fn placement_path(&self) -> Option<&Path> {
        Some(&self.placement.path)
    }
}
