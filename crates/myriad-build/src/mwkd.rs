//! The `mwkd` structure (Goswami, Zhang, Pajarola, Gobbetti 2010, section III): a multi-way
//! kd-tree.
//!
//! Top-down, a node with more than `s` points is split along its longest axis into `N` children
//! of equal count; the leaves hold the original points (at most `s` each). `N` is chosen so that
//! `log(n/s) / log N` is nearest a whole number (a fully balanced tree), among 2..=8 (the keys of
//! the file format give a node at most eight children).
//!
//! Bottom-up, each inner node is made of `s/N` representatives of each of its children
//! (Figure 4): the child's points are put in a `K^3` grid over it; inside each cell points whose
//! normals differ by less than `theta` form a cluster; while there are more clusters than wanted,
//! the cell with the most clusters is clustered again with its threshold doubled (up to one
//! cluster per cell; a grid still too fine is made coarser). Each cluster becomes one aggregate:
//! position, colour and intensity averaged with the members' splat areas as weights, the other
//! attributes those of the member nearest it, its normal the weighted mean, and a radius that
//! covers every member's splat. Aggregates are for drawing only: `extract` and the nothing-lost
//! tests read the leaves.
//!
//! Normals come from the input when it has them, else from the principal axes of each point's
//! `KNN` nearest neighbours in its leaf (the smallest axis); they are turned to point up (a normal
//! from a covariance has no sign). A leaf point's splat radius is the distance to its fourth
//! nearest neighbour (at most three times the median of its leaf), so that neighbouring splats
//! overlap.

use crate::kd::bounds_of;
use crate::ntree::pca;
use myriad_core::{Aabb, NodeKey, PointBatch};
use myriad_format::splat::Splats;
use rayon::prelude::*;
use std::collections::{BinaryHeap, HashMap};

/// Neighbours for a normal.
pub const KNN: usize = 12;
/// Starting normal-deviation threshold of the clustering, degrees.
pub const THETA: f32 = 10.0;

#[derive(Debug, Clone)]
pub struct MwkdParams {
    /// Fan-out `N`.
    pub fanout: usize,
    /// Target points per node `s`.
    pub capacity: usize,
    /// Cells per side `K` of the clustering grid to start from (Goswami et al. 2010 used 35
    /// throughout); `None`: the square root of the representatives wanted. Made coarser where it is
    /// too fine to reach their count.
    pub grid: Option<usize>,
    /// How the normals get their sign.
    pub orientation: Orientation,
}

/// Which way a point's normal faces.
#[derive(Debug, Clone, Default)]
pub enum Orientation {
    /// Estimated normals turned up (+z; the sign is unknown): a ceiling faces the sky.
    #[default]
    Up,
    /// The input's normals, as they are.
    Input,
    /// Estimated normals turned towards the scanner that saw the point: the scanners'
    /// positions by source ID (`s >= 1` was seen from `[s - 1]`; others are turned up).
    Scanners(std::sync::Arc<Vec<[f64; 3]>>),
    /// Estimated normals turned towards the side of its flight line an airborne scanner saw
    /// the point from, by source ID ([`crate::sides`]); points of other IDs are turned up.
    Flights(std::sync::Arc<Vec<Option<crate::sides::Side>>>),
}

impl Orientation {
    /// The normals have a sign (a node's cone may say it faces away).
    pub fn signed(&self) -> bool {
        !matches!(self, Orientation::Up)
    }
}

/// A built node of the multi-way kd-tree.
#[derive(Debug, Clone)]
pub struct MwNode {
    pub key: NodeKey,
    pub points: PointBatch,
    pub splats: Splats,
    pub bounds: Aabb,
    /// Inner nodes hold aggregates.
    pub aggregate: bool,
}

impl MwNode {
    /// As the pipeline carries nodes: one level of detail (all points), spaced by the mean
    /// radius; the bounds stored.
    pub fn into_built(self) -> crate::nested::BuiltNode {
        let n = self.points.len();
        let mean = self.splats.radii.iter().map(|&r| r as f64).sum::<f64>() / n.max(1) as f64;
        crate::nested::BuiltNode {
            key: self.key,
            points: self.points,
            prefix: vec![n as u64],
            spacing: vec![mean],
            shape: myriad_format::NodeShape {
                bounds: Some(self.bounds),
                contour: None,
                detail: None,
            },
            splats: Some((self.splats, self.aggregate)),
            acquisition: false,
        }
    }

