//! Step 3 of `convert` and the merge of a partitioned build: the levels above the chunks (or the
//! parts), bottom-up, families in parallel. A parent takes its representatives from its children
//! (`nested::take_up`, `kd::take_up`; mwkd: aggregates of them, `mwkd::take_up`); the children
//! are then final and written; the parent is spilled and becomes a child one level up.

use crate::kd;
use crate::nested::{self, BuiltNode, NestedParams};
use crate::nodes::{Pending, spill, unspill, write};
use crate::report::Report;
use crate::structure::Structure;
use myriad_core::{Aabb, NodeKey, Result, Schema};
use myriad_format::DatasetWriter;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::Path;

/// What the levels above are built with.
pub(crate) struct Above<'a> {
    pub structure: Structure,
    pub params: &'a NestedParams,
    pub mw: &'a crate::mwkd::MwkdParams,
    pub root: &'a Aabb,
    pub schema: &'a Schema,
    pub writer: &'a DatasetWriter,
    pub pool: &'a rayon::ThreadPool,
    pub spill_dir: &'a Path,
}

impl Above<'_> {
    /// Builds every level above the `pending` nodes and writes them and their children. Returns
    /// a copy of the nodes of `tops_level` as they were before their parents took points from
    /// them (a part's tops, [`crate::convert::Planned::tops_level`]).
    pub(crate) fn build(
        &self,
        pending: Vec<Pending>,
        tops_level: Option<u32>,
        report: &dyn Report,
    ) -> Result<Vec<BuiltNode>> {
        let (structure, params, mw, root, schema) =
            (self.structure, self.params, self.mw, self.root, self.schema);
        let (writer, spill_dir) = (self.writer, self.spill_dir);
        let mut tops = Vec::new();
        let mut by_level: BTreeMap<u32, Vec<Pending>> = BTreeMap::new();
        for p in pending {
            by_level.entry(p.key.level).or_default().push(p);
        }
        report.phase("merging", by_level.values().map(|v| v.len() as u64).sum());
        while let Some((&level, _)) = by_level.iter().next_back() {
            let mut nodes = by_level.remove(&level).expect("present");
            if Some(level) == tops_level {
                let mut again = Vec::with_capacity(nodes.len());
                for p in nodes {
                    let node = unspill(p, schema)?;
                    tops.push(node.clone());
                    again.push(spill(node, spill_dir)?);
                }
                nodes = again;
            }
            if level == 0 {
                for p in nodes {
                    write(writer, unspill(p, schema)?)?;
                }
                break;
            }
            let mut families: BTreeMap<NodeKey, Vec<Pending>> = BTreeMap::new();
            for n in nodes {
                families.entry(n.key.parent()).or_default().push(n);
            }
            let parents: Vec<Pending> = self.pool.install(|| {
                families
                    .into_par_iter()
                    .map(|(parent, kids)| -> Result<Pending> {
                        let count = kids.len() as u64;
                        let children = kids
                            .into_iter()
                            .map(|p| unspill(p, schema))
                            .collect::<Result<Vec<_>>>()?;
                        let (top, children) = match structure {
                            Structure::Kd => kd::take_up(parent, children, params),
                            Structure::Mwkd => {
                                let kids =
                                    children.into_iter().map(crate::mwkd::MwNode::from_built);
                                let (top, kids) = crate::mwkd::take_up(parent, kids.collect(), mw);
                                (
                                    top.into_built(),
                                    kids.into_iter().map(|k| k.into_built()).collect(),
                                )
                            }
                            _ => nested::take_up(parent, children, root, params),
                        };
                        for c in children {
                            write(writer, c)?;
                        }
                        report.advance(count);
                        spill(top, spill_dir)
                    })
                    .collect::<Result<Vec<_>>>()
            })?;
            by_level.entry(level - 1).or_default().extend(parents);
        }
        Ok(tops)
    }
}
