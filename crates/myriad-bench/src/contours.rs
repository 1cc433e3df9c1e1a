//! `myriad bench contours D.myr`: how far a layered dataset's contours (the oriented boxes of
//! Kanzok et al. 2015, which the selection culls by) are from the boxes of the nodes' own points. A
//! node's contour holds its whole subtree (culling needs that: a box of its own points alone could
//! leave out a descendant); Kanzok et al. size detail by the contour of the node's own points,
//! which nodes that pass points down store beside it (and which is checked against the one made
//! here). Each node's points are read and their contour made as the build makes contours
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

#[derive(Default)]
struct Ratios {
    area: Vec<f64>,
    thick: Vec<f64>,
    flat_stored: usize,
    flat_own: usize,
}

impl Ratios {
    fn add(&mut self, own: &Obb, stored: &Obb) {
        self.area
            .push(area(own) / area(stored).max(f64::MIN_POSITIVE));
        self.thick
            .push((thickness(own) / thickness(stored).max(f64::MIN_POSITIVE)).min(10.0));
        self.flat_stored += myriad_lod::select::flat(stored) as usize;
        self.flat_own += myriad_lod::select::flat(own) as usize;
    }

    fn row(&mut self, name: &str) {
        println!(
            "{name:>6} {:>6} {:>9.3} {:>9.3} {:>9.3} {:>10.3} {:>10.3} {:>12} {:>9}",
            self.area.len(),
            quantile(&mut self.area, 0.1),
            quantile(&mut self.area, 0.5),
            quantile(&mut self.area, 0.9),
            quantile(&mut self.thick, 0.1),
            quantile(&mut self.thick, 0.5),
            self.flat_stored,
            self.flat_own
        );
    }
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
        // Per level, and in all: own over stored areas and thicknesses, and how many of each
        // are flat (the selection's rule on detail binds only on flat contours).
        let mut by_level: BTreeMap<u32, Ratios> = BTreeMap::new();
        let mut all = Ratios::default();
        // Nodes that store their own points' contour, and how far it is from the one made here.
        let (mut stored_own, mut worst) = (0usize, 0f64);
        for e in nodes.iter().step_by(a.every.max(1)) {
            let Ok(b) = ds.read_node(e) else { continue };
            let stored = e.contour.expect("kept: nodes with a contour");
            let own =
                myriad_build::ntree::contour(&b.positions, &myriad_build::ntree::pca(&b.positions));
            if let Some(d) = &e.detail {
                stored_own += 1;
                worst = worst.max((area(d) / area(&own).max(f64::MIN_POSITIVE) - 1.0).abs());
            }
            for r in [by_level.entry(e.key.level).or_default(), &mut all] {
                r.add(&own, &stored);
            }
        }
        println!(
            "{}: {} nodes with contours, {} read; own points' contour against the stored (subtree) contour",
            path.display(),
            nodes.len(),
            all.area.len()
        );
        println!(
            "{:>6} {:>6} {:>9} {:>9} {:>9} {:>10} {:>10} {:>12} {:>9}",
            "level",
            "nodes",
            "area p10",
            "area p50",
            "area p90",
            "thick p10",
            "thick p50",
            "flat stored",
            "flat own"
        );
        for (level, r) in by_level.iter_mut() {
            r.row(&level.to_string());
        }
        all.row("all");
        println!(
            "(area: the sum of the box's three faces' areas, own over stored; thick: its smallest \
             extent, own over stored; p10/p50/p90: quantiles over the nodes; flat: nodes whose \
             box is at most {} as thick as long, on which the selection limits detail)",
            myriad_lod::select::FLAT_CONTOUR
        );
        println!(
            "{stored_own} of the nodes read store their own points' contour (the build's since \
             December 5: the selection sizes their detail by it); largest area difference from \
             the one made here: {:.2e}",
            worst
        );
    }
    Ok(())
}
