//! A scene's occlusion queries after each frame (`Occlusion::Queries`, Scheiblauer 2006, and the
//! checks of `Occlusion::Checked`): which boxes are tested, and what their answers make of the next
//! selection.

use super::Scene;
use crate::{Gpu, Rasterizer};
use myriad_core::{Aabb, NodeKey};
use myriad_lod::{Camera, Occlusion, Selection};
use std::collections::HashSet;
use std::sync::Arc;

/// Frames drawn at most for a selection under occlusion queries to settle ([`Scene::settle`]).
pub const SETTLE_FRAMES: usize = 12;

impl Scene {
    /// Loads what `camera` needs ([`Scene::converge`]) and, where occlusion queries act (from
    /// the frame after theirs), draws frames until the selection no longer changes (at most
    /// [`SETTLE_FRAMES`]): a view as it stays. Returns the last selection.
    pub fn settle(
        &mut self,
        gpu: &Gpu,
        raster: &Rasterizer,
        camera: &Camera,
        options: &myriad_lod::SelectOptions,
        style: &crate::Style,
    ) -> Selection {
        let mut selection = self.converge(camera, options, style.clip);
        let mut settled = None;
        for _ in 0..(if self.occlusion.queries() {
            SETTLE_FRAMES
        } else {
            0
        }) {
            let (_, s) = self.frame(gpu, raster, camera, options, style);
            selection = self.converge(camera, options, style.clip);
            let now = Some((s.nodes, s.culled, s.points));
            if now == settled {
                break;
            }
            settled = now;
        }
        selection
    }

    /// Occlusion queries (`Occlusion::Queries`, Scheiblauer 2006): the boxes of the nodes
    /// `selection` chose and of those it culled as hidden, tested against the frame just drawn; the
    /// next selection culls those of which no pixel showed. With `Occlusion::Checked`, the boxes of
    /// the nodes the software test culled (and of those drawn because the last queries saw
    /// them): the next selection lets it cull only those of which no pixel showed.
    /// `still_hidden`: the culled nodes were just queried against this frame and none showed
    /// ([`Scene::reveal`]): their answers are not asked for again.
    pub(super) fn query_hidden(
        &mut self,
        gpu: &Gpu,
        raster: &Rasterizer,
        camera: &Camera,
        selection: &Selection,
        still_hidden: bool,
    ) {
        if !self.occlusion.queries() {
            if !self.hidden.is_empty() || !self.shown.is_empty() {
                self.hidden = Default::default();
                self.shown = Default::default();
            }
            self.pending = None;
            return;
        }
        if let Some((ticket, keys)) = &mut self.pending {
            let Some(visible) = ticket.poll(gpu) else {
                return;
            };
            let keys = std::mem::take(keys);
            self.queried(&keys, visible);
            self.pending = None;
        }
        let keys: Vec<NodeKey> = if self.occlusion == Occlusion::Checked {
            // The nodes drawn because they were seen are tested again when the view or what
            // is drawn changed (whether they are hidden now); in a still view, not.
            let view = view_hash(camera, selection);
            let again = self.queried_view != Some(view);
            self.queried_view = Some(view);
            (selection.hidden.iter().copied())
                .chain(
                    (selection.nodes.iter())
                        .map(|n| n.key)
                        .filter(|k| again && self.shown.contains(k)),
                )
                .collect()
        } else {
            (selection.nodes.iter().map(|n| n.key))
                .chain(selection.hidden.iter().copied())
                .collect()
        };
        if self.query_wait {
            let known: HashSet<NodeKey> = if still_hidden {
                selection.hidden.iter().copied().collect()
            } else {
                HashSet::new()
            };
            let asked: Vec<NodeKey> = keys
                .iter()
                .filter(|k| !known.contains(k))
                .copied()
                .collect();
            let mut answers = raster.query(gpu, &self.query_boxes(&asked)).into_iter();
            let visible = (keys.iter())
                .map(|k| !known.contains(k) && answers.next().unwrap_or(true))
                .collect();
            self.queried(&keys, visible);
        } else {
            let boxes = self.query_boxes(&keys);
            self.pending = Some((raster.query_submit(gpu, &boxes), keys));
        }
    }

