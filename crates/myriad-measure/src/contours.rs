//! Contour lines of a terrain grid (`myriad contours`): marching squares over the cells' centres
//! at every multiple of an interval, the crossings of each level joined into polylines (closed
//! where they close). A square with a corner without a value has no contour; a saddle is decided
//! by the mean of its corners.

use std::collections::HashMap;

/// Most levels one call draws.
pub const MAX_LEVELS: f64 = 10_000.0;

/// A contour: its elevation, its vertices in plan, whether it closes.
#[derive(Debug, Clone, PartialEq)]
pub struct Contour {
    pub elevation: f64,
    pub points: Vec<[f64; 2]>,
    pub closed: bool,
}

/// The contours every `interval` of the terrain a dataset's ground edit holds (`myriad ground`),
/// for the viewers' overlay: the surface's height sampled at the centres of a grid of at most
/// `max_cells` cells over the dataset's extent, then [`contours`]. An error says why there are
/// none: no terrain, or more than [`MAX_LEVELS`] levels.
pub fn of_terrain(
    ds: &myriad_format::Dataset,
    interval: f64,
    max_cells: usize,
) -> Result<Vec<Contour>, String> {
    if !(interval.is_finite() && interval > 0.0) {
        return Err(format!("interval {interval}: a positive number"));
    }
    let ground = (ds.edits().and_then(|e| e.ground())).ok_or_else(|| {
        format!(
            "{}: no terrain (`myriad ground` finds it)",
            ds.path().display()
        )
    })?;
    let b = ds.meta.bounds;
    let [w, h, _] = b.size();
    let cell = (w.max(1e-9) * h.max(1e-9) / max_cells.max(4) as f64).sqrt();
    let most = max_cells.max(4);
    let (nx, ny) = (
        ((w / cell).ceil() as usize).clamp(2, most),
        ((h / cell).ceil() as usize).clamp(2, most),
    );
    let place = |c: f64, r: f64| [b.min[0] + (c + 0.5) * cell, b.min[1] + (r + 0.5) * cell];
    let mut z = Vec::with_capacity(nx * ny);
    for r in 0..ny {
        for c in 0..nx {
            let [x, y] = place(c as f64, r as f64);
            z.push(ground.height(x, y).map_or(f32::NAN, |v| v as f32));
        }
    }
    let (lo, hi) = (z.iter().filter(|v| !v.is_nan()))
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if ((hi - lo) as f64 / interval) > MAX_LEVELS {
        return Err(format!(
            "interval {interval}: more than {MAX_LEVELS} levels between {lo} and {hi}"
        ));
    }
    Ok(contours(&z, nx, ny, interval, place))
}

/// The contours of `z` (`nx` x `ny` values, row by row; NaN: none) every `interval` (levels at
/// its multiples), the centre of value `(c, r)` at `place(c, r)`.
pub fn contours(
    z: &[f32],
    nx: usize,
    ny: usize,
    interval: f64,
    place: impl Fn(f64, f64) -> [f64; 2],
) -> Vec<Contour> {
    let (lo, hi) = z
        .iter()
        .filter(|v| !v.is_nan())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v as f64), b.max(v as f64))
        });
    if nx < 2 || ny < 2 || lo > hi {
        return Vec::new();
    }
    let mut out = Vec::new();
    let first = (lo / interval).ceil() as i64;
    let last = (hi / interval).floor() as i64;
    for k in first..=last {
        let level = k as f64 * interval;
        out.extend(level_lines(z, nx, ny, level, &place));
    }
    out
}

/// An edge between two grid nodes (the lower index first): where a crossing lies.
type Edge = (usize, usize);