    pub fn from_built(b: crate::nested::BuiltNode) -> MwNode {
        let (splats, aggregate) = b.splats.unwrap_or_default();
        MwNode {
            key: b.key,
            bounds: b
                .shape
                .bounds
                .unwrap_or_else(|| bounds_of(&b.points.positions)),
            points: b.points,
            splats,
            aggregate,
        }
    }

    /// The normal cone: mean axis and the cosine of the widest angle to it.
    pub fn cone(&self) -> [f32; 4] {
        cone(&self.splats.normals)
    }

    /// [`MwNode::cone`] of any normals.
    pub fn cone_of(normals: &[[f32; 3]]) -> [f32; 4] {
        cone(normals)
    }
}

fn cone(normals: &[[f32; 3]]) -> [f32; 4] {
    let mut a = [0.0f32; 3];
    for n in normals {
        for k in 0..3 {
            a[k] += n[k];
        }
    }
    let len = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    if len < 1e-6 * normals.len().max(1) as f32 {
        return [0.0, 0.0, 1.0, -1.0];
    }
    let a = a.map(|x| x / len);
    let cos = normals
        .iter()
        .map(|n| n[0] * a[0] + n[1] * a[1] + n[2] * a[2])
        .fold(1.0f32, f32::min);
    [a[0], a[1], a[2], cos.clamp(-1.0, 1.0)]
}

/// The fan-out among 2..=8 that makes `log(n/s) / log N` nearest a whole number (at least one
/// level); ties go to the larger fan-out (a shallower tree).
pub fn fanout_for(n: u64, s: usize) -> usize {
    let m = (n as f64 / s.max(1) as f64).max(1.0);
    if m <= 1.0 {
        return 8;
    }
    (2..=8usize)
        .rev()
        .min_by(|&a, &b| {
            // Rounded, so that depths whole up to rounding tie.
            let off = |f: usize| {
                let l = m.ln() / (f as f64).ln();
                ((l - l.round().max(1.0)).abs() * 1e9).round() as i64
            };
            off(a).cmp(&off(b))
        })
        .unwrap_or(2)
}

fn up(n: [f32; 3]) -> [f32; 3] {
    if n[2] < 0.0 || (n[2] == 0.0 && (n[1] < 0.0 || (n[1] == 0.0 && n[0] < 0.0))) {
        n.map(|x| -x)
    } else {
        n
    }
}

fn unit(v: [f64; 3]) -> [f32; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if len > 0.0 {
        v.map(|x| (x / len) as f32)
    } else {
        [0.0, 0.0, 1.0]
    }
}

/// A uniform grid over points for k-nearest-neighbour queries. Written here: kiddo, the field's
/// kd-tree crate, answered 12-neighbour queries at 17 us each on 1 M points on this machine,
/// several times what a grid sized from the points' density takes on scan data.
struct Grid<'a> {
    pos: &'a [[f64; 3]],
    min: [f64; 3],
    h: f64,
    order: Vec<u32>,
    cells: HashMap<[i32; 3], (u32, u32)>,
    extent: i32,
}

