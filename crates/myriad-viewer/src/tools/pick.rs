//! Picking a point (a double click on the view): its coordinates and every attribute, and its
//! longitude, latitude and ellipsoidal height where the dataset's CRS gives them (through PROJ),
//! shown in the panel.

use crate::report::{self, describe};
use eframe::egui;

pub(crate) struct Picking {
    /// The point picked last, as text.
    picked: Option<String>,
    /// Picked points to longitude, latitude and ellipsoidal height (the dataset's CRS through
    /// PROJ; none without either).
    geographic: Option<myriad_io::proj::Geographic>,
}

impl Picking {
    /// Points of data in `crs`.
    pub fn new(crs: Option<&str>) -> Picking {
        Picking {
            picked: None,
            geographic: crs.and_then(|c| myriad_io::proj::Geographic::new(c).ok()),
        }
    }

    /// The point picked (none: nothing there).
    pub fn picked(&mut self, p: Option<myriad_render::Picked>) {
        self.picked = p.map(|p| {
            let geo = self.geographic.as_mut().and_then(|g| g.of(p.position));
            describe(&p) + &report::geographic(geo)
        });
    }

    /// The panel's part: the picked point, if any.
    pub fn panel(&self, ui: &mut egui::Ui) {
        if let Some(p) = &self.picked {
            ui.separator();
            ui.label("picked point");
            ui.monospace(p);
        }
    }
}
