//! Colour schemes: what a point's colour shows.

pub use crate::classes::class_colour;
use crate::classes::palette;
use crate::{Column, PointBatch, Schema};

/// What a point's colour shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ColorBy {
    /// Its RGB (16-bit, scaled down; 8-bit values stored in 16-bit fields taken as they are);
    /// the elevation ramp where there is none.
    Rgb,
    /// Grey levels.
    Intensity,
    /// A blue-green-yellow-red ramp over the dataset's height.
    Elevation,
    /// The usual colours of the ASPRS classes (ground brown, vegetation greens, building red,
    /// water blue, ...).
    Classification,
    ReturnNumber,
    PointSource,
    /// The node's level in the tree.
    Level,
    /// One light grey for every point, whatever its attributes: with shading on, the shape alone.
    Uniform,
    /// Any column through a gradient over a range ([`Ramp`]).
    Ramp(Ramp),
}

/// The gradients a [`Ramp`] maps values through, low to high.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Gradient {
    /// Blue, green, yellow, red (the elevation colours).
    Spectral,
    /// Perceptually even, dark violet to yellow, readable by the colour-blind.
    Viridis,
    /// A rainbow, dark blue through green and yellow to dark red (after Google's Turbo).
    Turbo,
    /// Black to white.
    Grey,
}

impl Gradient {
    pub const ALL: [Gradient; 4] = [
        Gradient::Spectral,
        Gradient::Viridis,
        Gradient::Turbo,
        Gradient::Grey,
    ];
    pub const NAMES: &str = "spectral, viridis, turbo, grey";

    pub fn parse(s: &str) -> Option<Gradient> {
        Some(match s.to_ascii_lowercase().as_str() {
            "spectral" | "rainbow" => Gradient::Spectral,
            "viridis" => Gradient::Viridis,
            "turbo" => Gradient::Turbo,
            "grey" | "gray" => Gradient::Grey,
            _ => return None,
        })
    }

    /// The colour at `t` in 0..1 (clamped).
    pub fn at(self, t: f64) -> [u8; 3] {
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        match self {
            Gradient::Spectral => ramp(t),
            Gradient::Grey => [(t * 255.0).round() as u8; 3],
            Gradient::Viridis => stops(&VIRIDIS, t),
            Gradient::Turbo => stops(&TURBO, t),
        }
    }
}

/// Viridis at nine even steps (matplotlib's colour map, to 8 bits).
const VIRIDIS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 45, 123],
    [59, 82, 139],
    [44, 114, 142],
    [33, 145, 140],
    [40, 174, 128],
    [94, 201, 98],
    [173, 220, 48],
    [253, 231, 37],
];

/// A rainbow after Google's Turbo, approximated at eleven even steps.
const TURBO: [[u8; 3]; 11] = [
    [48, 18, 59],
    [65, 69, 171],
    [70, 117, 237],
    [57, 162, 252],
    [27, 207, 212],
    [36, 236, 166],
    [97, 252, 108],
    [164, 252, 59],
    [250, 186, 57],
    [230, 95, 24],
    [122, 4, 3],
];

/// Linear between even stops.
fn stops(s: &[[u8; 3]], t: f64) -> [u8; 3] {
    let x = t * (s.len() - 1) as f64;
    let i = (x.floor() as usize).min(s.len() - 2);
    let f = x - i as f64;
    std::array::from_fn(|k| (s[i][k] as f64 * (1.0 - f) + s[i + 1][k] as f64 * f).round() as u8)
}

/// A column's values mapped through a gradient: `range[0]` low, `range[1]` high.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ramp {
    pub column: Column,
    pub gradient: Gradient,
    pub range: [f64; 2],
}

impl Ramp {
    /// The 2nd and 98th percentiles of the column in `sample` (the dataset's overview): a
    /// range few outliers stretch. `None` where the sample holds no value of it.
    pub fn fit(column: Column, sample: &PointBatch) -> Option<[f64; 2]> {
        let mut v: Vec<f64> = (0..sample.len())
            .map(|i| column.value(sample, i))
            .filter(|v| v.is_finite())
            .collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        let (lo, hi) = (at(0.02), at(0.98));
        Some(if hi > lo { [lo, hi] } else { [lo, lo + 1.0] })
    }
}

/// What `--color NAME [--gradient G] [--range LOW,HIGH]` asks for, against a dataset's schema:
/// a scheme by its name (without a gradient or a range), else a ramp over the column `NAME`
/// (elevation for `elevation`), through `G` (viridis, or spectral for elevation), over the range
/// given or [`Ramp::fit`] to `sample` (asked for only then: a dataset's overview is a read).
pub fn choose(
    name: &str,
    gradient: Option<Gradient>,
    range: Option<[f64; 2]>,
    schema: &Schema,
    sample: impl FnOnce() -> PointBatch,
) -> Result<ColorBy, String> {
    if gradient.is_none()
        && range.is_none()
        && let Some(c) = ColorBy::parse(name)
    {
        return Ok(c);
    }
    let column = Column::find(name, schema).ok_or_else(|| {
        format!(
            "--color \"{name}\": no such scheme (rgb, intensity, elevation, classification, \
             return, source, level, uniform) or attribute of this dataset (it has: x, y, z, {})",
            schema.names().join(", ")
        )
    })?;
    let gradient = gradient.unwrap_or(if matches!(column, Column::Axis(2)) {
        Gradient::Spectral
    } else {
        Gradient::Viridis
    });
    let range = match range {
        Some(r) => r,
        None => Ramp::fit(column, &sample()).unwrap_or([0.0, 1.0]),
    };
    Ok(ColorBy::Ramp(Ramp {
        column,
        gradient,
        range,
    }))
}

