//! A part's `.tops` file ([`crate::partition`]): its level-P nodes as they were before the
//! levels above took points from them, for the merge.

use super::{BuildPlan, PartSummary};
use crate::nested::BuiltNode;
use myriad_core::{Aabb, Error, NodeKey, Obb, PointBatch, Result};
use myriad_format::NodeShape;
use serde_json::{Value, json};
use std::io::{Read, Write};
use std::path::Path;

const TOPS_MAGIC: &[u8; 8] = b"MYRTOPS1";

fn shape_json(s: &NodeShape) -> Value {
    let obb = |o: &Obb| json!({"center": o.center, "axes": o.axes, "half": o.half_extents});
    json!({
        "bounds": s.bounds.map(|b| json!({"min": b.min, "max": b.max})),
        "contour": s.contour.as_ref().map(obb),
        "detail": s.detail.as_ref().map(obb),
    })
}

fn shape_from(v: &Value) -> Option<NodeShape> {
    let f3 = |x: &Value| -> Option<[f64; 3]> {
        let a = x.as_array().filter(|a| a.len() == 3)?;
        Some([a[0].as_f64()?, a[1].as_f64()?, a[2].as_f64()?])
    };
    let bounds = match &v["bounds"] {
        Value::Null => None,
        b => Some(Aabb::new(f3(&b["min"])?, f3(&b["max"])?)),
    };
    let obb = |c: &Value| -> Option<Option<Obb>> {
        if c.is_null() {
            return Some(None);
        }
        let axes = c["axes"].as_array().filter(|a| a.len() == 3)?;
        Some(Some(Obb {
            center: f3(&c["center"])?,
            axes: [f3(&axes[0])?, f3(&axes[1])?, f3(&axes[2])?],
            half_extents: f3(&c["half"])?,
        }))
    };
    Some(NodeShape {
        bounds,
        contour: obb(&v["contour"])?,
        detail: obb(&v["detail"])?,
    })
}

/// The `.tops` file: magic, the head's length (u64) and the head (JSON: plan, part, summary, the
/// nodes' keys, counts, levels and shapes), then every node's rows, zstd-compressed. Written
/// under a temporary name and renamed.
pub(crate) fn write(
    path: &Path,
    plan: &BuildPlan,
    index: usize,
    s: &PartSummary,
    tops: &[BuiltNode],
) -> Result<()> {
    let head = json!({
        "plan": plan.id, "part": index, "points": s.points,
        "bounds": (!s.bounds.is_empty()).then(|| json!({"min": s.bounds.min, "max": s.bounds.max})),
        "inputs": s.inputs.iter().map(|i| i.map(|(t, r)| json!({"taken": t, "read": r}))).collect::<Vec<_>>(),
        "skipped_non_finite": s.skipped_non_finite, "trimmed": s.trimmed,
        "nodes": tops.iter().map(|n| json!({
            "level": n.key.level, "cell": n.key.cell, "points": n.points.len(),
            "prefix": n.prefix, "spacing": n.spacing, "shape": shape_json(&n.shape),
        })).collect::<Vec<_>>(),
    })
    .to_string();
    let file = myriad_io::atomic::AtomicFile::create(path, true)?;
    let io = |e| Error::io(file.temp_path(), e);
    let mut f = std::io::BufWriter::new(file.open_write()?);
    f.write_all(TOPS_MAGIC).map_err(io)?;
    f.write_all(&(head.len() as u64).to_le_bytes())
        .map_err(io)?;
    f.write_all(head.as_bytes()).map_err(io)?;
    let mut z = zstd::Encoder::new(f, 1).map_err(io)?;
    let mut row = Vec::new();
    for n in tops {
        for i in 0..n.points.len() {
            row.clear();
            n.points.put_row(i, &mut row);
            z.write_all(&row).map_err(io)?;
        }
    }
    let f = z.finish().map_err(io)?;
    f.into_inner()
        .map_err(|e| io(e.into_error()))?
        .sync_all()
        .map_err(io)?;
    file.commit()
}

