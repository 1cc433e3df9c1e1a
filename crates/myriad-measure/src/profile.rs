//! Cross-sections (height profiles): the original points within half a width of a polyline,
//! each with its distance along the line and its offset across it, sorted along the line; as
//! CSV rows, a 2D plot (PNG) and, in `files`, a CAD drawing.

use crate::{Bound, Corridor, read_region};
use myriad_core::colour::{ColorBy, colours};
use myriad_format::Dataset;
use std::io::Write;

/// At most this many points in a profile held for sorting (about 1 GB); a LAS/LAZ export of
/// the corridor streams and has no limit.
pub const MAX_POINTS: u64 = 10_000_000;

/// A cross-section's points, sorted by distance along the line.
#[derive(Debug, Clone, Default)]
pub struct Profile {
    pub positions: Vec<[f64; 3]>,
    /// (distance along, offset across) of each point.
    pub stations: Vec<[f64; 2]>,
    /// The attributes' names and, per point, their values (row after row).
    pub columns: Vec<String>,
    pub values: Vec<f64>,
    /// Each point's colour as the view shows it.
    pub colours: Vec<[u8; 3]>,
    pub length: f64,
    pub width: f64,
    /// Decimals that hold a coordinate exactly (from the dataset's grid).
    pub decimals: usize,
    pub nodes_read: u64,
}

impl Profile {
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The lowest and highest elevation (0, 0 when empty).
    pub fn z_range(&self) -> (f64, f64) {
        let lo = self
            .positions
            .iter()
            .map(|p| p[2])
            .fold(f64::INFINITY, f64::min);
        let hi = (self.positions.iter().map(|p| p[2])).fold(f64::NEG_INFINITY, f64::max);
        if lo.is_finite() { (lo, hi) } else { (0.0, 0.0) }
    }

    /// The profile line: the highest point of each step of `step` along the line, as
    /// (distance, elevation), in order.
    pub fn top_line(&self, step: f64) -> Vec<[f64; 2]> {
        let mut out: Vec<[f64; 2]> = Vec::new();
        let mut bin = i64::MIN;
        for (s, p) in self.stations.iter().zip(&self.positions) {
            let b = (s[0] / step).floor() as i64;
            match out.last_mut() {
                Some(last) if b == bin => {
                    if p[2] > last[1] {
                        *last = [s[0], p[2]];
                    }
                }
                _ => {
                    out.push([s[0], p[2]]);
                    bin = b;
                }
            }
        }
        out
    }

    /// Writes the profile as CSV: x, y, z, distance, offset, then every attribute.
    pub fn write_csv(&self, mut w: impl Write) -> std::io::Result<()> {
        write!(w, "x,y,z,distance,offset")?;
        for c in &self.columns {
            write!(w, ",{c}")?;
        }
        writeln!(w)?;
        let d = self.decimals;
        let k = self.columns.len();
        for (i, (p, s)) in self.positions.iter().zip(&self.stations).enumerate() {
            write!(
                w,
                "{:.d$},{:.d$},{:.d$},{:.4},{:.4}",
                p[0], p[1], p[2], s[0], s[1]
            )?;
            for v in &self.values[i * k..(i + 1) * k] {
                write!(w, ",{v}")?;
            }
            writeln!(w)?;
        }
        Ok(())
    }

    /// The profile drawn as a picture `width` pixels wide: distance along to the right,
    /// elevation up, at one scale (or stretched upwards to at least a fifth of the width, as
    /// the returned vertical exaggeration says), grid lines at round steps. RGBA rows.
    pub fn plot(&self, width: u32) -> (u32, u32, Vec<u8>, f64) {
        let frame = self.frame(width);
        let (z0, _) = self.z_range();
        let Frame {
            margin,
            inner_h,
            exaggeration,
            height,
            ..
        } = frame;
        let inner_w = width as f64 - 2.0 * margin;
        let mut img = vec![0u8; (width * height * 4) as usize];
        for px in img.chunks_exact_mut(4) {
            px.copy_from_slice(&[250, 250, 250, 255]);
        }
        let mut put = |x: i64, y: i64, c: [u8; 3]| {
            if x >= 0 && y >= 0 && (x as u32) < width && (y as u32) < height {
                let at = ((y as u32 * width + x as u32) * 4) as usize;
                img[at..at + 3].copy_from_slice(&c);
            }
        };
        let to_px = |along: f64, z: f64| frame.to_px(along, z);
        let (along, heights) = self.grid(width);
        for g in along {
            let (x, _) = to_px(g, z0);
            for y in margin as i64..(margin + inner_h) as i64 {
                put(x.round() as i64, y, [215, 215, 215]);
            }
        }
        for gz in heights {
            let (_, y) = to_px(0.0, gz);
            for x in margin as i64..(margin + inner_w) as i64 {
                put(x, y.round() as i64, [215, 215, 215]);
            }
        }
        // The points nearest the line last, on top.
        let mut order: Vec<usize> = (0..self.len()).collect();
        order.sort_by(|&a, &b| {
            self.stations[b][1]
                .abs()
                .total_cmp(&self.stations[a][1].abs())
        });
        for i in order {
            let (x, y) = to_px(self.stations[i][0], self.positions[i][2]);
            let (x, y) = (x.floor() as i64, y.floor() as i64);
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                put(x + dx, y + dy, self.colours[i]);
            }
        }
        (width, height, img, exaggeration)
    }
}

