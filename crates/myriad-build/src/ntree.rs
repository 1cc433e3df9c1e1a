//! The `layered` structure's representatives (Kanzok, Linsen, Rosenthal 2015, section 3.1): inside
//! each node of the outer octree, an adaptive n-tree whose arity follows the local dimensionality
//! of the node's points: binary along a line, a quadtree over a plane, an octree in a volume
//! (Westin's anisotropy from the eigenvalues of their covariance). Cells split along the node's
//! principal axes, so a tilted wall is cut in its own plane.
//!
//! The paper inserts points one by one; each n-tree cell references the point nearest its
//! centre, cells split until the tree holds `capacity` points, and when a shallow cell must split
//! at capacity the deepest leaves are contracted (their Figure 1), keeping the distribution
//! homogeneous; a level-order traversal is the node's level of detail. The tree that process
//! converges to is built here directly, in level order: every level of the n-tree that fits the
//! capacity whole (one representative per occupied cell, the unused point nearest the cell's
//! centre), then, of the first level that does not fit, cells spread evenly over the node (taken
//! in bit-reversed order of their position along the n-tree's curve) until the capacity is
//! reached. So, as in the paper, a node holds exactly `capacity` points, and every prefix of them
//! is spread evenly.
//!
//! The node's contour: the oriented box of its points along the principal axes when the node is
//! flat (not volumetric by the paper's 0.03 threshold), otherwise their axis-aligned box.

use crate::mospt::Mospt;
pub use myriad_core::pca::{Pca, pca};
use myriad_core::{Aabb, Obb, PointBatch};

/// The paper's threshold on the Westin measures.
pub const FLAT_THRESHOLD: f64 = 0.03;

/// Local dimensionality by Westin's measures (Kanzok et al. 2015, equation 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dimensionality {
    Linear,
    Planar,
    Volumetric,
}

impl Dimensionality {
    pub fn of(p: &Pca) -> Dimensionality {
        let [l1, l2, l3] = p.eigenvalues;
        let sum = l1 + l2 + l3;
        if sum <= 0.0 {
            // All points in one place: nothing to split.
            return Dimensionality::Linear;
        }
        let cs = 3.0 * l3 / sum;
        let cp = 2.0 * (l2 - l3) / sum;
        if cs > FLAT_THRESHOLD {
            Dimensionality::Volumetric
        } else if cp > FLAT_THRESHOLD {
            Dimensionality::Planar
        } else {
            Dimensionality::Linear
        }
    }
    /// Axes the n-tree splits (the first ones of the principal frame).
    pub fn split_axes(self) -> usize {
        match self {
            Dimensionality::Linear => 1,
            Dimensionality::Planar => 2,
            Dimensionality::Volumetric => 3,
        }
    }
}

/// The contour of a node whose subtree holds `positions` (Kanzok et al. 2015, section 3.1).
pub fn contour(positions: &[[f64; 3]], p: &Pca) -> Obb {
    if Dimensionality::of(p) == Dimensionality::Volumetric {
        let mut b = Aabb::EMPTY;
        positions.iter().for_each(|&q| b.extend(q));
        return Obb::from_aabb(&b);
    }
    oriented_box(positions, p)
}

/// The box of `positions` along `p`'s axes.
pub fn oriented_box(positions: &[[f64; 3]], p: &Pca) -> Obb {
    let (lo, hi) = extents(positions, p);
    let mid: [f64; 3] = std::array::from_fn(|i| (lo[i] + hi[i]) * 0.5);
    let mut center = p.mean;
    for (i, axis) in p.axes.iter().enumerate() {
        for k in 0..3 {
            center[k] += axis[k] * mid[i];
        }
    }
    Obb {
        center,
        axes: p.axes,
        half_extents: std::array::from_fn(|i| (hi[i] - lo[i]) * 0.5),
    }
}

/// Smallest and largest coordinate of `positions` along each of `p`'s axes, relative to the mean.
fn extents(positions: &[[f64; 3]], p: &Pca) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for q in positions {
        let l = local(q, p);
        for i in 0..3 {
            lo[i] = lo[i].min(l[i]);
            hi[i] = hi[i].max(l[i]);
        }
    }
    (lo, hi)
}

fn local(q: &[f64; 3], p: &Pca) -> [f64; 3] {
    let d = [q[0] - p.mean[0], q[1] - p.mean[1], q[2] - p.mean[2]];
    p.axes.map(|a| d[0] * a[0] + d[1] * a[1] + d[2] * a[2])
}