impl<'a> Grid<'a> {
    fn new(pos: &'a [[f64; 3]], k: usize) -> Grid<'a> {
        let b = bounds_of(pos);
        let mut s = b.size();
        s.sort_by(|a, b| b.total_cmp(a));
        // Cells holding about k points on a surface through the box, at most 2^20 per axis.
        let area = (s[0] * s[1]).max(s[0] * s[0] * 1e-6).max(1e-18);
        let h = (area * k as f64 / pos.len().max(1) as f64)
            .sqrt()
            .max(s[0] / (1 << 20) as f64)
            .max(1e-9);
        let cell =
            |p: &[f64; 3]| -> [i32; 3] { std::array::from_fn(|a| ((p[a] - b.min[a]) / h) as i32) };
        let mut keyed: Vec<([i32; 3], u32)> = pos
            .iter()
            .enumerate()
            .map(|(i, p)| (cell(p), i as u32))
            .collect();
        keyed.sort_unstable();
        let mut cells = HashMap::new();
        let mut start = 0;
        while start < keyed.len() {
            let c = keyed[start].0;
            let end = start + keyed[start..].partition_point(|k| k.0 == c);
            cells.insert(c, (start as u32, end as u32));
            start = end;
        }
        let extent = (s[0] / h) as i32 + 2;
        Grid {
            pos,
            min: b.min,
            h,
            order: keyed.into_iter().map(|k| k.1).collect(),
            cells,
            extent,
        }
    }

    /// The `k` nearest points to point `i` (itself included), nearest first, with squared
    /// distances.
    fn nearest(&self, i: usize, k: usize) -> Vec<(f64, u32)> {
        let p = self.pos[i];
        let c: [i32; 3] = std::array::from_fn(|a| ((p[a] - self.min[a]) / self.h) as i32);
        let mut best: Vec<(f64, u32)> = Vec::with_capacity(k + 1);
        let mut r = 0i32;
        loop {
            // The shell of cells at Chebyshev distance r.
            for dx in -r..=r {
                for dy in -r..=r {
                    for dz in -r..=r {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != r {
                            continue;
                        }
                        let Some(&(s, e)) = self.cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz])
                        else {
                            continue;
                        };
                        for &j in &self.order[s as usize..e as usize] {
                            let q = self.pos[j as usize];
                            let d = (0..3).map(|a| (q[a] - p[a]).powi(2)).sum::<f64>();
                            if best.len() < k || d < best[best.len() - 1].0 {
                                let at = best.partition_point(|b| b.0 <= d);
                                best.insert(at, (d, j));
                                best.truncate(k);
                            }
                        }
                    }
                }
            }
            // Everything within r cells' distance has been seen.
            let reach = r as f64 * self.h;
            if (best.len() == k && best[k - 1].0 <= reach * reach) || r > self.extent {
                return best;
            }
            r += 1;
        }
    }
}

/// Normals (input's, else estimated; signed as `orientation` says) and splat radii of a leaf's
/// points.
pub fn leaf_splats(b: &PointBatch, orientation: &Orientation) -> Splats {
    let pos = &b.positions;
    let n = pos.len();
    if n == 0 {
        return Splats::default();
    }
    let grid = Grid::new(pos, KNN);
    let k = KNN.min(n);
    let (normals, radii): (Vec<[f32; 3]>, Vec<f32>) = (0..n)
        .into_par_iter()
        .map(|i| {
            let near = grid.nearest(i, k);
            let r = near.get(4.min(near.len() - 1)).map_or(0.0, |d| d.0.sqrt()) as f32;
            let normal = match &b.normal {
                Some(nn) => {
                    let v = nn[i];
                    unit([v[0] as f64, v[1] as f64, v[2] as f64])
                }
                None => {
                    let q: Vec<[f64; 3]> = near.iter().map(|&(_, j)| pos[j as usize]).collect();
                    let a = pca(&q).axes[2];
                    unit(a)
                }
            };
            let scanner = match orientation {
                Orientation::Scanners(at) => b
                    .point_source_id
                    .as_ref()
                    .and_then(|ids| at.get((ids[i] as usize).checked_sub(1)?)),
                _ => None,
            };
            let seen = match (orientation, &b.point_source_id) {
                (Orientation::Flights(sides), Some(ids)) => {
                    let angle = b.scan_angle.as_ref().map_or(0.0, |a| a[i]);
                    (sides.get(ids[i] as usize).copied().flatten())
                        .map(|side| side.seen_from(pos[i], angle))
                }
                _ => None,
            };
            let normal = match (orientation, scanner) {
                (Orientation::Input, _) if b.normal.is_some() => normal,
                (Orientation::Flights(_), _) => match seen {
                    Some(v) if (0..3).map(|a| normal[a] as f64 * v[a]).sum::<f64>() < 0.0 => {
                        normal.map(|x| -x)
                    }
                    Some(_) => normal,
                    None => up(normal),
                },
                // Towards the scanner: the side of the surface it saw.
                (_, Some(o)) => {
                    let p = pos[i];
                    let towards: f64 = (0..3).map(|a| normal[a] as f64 * (o[a] - p[a])).sum();
                    if towards < 0.0 {
                        normal.map(|x| -x)
                    } else {
                        normal
                    }
                }
                _ => up(normal),
            };
            (normal, r)
        })
        .unzip();
    // Duplicates (radius 0) get the smallest positive radius of the leaf; stray points, whose
    // fourth neighbour is far, at most three times the leaf's median, so that they do not
    // become discs over what lies around them.
    let mut sorted: Vec<f32> = radii.iter().copied().filter(|&r| r > 0.0).collect();
    sorted.sort_by(f32::total_cmp);
    let floor = sorted.first().copied().unwrap_or(1e-3);
    let ceiling = sorted
        .get(sorted.len() / 2)
        .map_or(f32::INFINITY, |m| 3.0 * m);
    Splats {
        normals,
        radii: radii
            .into_iter()
            .map(|r| r.max(floor).min(ceiling.max(floor)))
            .collect(),
    }
}