    /// The boxes the queries test for `keys`: each grown by its node's spacing on every side
    /// (points are drawn about that large, and a flat node's box would otherwise tie with its
    /// own points' depth).
    fn query_boxes(&self, keys: &[NodeKey]) -> Vec<[[f64; 3]; 8]> {
        keys.iter()
            .map(|k| {
                let e = self.hierarchy.get(k);
                let d = e.and_then(|e| e.spacing.first().copied()).unwrap_or(0.0);
                match e.and_then(|e| e.contour) {
                    Some(mut c) => {
                        c.half_extents = c.half_extents.map(|h| h + d);
                        c.corners()
                    }
                    None => {
                        let b = self.hierarchy.bounds(k);
                        Aabb::new(b.min.map(|v| v - d), b.max.map(|v| v + d)).corners()
                    }
                }
            })
            .collect()
    }

    /// Scheiblauer 2006's queries as Gobbetti and Marton schedule them ([`Scene::same_frame`]): the
    /// nodes `selection` culled as hidden, queried against the frame just drawn of it; those that
    /// show are no longer culled (`Queries`: out of the hidden set; `Checked`: seen), so that
    /// selecting again draws them in this frame. Returns how many showed.
    pub(super) fn reveal(
        &mut self,
        gpu: &Gpu,
        raster: &Rasterizer,
        selection: &Selection,
    ) -> usize {
        if selection.hidden.is_empty() {
            return 0;
        }
        let visible = raster.query(gpu, &self.query_boxes(&selection.hidden));
        let showing: Vec<NodeKey> = (selection.hidden.iter())
            .zip(&visible)
            .filter(|(_, v)| **v)
            .map(|(k, _)| *k)
            .collect();
        if showing.is_empty() {
            return 0;
        }
        if self.occlusion == Occlusion::Checked {
            let mut shown = (*self.shown).clone();
            shown.extend(showing.iter().copied());
            self.shown = Arc::new(shown);
        } else {
            let mut hidden = (*self.hidden).clone();
            for k in &showing {
                hidden.remove(k);
            }
            self.hidden = Arc::new(hidden);
        }
        showing.len()
    }

    /// The answers of the queries of `keys`' boxes.
    fn queried(&mut self, keys: &[NodeKey], visible: Vec<bool>) {
        if self.occlusion == Occlusion::Checked {
            // Those seen, and those seen before and not tested now (selected after the nodes
            // in the open, the budget did not reach them: nothing new is known).
            let tested: HashSet<NodeKey> = keys.iter().copied().collect();
            let mut shown: HashSet<NodeKey> = (self.shown.iter())
                .filter(|k| !tested.contains(k))
                .copied()
                .collect();
            if shown.len() > MAX_SHOWN {
                shown.clear();
            }
            shown.extend(
                keys.iter()
                    .zip(visible)
                    .filter(|(_, v)| *v)
                    .map(|(k, _)| *k),
            );
            self.hidden = Default::default();
            self.shown = Arc::new(shown);
        } else {
            self.shown = Default::default();
            self.hidden = Arc::new(hidden_of(keys, visible));
        }
    }
}

/// A hash of a camera and the nodes a selection draws.
fn view_hash(camera: &Camera, selection: &Selection) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for v in camera
        .position
        .iter()
        .chain(&camera.target)
        .chain(&camera.up)
    {
        v.to_bits().hash(&mut h);
    }
    (camera.fov_y.to_bits(), camera.width, camera.height).hash(&mut h);
    for n in &selection.nodes {
        (n.key, n.points).hash(&mut h);
    }
    h.finish()
}

/// Nodes seen by the queries of `Occlusion::Checked` kept untested at most (those of views left
/// behind are forgotten past it).
const MAX_SHOWN: usize = 100_000;

/// The nodes of `keys` whose box showed nowhere.
fn hidden_of(keys: &[NodeKey], visible: Vec<bool>) -> HashSet<NodeKey> {
    keys.iter()
        .zip(visible)
        .filter(|(_, v)| !v)
        .map(|(k, _)| *k)
        .collect()
}
