//! Every `myriad bench` benchmark, one module each: each prints its figures as medians over
//! several runs, next to a baseline measured in the same process (or a peer tool run side by
//! side), so that a noisy machine still gives a meaningful ratio. The `myriad` binary parses the
//! command line and calls a module's `run`; nothing here is product logic the other commands
//! need (that lives in the library crates the benchmarks measure).

pub mod baselines;
pub mod capacity;
pub mod contours;
pub mod convert;
pub mod culling;
pub mod export;
pub mod ground;
pub mod open;
pub mod open_scan;
pub mod partition;
pub mod passes;
pub mod prefetch;
pub mod profile;
pub mod read;
pub mod render;
pub mod serve;
pub mod stereo;
pub mod structures;
pub mod surface;
pub mod synth;
pub mod volume;
pub mod web;

use anyhow::{Result, bail};
use myriad_core::Aabb;
use myriad_lod::Camera;
use std::time::Instant;

/// The median of `v` (the upper one of an even count).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

pub(crate) fn time_points(f: impl Fn() -> Result<u64>, runs: usize) -> Result<(u64, f64)> {
    let mut rates = Vec::new();
    let mut n = 0;
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        n = f()?;
        rates.push(n as f64 / t.elapsed().as_secs_f64());
    }
    Ok((n, median(rates)))
}

/// A standard view of `view` (overview, top, close; None: the overview), its depth fitted to
/// `all`: what the benchmarks look from.
pub(crate) fn view_camera(
    name: Option<&str>,
    view: &Aabb,
    all: &Aabb,
    width: u32,
    height: u32,
) -> Result<Camera> {
    match Camera::view(name, view, all, width, height) {
        Some(c) => Ok(c),
        None => bail!("no standard view \"{}\"", name.unwrap_or_default()),
    }
}
