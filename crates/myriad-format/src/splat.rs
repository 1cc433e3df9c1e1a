//! Splat pages of the `mwkd` structure (Goswami et al. 2010, section III.C): for each point of a
//! node, its normal as a 16-bit index into a cube map of 104 x 104 cells per face, and its splat
//! radius in 8 bits between the node's smallest and largest radius. The page is the normal codes
//! (u16, little-endian) then the radius codes, zstd-compressed; its entry in the hierarchy carries
//! the radius range, the node's normal cone and whether its points are aggregates (inner nodes) or
//! original points (leaves).

pub use crate::hierarchy::SplatInfo;

/// Cells per side of a cube-map face.
pub const FACE_CELLS: u32 = 104;

/// The smallest cone holding both normal cones `a` and `b` (unit axis, cosine of the half
/// angle; -1: every direction): what a node's cone must hold of its children's, so that a node
/// facing away has no subtree that does not.
pub fn cone_union(a: [f32; 4], b: [f32; 4]) -> [f32; 4] {
    let angle = |c: f32| (c.clamp(-1.0, 1.0) as f64).acos();
    let (ta, tb) = (angle(a[3]), angle(b[3]));
    let dot: f64 = (0..3).map(|k| a[k] as f64 * b[k] as f64).sum();
    let phi = dot.clamp(-1.0, 1.0).acos();
    if phi + tb <= ta {
        return a;
    }
    if phi + ta <= tb {
        return b;
    }
    let t = (ta + phi + tb) / 2.0;
    if t >= std::f64::consts::PI || phi >= std::f64::consts::PI - 1e-9 {
        return [0.0, 0.0, 1.0, -1.0];
    }
    // The axis turned from a's towards b's by t - ta, in their plane.
    let turn = t - ta;
    let perp: [f64; 3] = std::array::from_fn(|k| b[k] as f64 - dot * a[k] as f64);
    let len = (perp.iter().map(|x| x * x).sum::<f64>()).sqrt();
    if len < 1e-12 {
        return [a[0], a[1], a[2], t.cos() as f32];
    }
    let axis: [f64; 3] =
        std::array::from_fn(|k| a[k] as f64 * turn.cos() + perp[k] / len * turn.sin());
    // Rounding: a hair wider, never narrower.
    [
        axis[0] as f32,
        axis[1] as f32,
        axis[2] as f32,
        ((t + 1e-6).min(std::f64::consts::PI).cos()) as f32,
    ]
}

/// Normals and radii of a node's points, decoded.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Splats {
    pub normals: Vec<[f32; 3]>,
    pub radii: Vec<f32>,
}

/// The cube-map index of a direction (the face of its largest component, then the cell).
pub fn normal_code(n: [f32; 3]) -> u16 {
    let a = n.map(f32::abs);
    let axis = if a[0] >= a[1] && a[0] >= a[2] {
        0
    } else if a[1] >= a[2] {
        1
    } else {
        2
    };
    let m = a[axis].max(f32::MIN_POSITIVE);
    let face = axis as u32 * 2 + (n[axis] < 0.0) as u32;
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let cell = |x: f32| (((x / m + 1.0) * 0.5 * FACE_CELLS as f32) as u32).min(FACE_CELLS - 1);
    (face * FACE_CELLS * FACE_CELLS + cell(n[v]) * FACE_CELLS + cell(n[u])) as u16
}

/// The unit direction at the centre of a cube-map cell.
pub fn normal_from_code(code: u16) -> [f32; 3] {
    let c = code as u32;
    let face = (c / (FACE_CELLS * FACE_CELLS)).min(5);
    let rest = c % (FACE_CELLS * FACE_CELLS);
    let (cv, cu) = (rest / FACE_CELLS, rest % FACE_CELLS);
    let axis = (face / 2) as usize;
    let mut n = [0.0f32; 3];
    n[axis] = if face % 2 == 1 { -1.0 } else { 1.0 };
    let at = |k: u32| (k as f32 + 0.5) / FACE_CELLS as f32 * 2.0 - 1.0;
    n[(axis + 1) % 3] = at(cu);
    n[(axis + 2) % 3] = at(cv);
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    n.map(|x| x / len)
}

/// The 8-bit code of `r` in `[lo, hi]`.
pub fn radius_code(r: f32, lo: f32, hi: f32) -> u8 {
    if hi <= lo {
        return 0;
    }
    (((r - lo) / (hi - lo)).clamp(0.0, 1.0) * 255.0).round() as u8
}

pub fn radius_from_code(c: u8, lo: f32, hi: f32) -> f32 {
    lo + (hi - lo) * c as f32 / 255.0
}

#[cfg(not(target_arch = "wasm32"))]
/// The page bytes of `s` and its radius range.
pub fn encode(s: &Splats) -> (Vec<u8>, [f32; 2]) {
    let lo = s.radii.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = s.radii.iter().copied().fold(0.0f32, f32::max);
    let lo = if lo.is_finite() { lo } else { 0.0 };
    let mut raw = Vec::with_capacity(s.normals.len() * 3);
    for &n in &s.normals {
        raw.extend_from_slice(&normal_code(n).to_le_bytes());
    }
    raw.extend(s.radii.iter().map(|&r| radius_code(r, lo, hi)));
    (crate::codec::compress(&raw, 3), [lo, hi])
}

