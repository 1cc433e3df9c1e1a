//! Datasets still being built: a layer shows its scan's preview (a small dataset of a sample
//! read without decoding the scan), then the build as it goes (its snapshots,
//! `myriad_build::growing`: the chunks built so far, the preview where they are not), until the
//! scan's own dataset arrives, and then draws that, with the layer's settings and the view as
//! they are. The build takes the chunks nearest the camera's target first.

use crate::shown::{Layer, Layers};
use myriad_build::growing::Growing;
use myriad_format::Dataset;
use std::collections::HashMap;
use std::sync::mpsc::Receiver;
use std::sync::{Arc, Mutex};

/// What a build sends when it ends: the layer's index, and its dataset or why there is none.
pub type Built = (usize, Result<Arc<Dataset>, String>);

/// The builds a viewer waits for.
pub struct Builds {
    rx: Receiver<Built>,
    left: usize,
    growing: Running,
    /// The snapshot each layer draws.
    shown: HashMap<usize, u64>,
}

/// The builds running, by layer: whoever builds puts its [`Growing`] here when it starts and
/// takes it out when it ends.
pub type Running = Arc<Mutex<HashMap<usize, Arc<Growing>>>>;

impl Builds {
    /// `left` builds, each sending what it built on `rx`, and drawn as they go through
    /// `growing`.
    pub fn new(rx: Receiver<Built>, left: usize, growing: Running) -> Builds {
        Builds {
            rx,
            left,
            growing,
            shown: HashMap::new(),
        }
    }

    /// Whether every build has ended.
    pub fn done(&self) -> bool {
        self.left == 0
    }
    /// Puts the datasets that arrived in `layers`, in place of their previews (or of the
    /// datasets of scans that changed), and looks again within a second: builds still running
    /// and watched scans send theirs while the window may be idle. The builds take the chunks
    /// around `focus` (what the camera looks at) next. Whether a layer's scene changed (the
    /// next frame is drawn).
    pub(crate) fn take(
        &mut self,
        ctx: &eframe::egui::Context,
        layers: &mut Layers,
        focus: [f64; 3],
    ) -> bool {
        let b = self;
        let mut redraw = false;
        ctx.request_repaint_after(std::time::Duration::from_secs(1));
        // Snapshots newer than those drawn.
        let running: Vec<(usize, Arc<Growing>)> = (b.growing.lock().expect("builds lock").iter())
            .map(|(i, g)| (*i, g.clone()))
            .collect();
        for (i, g) in running {
            // The chunks around what the camera looks at are built next.
            g.set_focus(Some(focus));
            let Some(s) = g.latest() else { continue };
            if b.shown.get(&i).is_some_and(|v| *v >= s.version) {
                continue;
            }
            let first = !b.shown.contains_key(&i);
            b.shown.insert(i, s.version);
            redraw = true;
            let Some(layer) = layers.list.get_mut(i) else {
                continue;
            };
            layer.scene = crate::shown::reopen(
                &layer.scene,
                s.dataset.clone(),
                &layers.filter,
                layers.shares,
                layers.colour,
            );
            layer.dataset = s.dataset;
            let name = base_name(&layer.name).to_string();
            layer.name = format!("{name} (built: {} of {} chunks)", s.built, s.chunks);
            if first {
                println!("{name}: drawing its build as it goes");
            }
        }
        while let Ok((i, built)) = b.rx.try_recv() {
            b.shown.remove(&i);
            redraw = true;
            b.left = b.left.saturating_sub(1);
            let Some(layer) = layers.list.get_mut(i) else {
                continue;
            };
            match built {
                Ok(ds) => swap(layer, ds, &layers.filter, layers.shares, layers.colour),
                Err(why) => eprintln!("error: {why} (what is shown stays)"),
            }
        }
        redraw
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
    layer.name = base_name(&layer.name).to_string();
    println!("{}: its dataset is built, drawn from now on", layer.name);
}

/// A layer's name without what it says of a build (" (preview)", " (built: 3 of 9 chunks)").
fn base_name(name: &str) -> &str {
    match name.rfind(" (") {
        Some(i)
            if name.ends_with(')')
                && (name[i..].starts_with(" (preview") || name[i..].starts_with(" (built")) =>
        {
            &name[..i]
        }
        _ => name,
    }
}
