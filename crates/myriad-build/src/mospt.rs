//! The Memory Optimized Sequential Point Tree (MOSPT) of one node (Scheiblauer 2006, chapter 3):
//! the node's original points in level order, so that a prefix of the order is a coarser level of
//! detail of the node, and no point is invented.
//!
//! The thesis inserts points into an octree, then pulls one representative per cell up, bottom to
//! top, and sequentializes by a level-order traversal. Here the same tree is built flat: points
//! are sorted by their Morton code at the finest depth, so every cell of every level is a
//! contiguous run; bottom-up, each occupied cell picks one representative among its children's
//! representatives, and the children it passes over keep the finer level. A point's level is the
//! coarsest level whose cell it represents. Hence the invariant the renderer relies on: the points
//! of levels `0..=l` are exactly one original point per occupied cell of level `l`.
//!
//! Choosing the representative: the thesis takes the point nearest the cell's mean colour
//! (perceptual distance). We do that when the input has colour, with the "redmean" weighting as
//! the perceptual distance; without colour, the point nearest the cell's centroid, which keeps
//! coarse levels on the geometry they stand for rather than at an arbitrary corner.
//!
//! Points that share a finest-level cell with their representative (duplicates, or more points
//! than `max_depth` resolves: the thesis's leaf strategy 3.a) form a last level `depth + 1`.

use myriad_core::{Aabb, PointBatch};

/// A node's points in level order.
#[derive(Debug, Clone, PartialEq)]
pub struct Mospt {
    /// `order[i]` is the index, in the input batch, of the i-th point of the level order.
    pub order: Vec<u32>,
    /// `prefix[l]` points (of `order`) make up level of detail `l`; the last entry is the
    /// point count.
    pub prefix: Vec<u64>,
    /// Cell size of each level: the spacing of the points of levels `0..=l`. The last level
    /// (points sharing a finest cell) repeats the finest spacing.
    pub spacing: Vec<f64>,
}

/// Perceptual-ish squared distance between 16-bit colours ("redmean" weighting).
fn colour_distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    let r = (a[0] + b[0]) * 0.5 / 65535.0;
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    (2.0 + r) * d[0] * d[0] + 4.0 * d[1] * d[1] + (3.0 - r) * d[2] * d[2]
}

/// Levels of the Morton codes [`codes`] computes.
pub const CODE_LEVELS: u32 = 21;

/// Morton codes of `batch`'s points at [`CODE_LEVELS`] levels below the cube `cube`.
pub fn codes(batch: &PointBatch, cube: &Aabb) -> Vec<u64> {
    let side = cube
        .size()
        .into_iter()
        .fold(0.0f64, f64::max)
        .max(f64::MIN_POSITIVE);
    let cells = (1u64 << CODE_LEVELS) as f64;
    let cell_of = |p: [f64; 3], a: usize| {
        (((p[a] - cube.min[a]) / side * cells) as i64).clamp(0, (1 << CODE_LEVELS) - 1) as u32
    };
    batch
        .positions
        .iter()
        .map(|&p| myriad_core::geometry::morton(cell_of(p, 0), cell_of(p, 1), cell_of(p, 2)))
        .collect()
}

/// The order that sorts `codes`, and the codes in that order.
pub fn sort_codes(codes: &[u64]) -> (Vec<u32>, Vec<u64>) {
    // Sort (code, index) pairs: sorting indices by a looked-up key would miss the cache. No two
    // pairs are equal, so the unstable sort leaves equal codes in their indices' order. The
    // radix sort made eight passes over a chunk of 63-bit codes: 39 ns a pair at 450 k pairs,
    // 60-72 at 2 M (a chunk of a large build), against 32 and 37 for this sort.
    let mut pairs: Vec<(u64, u32)> = codes
        .iter()
        .enumerate()
        .map(|(i, &c)| (c, i as u32))
        .collect();
    pairs.sort_unstable();
    pairs.into_iter().map(|(c, i)| (i, c)).unzip()
}

