//! Principal component analysis of 3-D points: the covariance's eigenvectors, by a small Jacobi
//! solver (a 3x3 solver is a few lines, and the linear-algebra crates are large dependencies for
//! it). Used by the builders (node contours, normals) and the renderer's surfaces.

/// Principal axes of a set of points: mean, axes (rows) by decreasing eigenvalue, eigenvalues.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pca {
    pub mean: [f64; 3],
    pub axes: [[f64; 3]; 3],
    pub eigenvalues: [f64; 3],
}

/// Eigenvalues and eigenvectors (columns of the returned matrix, rows after transposing) of a
/// symmetric 3x3 matrix by cyclic Jacobi rotations. Written here: a 3x3 solver is a few lines, and
/// the linear-algebra crates are large dependencies for it.
fn symmetric_eigen(mut a: [[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..50 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        let scale = a[0][0].abs() + a[1][1].abs() + a[2][2].abs();
        if off <= 1e-15 * scale.max(f64::MIN_POSITIVE) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // A <- J^T A J, V <- V J with J the rotation in the (p, q) plane.
            for k in 0..3 {
                let (akp, akq) = (a[k][p], a[k][q]);
                a[k][p] = c * akp - s * akq;
                a[k][q] = s * akp + c * akq;
            }
            for k in 0..3 {
                let (apk, aqk) = (a[p][k], a[q][k]);
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            for row in &mut v {
                let (vkp, vkq) = (row[p], row[q]);
                row[p] = c * vkp - s * vkq;
                row[q] = s * vkp + c * vkq;
            }
        }
    }
    ([a[0][0], a[1][1], a[2][2]], v)
}

/// The principal axes of `positions` (relative to their mean, for precision).
pub fn pca(positions: &[[f64; 3]]) -> Pca {
    let n = positions.len().max(1) as f64;
    let mut mean = [0.0; 3];
    for p in positions {
        for a in 0..3 {
            mean[a] += p[a] / n;
        }
    }
    let mut c = [[0.0; 3]; 3];
    for p in positions {
        let d = [p[0] - mean[0], p[1] - mean[1], p[2] - mean[2]];
        for i in 0..3 {
            for j in 0..3 {
                c[i][j] += d[i] * d[j] / n;
            }
        }
    }
    Pca::of_covariance(mean, c)
}

impl Pca {
    /// The principal axes of a covariance matrix about `mean`.
    pub fn of_covariance(mean: [f64; 3], c: [[f64; 3]; 3]) -> Pca {
        let (values, vectors) = symmetric_eigen(c);
        let mut idx = [0usize, 1, 2];
        idx.sort_by(|&a, &b| values[b].total_cmp(&values[a]));
        let axis = |i: usize| {
            let v = [vectors[0][i], vectors[1][i], vectors[2][i]];
            let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            v.map(|x| x / len)
        };
        let a0 = axis(idx[0]);
        let a1 = axis(idx[1]);
        // A right-handed frame.
        let a2 = [
            a0[1] * a1[2] - a0[2] * a1[1],
            a0[2] * a1[0] - a0[0] * a1[2],
            a0[0] * a1[1] - a0[1] * a1[0],
        ];
        Pca {
            mean,
            axes: [a0, a1, a2],
            eigenvalues: idx.map(|i| values[i].max(0.0)),
        }
    }
}