/// Builds the level order of a node's points by the adaptive n-tree. A leaf (`keep_all`) orders
/// every point; an inner node only its first `capacity`. Returns the order (indices into
/// `batch`, the kept ones), the prefix count and spacing of each level, and the node's principal
/// axes.
pub fn build(batch: &PointBatch, capacity: usize, keep_all: bool) -> (Mospt, Pca) {
    let pos = &batch.positions;
    let n = pos.len();
    let p = pca(pos);
    let k = Dimensionality::of(&p).split_axes();
    let (lo, hi) = extents(pos, &p);
    let size: [f64; 3] = std::array::from_fn(|i| (hi[i] - lo[i]).max(0.0));
    // Levels the codes resolve: k bits per level in 63.
    let levels = (63 / k as u32).min(21);
    let cells = (1u64 << levels) as f64;
    let mut coded: Vec<(u64, u32)> = pos
        .iter()
        .enumerate()
        .map(|(i, q)| {
            let l = local(q, &p);
            let mut code = 0u64;
            let mut c = [0u64; 3];
            for a in 0..k {
                let t = if size[a] > 0.0 {
                    (l[a] - lo[a]) / size[a]
                } else {
                    0.0
                };
                c[a] = ((t * cells) as u64).min((1 << levels) - 1);
            }
            for bit in (0..levels).rev() {
                for ca in c.iter().take(k) {
                    code = code << 1 | (ca >> bit & 1);
                }
            }
            (code, i as u32)
        })
        .collect();
    coded.sort_unstable();
    let want = if keep_all { n } else { capacity.min(n) };
    let mut taken = vec![false; n];
    let mut order: Vec<u32> = Vec::with_capacity(want);
    let mut prefix = Vec::new();
    let mut spacing = Vec::new();
    let widest = (0..k).map(|a| size[a]).fold(0.0, f64::max);
    // Position of a point along the split axes, as fractions of the node's extent.
    let frac = |i: u32| -> [f64; 3] {
        let l = local(&pos[i as usize], &p);
        std::array::from_fn(|a| {
            if a < k && size[a] > 0.0 {
                (l[a] - lo[a]) / size[a]
            } else {
                0.5
            }
        })
    };
    for level in 0..=levels {
        if order.len() >= want {
            break;
        }
        let shift = k as u32 * (levels - level);
        let side = 1.0 / (1u64 << level) as f64;
        // One candidate per occupied cell: its untaken point nearest the cell's centre.
        let mut reps: Vec<u32> = Vec::new();
        let mut start = 0;
        while start < n {
            let cell = coded[start].0 >> shift;
            let end = start + coded[start..].partition_point(|c| c.0 >> shift == cell);
            let mut best: Option<(f64, u32)> = None;
            for &(_, i) in &coded[start..end] {
                if taken[i as usize] {
                    continue;
                }
                let f = frac(i);
                let d: f64 = (0..k)
                    .map(|a| {
                        let c =
                            ((f[a] / side).floor().min((1u64 << level) as f64 - 1.0) + 0.5) * side;
                        (f[a] - c) * (f[a] - c)
                    })
                    .sum();
                if best.is_none_or(|b| d < b.0) {
                    best = Some((d, i));
                }
            }
            if let Some((_, i)) = best {
                reps.push(i);
            }
            start = end;
        }
        if reps.is_empty() {
            continue;
        }
        let room = want - order.len();
        if reps.len() > room {
            // Contraction at capacity: the cells of this level spread evenly over the node.
            let bits = usize::BITS - (reps.len() - 1).leading_zeros();
            let mut spread: Vec<(usize, u32)> = reps
                .iter()
                .enumerate()
                .map(|(j, &i)| (j.reverse_bits() >> (usize::BITS - bits.max(1)), i))
                .collect();
            spread.sort_unstable();
            reps = spread.into_iter().take(room).map(|s| s.1).collect();
        }
        for &i in &reps {
            taken[i as usize] = true;
        }
        order.extend_from_slice(&reps);
        prefix.push(order.len() as u64);
        spacing.push(widest * side);
    }
    if order.len() < want {
        // Points the finest cells do not separate (duplicates): a last level.
        order.extend(
            (0..n as u32)
                .filter(|&i| !taken[i as usize])
                .take(want - order.len()),
        );
        prefix.push(order.len() as u64);
        spacing.push(spacing.last().copied().unwrap_or(0.0));
    }
    (
        Mospt {
            order,
            prefix,
            spacing,
        },
        p,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_core::{Attribute, Schema};

    fn batch(points: &[[f64; 3]]) -> PointBatch {
        let mut b = PointBatch::with_schema(&Schema::new(vec![Attribute::Intensity]), 0);
        for &p in points {
            b.positions.push(p);
            b.intensity.as_mut().unwrap().push(0);
        }
        b
    }

    /// A tilted plane z = x/2, a line along (1, 1, 1), and a cube of points.
    fn shapes() -> [Vec<[f64; 3]>; 3] {
        let plane = (0..1600)
            .map(|i| {
                let (x, y) = ((i % 40) as f64, (i / 40) as f64);
                [x, y, x * 0.5]
            })
            .collect();
        let line = (0..500).map(|i| [i as f64; 3]).collect();
        let cube = (0..1000)
            .map(|i| [(i % 10) as f64, (i / 10 % 10) as f64, (i / 100) as f64])
            .collect();
        [plane, line, cube]
    }

    #[test]
    fn dimensionality_and_axes() {
        let [plane, line, cube] = shapes();
        let p = pca(&plane);
        assert_eq!(Dimensionality::of(&p), Dimensionality::Planar);
        // The plane's normal is the least axis: (-1/2, 0, 1) normalised, up to sign.
        let n = p.axes[2];
        let want = [-0.5 / 1.25f64.sqrt(), 0.0, 1.0 / 1.25f64.sqrt()];
        let dot: f64 = (0..3).map(|i| n[i] * want[i]).sum();
        assert!((dot.abs() - 1.0).abs() < 1e-9, "{n:?}");
        assert_eq!(Dimensionality::of(&pca(&line)), Dimensionality::Linear);
        assert_eq!(Dimensionality::of(&pca(&cube)), Dimensionality::Volumetric);
    }

    #[test]
    fn contours_hug_flat_nodes() {
        let [plane, _, cube] = shapes();
        let c = contour(&plane, &pca(&plane));
        // Flat: the oriented box is as thin as the plane (the axis-aligned one is 19.5 high).
        assert!(c.half_extents[2] < 1e-9, "{c:?}");
        assert!(plane.iter().all(|&q| {
            let d: [f64; 3] = std::array::from_fn(|a| q[a] - c.center[a]);
            (0..3).all(|i| {
                (d[0] * c.axes[i][0] + d[1] * c.axes[i][1] + d[2] * c.axes[i][2]).abs()
                    <= c.half_extents[i] + 1e-9
            })
        }));
        // Volumetric: the axis-aligned box.
        let c = contour(&cube, &pca(&cube));
        assert_eq!(c.axes, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        assert_eq!(c.half_extents, [4.5, 4.5, 4.5]);
    }

    #[test]
    fn level_order_is_spread_and_complete() {
        let [plane, line, cube] = shapes();
        for pts in [plane, line, cube] {
            let b = batch(&pts);
            let (leaf, _) = build(&b, 64, true);
            // A leaf orders every point exactly once.
            let mut seen = leaf.order.clone();
            seen.sort_unstable();
            assert_eq!(seen, (0..pts.len() as u32).collect::<Vec<_>>());
            assert_eq!(*leaf.prefix.last().unwrap(), pts.len() as u64);
            assert!(leaf.prefix.windows(2).all(|w| w[0] < w[1]));
            assert!(leaf.spacing.windows(2).all(|w| w[0] >= w[1]));
            // An inner node keeps exactly its capacity, the first levels of the leaf's order.
            let (inner, _) = build(&b, 100, false);
            assert_eq!(inner.order.len(), 100);
            assert_eq!(*inner.prefix.last().unwrap(), 100);
            let whole = inner.prefix.len() - 1;
            let n = inner.prefix[whole - 1] as usize;
            assert_eq!(inner.order[..n], leaf.order[..n]);
        }
        // On the 40 x 40 plane (a quadtree), the 16 points of level 2 are one per cell of a
        // 4 x 4 grid over it: every 10 x 10 square holds one.
        let [plane, ..] = shapes();
        let (m, _) = build(&batch(&plane), 21, false);
        assert_eq!(m.prefix, vec![1, 5, 21]);
        let mut squares: Vec<(usize, usize)> = m.order[5..]
            .iter()
            .map(|&i| {
                let q = plane[i as usize];
                ((q[0] / 10.0) as usize, (q[1] / 10.0) as usize)
            })
            .collect();
        squares.sort_unstable();
        squares.dedup();
        assert_eq!(squares.len(), 16, "{squares:?}");
        // Contraction at capacity 15: 10 of the 16 cells of level 2, spread: each half of the
        // plane gets about half of them.
        let (m, _) = build(&batch(&plane), 15, false);
        assert_eq!(m.prefix, vec![1, 5, 15]);
        let left = m.order[5..]
            .iter()
            .filter(|&&i| plane[i as usize][0] < 20.0)
            .count();
        assert!((4..=6).contains(&left), "{left}");
    }
}
