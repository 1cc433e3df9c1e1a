//! A built node's way out: its points put in acquisition order and written to the dataset
//! (with its splat page), or spilled to disk as rows while the levels above may still take points
//! from it, and read back.

use crate::nested::BuiltNode;
use crate::order::acquisition_permutation;
use myriad_core::{Error, NodeKey, PointBatch, Result, Schema};
use myriad_format::{DatasetWriter, NodeShape};
use std::path::{Path, PathBuf};

/// A node waiting on disk for the levels above: its points as rows, in MOSPT order.
pub(crate) struct Pending {
    pub(crate) key: NodeKey,
    path: PathBuf,
    points: usize,
    prefix: Vec<u64>,
    spacing: Vec<f64>,
    shape: NodeShape,
    /// Normals and radii spilled next to the rows (`mwkd`), and whether they are aggregates.
    splats: Option<(PathBuf, bool)>,
    acquisition: bool,
}

/// Puts the points of each level of detail of a node in acquisition order (GPS time) when the
/// points have it. Any order within a level keeps the prefix property; acquisition order makes
/// neighbours in the page neighbours along a scan line, which compresses far better (time deltas
/// are nearly constant, positions and intensities change slowly). The last level (where a
/// budget usually cuts a node) is first dealt into `STRATA` strata, each spread over the
/// node: the k-th point (in acquisition order) of each cell of twice the level's spacing goes
/// to stratum k (the last takes the rest), so that a prefix draws a thin even sample of the
/// whole node rather than a run of scan lines; each stratum stays in acquisition order.
fn acquisition_order(node: &mut BuiltNode) {
    if node.acquisition {
        return;
    }
    let n = node.points.len();
    let order = acquisition_permutation(&node.points, None, n, &node.prefix, &node.spacing);
    if order.iter().enumerate().all(|(i, &o)| i as u32 == o) {
        return;
    }
    node.points = node.points.gather(&order);
    if let Some((s, _)) = &mut node.splats {
        s.normals = order.iter().map(|&i| s.normals[i as usize]).collect();
        s.radii = order.iter().map(|&i| s.radii[i as usize]).collect();
    }
    node.acquisition = true;
}

pub(crate) fn write(writer: &DatasetWriter, mut node: BuiltNode) -> Result<u64> {
    acquisition_order(&mut node);
    let mut bytes = writer.write_node(
        node.key,
        &node.points,
        &node.prefix,
        &node.spacing,
        node.shape,
    )?;
    if let Some((s, aggregate)) = &node.splats {
        let cone = crate::mwkd::MwNode::cone_of(&s.normals);
        bytes += writer.write_splats(node.key, s, cone, *aggregate)?;
    }
    Ok(bytes)
}

pub(crate) fn spill(node: BuiltNode, dir: &Path) -> Result<Pending> {
    let path = dir.join(format!("node-{}.rows", node.key));
    let mut bytes = Vec::with_capacity(node.points.len() * node.points.row_size());
    for i in 0..node.points.len() {
        node.points.put_row(i, &mut bytes);
    }
    std::fs::write(&path, &bytes).map_err(|e| Error::io(&path, e))?;
    let splats = match &node.splats {
        Some((s, aggregate)) => {
            let sp = dir.join(format!("node-{}.splats", node.key));
            let mut b = Vec::with_capacity(s.radii.len() * 16);
            for (n, r) in s.normals.iter().zip(&s.radii) {
                for v in n.iter().chain(std::iter::once(r)) {
                    b.extend_from_slice(&v.to_le_bytes());
                }
            }
            std::fs::write(&sp, &b).map_err(|e| Error::io(&sp, e))?;
            Some((sp, *aggregate))
        }
        None => None,
    };
    Ok(Pending {
        key: node.key,
        path,
        points: node.points.len(),
        prefix: node.prefix,
        spacing: node.spacing,
        shape: node.shape,
        splats,
        acquisition: node.acquisition,
    })
}

