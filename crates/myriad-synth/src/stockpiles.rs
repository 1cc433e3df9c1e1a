//! The stockpile site: cones and ridges (triangular prisms) of material of known volume on a
//! tilted plane of ground, scanned from above at an even density (one pulse per cell of a
//! square grid, jittered within it). A pile's volume above the ground is exactly its solid's
//! (each pile is raised over the plane along the vertical), so volume tools can be checked
//! against the analytic value. Epoch 2 is a later survey of the same site with the first pile
//! taken away (and the pulses jittered anew).

use crate::rng::{hash3, sub, unit};
use crate::scan::push_single;
use myriad_core::PointBatch;

/// Pulses per square metre.
pub const DENSITY: f64 = 16.0;
/// Piles stand one per square of this side, those wholly inside the site.
pub const PLOT: f64 = 40.0;
/// Ground and pile classes (ASPRS): ground, and unclassified for the material.
pub const GROUND: u8 = 2;
pub const MATERIAL: u8 = 1;

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// A cone of this base radius.
    Cone { radius: f64 },
    /// A ridge: a triangular prism `length` long on a base `width` wide, its axis at `angle`
    /// (radians from the x axis), its ends vertical.
    Prism { length: f64, width: f64, angle: f64 },
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pile {
    /// In the site's coordinates (the scan adds [`crate::ORIGIN`]).
    pub centre: [f64; 2],
    pub height: f64,
    pub shape: Shape,
}

impl Pile {
    /// Its volume: a third of base times height for a cone, half of base times height times
    /// length for a ridge.
    pub fn volume(&self) -> f64 {
        match self.shape {
            Shape::Cone { radius } => std::f64::consts::PI * radius * radius * self.height / 3.0,
            Shape::Prism { length, width, .. } => width * self.height * length / 2.0,
        }
    }

    /// The height of material at (x, y) above the ground.
    pub fn height_at(&self, x: f64, y: f64) -> f64 {
        let (dx, dy) = (x - self.centre[0], y - self.centre[1]);
        match self.shape {
            Shape::Cone { radius } => {
                let d = (dx * dx + dy * dy).sqrt();
                (self.height * (1.0 - d / radius)).max(0.0)
            }
            Shape::Prism {
                length,
                width,
                angle,
            } => {
                let (s, c) = angle.sin_cos();
                let along = dx * c + dy * s;
                let across = -dx * s + dy * c;
                if along.abs() > length / 2.0 {
                    return 0.0;
                }
                (self.height * (1.0 - 2.0 * across.abs() / width)).max(0.0)
            }
        }
    }

    /// The largest distance of the pile's footprint from its centre.
    pub fn reach(&self) -> f64 {
        match self.shape {
            Shape::Cone { radius } => radius,
            Shape::Prism { length, width, .. } => (length * length + width * width).sqrt() / 2.0,
        }
    }

    /// A square around the pile with `margin` of ground on every side, as X,Y,... (what
    /// `myriad volume --polygon` takes), shifted by `origin`.
    pub fn polygon(&self, margin: f64, origin: [f64; 3]) -> String {
        let r = self.reach() + margin;
        let (x, y) = (self.centre[0] + origin[0], self.centre[1] + origin[1]);
        [(-r, -r), (r, -r), (r, r), (-r, r)]
            .iter()
            .map(|(a, b)| format!("{},{}", x + a, y + b))
            .collect::<Vec<_>>()
            .join(",")
    }
}

/// The site for a scan of `points` points.
#[derive(Debug, Clone)]
pub struct Site {
    seed: u64,
    epoch: u32,
    /// Pulses per row and the pulse spacing.
    columns: u64,
    spacing: f64,
    piles: Vec<Pile>,
}

