//! `myriad bench contours D.myr`: how far a layered dataset's contours (000's oriented boxes,
//! which the selection sizes a node's detail and culls by) are from the boxes of the nodes' own
//! points. A node's stored contour holds its whole subtree (culling needs that: a box of its own
//! points alone could leave out a descendant); 000 sizes detail by the contour of the node's own
//! points. Each node's points are read and their contour made as the build makes contours
//! ([`myriad_build::ntree::contour`]); the two are compared by their area (the sum of their
//! three faces' areas: what a view projects of them, over all directions) and by their
//! thickness (the smallest extent: what an edge-on view sees), per level and in all.

use anyhow::{Result, bail};
use clap::Args;
use myriad_core::Obb;
use myriad_format::Dataset;
use std::collections::BTreeMap;
use std::path::PathBuf;

#[derive(Args)]
pub struct ContoursBenchArgs {
    /// Layered datasets (convert --structure layered)
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    /// Read every Nth node only (all: 1)
    #[arg(long, default_value_t = 1)]
    every: usize,
}

/// The sum of the areas of a box's three faces (a third of its surface).
fn area(o: &Obb) -> f64 {
    let [a, b, c] = o.half_extents.map(|h| 2.0 * h);
    a * b + b * c + c * a
}

fn thickness(o: &Obb) -> f64 {
    2.0 * o.half_extents.iter().copied().fold(f64::INFINITY, f64::min)
}

/// The value at fraction `q` of the sorted `v`.
fn quantile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(((v.len() as f64 - 1.0) * q).round() as usize)
        .copied()
        .unwrap_or(f64::NAN)
}

pub fn run(a: ContoursBenchArgs) -> Result<()> {
    for path in &a.datasets {
        let ds = Dataset::open(path)?;
        let (mut nodes, _) = ds.nodes();
        nodes.retain(|e| e.contour.is_some() && e.points >= 4);
        if nodes.is_empty() {
            bail!(
                "{}: no node has a contour (convert --structure layered)",
                path.display()
            );
        }
        nodes.sort_by_key(|e| e.key);
        // Per level: own area / stored area, own thickness / stored thickness.
        let mut by_level: BTreeMap<u32, (Vec<f64>, Vec<f64>)> = BTreeMap::new();
        let (mut areas, mut thick) = (Vec::new(), Vec::new());
        for e in nodes.iter().step_by(a.every.max(1)) {
            let Ok(b) = ds.read_node(e) else { continue };
            let stored = e.contour.expect("kept: nodes with a contour");
            let own =
                myriad_build::ntree::contour(&b.positions, &myriad_build::ntree::pca(&b.positions));
            let ra = area(&own) / area(&stored).max(f64::MIN_POSITIVE);
            let rt = thickness(&own) / thickness(&stored).max(f64::MIN_POSITIVE);
            let l = by_level.entry(e.key.level).or_default();
            l.0.push(ra);
            l.1.push(rt.min(10.0));
            areas.push(ra);
            thick.push(rt.min(10.0));
        }
        println!(
            "{}: {} nodes with contours, {} read; own points' contour against the stored (subtree) contour",
            path.display(),
            nodes.len(),
            areas.len()
        );
        println!(
            "{:>6} {:>6} {:>9} {:>9} {:>9} {:>10} {:>10}",
            "level", "nodes", "area p10", "area p50", "area p90", "thick p10", "thick p50"
        );
        let row = |name: String, v: &mut (Vec<f64>, Vec<f64>)| {
            println!(
                "{name:>6} {:>6} {:>9.3} {:>9.3} {:>9.3} {:>10.3} {:>10.3}",
                v.0.len(),
                quantile(&mut v.0, 0.1),
                quantile(&mut v.0, 0.5),
                quantile(&mut v.0, 0.9),
                quantile(&mut v.1, 0.1),
                quantile(&mut v.1, 0.5)
            )
        };
        for (level, v) in by_level.iter_mut() {
            row(level.to_string(), v);
        }
        row("all".into(), &mut (areas, thick));
        println!(
            "(area: the sum of the box's three faces' areas, own over stored; thick: its smallest \
             extent, own over stored; p10/p50/p90: quantiles over the nodes)"
        );
    }
    Ok(())
}