/// Decodes a page of `n` splats; an error says what is wrong.
pub fn decode(page: &[u8], n: usize, radius: [f32; 2]) -> Result<Splats, String> {
    // Streamed, so that memory follows what the page really holds rather than the count its
    // entry claims (a damaged count asked for 7.7 GB up front under the fuzzer).
    let raw =
        crate::codec::decompress_streamed(page, n * 3).map_err(|e| format!("splat page: {e}"))?;
    if raw.len() != n * 3 {
        return Err(format!(
            "splat page holds {} bytes, {n} splats need {}",
            raw.len(),
            n * 3
        ));
    }
    let normals = raw[..2 * n]
        .chunks_exact(2)
        .map(|b| {
            let code = u16::from_le_bytes([b[0], b[1]]);
            if code as u32 >= 6 * FACE_CELLS * FACE_CELLS {
                Err(format!("normal code {code} is not a cube-map cell"))
            } else {
                Ok(normal_from_code(code))
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    let radii = raw[2 * n..]
        .iter()
        .map(|&c| radius_from_code(c, radius[0], radius[1]))
        .collect();
    Ok(Splats { normals, radii })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normals_round_trip_within_a_cell() {
        // 6 * 104^2 cells fit in 16 bits.
        const { assert!(6 * FACE_CELLS * FACE_CELLS <= 1 << 16) };
        let mut worst = 1.0f32;
        for i in 0..2000 {
            let t = i as f32 * 0.7;
            let z = (i as f32 / 1000.0) - 1.0;
            let r = (1.0 - z * z).sqrt();
            let n = [r * t.cos(), r * t.sin(), z];
            let back = normal_from_code(normal_code(n));
            let dot: f32 = (0..3).map(|a| n[a] * back[a]).sum();
            worst = worst.min(dot);
        }
        // A cell spans at most 2/104 of a face: about 1.1 degrees.
        assert!(
            worst > 1.5f32.to_radians().cos(),
            "{}",
            worst.acos().to_degrees()
        );
        for axis in [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]] {
            let back = normal_from_code(normal_code(axis));
            assert!((0..3).map(|a| axis[a] * back[a]).sum::<f32>() > 0.9999);
        }
    }

    #[test]
    fn a_cone_union_holds_both_cones() {
        let deg = |d: f32| d.to_radians().cos();
        let up = [0.0, 0.0, 1.0, deg(10.0)];
        // Inside: the wider one.
        assert_eq!(cone_union(up, [0.0, 0.0, 1.0, deg(5.0)]), up);
        // 30 degrees apart, 10 each: 25 degrees about the middle.
        let s = 30f32.to_radians();
        let tilted = [s.sin(), 0.0, s.cos(), deg(10.0)];
        let u = cone_union(up, tilted);
        assert!((u[3].acos().to_degrees() - 25.0).abs() < 0.01, "{u:?}");
        let mid = 15f32.to_radians();
        assert!((u[0] - mid.sin()).abs() < 1e-5 && (u[2] - mid.cos()).abs() < 1e-5);
        // Every direction of both, sampled, lies within the union.
        for c in [up, tilted] {
            let t = c[3].acos();
            for k in 0..16 {
                let az = k as f32 / 16.0 * std::f32::consts::TAU;
                // A direction at the cone's rim about its own axis (axes in the x-z plane).
                let (ax, az_) = (c[0], c[2]);
                let (e1, e2) = ([az_, 0.0, -ax], [0.0, 1.0, 0.0]);
                let d: [f32; 3] = std::array::from_fn(|i| {
                    c[i] * t.cos() + (e1[i] * az.cos() + e2[i] * az.sin()) * t.sin()
                });
                let cos: f32 = (0..3).map(|i| d[i] * u[i]).sum();
                assert!(cos >= u[3] - 1e-5, "{d:?} {u:?}");
            }
        }
        // Opposite axes, or a cone of every direction: every direction.
        let down = [0.0, 0.0, -1.0, deg(10.0)];
        assert_eq!(cone_union(up, down)[3], -1.0);
        assert_eq!(cone_union(up, [0.0, 0.0, 1.0, -1.0])[3], -1.0);
    }

    #[test]
    fn pages_round_trip() {
        let s = Splats {
            normals: vec![[0.0, 0.0, 1.0], [0.6, 0.8, 0.0], [0.0, -1.0, 0.0]],
            radii: vec![0.5, 2.0, 1.0],
        };
        let (page, range) = encode(&s);
        assert_eq!(range, [0.5, 2.0]);
        let back = decode(&page, 3, range).unwrap();
        assert_eq!(back.radii[0], 0.5);
        assert_eq!(back.radii[1], 2.0);
        assert!((back.radii[2] - 1.0).abs() <= 1.5 / 255.0);
        assert!(decode(&page, 4, range).is_err());
        // A damaged count far beyond what the page holds: an error, with no allocation of it.
        assert!(decode(&page, u32::MAX as usize, range).is_err());
        assert!(decode(&page[..page.len() - 1], 3, range).is_err());
    }
}
