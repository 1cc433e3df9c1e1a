//! What a surface is made from: a scene whose last selection is everything a view selects
//! within a budget, every node of it loaded (`mesh` and `bench surface` start here).

use crate::{ColorBy, Scene};
use myriad_core::Aabb;
use myriad_format::Dataset;
use myriad_lod::{Camera, SelectOptions};
use std::sync::Arc;

/// A scene of `ds` coloured by `colour`, converged on the camera `view` makes of the scene's
/// view bounds, at `budget` points (`u64::MAX`: every point, no level of detail); and that
/// camera. Pages that failed to load are in `scene.loader.failed_pages()`.
pub fn drawn_scene(
    ds: Arc<Dataset>,
    budget: u64,
    colour: ColorBy,
    view: impl FnOnce(&Aabb) -> Result<Camera, String>,
) -> Result<(Scene, Camera), String> {
    let mut scene = Scene::open(ds.clone(), 2 << 30, 1 << 30);
    if scene.hierarchy.pages() == 0
        && let Err(d) = ds.hierarchy_page(&ds.root_page())
    {
        return Err(format!("{} (nothing left to draw)", ds.damage_error(&d)));
    }
    scene.set_colour(colour);
    let cam = view(&scene.view_bounds)?;
    let options = SelectOptions {
        budget,
        min_pixels: if budget == u64::MAX { 0.0 } else { 1.0 },
    };
    scene.last = scene.converge(&cam, &options, None);
    Ok((scene, cam))
}
