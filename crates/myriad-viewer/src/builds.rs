//! Datasets still being built: a layer shows its scan's preview (a small dataset of a sample
//! read without decoding the scan) until the scan's own dataset arrives, and then draws that,
//! with the layer's settings and the view as they are.

use crate::{App, Layer};
use myriad_format::Dataset;
use std::sync::Arc;
use std::sync::mpsc::Receiver;

/// What a build sends when it ends: the layer's index, and its dataset or why there is none.
pub type Built = (usize, Result<Arc<Dataset>, String>);

/// The builds a viewer waits for.
pub struct Builds {
    rx: Receiver<Built>,
    left: usize,
}

impl Builds {
    /// `left` builds, each sending what it built on `rx`.
    pub fn new(rx: Receiver<Built>, left: usize) -> Builds {
        Builds { rx, left }
    }

    /// Whether every build has ended.
    pub fn done(&self) -> bool {
        self.left == 0
    }
}

impl App {
    /// Puts the datasets that arrived in their layers, in place of their previews (or of the
    /// datasets of scans that changed), and looks again within a second: builds still running
    /// and watched scans send theirs while the window may be idle.
    pub(crate) fn take_builds(&mut self, ctx: &eframe::egui::Context) {
        let Some(b) = &mut self.builds else {
            return;
        };
        ctx.request_repaint_after(std::time::Duration::from_secs(1));
        while let Ok((i, built)) = b.rx.try_recv() {
            b.left = b.left.saturating_sub(1);
            let Some(layer) = self.layers.get_mut(i) else {
                continue;
            };
            match built {
                Ok(ds) => swap(layer, ds, &self.filter, self.shares, self.colour),
                Err(why) => eprintln!("error: {why} (what is shown stays)"),
            }
        }
    }
}

/// The layer's scene replaced by one of `ds`, its settings kept.
fn swap(
    layer: &mut Layer,
    ds: Arc<Dataset>,
    filter: &myriad_measure::Filter,
    shares: (usize, usize),
    colour: myriad_render::ColorBy,
) {
    layer.scene = crate::shown::reopen(&layer.scene, ds.clone(), filter, shares, colour);
    layer.dataset = ds;
    if let Some(name) = layer.name.strip_suffix(" (preview)") {
        layer.name = name.to_string();
    }
    println!("{}: its dataset is built, drawn from now on", layer.name);
}