/// Builds the MOSPT of `batch`, whose points lie in the cube `cube` (an octree node), with at
/// most `max_depth` (at most 21) levels below the root cell.
pub fn build(batch: &PointBatch, cube: &Aabb, max_depth: u32) -> Mospt {
    let (sorted, sc) = sort_codes(&codes(batch, cube));
    build_sorted(batch, sorted, &sc, cube, max_depth)
}

/// [`build`] for points whose Morton order is known: `sorted` lists the node's points (indices
/// into `batch`, which may hold other points besides) in that order and `sorted_codes` their
/// codes ([`codes`], relative to `cube`), in the same order. `order` holds indices into `batch`.
pub fn build_sorted(
    batch: &PointBatch,
    sorted: Vec<u32>,
    sorted_codes: &[u64],
    cube: &Aabb,
    max_depth: u32,
) -> Mospt {
    let mut m = build_places(batch, &sorted, sorted_codes, cube, max_depth, None);
    for o in &mut m.order {
        *o = sorted[*o as usize];
    }
    m
}

/// [`build_sorted`], with `order` naming each point by its place in `sorted` rather than by
/// its index in `batch`. With `fit`, `order` holds only the prefix a node of at most `fit`
/// points keeps (the deepest level whose prefix fits, at least the root point: what
/// [`crate::nested::fitting_prefix`] takes of the whole order), and `prefix` is still the
/// whole tree's: a node that passes the rest down needs no order of the rest.
pub fn build_places(
    batch: &PointBatch,
    sorted: &[u32],
    sorted_codes: &[u64],
    cube: &Aabb,
    max_depth: u32,
    fit: Option<usize>,
) -> Mospt {
    let n = sorted.len();
    assert!(n <= u32::MAX as usize, "a node holds at most 2^32 points");
    assert_eq!(sorted_codes.len(), n);
    let max_depth = max_depth.min(CODE_LEVELS);
    let side = cube
        .size()
        .into_iter()
        .fold(0.0f64, f64::max)
        .max(f64::MIN_POSITIVE);
    // Codes at `max_depth`, in sorted order.
    let base = 3 * (CODE_LEVELS - max_depth);
    let sc = |i: usize| sorted_codes[i] >> base;

    // The effective depth: the first level whose cells already separate the points as well as
    // `max_depth` does; finer levels would add nothing. Two neighbours in Morton order whose
    // codes differ first separate at the level given by their highest differing bit.
    let depth = sorted_codes
        .windows(2)
        .map(|w| (w[0] >> base) ^ (w[1] >> base))
        .filter(|&x| x != 0)
        .map(|x| max_depth - (63 - x.leading_zeros()) / 3)
        .max()
        .unwrap_or(0);

    // Per point, by its place in `sorted`: the level at which it enters (depth + 1: never a
    // representative).
    let mut level = vec![depth + 1; n];
    // What a cell's mean is taken of (colour, else position), by place, read once.
    let rgb = batch.rgb.as_ref();
    let values: Vec<[f64; 3]> = match rgb {
        Some(c) => sorted
            .iter()
            .map(|&i| c[i as usize].map(f64::from))
            .collect(),
        None => sorted
            .iter()
            .map(|&i| batch.positions[i as usize])
            .collect(),
    };
    let distance = |a: [f64; 3], b: [f64; 3]| -> f64 {
        if rgb.is_some() {
            colour_distance(a, b)
        } else {
            (0..3).map(|k| (a[k] - b[k]).powi(2)).sum()
        }
    };
    // The candidate nearest `mean`, the first of equals.
    let nearest = |candidates: &mut dyn Iterator<Item = u32>, mean: [f64; 3]| -> u32 {
        let mut best = (f64::INFINITY, u32::MAX);
        for c in candidates {
            let d = distance(values[c as usize], mean);
            if d < best.0 || best.1 == u32::MAX {
                best = (d, c);
            }
        }
        best.1
    };
    // Cells of the current level, as runs of `sorted`: (start, end, representative's place,
    // value sum).
    #[derive(Clone, Copy)]
    struct Cell {
        start: usize,
        end: usize,
        rep: u32,
        sum: [f64; 3],
    }
    // Finest level: every run of equal codes (at `depth`) is a cell; its representative is the
    // point nearest the cell's mean.
    let shift_of = |l: u32| 3 * (max_depth - l);
    let mut current: Vec<Cell> = Vec::new();
    let mut start = 0;
    while start < n {
        let key = sc(start) >> shift_of(depth);
        let mut end = start;
        let mut sum = [0.0; 3];
        while end < n && sc(end) >> shift_of(depth) == key {
            (0..3).for_each(|k| sum[k] += values[end][k]);
            end += 1;
        }
        let rep = if end - start == 1 {
            start as u32
        } else {
            let mean = sum.map(|s| s / (end - start) as f64);
            nearest(&mut (start as u32..end as u32), mean)
        };
        level[rep as usize] = depth;
        current.push(Cell {
            start,
            end,
            rep,
            sum,
        });
        start = end;
    }
    // Coarser levels. A cell with one child cell is that child again (same points, same
    // representative), so only where siblings meet is there work: two neighbouring finest cells
    // share every cell above the level at which their codes part, and at level l the cells
    // whose boundaries part at l + 1 merge into their parent; the representative nearest the
    // merged mean moves up, and the others' coarsest level is l + 1. Linear in the cells,
    // however deep the tree.
    let m = current.len();
    let parts_at = |j: usize| {
        let x = sc(current[j - 1].start) ^ sc(current[j].start);
        (max_depth - (63 - x.leading_zeros()) / 3) as usize
    };
    // Boundaries by the level they part at (a counting sort), ascending within a level.
    let mut begin = vec![0usize; depth as usize + 2];
    (1..m).for_each(|j| begin[parts_at(j) + 1] += 1);
    for l in 1..begin.len() {
        begin[l] += begin[l - 1];
    }
    // Occupied cells of level l: one more than the boundaries parting at l or above it. These
    // are the prefix counts: levels 0..=l hold one point per cell of level l.
    let cells = |l: usize| if m == 0 { 0 } else { 1 + begin[l + 1] as u64 };
    // The level whose groups make up the kept prefix, when only that is wanted.
    let kept_level = fit.map(|cap| {
        (0..=depth as usize)
            .rev()
            .find(|&l| cells(l) as usize <= cap)
            .unwrap_or(0)
    });
    let mut kept_reps: Vec<u32> = Vec::new();
    let mut snapshot = |l: usize, end: &[u32], current: &[Cell]| {
        if kept_level == Some(l) {
            let mut s = 0;
            while s < m {
                kept_reps.push(current[s].rep);
                s = end[s] as usize;
            }
        }
    };
    let mut fill = begin.clone();
    let mut bounds = vec![0u32; m.saturating_sub(1)];
    for j in 1..m {
        let b = parts_at(j);
        bounds[fill[b]] = j as u32;
        fill[b] += 1;
    }
    // Groups of finest cells, named by their first: where each ends, and the group ending at
    // each boundary.
    let mut end: Vec<u32> = (1..=m as u32).collect();
    let mut first: Vec<u32> = (0..=m as u32).map(|e| e.saturating_sub(1)).collect();
    let mut children = Vec::with_capacity(8);
    snapshot(depth as usize, &end, &current);
    for l in (0..depth as usize).rev() {
        let parting = &bounds[begin[l + 1]..begin[l + 2]];
        let mut i = 0;
        while i < parting.len() {
            let s = first[parting[i] as usize] as usize;
            let mut e = end[s] as usize;
            children.clear();
            children.push(s);
            while i < parting.len() && parting[i] as usize == e {
                children.push(e);
                e = end[e] as usize;
                i += 1;
            }
            let mut sum = [0.0; 3];
            for &c in &children {
                (0..3).for_each(|k| sum[k] += current[c].sum[k]);
            }
            let points = current[e - 1].end - current[s].start;
            let mean = sum.map(|v| v / points as f64);
            let rep = nearest(&mut children.iter().map(|&c| current[c].rep), mean);
            for &c in &children {
                if current[c].rep != rep {
                    level[current[c].rep as usize] = l as u32 + 1;
                }
            }
            current[s].rep = rep;
            current[s].sum = sum;
            end[s] = e as u32;
            first[e] = s as u32;
        }
        snapshot(l, &end, &current);
    }
    if m > 0 {
        level[current[0].rep as usize] = 0;
    }

    // Level order; within a level, Morton order: a counting sort by level keeps `sorted`'s order
    // (the kept groups' representatives are in Morton order too).
    let levels = depth as usize + 2;
    let mut prefix: Vec<u64> = (0..=depth as usize).map(cells).collect();
    prefix.push(n as u64);
    let mut next: Vec<usize> = std::iter::once(0)
        .chain(prefix[..levels - 1].iter().map(|&p| p as usize))
        .collect();
    let order = match kept_level {
        Some(k) => {
            let mut order = vec![0u32; prefix[k] as usize];
            for &p in &kept_reps {
                let l = level[p as usize] as usize;
                order[next[l]] = p;
                next[l] += 1;
            }
            order
        }
        None => {
            let mut order = vec![0u32; n];
            for (p, &l) in level.iter().enumerate() {
                order[next[l as usize]] = p as u32;
                next[l as usize] += 1;
            }
            order
        }
    };
    let spacing = (0..levels)
        .map(|l| side / (1u64 << (l.min(depth as usize))) as f64)
        .collect();
    Mospt {
        order,
        prefix,
        spacing,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_core::{Attribute, Schema};
    use std::collections::HashSet;

    fn batch(points: &[[f64; 3]], colours: Option<&[[u16; 3]]>) -> PointBatch {
        let schema = Schema::new(if colours.is_some() {
            vec![Attribute::Rgb]
        } else {
            vec![]
        });
        let mut b = PointBatch::with_schema(&schema, points.len());
        b.positions = points.to_vec();
        if let Some(c) = colours {
            b.rgb = Some(c.to_vec());
        }
        b
    }

    fn unit() -> Aabb {
        Aabb::new([0.0; 3], [1.0; 3])
    }

    /// Checks the invariants every MOSPT must keep.
    fn check(b: &PointBatch, cube: &Aabb, max_depth: u32) -> Mospt {
        let m = build(b, cube, max_depth);
        let n = b.len();
        let mut seen = m.order.clone();
        seen.sort_unstable();
        assert_eq!(
            seen,
            (0..n as u32).collect::<Vec<_>>(),
            "order is a permutation"
        );
        assert_eq!(*m.prefix.last().unwrap(), n as u64);
        assert!(m.prefix.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(m.prefix[0], 1.min(n as u64), "one root point");
        let depth = m.prefix.len() as u32 - 2;
        let side = cube.size()[0];
        for l in 0..=depth {
            let cell = |i: u32| {
                let p = b.positions[i as usize];
                let c = (1u64 << l) as f64;
                (0..3)
                    .map(|a| ((p[a] - cube.min[a]) / side * c).min(c - 1.0) as u64)
                    .collect::<Vec<_>>()
            };
            let prefix: Vec<Vec<u64>> = m.order[..m.prefix[l as usize] as usize]
                .iter()
                .map(|&i| cell(i))
                .collect();
            let distinct: HashSet<_> = prefix.iter().cloned().collect();
            assert_eq!(
                distinct.len(),
                prefix.len(),
                "level {l}: two points in one cell"
            );
            let all: HashSet<_> = (0..n as u32).map(cell).collect();
            assert_eq!(distinct, all, "level {l}: an occupied cell has no point");
            assert_eq!(m.spacing[l as usize], side / (1u64 << l) as f64);
        }
        m
    }

    fn random_points(n: usize, seed: u64) -> Vec<[f64; 3]> {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        // Clustered: half the points on a plane, half spread, like a scan.
        (0..n)
            .map(|i| {
                if i % 2 == 0 {
                    [next(), next(), 0.25]
                } else {
                    [next(), next(), next()]
                }
            })
            .collect()
    }

    #[test]
    fn prefixes_hold_one_point_per_occupied_cell() {
        for (n, seed, depth) in [
            (1, 1, 5),
            (2, 2, 5),
            (1000, 3, 4),
            (20_000, 4, 8),
            (5000, 5, 21),
        ] {
            let pts = random_points(n, seed);
            check(&batch(&pts, None), &unit(), depth);
            let colours: Vec<[u16; 3]> = (0..n)
                .map(|i| [(i * 97 % 65536) as u16, (i * 13 % 65536) as u16, 7])
                .collect();
            check(&batch(&pts, Some(&colours)), &unit(), depth);
        }
    }

    #[test]
    fn the_morton_order_keeps_equal_codes_in_input_order() {
        // Many equal codes (few distinct values, some at the extremes): the order must be the
        // stable sort's, which the nested build and the leaves' last level rely on.
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let codes: Vec<u64> = (0..50_000)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                [0, 1, 1 << 62, (1 << 63) - 1, x % 97][(x >> 40) as usize % 5]
            })
            .collect();
        let mut stable: Vec<u32> = (0..codes.len() as u32).collect();
        stable.sort_by_key(|&i| codes[i as usize]);
        let (order, sorted) = sort_codes(&codes);
        assert_eq!(order, stable);
        assert!(sort_codes(&[]).0.is_empty());
        // The codes come with the order, each its point's.
        let expected: Vec<u64> = stable.iter().map(|&i| codes[i as usize]).collect();
        assert_eq!(sorted, expected);
    }

    #[test]
    fn a_fitted_order_is_the_whole_orders_fitting_prefix() {
        for (n, seed, depth, cap) in [(20_000, 7, 7, 5000), (20_000, 8, 7, 1), (3000, 9, 21, 700)] {
            let pts = random_points(n, seed);
            let colours: Vec<[u16; 3]> = (0..n)
                .map(|i| [(i * 31 % 65536) as u16, (i * 7 % 65536) as u16, 9])
                .collect();
            let b = batch(&pts, Some(&colours));
            let (sorted, sc) = sort_codes(&codes(&b, &unit()));
            let whole = build_places(&b, &sorted, &sc, &unit(), depth, None);
            let fitted = build_places(&b, &sorted, &sc, &unit(), depth, Some(cap));
            let keep = crate::nested::fitting_prefix(&whole, cap);
            assert!(
                keep < n && (keep <= cap || keep == 1),
                "n {n}: keeps {keep}"
            );
            assert_eq!(fitted.order, whole.order[..keep], "n {n}, cap {cap}");
            assert_eq!(
                (&fitted.prefix, &fitted.spacing),
                (&whole.prefix, &whole.spacing)
            );
        }
    }

    #[test]
    fn representative_is_nearest_the_mean_colour() {
        let pts = [[0.1, 0.1, 0.1], [0.2, 0.1, 0.1], [0.3, 0.1, 0.1]];
        let colours = [[0, 0, 0], [65535, 65535, 65535], [32000, 33000, 32500]];
        let m = check(&batch(&pts, Some(&colours)), &unit(), 1);
        assert_eq!(m.order[0], 2, "grey is nearest the mean colour");
        assert_eq!(m.prefix, vec![1, 3]);
    }

    #[test]
    fn without_colour_the_representative_is_nearest_the_centroid() {
        let pts = [
            [0.1, 0.1, 0.1],
            [0.21, 0.2, 0.2],
            [0.3, 0.3, 0.3],
            [0.05, 0.3, 0.1],
        ];
        let m = check(&batch(&pts, None), &unit(), 1);
        assert_eq!(m.order[0], 1);
    }

    #[test]
    fn duplicates_form_the_last_level() {
        let pts = vec![[0.5, 0.5, 0.5]; 5];
        let m = check(&batch(&pts, None), &unit(), 10);
        assert_eq!(
            m.prefix,
            vec![1, 5],
            "one representative, four duplicates after it"
        );
    }

    #[test]
    fn spacing_halves_and_depth_stops_when_points_are_separated() {
        // In an 8 m cube, points at 0.1 and 0.9 share a cell down to 1 m cells and are separated
        // by the 0.5 m cells of level 4; deeper levels (up to 12) would add nothing.
        let m = check(
            &batch(&[[0.1, 0.1, 0.1], [0.9, 0.9, 0.9]], None),
            &Aabb::new([0.0; 3], [8.0; 3]),
            12,
        );
        assert_eq!(m.prefix, vec![1, 1, 1, 1, 2, 2]);
        assert_eq!(m.spacing, vec![8.0, 4.0, 2.0, 1.0, 0.5, 0.5]);
    }
}