impl ColorBy {
    pub fn parse(s: &str) -> Option<ColorBy> {
        Some(match s {
            "rgb" => ColorBy::Rgb,
            "intensity" => ColorBy::Intensity,
            "elevation" => ColorBy::Elevation,
            "classification" => ColorBy::Classification,
            "return" | "return-number" => ColorBy::ReturnNumber,
            "source" | "point-source" => ColorBy::PointSource,
            "level" | "lod" => ColorBy::Level,
            "uniform" | "none" => ColorBy::Uniform,
            _ => return None,
        })
    }
}

fn ramp(t: f64) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    // Blue, green, yellow, red.
    let (r, g, b) = if t < 0.5 {
        (0.0, 2.0 * t, 1.0 - 2.0 * t)
    } else {
        (2.0 * t - 1.0, 2.0 - 2.0 * t, 0.0)
    };
    [(r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8]
}

/// RGBA8 colours of a batch's first `n` points by `scheme`; `z_range` spans the elevation ramp,
/// `level` is the node's level. A scheme whose attribute the batch lacks falls back to elevation.
pub fn colours(
    b: &PointBatch,
    n: usize,
    scheme: ColorBy,
    z_range: (f64, f64),
    level: u32,
) -> Vec<[u8; 4]> {
    let rgba = |c: [u8; 3]| [c[0], c[1], c[2], 255];
    let elevation = || {
        let (lo, hi) = z_range;
        b.positions[..n]
            .iter()
            .map(|p| rgba(ramp((p[2] - lo) / (hi - lo).max(1e-9))))
            .collect()
    };
    match scheme {
        ColorBy::Rgb => match &b.rgb {
            Some(rgb) => {
                let wide = rgb[..n].iter().any(|c| c.iter().any(|&v| v > 255));
                let f = |v: u16| if wide { (v >> 8) as u8 } else { v as u8 };
                rgb[..n].iter().map(|c| rgba(c.map(f))).collect()
            }
            None => elevation(),
        },
        ColorBy::Intensity => match &b.intensity {
            Some(i) => {
                let wide = i[..n].iter().any(|&v| v > 255);
                i[..n]
                    .iter()
                    .map(|&v| {
                        let g = if wide { (v >> 8) as u8 } else { v as u8 };
                        rgba([g, g, g])
                    })
                    .collect()
            }
            None => elevation(),
        },
        ColorBy::Elevation => elevation(),
        ColorBy::Classification => match &b.classification {
            Some(c) => {
                let scheme = crate::classes::current();
                c[..n].iter().map(|&c| rgba(scheme.colour(c))).collect()
            }
            None => elevation(),
        },
        ColorBy::ReturnNumber => match &b.return_number {
            Some(r) => r[..n].iter().map(|&r| rgba(palette(r as u32))).collect(),
            None => elevation(),
        },
        ColorBy::PointSource => match &b.point_source_id {
            Some(s) => s[..n].iter().map(|&s| rgba(palette(s as u32))).collect(),
            None => elevation(),
        },
        ColorBy::Level => vec![rgba(palette(level)); n],
        ColorBy::Uniform => vec![[210, 210, 210, 255]; n],
        ColorBy::Ramp(r) => {
            let [lo, hi] = r.range;
            let span = if hi > lo { hi - lo } else { 1.0 };
            let colour = |v: f64| rgba(r.gradient.at((v - lo) / span));
            match r.column {
                // The terrain found once for the node (a point without one: at its level).
                Column::AboveGround(id) => {
                    let g = crate::ground::get(id);
                    (b.positions[..n].iter())
                        .map(|p| {
                            let h = g.as_ref().and_then(|g| g.height(p[0], p[1]));
                            colour(h.map_or(0.0, |h| p[2] - h))
                        })
                        .collect()
                }
                c => (0..n).map(|i| colour(c.value(b, i))).collect(),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Attribute, Schema};

    /// A terrain rising 1 a unit of x, none where x < 0.
    struct Slope;
    impl crate::ground::GroundHeight for Slope {
        fn height(&self, x: f64, _: f64) -> Option<f64> {
            (x >= 0.0).then_some(x)
        }
    }

    #[test]
    fn heights_above_the_ground_through_a_gradient() {
        let id = crate::ground::register("colour-test", std::sync::Arc::new(Slope));
        let mut b = PointBatch::with_schema(&Schema::new(vec![]), 0);
        b.positions = vec![
            [0.0, 0.0, 0.0],
            [2.0, 5.0, 7.0],
            [4.0, 0.0, 4.0],
            [-1.0, 0.0, 9.0],
        ];
        let column = Column::AboveGround(id);
        let r = Ramp {
            column,
            gradient: Gradient::Turbo,
            range: [0.0, 10.0],
        };
        let c = colours(&b, 4, ColorBy::Ramp(r), (0.0, 1.0), 0);
        let at = |t: f64| {
            let [r, g, b] = Gradient::Turbo.at(t);
            [r, g, b, 255]
        };
        // 0, 5 and 0 above it; the last has no terrain under it: at the ground's colour.
        assert_eq!(c, vec![at(0.0), at(0.5), at(0.0), at(0.0)]);
        assert_eq!(column.value(&b, 1), 5.0);
        assert!(column.value(&b, 3).is_nan());
    }

    #[test]
    fn colour_schemes() {
        let schema = Schema::new(vec![
            Attribute::Classification,
            Attribute::Intensity,
            Attribute::Rgb,
        ]);
        let mut b = PointBatch::with_schema(&schema, 3);
        for (i, (class, int)) in [(2u8, 0u16), (6, 65535), (9, 256)].iter().enumerate() {
            b.positions.push([0.0, 0.0, i as f64]);
            b.classification.as_mut().unwrap().push(*class);
            b.intensity.as_mut().unwrap().push(*int);
            b.rgb.as_mut().unwrap().push([200, 100, 50]);
        }
        let c = colours(&b, 3, ColorBy::Classification, (0.0, 2.0), 0);
        assert_eq!(c[0], [166, 120, 72, 255], "ground is brown");
        assert_eq!(c[1], [230, 90, 60, 255], "building is red");
        assert_eq!(c[2], [40, 100, 255, 255], "water is blue");
        let c = colours(&b, 3, ColorBy::Intensity, (0.0, 2.0), 0);
        assert_eq!((c[0][0], c[1][0], c[2][0]), (0, 255, 1));
        // 8-bit colour in 16-bit fields is taken as it is.
        assert_eq!(
            colours(&b, 1, ColorBy::Rgb, (0.0, 2.0), 0)[0],
            [200, 100, 50, 255]
        );
        let e = colours(&b, 3, ColorBy::Elevation, (0.0, 2.0), 0);
        assert_eq!(e[0], [0, 0, 255, 255], "lowest is blue");
        assert_eq!(e[2], [255, 0, 0, 255], "highest is red");
        // Lacking the attribute: elevation.
        assert_eq!(colours(&b, 3, ColorBy::PointSource, (0.0, 2.0), 0), e);
        assert_eq!(colours(&b, 2, ColorBy::Level, (0.0, 2.0), 3).len(), 2);
        assert_eq!(
            ColorBy::parse("classification"),
            Some(ColorBy::Classification)
        );
        assert_eq!(ColorBy::parse("purple"), None);
    }

    #[test]
    fn ramps_over_any_column() {
        let schema = Schema::new(vec![Attribute::Intensity, Attribute::GpsTime]);
        let mut b = PointBatch::with_schema(&schema, 101);
        for i in 0..101 {
            b.positions.push([0.0, 0.0, i as f64]);
            b.intensity.as_mut().unwrap().push(i as u16 * 10);
            b.gps_time.as_mut().unwrap().push(1000.0 + i as f64);
        }
        let c = choose(
            "gps_time",
            Some(Gradient::Grey),
            Some([1000.0, 1100.0]),
            &schema,
            || b.clone(),
        )
        .unwrap();
        let px = colours(&b, 101, c, (0.0, 1.0), 0);
        assert_eq!(px[0], [0, 0, 0, 255]);
        assert_eq!(px[100], [255, 255, 255, 255]);
        assert!(
            px.windows(2).all(|w| w[0][0] <= w[1][0]),
            "rises with the value"
        );
        // Fitted to the sample: 2nd to 98th percentile.
        let ColorBy::Ramp(r) = choose("intensity", Some(Gradient::Viridis), None, &schema, || {
            b.clone()
        })
        .unwrap() else {
            panic!("a ramp")
        };
        assert_eq!(r.range, [20.0, 980.0]);
        assert_eq!(Gradient::Viridis.at(0.0), [68, 1, 84]);
        assert_eq!(Gradient::Viridis.at(1.0), [253, 231, 37]);
        assert_eq!(Gradient::Turbo.at(0.5), [36, 236, 166]);
        // A scheme by name stays one; an unknown name is refused, naming what there is.
        assert_eq!(
            choose("intensity", None, None, &schema, || b.clone()),
            Ok(ColorBy::Intensity)
        );
        let e = choose("amplitude", None, None, &schema, || b.clone()).unwrap_err();
        assert!(e.contains("\"amplitude\"") && e.contains("gps_time"), "{e}");
    }
}