impl Profile {
    /// The grid lines of the picture [`Profile::plot`] draws `width` pixels wide: the
    /// distances along (every round step of about a tenth of the length) and the elevations
    /// (about a fifth of the rise).
    pub fn grid(&self, _width: u32) -> (Vec<f64>, Vec<f64>) {
        let (z0, z1) = self.z_range();
        let rise = (z1 - z0).max(1e-3);
        // Counted, not stepped until past the end: at elevations of 1e13 with millimetres of
        // rise, adding the step left the value where it was (found by an audit).
        let lines = |from: f64, to: f64, step: f64| {
            let n = ((to + 1e-9 - from) / step).floor();
            let n = if n.is_finite() {
                n.clamp(-1.0, 100.0) as i64
            } else {
                -1
            };
            (0..=n)
                .map(move |k| from + k as f64 * step)
                .collect::<Vec<_>>()
        };
        let zstep = nice_step(rise / 5.0);
        (
            lines(0.0, self.length, nice_step(self.length / 10.0)),
            lines((z0 / zstep).ceil() * zstep, z1, zstep),
        )
    }
}

/// Where a profile's picture puts distance along and elevation ([`Profile::plot`]), both ways:
/// what a view of the profile measures in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    pub margin: f64,
    /// Pixels per unit along the line; up, this times `exaggeration`.
    pub per_m: f64,
    pub exaggeration: f64,
    pub inner_h: f64,
    pub z0: f64,
    pub width: u32,
    pub height: u32,
}

impl Frame {
    /// The pixel of (distance along, elevation).
    pub fn to_px(&self, along: f64, z: f64) -> (f64, f64) {
        (
            self.margin + along * self.per_m,
            self.margin + self.inner_h - (z - self.z0) * self.per_m * self.exaggeration,
        )
    }

    /// The (distance along, elevation) of a pixel.
    pub fn from_px(&self, x: f64, y: f64) -> [f64; 2] {
        [
            (x - self.margin) / self.per_m,
            self.z0 + (self.margin + self.inner_h - y) / (self.per_m * self.exaggeration),
        ]
    }
}

/// What two points of a profile, (distance along, elevation) each, are apart: along, in height,
/// the slope (percent and degrees) and straight.
pub fn between(a: [f64; 2], b: [f64; 2], units: &str) -> String {
    let (run, rise) = (b[0] - a[0], b[1] - a[1]);
    let slope = if run.abs() > 1e-12 {
        format!(
            "{:+.2} % ({:+.2}°)",
            100.0 * rise / run,
            rise.atan2(run.abs()).to_degrees()
        )
    } else {
        "vertical".into()
    };
    format!(
        "along {:.3} {units}, height {:+.3} {units}, slope {slope}, distance {:.3} {units}",
        run.abs(),
        rise,
        run.hypot(rise)
    )
}

impl Profile {
    /// The frame of a picture `width` pixels wide: one scale both ways, stretched upwards to
    /// at least a fifth of the width (at most one and a half).
    pub fn frame(&self, width: u32) -> Frame {
        let (z0, z1) = self.z_range();
        let margin = 16.0;
        let inner_w = width as f64 - 2.0 * margin;
        let per_m = inner_w / self.length.max(1e-9);
        let natural = (z1 - z0).max(1e-3) * per_m;
        let inner_h = natural.clamp(width as f64 / 5.0, width as f64 * 1.5);
        Frame {
            margin,
            per_m,
            exaggeration: inner_h / natural,
            inner_h,
            z0,
            width,
            height: (inner_h + 2.0 * margin).round() as u32,
        }
    }
}