/// A part's `.tops` file read back: its head and its nodes.
pub(crate) fn read(path: &Path, plan: &BuildPlan, index: usize) -> Result<(Value, Vec<BuiltNode>)> {
    let mut f = std::fs::File::open(path).map_err(|e| {
        Error::Invalid(format!(
            "{}: part {index} has not finished ({e}): run `myriad convert --plan PLAN --part \
             {index} -o {}` again",
            path.display(),
            path.parent().unwrap_or(Path::new(".")).display()
        ))
    })?;
    let io = |e| Error::io(path, e);
    let mut magic = [0u8; 16];
    f.read_exact(&mut magic).map_err(io)?;
    if &magic[..8] != TOPS_MAGIC {
        return Err(Error::at_byte(path, 0, "not a part's .tops file"));
    }
    let len = u64::from_le_bytes(magic[8..].try_into().expect("8 bytes"));
    if len > 1 << 30 {
        return Err(Error::at_byte(path, 8, "head length out of range"));
    }
    let mut head = vec![0u8; len as usize];
    f.read_exact(&mut head).map_err(io)?;
    let head: Value = serde_json::from_slice(&head)
        .map_err(|e| Error::at_byte(path, 16 + e.column() as u64, format!("head: {e}")))?;
    if head["plan"].as_str() != Some(plan.id.as_str())
        || head["part"].as_u64() != Some(index as u64)
    {
        return Err(Error::Invalid(format!(
            "{}: built from another plan or part (plan {}, part {}), not part {index} of plan {}",
            path.display(),
            head["plan"],
            head["part"],
            plan.id
        )));
    }
    let mut rows = Vec::new();
    zstd::Decoder::new(f)
        .and_then(|mut z| z.read_to_end(&mut rows))
        .map_err(io)?;
    let schema = &plan.dataset.schema;
    let row = PointBatch::with_schema(schema, 0).row_size();
    let mut at = 0usize;
    let mut nodes = Vec::new();
    let bad = |m: &str| Error::at_byte(path, 16, format!("head: {m}"));
    for n in head["nodes"].as_array().ok_or_else(|| bad("no nodes"))? {
        let count = n["points"].as_u64().ok_or_else(|| bad("node points"))? as usize;
        let cell = n["cell"]
            .as_array()
            .filter(|c| c.len() == 3)
            .and_then(|c| {
                Some([
                    c[0].as_u64()? as u32,
                    c[1].as_u64()? as u32,
                    c[2].as_u64()? as u32,
                ])
            })
            .ok_or_else(|| bad("node cell"))?;
        let nums = |k: &str| {
            n[k].as_array()
                .map(|a| a.iter().map(|x| x.as_f64()).collect::<Option<Vec<_>>>())
        };
        let prefix = nums("prefix").flatten().ok_or_else(|| bad("node prefix"))?;
        let spacing = nums("spacing")
            .flatten()
            .ok_or_else(|| bad("node spacing"))?;
        let end = at + count * row;
        if end > rows.len() {
            return Err(Error::at_byte(
                path,
                16 + len,
                "rows end before the nodes' points",
            ));
        }
        let mut b = PointBatch::with_schema(schema, count);
        for r in rows[at..end].chunks_exact(row) {
            b.push_row(r);
        }
        at = end;
        nodes.push(BuiltNode {
            key: NodeKey {
                level: n["level"].as_u64().ok_or_else(|| bad("node level"))? as u32,
                cell,
            },
            points: b,
            prefix: prefix.into_iter().map(|p| p as u64).collect(),
            spacing,
            shape: shape_from(&n["shape"]).ok_or_else(|| bad("node shape"))?,
            splats: None,
            acquisition: false,
        });
    }
    if at != rows.len() {
        return Err(Error::at_byte(
            path,
            16 + len,
            "rows beyond the nodes' points",
        ));
    }
    Ok((head, nodes))
}