/// Figure 4: `target` aggregates of a node's points.
pub fn representatives(
    points: &PointBatch,
    splats: &Splats,
    bounds: &Aabb,
    target: usize,
    signed: bool,
    grid: Option<usize>,
) -> (PointBatch, Splats) {
    let n = points.len();
    if n <= target.max(1) {
        return (points.clone(), splats.clone());
    }
    let side = bounds.size().into_iter().fold(0.0, f64::max).max(1e-9);
    let mut k = grid
        .unwrap_or((target as f64).sqrt().ceil() as usize)
        .clamp(2, 256);
    let clusters = loop {
        match cluster(points, splats, bounds.min, side, k, target, signed) {
            Some(c) => break c,
            None => k = (k * 2 / 3).max(1),
        }
    };
    aggregate(points, splats, &clusters, signed)
}

/// Clusters by normal deviation in a `k^3` grid until at most `target` remain; `None` when even
/// one cluster per occupied cell is too many.
fn cluster(
    points: &PointBatch,
    splats: &Splats,
    min: [f64; 3],
    side: f64,
    k: usize,
    target: usize,
    signed: bool,
) -> Option<Vec<Vec<u32>>> {
    let cell = |p: &[f64; 3]| -> usize {
        let c = |a: usize| (((p[a] - min[a]) / side * k as f64) as usize).min(k - 1);
        (c(2) * k + c(1)) * k + c(0)
    };
    let mut keyed: Vec<(usize, u32)> = points
        .positions
        .iter()
        .enumerate()
        .map(|(i, p)| (cell(p), i as u32))
        .collect();
    keyed.sort_unstable();
    let mut cells: Vec<Vec<u32>> = Vec::new();
    let mut start = 0;
    while start < keyed.len() {
        let c = keyed[start].0;
        let end = start + keyed[start..].partition_point(|x| x.0 == c);
        cells.push(keyed[start..end].iter().map(|x| x.1).collect());
        start = end;
    }
    if cells.len() > target {
        return None;
    }
    let group = |members: &[u32], theta: f32| -> Vec<Vec<u32>> {
        if theta >= 180.0 {
            return vec![members.to_vec()];
        }
        let cos = theta.to_radians().cos();
        let mut out: Vec<(usize, Vec<u32>)> = Vec::new();
        for &i in members {
            let n = splats.normals[i as usize];
            let found = out.iter_mut().find(|(first, _)| {
                let m = splats.normals[*first];
                // Signed normals facing opposite ways (a thin wall's sides) stay apart.
                let d = n[0] * m[0] + n[1] * m[1] + n[2] * m[2];
                (if signed { d } else { d.abs() }) >= cos
            });
            match found {
                Some((_, c)) => c.push(i),
                None => out.push((i as usize, vec![i])),
            }
        }
        out.into_iter().map(|c| c.1).collect()
    };
    // Every point its own cluster; a cell is first clustered at THETA, then at double the
    // threshold each time it is taken again.
    let mut theta = vec![THETA / 2.0; cells.len()];
    let mut groups: Vec<Vec<Vec<u32>>> = cells
        .iter()
        .map(|c| c.iter().map(|&i| vec![i]).collect())
        .collect();
    let mut count: usize = groups.iter().map(|g| g.len()).sum();
    let mut queue: BinaryHeap<(usize, usize)> = groups
        .iter()
        .enumerate()
        .map(|(i, g)| (g.len(), i))
        .collect();
    while count > target {
        let Some((len, i)) = queue.pop() else { break };
        if len != groups[i].len() {
            continue;
        }
        theta[i] = if theta[i] >= 90.0 {
            180.0
        } else {
            theta[i] * 2.0
        };
        let g = group(&cells[i], theta[i]);
        count = count - groups[i].len() + g.len();
        groups[i] = g;
        if groups[i].len() > 1 {
            queue.push((groups[i].len(), i));
        }
    }
    Some(groups.into_iter().flatten().collect())
}