fn level_lines(
    z: &[f32],
    nx: usize,
    ny: usize,
    level: f64,
    place: &impl Fn(f64, f64) -> [f64; 2],
) -> Vec<Contour> {
    // Values exactly at the level count as above it: no crossing falls on a node.
    let above = |i: usize| z[i] as f64 >= level;
    let mut segments: Vec<(Edge, Edge)> = Vec::new();
    for r in 0..ny - 1 {
        for c in 0..nx - 1 {
            let (a, b, d, e) = (
                r * nx + c,
                r * nx + c + 1,
                (r + 1) * nx + c + 1,
                (r + 1) * nx + c,
            );
            if [a, b, d, e].iter().any(|&i| z[i].is_nan()) {
                continue;
            }
            let case = (above(a) as u8)
                | (above(b) as u8) << 1
                | (above(d) as u8) << 2
                | (above(e) as u8) << 3;
            let (top, right, bottom, left) = ((a, b), (b, d), (e, d), (a, e));
            let mean = (z[a] + z[b] + z[d] + z[e]) as f64 / 4.0 >= level;
            match case {
                0 | 15 => {}
                1 | 14 => segments.push((left, top)),
                2 | 13 => segments.push((top, right)),
                3 | 12 => segments.push((left, right)),
                4 | 11 => segments.push((right, bottom)),
                6 | 9 => segments.push((top, bottom)),
                7 | 8 => segments.push((left, bottom)),
                5 if mean => {
                    segments.push((left, bottom));
                    segments.push((top, right));
                }
                5 => {
                    segments.push((left, top));
                    segments.push((right, bottom));
                }
                10 if mean => {
                    segments.push((left, top));
                    segments.push((right, bottom));
                }
                _ => {
                    segments.push((left, bottom));
                    segments.push((top, right));
                }
            }
        }
    }
    let point = |(i, j): Edge| -> [f64; 2] {
        let t = (level - z[i] as f64) / (z[j] as f64 - z[i] as f64);
        let (ci, ri) = ((i % nx) as f64, (i / nx) as f64);
        let (cj, rj) = ((j % nx) as f64, (j / nx) as f64);
        place(ci + t * (cj - ci), ri + t * (rj - ri))
    };
    // Join: every crossing is shared by at most two segments.
    let mut at: HashMap<Edge, Vec<usize>> = HashMap::new();
    for (s, (p, q)) in segments.iter().enumerate() {
        at.entry(*p).or_default().push(s);
        at.entry(*q).or_default().push(s);
    }
    let mut used = vec![false; segments.len()];
    let mut lines = Vec::new();
    // Open lines start at a crossing of one segment; what is left after them closes.
    let mut starts: Vec<(Edge, usize)> = (at.iter())
        .filter(|(_, v)| v.len() == 1)
        .map(|(e, v)| (*e, v[0]))
        .collect();
    starts.sort_unstable();
    let rest: Vec<(Edge, usize)> = (0..segments.len()).map(|s| (segments[s].0, s)).collect();
    for (start, s0) in starts.into_iter().chain(rest) {
        if used[s0] {
            continue;
        }
        let mut chain = vec![start];
        let (mut here, mut s) = (start, s0);
        loop {
            used[s] = true;
            let (p, q) = segments[s];
            let next = if p == here { q } else { p };
            chain.push(next);
            here = next;
            match at[&here].iter().find(|&&t| !used[t]) {
                Some(&t) => s = t,
                None => break,
            }
        }
        let closed = chain.len() > 2 && chain.first() == chain.last();
        if closed {
            chain.pop();
        }
        // A crossing on a node (a value exactly at the level) repeats a vertex; a line of one
        // place (a peak exactly at the level) is no line.
        let mut points: Vec<[f64; 2]> = chain.into_iter().map(point).collect();
        points.dedup();
        if closed && points.len() > 1 && points.first() == points.last() {
            points.pop();
        }
        if points.len() < 2 {
            continue;
        }
        lines.push(Contour {
            elevation: level,
            closed: closed && points.len() > 2,
            points,
        });
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cone_gives_closed_circles_and_a_slope_open_lines() {
        let n = 41;
        let cone: Vec<f32> = (0..n * n)
            .map(|i| {
                let (x, y) = ((i % n) as f64 - 20.0, (i / n) as f64 - 20.0);
                (10.0 - (x * x + y * y).sqrt()) as f32
            })
            .collect();
        let c = contours(&cone, n, n, 2.5, |x, y| [x, y]);
        // Circles of radius 10 - level inside the grid (levels 0 to 10), arcs cut by its edges
        // beyond (radius over 20).
        for l in &c {
            let r = 10.0 - l.elevation;
            assert_eq!(l.closed, r < 20.0, "{}", l.elevation);
            for p in &l.points {
                let d = ((p[0] - 20.0).powi(2) + (p[1] - 20.0).powi(2)).sqrt();
                assert!((d - r).abs() < 0.3, "{} at {d}", l.elevation);
            }
        }
        assert_eq!(c.iter().filter(|l| l.elevation == 5.0).count(), 1);
        // A peak exactly at a level is a place, not a line.
        let peak = [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0];
        assert!(contours(&peak, 3, 3, 1.0, |x, y| [x, y]).is_empty());
        let slope: Vec<f32> = (0..n * n).map(|i| (i % n) as f32 * 0.5).collect();
        let c = contours(&slope, n, n, 5.0, |x, y| [x, y]);
        let levels: Vec<f64> = c.iter().map(|l| l.elevation).collect();
        assert_eq!(levels, vec![5.0, 10.0, 15.0, 20.0]);
        for l in &c {
            assert!(!l.closed && l.points.len() == n);
            assert!(
                l.points
                    .iter()
                    .all(|p| (p[0] - l.elevation / 0.5).abs() < 1e-9)
            );
        }
    }
}
