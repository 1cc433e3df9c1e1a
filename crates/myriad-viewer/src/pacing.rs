//! Budget pacing: the selection's options (the point budget, the level-of-detail threshold),
//! the budget following the frame rate toward a target while the camera moves (held or not:
//! `myriad_lod::Pace`), the resolution and budget by whether the camera moves (`motion.rs`),
//! and the frame time and rate, smoothed. The panel's budget and frame-rate controls.

use crate::motion::{Drawn, Motion};
use eframe::egui;
use myriad_lod::{Camera, Pace, SelectOptions};
use myriad_render::FrameStats;
use std::time::Instant;

/// Frame time, smoothed.
#[derive(Default)]
pub(crate) struct Timing {
    pub frame_ms: f64,
    pub fps: f64,
    last: Option<Instant>,
}

pub(crate) struct Pacing {
    /// The budget (points) and the level-of-detail threshold the frames select with.
    pub select: SelectOptions,
    /// The budget following the frame rate while the camera moves, if held (its maximum is
    /// the budget slider's, the budget at rest).
    pub pace: Option<Pace>,
    /// The resolution and budget by whether the camera moves.
    pub motion: Motion,
    /// The last frame was drawn as moving.
    pub moving: bool,
    pub timing: Timing,
    /// The last frame drawn's time (ms).
    pub drawn_ms: f64,
}

impl Pacing {
    /// `budget` points at most; `target_fps`: the frame rate held while moving; the view drawn
    /// at `moving_scale` of its size while moving.
    pub fn new(budget: u64, min_pixels: f64, target_fps: Option<f64>, moving_scale: f32) -> Pacing {
        Pacing {
            select: SelectOptions { budget, min_pixels },
            pace: target_fps.map(|fps| Pace::new(fps, budget, 100_000, budget)),
            motion: Motion::new(moving_scale),
            moving: false,
            timing: Timing::default(),
            drawn_ms: 0.0,
        }
    }

    /// A frame starts at `now` with the camera `full` (at the view's size); `scripted`: a
    /// scripted move is under way. Moving: the budget the frame rate allows, at the lower
    /// resolution; at rest: the whole budget at the full one.
    pub fn start(&mut self, full: &Camera, now: Instant, scripted: bool) -> Drawn {
        let drawn = self.motion.frame(full, now, scripted);
        self.moving = drawn.moving;
        if let Some(p) = &self.pace {
            self.select.budget = if drawn.moving { p.budget() } else { p.max };
        }
        drawn
    }

    /// The frame begun at `t` ended, an image `drawn` (or the last one shown again) with
    /// `stats`: the rate and times followed, and the budget where it is held. The interval
    /// since the frame before and the drawing's time (ms), where an image was drawn after one.
    pub fn end(&mut self, t: Instant, drawn: bool, stats: &[FrameStats]) -> Option<(f64, f64)> {
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let now = Instant::now();
        let mut times = None;
        if let Some(last) = self.timing.last.filter(|_| drawn) {
            let interval = now.duration_since(last).as_secs_f64().max(1e-6);
            self.timing.fps = 0.8 * self.timing.fps + 0.2 / interval;
            // The budget follows the frames drawn with it: a threaded frame may still draw a
            // selection made with an earlier budget (a feedback loop with a delay in it
            // oscillates).
            let current = stats.iter().all(|s| s.select_budget == self.select.budget);
            if let Some(p) = self.pace.as_mut().filter(|_| current && self.moving) {
                let drawn: u64 = stats.iter().map(|s| s.points).sum();
                let selected: u64 = stats.iter().map(|s| s.selected_points).sum();
                let limited = selected as f64 >= 0.98 * self.select.budget as f64;
                self.select.budget = p.frame(interval, drawn, limited);
            }
            times = Some((interval * 1e3, ms));
        }
        self.timing.last = Some(now);
        if drawn {
            self.timing.frame_ms = 0.8 * self.timing.frame_ms + 0.2 * ms;
            self.drawn_ms = ms;
        }
        times
    }

    /// The budget's slider (the most points where the frame rate is held), holding the frame
    /// rate and its target, and the level-of-detail threshold.
    pub fn panel(&mut self, ui: &mut egui::Ui) {
        let most = self.pace.as_ref().map_or(self.select.budget, |p| p.max);
        let mut budget = most as f64 / 1e6;
        ui.add(
            egui::Slider::new(&mut budget, 0.1..=20.0)
                .logarithmic(true)
                .text(if self.pace.is_some() {
                    "most points (M)"
                } else {
                    "budget (M points)"
                }),
        );
        let budget = (budget * 1e6) as u64;
        let mut hold = self.pace.is_some();
        ui.checkbox(&mut hold, "hold the frame rate");
        match (&mut self.pace, hold) {
            (Some(p), true) => {
                p.max = budget;
                let mut fps = 1.0 / p.target;
                ui.add(egui::Slider::new(&mut fps, 1.0..=120.0).text("target fps"));
                p.target = 1.0 / fps;
                ui.label(format!(
                    "budget now {:.2} M points",
                    self.select.budget as f64 / 1e6
                ));
            }
            (None, true) => {
                self.pace = Some(Pace::new(30.0, budget, 100_000, budget));
            }
            (_, false) => {
                self.pace = None;
                self.select.budget = budget;
            }
        }
        ui.add(
            egui::Slider::new(&mut self.select.min_pixels, 0.25..=8.0)
                .logarithmic(true)
                .text("LOD threshold (px)"),
        );
    }
}