/// One aggregate per cluster.
fn aggregate(
    points: &PointBatch,
    splats: &Splats,
    clusters: &[Vec<u32>],
    signed: bool,
) -> (PointBatch, Splats) {
    let mut rows = Vec::with_capacity(clusters.len());
    let mut centres = Vec::with_capacity(clusters.len());
    let mut out = Splats::default();
    let mut rgb = Vec::new();
    let mut intensity = Vec::new();
    for c in clusters {
        let w = |i: u32| {
            let r = splats.radii[i as usize] as f64;
            (r * r).max(1e-12)
        };
        let total: f64 = c.iter().map(|&i| w(i)).sum();
        let mut centre = [0.0; 3];
        let mut normal = [0.0; 3];
        let mut facing = [0.0; 3];
        let first = splats.normals[c[0] as usize];
        for &i in c {
            let p = points.positions[i as usize];
            let n = splats.normals[i as usize];
            // The axis: normals summed on the first one's side (a cluster may hold both faces
            // of a thin wall); signed normals then face the side most of the weight faces.
            let sign = if n[0] * first[0] + n[1] * first[1] + n[2] * first[2] < 0.0 {
                -1.0
            } else {
                1.0
            };
            for a in 0..3 {
                centre[a] += p[a] * w(i) / total;
                normal[a] += sign * n[a] as f64 * w(i);
                facing[a] += n[a] as f64 * w(i);
            }
        }
        if signed && (0..3).map(|a| normal[a] * facing[a]).sum::<f64>() < 0.0 {
            normal = normal.map(|x| -x);
        }
        let dist = |i: u32| {
            let p = points.positions[i as usize];
            ((0..3).map(|a| (p[a] - centre[a]).powi(2)).sum::<f64>()).sqrt()
        };
        let nearest = *c
            .iter()
            .min_by(|&&a, &&b| dist(a).total_cmp(&dist(b)))
            .expect("a cluster has members");
        let radius = c
            .iter()
            .map(|&i| dist(i) + splats.radii[i as usize] as f64)
            .fold(0.0, f64::max);
        rows.push(nearest);
        centres.push(centre);
        out.normals.push(if signed {
            unit(normal)
        } else {
            up(unit(normal))
        });
        out.radii.push(radius as f32);
        if let Some(col) = &points.rgb {
            let mut s = [0.0; 3];
            for &i in c {
                for (a, v) in s.iter_mut().enumerate() {
                    *v += col[i as usize][a] as f64 * w(i) / total;
                }
            }
            rgb.push(s.map(|v| v.round().clamp(0.0, 65535.0) as u16));
        }
        if let Some(col) = &points.intensity {
            let s: f64 = c
                .iter()
                .map(|&i| col[i as usize] as f64 * w(i) / total)
                .sum();
            intensity.push(s.round().clamp(0.0, 65535.0) as u16);
        }
    }
    let mut b = points.gather(&rows);
    b.positions = centres;
    if b.rgb.is_some() {
        b.rgb = Some(rgb);
    }
    if b.intensity.is_some() {
        b.intensity = Some(intensity);
    }
    if b.normal.is_some() {
        b.normal = Some(out.normals.clone());
    }
    (b, out)
}

/// Splits `idx` (indices into `pos`) along the longest axis of `b` into `n` runs of equal count.
fn split_equal(pos: &[[f64; 3]], b: &Aabb, mut idx: Vec<u32>, n: usize) -> Vec<Vec<u32>> {
    let s = b.size();
    let axis = (0..3).max_by(|&i, &j| s[i].total_cmp(&s[j])).unwrap_or(0);
    idx.sort_unstable_by(|&a, &b| pos[a as usize][axis].total_cmp(&pos[b as usize][axis]));
    let len = idx.len();
    (0..n)
        .map(|i| idx[i * len / n..(i + 1) * len / n].to_vec())
        .filter(|v| !v.is_empty())
        .collect()
}