impl Site {
    pub fn plan(points: u64, seed: u64, epoch: u32) -> Site {
        let spacing = 1.0 / DENSITY.sqrt();
        let columns = ((points as f64).sqrt().ceil() as u64).max(1);
        let side = columns as f64 * spacing;
        let plots = (side / PLOT).floor() as i64;
        let mut piles = Vec::new();
        for j in 0..plots {
            for i in 0..plots {
                let h = hash3(seed ^ 0x5107_C0FE, i, j);
                let centre = [
                    (i as f64 + 0.5) * PLOT + (sub(h, 1) - 0.5) * 6.0,
                    (j as f64 + 0.5) * PLOT + (sub(h, 2) - 0.5) * 6.0,
                ];
                let shape = if unit(h) < 0.5 {
                    Shape::Cone {
                        radius: 6.0 + 6.0 * sub(h, 3),
                    }
                } else {
                    Shape::Prism {
                        length: 12.0 + 12.0 * sub(h, 3),
                        width: 8.0 + 4.0 * sub(h, 4),
                        angle: std::f64::consts::PI * sub(h, 5),
                    }
                };
                let height = match shape {
                    Shape::Cone { .. } => 2.5 + 4.5 * sub(h, 6),
                    Shape::Prism { .. } => 2.0 + 3.0 * sub(h, 6),
                };
                piles.push(Pile {
                    centre,
                    height,
                    shape,
                });
            }
        }
        Site {
            seed,
            epoch: epoch.max(1),
            columns,
            spacing,
            piles,
        }
    }

    /// The piles standing at this epoch (the first is gone from epoch 2 on).
    pub fn piles(&self) -> &[Pile] {
        if self.epoch >= 2 && !self.piles.is_empty() {
            &self.piles[1..]
        } else {
            &self.piles
        }
    }

    /// Every pile of the site, the removed one first.
    pub fn all_piles(&self) -> &[Pile] {
        &self.piles
    }

    /// The ground: a plane rising 1.5 % to the east and 0.8 % to the north, 100 m up.
    pub fn ground(x: f64, y: f64) -> f64 {
        100.0 + 0.015 * x + 0.008 * y
    }

    /// Pulse `k`: one point in cell (k mod columns, k / columns) of the grid.
    pub fn pulse(&self, k: u64, out: &mut PointBatch) {
        let h = hash3(self.seed ^ ((self.epoch as u64) << 40), k as i64, 0x57);
        let (i, j) = (k % self.columns, k / self.columns);
        let x = (i as f64 + unit(h)) * self.spacing;
        let y = (j as f64 + sub(h, 1)) * self.spacing;
        let mut z = Site::ground(x, y);
        let mut material = None;
        // A pile's neighbours are whole plots away: at most the one of this plot.
        for (n, p) in self.piles().iter().enumerate() {
            let (dx, dy) = (x - p.centre[0], y - p.centre[1]);
            if dx.abs() <= p.reach() && dy.abs() <= p.reach() {
                let t = p.height_at(x, y);
                if t > 0.0 {
                    z += t;
                    material = Some(n);
                    break;
                }
            }
        }
        let (class, rgb, intensity) = match material {
            Some(n) => {
                let tone = 170.0 + 40.0 * sub(hash3(self.seed, n as i64, 9), 0);
                let c = [tone, tone * 0.88, tone * 0.7].map(|v| (v * 256.0) as u16);
                (MATERIAL, c, 900 + (sub(h, 2) * 200.0) as u16)
            }
            None => (
                GROUND,
                [96 * 256, 118 * 256, 70 * 256],
                400 + (sub(h, 2) * 200.0) as u16,
            ),
        };
        let gps = k as f64 * 1e-5;
        push_single(
            out,
            [x, y, z],
            intensity,
            class,
            self.epoch as u16,
            gps,
            rgb,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn piles_have_their_volumes() {
        let s = Site::plan(1_000_000, 3, 1);
        assert!(s.piles().len() >= 4, "{}", s.piles().len());
        // Integrate each pile's height on a fine grid: its analytic volume.
        for p in s.piles() {
            let r = p.reach();
            let step = 0.02;
            let mut v = 0.0;
            let n = (2.0 * r / step) as i64;
            for j in 0..n {
                for i in 0..n {
                    let x = p.centre[0] - r + (i as f64 + 0.5) * step;
                    let y = p.centre[1] - r + (j as f64 + 0.5) * step;
                    v += p.height_at(x, y) * step * step;
                }
            }
            assert!(
                (v - p.volume()).abs() < 0.002 * p.volume(),
                "{p:?}: {v} vs {}",
                p.volume()
            );
        }
        assert_eq!(
            Site::plan(1_000_000, 3, 2).piles().len(),
            s.piles().len() - 1
        );
    }
}
