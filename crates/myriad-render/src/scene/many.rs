//! Frames of several scenes seen together (`view` shows several datasets at once): one point
//! budget over all of them, one image with one depth buffer; selections made on the frame's
//! thread (`frame_many`, with occlusion queries in the same frame where the scenes wait for
//! them) or on each scene's selection thread (`frame_many_threaded`).

use super::{FrameStats, REVEAL_ROUNDS, Scene};
use crate::selector::Selector;
use crate::{Gpu, Rasterizer, Style};
use myriad_lod::{Camera, SelectOptions, Selection, merge};
use std::time::{Duration, Instant};

/// One frame of several scenes seen together: one point budget over all of them (`select_many`),
/// drawn into one image with one depth buffer. Where every scene waits for its queries
/// ([`Scene::query_wait`], [`Scene::same_frame`]), the nodes culled that show are drawn in
/// the same frame, as [`Scene::frame`] does.
pub fn frame_many(
    scenes: &mut [&mut Scene],
    gpu: &Gpu,
    raster: &Rasterizer,
    camera: &Camera,
    options: &SelectOptions,
    style: &Style,
) -> (Vec<u8>, Vec<FrameStats>) {
    let select_all = |scenes: &mut [&mut Scene]| {
        let t = Instant::now();
        let alone = scenes
            .iter()
            .map(|s| s.select(camera, options, style.clip))
            .collect();
        (merge(alone, options.budget), t.elapsed())
    };
    let (selections, mut select) = select_all(scenes);
    let (mut image, mut stats) = draw_many(scenes, selections, gpu, raster, camera, style);
    // As `Scene::frame`: where every scene waits for its queries, the nodes culled that show
    // in the frame are drawn in it (the selections made and drawn again).
    let same_frame = scenes
        .iter()
        .all(|s| s.occlusion.queries() && s.query_wait && s.same_frame);
    let mut revealed = vec![0; scenes.len()];
    let mut query = Duration::ZERO;
    let mut still_hidden = false;
    for _ in 0..REVEAL_ROUNDS {
        if !same_frame || scenes.is_empty() {
            break;
        }
        let t = Instant::now();
        let more: Vec<usize> = scenes
            .iter_mut()
            .map(|s| {
                let last = std::mem::take(&mut s.last);
                let n = s.reveal(gpu, raster, &last);
                s.last = last;
                n
            })
            .collect();
        query += t.elapsed();
        if more.iter().all(|&n| n == 0) {
            still_hidden = true;
            break;
        }
        revealed.iter_mut().zip(&more).for_each(|(r, n)| *r += n);
        let (selections, took) = select_all(scenes);
        select += took;
        (image, stats) = draw_many(scenes, selections, gpu, raster, camera, style);
    }
    query_many(scenes, &mut stats, gpu, raster, camera, still_hidden);
    for (s, r) in stats.iter_mut().zip(revealed) {
        s.select = select;
        s.select_current = true;
        s.select_budget = options.budget;
        s.revealed = r;
        s.query += query / scenes.len().max(1) as u32;
    }
    (image, stats)
}

/// Each scene's occlusion queries after a frame of [`draw_many`] (`Scene::query_hidden`), their
/// time in its statistics.
fn query_many(
    scenes: &mut [&mut Scene],
    stats: &mut [FrameStats],
    gpu: &Gpu,
    raster: &Rasterizer,
    camera: &Camera,
    still_hidden: bool,
) {
    for (s, scene) in stats.iter_mut().zip(scenes.iter_mut()) {
        let t = Instant::now();
        let last = std::mem::take(&mut scene.last);
        scene.query_hidden(gpu, raster, camera, &last, still_hidden);
        scene.last = last;
        s.query = t.elapsed();
    }
}

/// [`frame_many`] with each scene's selection on its own thread ([`crate::selector`]): asks for
/// this camera's selections and draws the newest ones finished (the last ones while none has),
/// with uploads bounded by each scene's [`Scene::upload_limit`]. Never waits for selection,
/// disk or uploads; the first frames, before any selection is in, are empty.
pub fn frame_many_threaded(
    scenes: &mut [&mut Scene],
    gpu: &Gpu,
    raster: &Rasterizer,
    camera: &Camera,
    options: &SelectOptions,
    style: &Style,
) -> (Vec<u8>, Vec<FrameStats>) {
    let t = Instant::now();
    let mut serials = Vec::new();
    for scene in scenes.iter_mut() {
        let request = scene.request(camera, options, style.clip);
        let selector = scene.selector.get_or_insert_with(Selector::new);
        let serial = selector.ask(request);
        if let Some(a) = selector.take() {
            scene.alone = Some(a);
        }
        serials.push(serial);
    }
    let alone = scenes
        .iter()
        .map(|s| {
            s.alone
                .as_ref()
                .map(|a| a.selection.clone())
                .unwrap_or_default()
        })
        .collect();
    let selections = merge(alone, options.budget);
    let select = t.elapsed();
    let (image, mut stats) = draw_many(scenes, selections, gpu, raster, camera, style);
    query_many(scenes, &mut stats, gpu, raster, camera, false);
    for ((s, scene), serial) in stats.iter_mut().zip(scenes.iter()).zip(serials) {
        s.select = select;
        match &scene.alone {
            Some(a) => {
                s.select_budget = a.budget;
                s.select_thread = a.took;
                s.select_lag = serial - a.serial;
                s.select_current = a.camera == *camera;
            }
            None => {
                s.select_lag = serial;
                s.select_current = false;
            }
        }
    }
    (image, stats)
}

/// Loads, uploads and draws the given selections of `scenes` in one image (each scene's
/// selection then its `last`); the callers query (`query_many`).
fn draw_many(
    scenes: &mut [&mut Scene],
    selections: Vec<Selection>,
    gpu: &Gpu,
    raster: &Rasterizer,
    camera: &Camera,
    style: &Style,
) -> (Vec<u8>, Vec<FrameStats>) {
    let t = Instant::now();
    let mut uploads = Vec::new();
    for (scene, selection) in scenes.iter_mut().zip(&selections) {
        scene.take(selection);
        uploads.push(scene.upload(gpu, selection));
    }
    let upload = t.elapsed();
    let t = Instant::now();
    let mut all_draws = Vec::new();
    let mut tree = Vec::new();
    let mut stats = Vec::new();
    let mut drawn = Vec::new();
    for ((scene, selection), uploads) in scenes.iter().zip(&selections).zip(uploads) {
        let (draws, entries, keys) = scene.draws(selection, tree.len() as u32);
        let holes = scene.holes(selection, &keys);
        drawn.push(keys);
        stats.push(FrameStats {
            uploads: uploads.0,
            upload_bytes: uploads.1,
            read_bytes: raster.bytes_read(gpu, camera, &draws, style),
            upload,
            holes,
            ..scene.stats(selection, &draws)
        });
        tree.extend(entries);
        all_draws.extend(draws);
    }
    if scenes.iter().any(|s| s.occlusion.queries()) {
        raster.keep_depth();
    }
    let image = raster.render(gpu, camera, &all_draws, &tree, style);
    drop(all_draws);
    let draw = t.elapsed();
    for s in stats.iter_mut() {
        s.draw = draw;
    }
    for ((scene, selection), keys) in scenes.iter_mut().zip(selections).zip(drawn) {
        scene.last = selection;
        scene.drawn = keys;
    }
    (image, stats)
}