/// Builds the subtree at `key` over `batch`, handing each node to `emit`, children before their
/// parent (the root last).
pub fn build_subtree_with<E>(
    batch: PointBatch,
    key: NodeKey,
    p: &MwkdParams,
    emit: &mut dyn FnMut(MwNode) -> Result<(), E>,
) -> Result<MwNode, E> {
    let bounds = bounds_of(&batch.positions);
    if batch.len() <= p.capacity || key.level >= crate::kd::MAX_LEVEL {
        let splats = leaf_splats(&batch, &p.orientation);
        return Ok(MwNode {
            key,
            points: batch,
            splats,
            bounds,
            aggregate: false,
        });
    }
    let parts = split_equal(
        &batch.positions,
        &bounds,
        (0..batch.len() as u32).collect(),
        p.fanout,
    );
    let mut children = Vec::with_capacity(parts.len());
    for (i, part) in parts.iter().enumerate() {
        let child = build_subtree_with(batch.gather(part), key.child(i), p, emit)?;
        children.push(child);
    }
    drop(batch);
    let (top, children) = take_up(key, children, p);
    for c in children {
        emit(c)?;
    }
    Ok(top)
}

/// An inner node made of `s/N` representatives of each child; the children are returned as they
/// were (their points stay theirs).
pub fn take_up(key: NodeKey, children: Vec<MwNode>, p: &MwkdParams) -> (MwNode, Vec<MwNode>) {
    let target = (p.capacity / p.fanout).max(1);
    let reps: Vec<(PointBatch, Splats)> = children
        .par_iter()
        .map(|c| {
            representatives(
                &c.points,
                &c.splats,
                &c.bounds,
                target,
                p.orientation.signed(),
                p.grid,
            )
        })
        .collect();
    let mut points: Option<PointBatch> = None;
    let mut splats = Splats::default();
    let mut bounds = Aabb::EMPTY;
    for ((b, s), c) in reps.into_iter().zip(&children) {
        match &mut points {
            Some(all) => all.append(&b),
            None => points = Some(b),
        }
        splats.normals.extend(s.normals);
        splats.radii.extend(s.radii);
        bounds = bounds.union(&c.bounds);
    }
    (
        MwNode {
            key,
            points: points.unwrap_or_default(),
            splats,
            bounds,
            aggregate: true,
        },
        children,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_core::{Attribute, Schema};

    /// A wavy surface of `n` points with colour and ids in the intensity.
    fn surface(n: usize) -> PointBatch {
        let mut b =
            PointBatch::with_schema(&Schema::new(vec![Attribute::Intensity, Attribute::Rgb]), 0);
        let side = (n as f64).sqrt().ceil() as usize;
        for i in 0..n {
            let (x, y) = ((i % side) as f64 * 0.1, (i / side) as f64 * 0.1);
            b.positions.push([x, y, (x * 0.3).sin()]);
            b.intensity.as_mut().unwrap().push(i as u16);
            b.rgb.as_mut().unwrap().push([(x * 1000.0) as u16, 0, 0]);
        }
        b
    }

    #[test]
    fn fanout_makes_the_depth_whole() {
        // n/s = 64: 2, 4 and 8 are all whole (6, 3, 2 levels): the shallowest.
        assert_eq!(fanout_for(64 * 1000, 1000), 8);
        // n/s = 27: 3^3.
        assert_eq!(fanout_for(27 * 1000, 1000), 3);
        // n/s = 25: 5^2.
        assert_eq!(fanout_for(25 * 1000, 1000), 5);
    }

    #[test]
    fn normals_and_radii_of_a_plane() {
        let mut b = surface(2500);
        for p in &mut b.positions {
            p[2] = 0.5 * p[0] + 2.0;
        }
        let s = leaf_splats(&b, &Orientation::Up);
        let want = unit([-0.5, 0.0, 1.0]);
        for n in &s.normals {
            let d = n[0] * want[0] + n[1] * want[1] + n[2] * want[2];
            assert!(d > 0.999, "{n:?}");
        }
        // Grid spacing 0.1 along y, 0.1 * 1.118 along the slope: the 4th neighbour is at the
        // diagonal or the next row.
        let r = s.radii[1275];
        assert!(r > 0.1 && r < 0.2, "{r}");
    }

    #[test]
    fn normals_face_their_scanner_or_keep_the_inputs_sign() {
        // A ceiling (z = 3) seen from below by scanner 1, a floor (z = 0) from above by
        // scanner 2, and a floor point whose source names no scanner.
        let mut b = PointBatch::with_schema(&Schema::new(vec![Attribute::PointSourceId]), 0);
        for i in 0..800 {
            let (x, y) = ((i % 20) as f64 * 0.1, (i / 20 % 20) as f64 * 0.1);
            let ceiling = i < 400;
            b.positions.push([
                x + if ceiling { 0.0 } else { 10.0 },
                y,
                if ceiling { 3.0 } else { 0.0 },
            ]);
            b.point_source_id.as_mut().unwrap().push(match i {
                799 => 7,
                _ if ceiling => 1,
                _ => 2,
            });
        }
        let scanners =
            Orientation::Scanners(std::sync::Arc::new(vec![[1.0, 1.0, 1.5], [11.0, 1.0, 1.5]]));
        let s = leaf_splats(&b, &scanners);
        assert!(
            s.normals[..400].iter().all(|n| n[2] < -0.99),
            "{:?}",
            s.normals[0]
        );
        assert!(s.normals[400..].iter().all(|n| n[2] > 0.99));
        // Without scanners every estimated normal is turned up: the ceiling faces the sky.
        let s = leaf_splats(&b, &Orientation::Up);
        assert!(s.normals.iter().all(|n| n[2] > 0.99));
        // The input's normals keep their sign.
        let mut with = b.clone();
        with.normal = Some(vec![[0.0, 0.0, -1.0]; 800]);
        let s = leaf_splats(&with, &Orientation::Input);
        assert!(s.normals.iter().all(|n| n[2] == -1.0));
        // Aggregates of signed normals keep a side.
        let mut wall = PointBatch::with_schema(&Schema::new(vec![Attribute::Intensity]), 0);
        let mut normals = Vec::new();
        for i in 0..2000 {
            let side = if i % 2 == 0 { 1.0 } else { -1.0 };
            wall.positions.push([
                (i / 2 % 30) as f64 * 0.1,
                (i / 60) as f64 * 0.1,
                side * 0.001,
            ]);
            wall.intensity.as_mut().unwrap().push(i as u16);
            normals.push([0.0, 0.0, side as f32]);
        }
        let splats = Splats {
            radii: vec![0.05; 2000],
            normals,
        };
        let bounds = bounds_of(&wall.positions);
        // Clusters holding both faces keep the wall's axis (facing the heavier side).
        let (_, reps) = representatives(&wall, &splats, &bounds, 200, true, None);
        assert!(reps.normals.iter().all(|n| n[2].abs() > 0.99));
    }

    #[test]
    fn inner_nodes_aggregate_and_leaves_keep_every_point() {
        let b = surface(20_000);
        let p = MwkdParams {
            fanout: 4,
            capacity: 2000,
            grid: None,
            orientation: Orientation::Up,
        };
        let mut nodes = Vec::new();
        let root = build_subtree_with(b, NodeKey::ROOT, &p, &mut |n| {
            nodes.push(n);
            Ok::<(), ()>(())
        })
        .unwrap();
        nodes.push(root);
        let leaves: Vec<&MwNode> = nodes.iter().filter(|n| !n.aggregate).collect();
        let mut ids: Vec<u16> = leaves
            .iter()
            .flat_map(|n| n.points.intensity.clone().unwrap())
            .collect();
        ids.sort_unstable();
        assert_eq!(ids, (0..20_000u32).map(|i| i as u16).collect::<Vec<_>>());
        // Equal-sized leaves (20 000 / 16 = 1250) at one depth; inner nodes near s points.
        assert!(
            leaves
                .iter()
                .all(|n| n.points.len() == 1250 && n.key.level == 2)
        );
        for n in nodes.iter().filter(|n| n.aggregate) {
            assert!(
                n.points.len() <= 2000 && n.points.len() >= 1000,
                "{}",
                n.points.len()
            );
            assert_eq!(n.splats.radii.len(), n.points.len());
            // Aggregates cover: every leaf point below lies within some aggregate's splat.
        }
        let root = nodes.iter().find(|n| n.key == NodeKey::ROOT).unwrap();
        let covered = |p: [f64; 3]| {
            root.points
                .positions
                .iter()
                .zip(&root.splats.radii)
                .any(|(q, &r)| {
                    (0..3).map(|a| (p[a] - q[a]).powi(2)).sum::<f64>().sqrt() <= r as f64 + 1e-9
                })
        };
        for l in &leaves {
            assert!(l.points.positions.iter().step_by(97).all(|&p| covered(p)));
        }
        // Normals point up; the cone of the root is a surface's: well under 90 degrees.
        assert!(root.splats.normals.iter().all(|n| n[2] >= 0.0));
        assert!(root.cone()[3] > 0.0, "{:?}", root.cone());
    }
}
