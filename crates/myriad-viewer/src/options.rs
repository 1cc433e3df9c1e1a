//! What the command line gives the viewer.

use crate::builds::Builds;
use myriad_render::{ColorBy, Style};
use std::path::PathBuf;

/// What the command line gives the viewer.
pub struct ViewOptions {
    pub width: u32,
    pub height: u32,
    /// Eye and target; None: the data framed from above at 45 degrees.
    pub camera: Option<([f64; 3], [f64; 3])>,
    pub fov: f64,
    pub budget: u64,
    pub style: Style,
    pub colour: ColorBy,
    /// Only the points this filter keeps (`--classes`, `--where`).
    pub filter: myriad_measure::Filter,
    /// Write the window to this PNG once the view has converged.
    pub screenshot: Option<PathBuf>,
    /// Close the window after that screenshot.
    pub exit_after_converged: bool,
    /// Scripted navigation first: orbit this many frames (8 pixels of drag each), then print the
    /// frame times seen while moving.
    pub orbit_frames: u32,
    /// Draw on the window's GPU adapter even where it is a software one (lavapipe), which the
    /// CPU path otherwise replaces.
    pub gpu: bool,
    /// On a GPU, read each frame back and upload it as an egui texture (as before the frame
    /// went straight to the window), to compare.
    pub readback: bool,
    /// Hold this frame rate by adjusting the budget (`budget` is then its most).
    pub target_fps: Option<f64>,
    /// Fraction of the view's width and height drawn while the camera moves (None: half on
    /// the CPU path, full on a GPU).
    pub moving_scale: Option<f32>,
    pub occlusion: myriad_lod::Occlusion,
    /// Pixels a level's spacing must cover to be drawn.
    pub lod_threshold: f64,
    /// Show the surface the points make (Schiffner et al. 2015) instead of the points.
    pub surface: Option<myriad_render::surface::Surface>,
    /// Both eyes side by side, this far apart (Discher et al. 2018), from the first visible
    /// dataset.
    pub stereo: Option<f64>,
    /// Datasets being built while their layers show a preview.
    pub builds: Option<Builds>,
    /// The first dataset's saved work (annotations, measurements), read on opening and
    /// written as it changes; `None`: not kept.
    pub work: Option<PathBuf>,
    /// Open in this axis view, and in the parallel (orthographic) view.
    pub view: Option<crate::nav::View>,
    pub parallel: bool,
    /// A cross-section to cut on opening: the line in plan and the width.
    pub section: Option<SectionAsked>,
    /// A volume to measure on opening (its result printed): the polygon, an elevation for
    /// the base (none: the rim's plane) and a cell size (none: from the spacing).
    pub volume: Option<VolumeAsked>,
    /// The dataset the edit tool edits, and the edits to make on opening.
    pub edits: Option<crate::tools::edit::EditsAsked>,
    /// Contours of the terrain every this much, shown on opening.
    pub contours: Option<f64>,
    /// Camera path views to record and save, and a path to play, on opening.
    pub paths: Option<crate::tools::path::PathsAsked>,
    /// The map beside the view: a tile address template (`{z}/{x}/{y}`).
    pub map_tiles: Option<String>,
    /// Open photo N (from 1) kept with the first dataset, the camera at its pose.
    pub photo: Option<usize>,
}

/// A section asked for on the command line: the line in plan and the width.
pub type SectionAsked = (Vec<[f64; 2]>, f64);

/// A volume asked for on the command line: the polygon, an elevation for the base (none: the
/// rim's plane) and a cell size (none: from the spacing).
#[derive(Debug, Clone)]
pub struct VolumeAsked {
    pub polygon: Vec<[f64; 2]>,
    pub base: Option<f64>,
    pub cell: Option<f64>,
}
