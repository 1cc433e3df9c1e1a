//! A point budget that follows the frame rate (Discher et al. 2018, section 4: the budget is
//! adjusted to hold the target frame rate; Scheiblauer 2006: a minimum frame rate).
//!
//! Each frame reports how long it took and how many points it drew; the next budget scales the
//! points drawn by (target / measured) to the power [`GAIN`], within a factor of [`STEP`] either
//! way. Half the correction per frame (the gain) converges geometrically yet does not overshoot
//! when the frame time is late by one frame or noisy; within [`DEADBAND`] of the target the budget
//! stays as it is, so noise does not make it wander. It grows only while the budget limits the
//! frame (a view that needs fewer points does not inflate it).

/// Fraction of the correction applied per frame (in the logarithm).
pub const GAIN: f64 = 0.5;
/// The most the budget changes in one frame (a factor).
pub const STEP: f64 = 2.0;
/// Frame times within this fraction of the target leave the budget alone.
pub const DEADBAND: f64 = 0.05;

#[derive(Debug, Clone)]
pub struct Pace {
    /// The frame time to hold, in seconds.
    pub target: f64,
    pub min: u64,
    pub max: u64,
    budget: u64,
}

impl Pace {
    /// Holding `fps` frames per second, starting from `budget`, never outside `min..=max`.
    pub fn new(fps: f64, budget: u64, min: u64, max: u64) -> Pace {
        Pace {
            target: 1.0 / fps.max(0.1),
            min,
            max: max.max(min),
            budget: budget.clamp(min, max.max(min)),
        }
    }

    /// The budget to use for the next frame.
    pub fn budget(&self) -> u64 {
        self.budget
    }

    /// A frame took `seconds`, drew `points`; `limited`: the budget stopped its selection.
    /// Returns the next budget.
    pub fn frame(&mut self, seconds: f64, points: u64, limited: bool) -> u64 {
        // `min` and `max` may have moved since (the panel's slider).
        self.budget = self.budget.clamp(self.min, self.max.max(self.min));
        if !(seconds > 0.0 && seconds.is_finite()) {
            return self.budget;
        }
        // Not averaged: an average lags, and a lagging measure overshoots. A single slow frame
        // (pages landing) takes the budget down by the square root of its slowness, and the
        // next frames bring it back.
        let ratio = self.target / seconds;
        if (ratio - 1.0).abs() <= DEADBAND {
            return self.budget;
        }
        if ratio > 1.0 && !limited {
            // Faster than needed with everything in: the budget is not what limits.
            return self.budget;
        }
        let factor = ratio.powf(GAIN).clamp(1.0 / STEP, STEP);
        // Scale what was drawn (the budget may be far above it when the view needs less).
        let base = if limited {
            self.budget
        } else {
            points.max(self.min)
        };
        self.budget = ((base as f64 * factor) as u64).clamp(self.min, self.max);
        self.budget
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame costing 8 ms plus 40 ns per point, with ±5 % noise from a fixed sequence; the
    /// view would take 10 M points.
    fn simulate(pace: &mut Pace, frames: usize) -> Vec<(f64, u64)> {
        let mut out = Vec::new();
        let mut noise = 0x2545_F491_4F6C_DD1Du64;
        for _ in 0..frames {
            let budget = pace.budget();
            let points = budget.min(10_000_000);
            noise ^= noise << 13;
            noise ^= noise >> 7;
            noise ^= noise << 17;
            let jitter = 1.0 + 0.05 * ((noise % 2001) as f64 / 1000.0 - 1.0);
            let t = (0.008 + 40e-9 * points as f64) * jitter;
            pace.frame(t, points, points == budget);
            out.push((t, budget));
        }
        out
    }

    #[test]
    fn converges_on_the_target_and_holds_it() {
        // 10 fps: 100 ms = 8 ms + 2.3 M points.
        let mut pace = Pace::new(10.0, 20_000_000, 100_000, 50_000_000);
        let run = simulate(&mut pace, 60);
        // Within 15 % in under 15 frames (1.5 s at 10 fps), and staying there.
        let first = run
            .iter()
            .position(|&(t, _)| (t - 0.1).abs() < 0.015)
            .unwrap();
        assert!(first < 15, "settled after {first} frames: {run:?}");
        assert!(
            run[first..].iter().all(|&(t, _)| (t - 0.1).abs() < 0.015),
            "{run:?}"
        );
        // No oscillation: over the last 30 frames the budget moves by under 10 %.
        let tail: Vec<u64> = run[30..].iter().map(|r| r.1).collect();
        let (lo, hi) = (tail.iter().min().unwrap(), tail.iter().max().unwrap());
        assert!((*hi as f64) < 1.1 * *lo as f64, "{tail:?}");
        assert!((2_000_000..2_600_000).contains(lo), "{lo}");
        // From below too (a small start), within the same time.
        let mut pace = Pace::new(10.0, 100_000, 100_000, 50_000_000);
        let run = simulate(&mut pace, 40);
        assert!(
            run[15..].iter().all(|&(t, _)| (t - 0.1).abs() < 0.015),
            "{run:?}"
        );
    }

    #[test]
    fn does_not_grow_past_what_the_view_needs_nor_its_limits() {
        // The view needs 10 M points and draws them in 48 ms: 30 fps holds with them all; the
        // budget stays where it is rather than climbing to the maximum.
        let mut pace = Pace::new(10.0, 20_000_000, 100_000, 50_000_000);
        for _ in 0..50 {
            pace.frame(0.048, 10_000_000, false);
        }
        assert_eq!(pace.budget(), 20_000_000);
        // Hopelessly slow: it stops at the minimum.
        let mut pace = Pace::new(90.0, 1_000_000, 200_000, 5_000_000);
        for _ in 0..50 {
            let b = pace.budget();
            pace.frame(1.0, b, true);
        }
        assert_eq!(pace.budget(), 200_000);
        // A bad measurement changes nothing.
        assert_eq!(pace.frame(f64::NAN, 1, true), 200_000);
        // A lower most (the panel's slider) holds even on a frame right on target.
        let mut pace = Pace::new(10.0, 4_000_000, 100_000, 5_000_000);
        pace.max = 1_000_000;
        assert_eq!(pace.frame(0.1, 4_000_000, true), 1_000_000);
    }
}