pub(crate) fn unspill(p: Pending, schema: &Schema) -> Result<BuiltNode> {
    let bytes = std::fs::read(&p.path).map_err(|e| Error::io(&p.path, e))?;
    let mut b = PointBatch::with_schema(schema, p.points);
    let row = b.row_size();
    if bytes.len() != row * p.points {
        return Err(Error::at_byte(
            &p.path,
            bytes.len() as u64,
            "spilled node has the wrong size",
        ));
    }
    for r in bytes.chunks_exact(row) {
        b.push_row(r);
    }
    std::fs::remove_file(&p.path).map_err(|e| Error::io(&p.path, e))?;
    let splats = match p.splats {
        Some((sp, aggregate)) => {
            let bytes = std::fs::read(&sp).map_err(|e| Error::io(&sp, e))?;
            if bytes.len() != 16 * p.points {
                return Err(Error::at_byte(
                    &sp,
                    bytes.len() as u64,
                    "spilled splats have the wrong size",
                ));
            }
            let mut s = myriad_format::splat::Splats::default();
            for r in bytes.chunks_exact(16) {
                let f = |i: usize| f32::from_le_bytes(r[4 * i..4 * i + 4].try_into().unwrap());
                s.normals.push([f(0), f(1), f(2)]);
                s.radii.push(f(3));
            }
            std::fs::remove_file(&sp).map_err(|e| Error::io(&sp, e))?;
            Some((s, aggregate))
        }
        None => None,
    };
    Ok(BuiltNode {
        key: p.key,
        points: b,
        prefix: p.prefix,
        spacing: p.spacing,
        shape: p.shape,
        splats,
        acquisition: p.acquisition,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_last_level_is_spread_over_the_node_and_each_stratum_in_acquisition_order() {
        // A 10 m square scanned line by line, a point every 0.1 m: the last level of a node.
        let schema = Schema::new(vec![myriad_core::Attribute::GpsTime]);
        let mut b = PointBatch::with_schema(&schema, 0);
        for i in 0..10_000 {
            b.positions.push([
                (i % 100) as f64 * 0.1 + 0.05,
                (i / 100) as f64 * 0.1 + 0.05,
                0.0,
            ]);
            b.gps_time.as_mut().unwrap().push(i as f64);
        }
        let mut node = BuiltNode {
            key: NodeKey::ROOT,
            points: b,
            prefix: vec![10_000],
            spacing: vec![0.1],
            shape: NodeShape::default(),
            splats: None,
            acquisition: false,
        };
        // The cells of 0.2 m that the first quarter of the points reaches.
        let reach = |node: &BuiltNode| {
            let cells: std::collections::HashSet<[i64; 2]> = node.points.positions[..2500]
                .iter()
                .map(|p| [(p[0] / 0.2) as i64, (p[1] / 0.2) as i64])
                .collect();
            cells.len() as f64 / 2500.0
        };
        // In scan-line order: 25 of 100 lines, 13 of 50 rows of cells.
        assert_eq!(reach(&node), 0.26, "a quarter of the square");
        acquisition_order(&mut node);
        assert_eq!(reach(&node), 1.0, "a point in every cell");
        let t = node.points.gps_time.as_ref().unwrap(); // four strata, each in time order
        for stratum in t.chunks(2500) {
            assert!(stratum.windows(2).all(|w| w[0] < w[1]));
        }
        assert!(t[2499] > t[2500]);
    }

    #[test]
    fn nodes_gathered_in_acquisition_order() {
        // A builder's node (its points ordered by index, then gathered once) is the node the
        // writer would make of the same points gathered in level order.
        let schema = Schema::new(vec![myriad_core::Attribute::GpsTime]);
        let mut b = PointBatch::with_schema(&schema, 0);
        let mut seed = 7u64;
        for _ in 0..5000 {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let r = |s: u64, k: u32| ((s >> k) & 0xffff) as f64 / 65536.0;
            b.positions.push([r(seed, 0), r(seed, 16), r(seed, 32)]);
            b.gps_time.as_mut().unwrap().push(r(seed, 48) * 100.0);
        }
        let cube = myriad_core::Aabb::new([0.0; 3], [1.0; 3]);
        let m = crate::mospt::build(&b, &cube, 5);
        for keep in [1, 300, 5000] {
            let node = crate::nested::node_from_prefix(NodeKey::ROOT, &b, &m, keep);
            assert!(node.acquisition);
            let mut plain = BuiltNode {
                points: b.gather(&m.order[..keep]),
                acquisition: false,
                ..node.clone()
            };
            acquisition_order(&mut plain);
            assert_eq!(node.points.positions, plain.points.positions, "keep {keep}");
            assert_eq!(node.points.gps_time, plain.points.gps_time);
        }
    }

    #[test]
    fn levels_in_acquisition_order() {
        let schema = Schema::new(vec![myriad_core::Attribute::GpsTime]);
        let mut b = PointBatch::with_schema(&schema, 0);
        let times = [5.0, -3.0, 1.0, 9.0, -7.5, 2.0, 0.0, -0.0];
        for (i, &t) in times.iter().enumerate() {
            b.positions.push([i as f64, 0.0, 0.0]);
            b.gps_time.as_mut().unwrap().push(t);
        }
        let mut node = BuiltNode {
            key: NodeKey::ROOT,
            points: b,
            prefix: vec![1, 4, 8],
            spacing: vec![4.0, 2.0, 1.0],
            shape: NodeShape::default(),
            splats: None,
            acquisition: false,
        };
        acquisition_order(&mut node);
        let t = node.points.gps_time.as_ref().unwrap();
        // Level 0 is one point; level 1 (points 1..4) was already in order.
        assert_eq!(&t[..4], &[5.0, -3.0, 1.0, 9.0]);
        assert_eq!(
            t[4..].iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            [-7.5f64, -0.0, 0.0, 2.0].map(f64::to_bits)
        );
        // Positions moved with their times.
        assert_eq!(node.points.positions[4][0], 4.0);
        assert_eq!(node.points.positions[7][0], 5.0);
    }
}
