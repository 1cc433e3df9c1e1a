//! A node's GPU words (its positions encoded, its colours by the scheme shown, its splat codes)
//! made on the loader threads as each node is read (Kanzok et al. 2015, section 3.4: no per-point
//! work on the frame thread), so that an upload only hands them to the GPU. Made for the settings
//! current when the node was read ([`Words`]); a node read under other settings (the scheme changed
//! since) is encoded at its upload, as before.

use super::Scene;
use crate::{ColorBy, Encoded, Encoding, Gpu, colours};
use myriad_format::NodeEntry;
use myriad_format::page::Quantization;
use myriad_lod::Selection;
use myriad_lod::stream::{Loaded, Prepared};
use std::sync::Arc;

/// What a node's words depend on beyond its points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Words {
    colour: ColorBy,
    z_range: (f64, f64),
    positions: Positions,
}

/// How positions are encoded ([`Encoding`], the fitted grid made per node).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Positions {
    F32([f64; 3]),
    Grid(Quantization),
    Fitted([f64; 3]),
}

/// Words made on a loader thread, and the settings they were made for.
struct Made {
    words: Words,
    encoded: Encoded,
}

impl Words {
    /// Node `key`'s words (`e`: its entry, whose spacings say which points are lone,
    /// [`myriad_lod::lone_radius`]).
    pub(crate) fn encode(&self, e: &NodeEntry, node: &Loaded) -> Encoded {
        let key = &e.key;
        let c = colours(
            &node.points,
            node.len(),
            self.colour,
            self.z_range,
            key.level,
        );
        let encoding = match self.positions {
            Positions::F32(origin) => Encoding::F32 { origin },
            Positions::Grid(g) => Encoding::Grid(g),
            Positions::Fitted(origin) => Encoding::fitted(origin, &node.positions),
        };
        let lone = myriad_core::geometry::lone_points(&node.positions, myriad_lod::lone_radius(e));
        let words = Encoded::new(encoding, &node.positions, &c).with_lone(&lone);
        match &node.splats {
            Some(s) => words.with_splats(&s.normals, &s.radii),
            None => words,
        }
    }
}

impl Words {
    /// Node `key`'s words, as a loader thread keeps them with the node.
    pub(crate) fn prepare(&self, e: &NodeEntry, node: &Loaded) -> Prepared {
        let encoded = self.encode(e, node);
        Prepared {
            bytes: encoded.bytes(),
            made: Arc::new(Made {
                words: *self,
                encoded,
            }),
        }
    }
}

impl Scene {
    /// Uploads the selected nodes that are resident but not on the GPU; returns how many, and
    /// their bytes.
    pub fn upload(&mut self, gpu: &Gpu, selection: &Selection) -> (usize, usize) {
        self.buffers.next_frame();
        // Stand-ins stay on the GPU while they are needed.
        for k in self.stand_ins(selection) {
            self.buffers.touch(&k);
        }
        let words = self.words();
        self.prepare_words(words);
        let mut uploads = 0;
        let mut bytes_up = 0;
        // Parents read to stand in for their children come first, as they were read.
        let keys = self.parents_wanted(selection);
        for key in keys.iter().chain(selection.nodes.iter().map(|n| &n.key)) {
            if self.buffers.touch(key) || bytes_up >= self.upload_limit {
                continue;
            }
            let (Some(batch), Some(e)) = (self.loader.get(key), self.hierarchy.get(key)) else {
                continue;
            };
            // Made on a loader thread; else (read before these settings) encoded here.
            let p = match prepared(&batch, &words) {
                Some(e) => {
                    self.uploads_prepared += 1;
                    e.upload(gpu)
                }
                None => {
                    self.uploads_encoded += 1;
                    words.encode(e, &batch).into_points(gpu)
                }
            };
            let bytes = p.bytes();
            bytes_up += bytes;
            self.buffers.insert(*key, p, bytes);
            uploads += 1;
        }
        (uploads, bytes_up)
    }

    /// The settings a node's words are made for now.
    pub(crate) fn words(&self) -> Words {
        Words {
            colour: self.colour,
            z_range: self.z_range,
            positions: match self.grid {
                _ if self.f32_positions => Positions::F32(self.origin),
                Some(g) => Positions::Grid(g),
                None => Positions::Fitted(self.origin),
            },
        }
    }

    /// Has the loader threads make each node's words for `words` from now on (where they were
    /// asked for other settings).
    pub(crate) fn prepare_words(&mut self, words: Words) {
        if self.prepared_for == Some(words) {
            return;
        }
        self.prepared_for = Some(words);
        self.loader
            .set_prepare(Some(Arc::new(move |e, node| Some(words.prepare(e, node)))));
    }
}

/// `node`'s words for `words`, as the loader made them (None: they were made for other
/// settings, or not at all).
pub(crate) fn prepared<'a>(node: &'a Loaded, words: &Words) -> Option<&'a Encoded> {
    let made = node.prepared.as_ref()?.made.downcast_ref::<Made>()?;
    (made.words == *words).then_some(&made.encoded)
}