/// 1, 2 or 5 times a power of ten, at least `x`.
pub fn nice_step(x: f64) -> f64 {
    let x = x.max(1e-9);
    let p = 10f64.powf(x.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * p)
        .find(|s| *s >= x * 0.999)
        .unwrap_or(10.0 * p)
}

/// The cross-section of `ds` along `corridor`: every original point in it that `filter` keeps,
/// coloured by `colour`; an error past [`MAX_POINTS`].
pub fn profile(
    ds: &Dataset,
    corridor: &Corridor,
    filter: &Bound,
    colour: ColorBy,
) -> Result<Profile, String> {
    let schema = &ds.meta.schema;
    let fields = myriad_core::Column::columns(schema);
    let scale = ds.meta.quantization.scale;
    let finest = scale.iter().copied().fold(f64::INFINITY, f64::min);
    let mut p = Profile {
        columns: fields.iter().map(|(n, _)| n.clone()).collect(),
        length: corridor.length(),
        width: corridor.width(),
        decimals: (-finest.log10()).ceil().clamp(0.0, 9.0) as usize,
        ..Profile::default()
    };
    let z_range = (ds.meta.bounds.min[2], ds.meta.bounds.max[2]);
    let mut too_many = false;
    let read = read_region(ds, corridor, filter, |b| {
        if too_many || p.positions.len() as u64 + b.len() as u64 > MAX_POINTS {
            too_many = true;
            return;
        }
        let c = colours(b, b.len(), colour, z_range, 0);
        for i in 0..b.len() {
            let q = b.positions[i];
            let (along, across) = corridor.station(q[0], q[1]).expect("read_region kept it");
            p.positions.push(q);
            p.stations.push([along, across]);
            p.values.extend(fields.iter().map(|(_, f)| f.value(b, i)));
            p.colours.push([c[i][0], c[i][1], c[i][2]]);
        }
    })?;
    if too_many {
        return Err(format!(
            "the corridor holds more than {MAX_POINTS} points: a narrower --width or a shorter \
             --line, or a .las/.laz output, which has no limit"
        ));
    }
    p.nodes_read = read.nodes;
    // Sorted along the line (then across, then by position, so that the order is one).
    let mut order: Vec<usize> = (0..p.positions.len()).collect();
    order.sort_by(|&a, &b| {
        (p.stations[a][0].total_cmp(&p.stations[b][0]))
            .then(p.stations[a][1].total_cmp(&p.stations[b][1]))
            .then(p.positions[a][2].total_cmp(&p.positions[b][2]))
    });
    let k = p.columns.len();
    p.values = order
        .iter()
        .flat_map(|&i| p.values[i * k..(i + 1) * k].iter().copied())
        .collect();
    p.positions = order.iter().map(|&i| p.positions[i]).collect();
    p.stations = order.iter().map(|&i| p.stations[i]).collect();
    p.colours = order.iter().map(|&i| p.colours[i]).collect();
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_and_top_line() {
        assert_eq!(nice_step(0.7), 1.0);
        assert_eq!(nice_step(1.5), 2.0);
        assert_eq!(nice_step(30.0), 50.0);
        let p = Profile {
            positions: vec![[0.0, 0.0, 1.0], [0.0, 0.0, 3.0], [0.0, 0.0, 2.0]],
            stations: vec![[0.1, 0.0], [0.4, 0.0], [1.2, 0.0]],
            ..Profile::default()
        };
        assert_eq!(p.top_line(1.0), vec![[0.4, 3.0], [1.2, 2.0]]);
    }

    #[test]
    fn a_pictures_pixels_map_back_to_the_profile() {
        let p = Profile {
            positions: vec![[0.0, 0.0, 100.0], [0.0, 0.0, 112.0]],
            stations: vec![[0.0, 0.0], [80.0, 0.0]],
            colours: vec![[0, 0, 0]; 2],
            length: 80.0,
            ..Profile::default()
        };
        let f = p.frame(800);
        let (w, h, _, ex) = p.plot(800);
        assert_eq!((w, h, ex), (800, f.height, f.exaggeration));
        let (x, y) = f.to_px(30.0, 104.5);
        let back = f.from_px(x, y);
        assert!((back[0] - 30.0).abs() < 1e-9 && (back[1] - 104.5).abs() < 1e-9);
        assert_eq!(
            between([10.0, 100.0], [40.0, 103.0], "m"),
            "along 30.000 m, height +3.000 m, slope +10.00 % (+5.71°), distance 30.150 m"
        );
        assert!(between([1.0, 0.0], [1.0, 2.0], "m").contains("slope vertical"));
    }
}
