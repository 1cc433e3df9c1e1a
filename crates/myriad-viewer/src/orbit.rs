//! The scripted orbit (`view --orbit-frames N`, a benchmark): the camera turned 8 pixels of
//! drag a frame for N frames, the frame times seen while moving printed at the end, and the
//! view at rest after it reported once it has converged.

use myriad_lod::{Camera, Pace};
use myriad_render::FrameStats;

pub(crate) struct Orbit {
    /// Frames still to orbit.
    left: u32,
    /// Frame intervals and drawing times (ms) while orbiting.
    times: Vec<(f64, f64)>,
    /// The view at rest after the orbit was reported.
    rest_reported: bool,
}

impl Orbit {
    pub fn new(frames: u32) -> Orbit {
        Orbit {
            left: frames,
            times: Vec::new(),
            rest_reported: false,
        }
    }

    /// The orbit is under way.
    pub fn on(&self) -> bool {
        self.left > 0
    }

    /// This frame's turn, while orbiting.
    pub fn step(&self, nav: &mut crate::nav::Nav) {
        if self.on() {
            nav.orbit(8.0, 0.0);
        }
    }

    /// A frame drawn while orbiting: its interval and drawing time (ms). After the last, the
    /// times are printed (and the budget the frame rate settled on, where `pace` held it).
    pub fn frame(
        &mut self,
        time: (f64, f64),
        stats: &[FrameStats],
        pace: Option<&Pace>,
        budget: u64,
    ) {
        if !self.on() {
            return;
        }
        self.times.push(time);
        self.left -= 1;
        if self.left == 0 {
            report_orbit(&mut self.times, stats, pace.map(|p| p.target));
            if pace.is_some() {
                println!("budget settled on {budget} points");
            }
        }
    }

    /// Once the view has converged after an orbit: the points drawn, the view's size, the
    /// budget and the last frame's time (`drawn_ms`), printed once.
    pub fn at_rest(
        &mut self,
        converged: bool,
        points: u64,
        c: &Camera,
        budget: u64,
        drawn_ms: f64,
    ) {
        if converged && !self.times.is_empty() && !self.rest_reported {
            self.rest_reported = true;
            println!(
                "at rest: {points} points drawn at {}x{} (budget {budget}), the last frame {drawn_ms:.1} ms",
                c.width, c.height
            );
        }
    }
}

/// Prints the frame times seen while orbiting: the interval between frames (what input waits
/// for at most twice: an event arriving during one frame is drawn by the next) and the drawing.
fn report_orbit(times: &mut [(f64, f64)], stats: &[FrameStats], target: Option<f64>) {
    if times.is_empty() {
        return;
    }
    if let Some(target) = target {
        // When the interval first came within 15 % of the target, and how many frames after
        // that stayed there (pages landing while orbiting make single slow frames).
        let ms = target * 1e3;
        let near = |t: &(f64, f64)| (t.0 - ms).abs() <= 0.15 * ms;
        match times.iter().position(near) {
            Some(first) => {
                let after: f64 = times[..first].iter().map(|t| t.0).sum::<f64>() / 1e3;
                let rest = &times[first..];
                let within = rest.iter().filter(|t| near(t)).count();
                let mut tail: Vec<f64> = rest.iter().map(|t| t.0).collect();
                tail.sort_by(f64::total_cmp);
                println!(
                    "frame interval within 15 % of {ms:.0} ms after {after:.2} s (frame {first}); then {within} of {} frames within, median {:.1} ms",
                    rest.len(),
                    tail[tail.len() / 2]
                );
            }
            None => println!("frame interval never within 15 % of {ms:.0} ms"),
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let mut interval: Vec<f64> = times.iter().map(|t| t.0).collect();
    let mut draw: Vec<f64> = times.iter().map(|t| t.1).collect();
    let points: u64 = stats.iter().map(|s| s.points).sum();
    println!(
        "orbiting {} frames: median frame interval {:.1} ms (max {:.1}), drawing {:.1} ms, {} points in the last",
        times.len(),
        median(&mut interval),
        interval.last().copied().unwrap_or(0.0),
        median(&mut draw),
        points
    );
}
