//! Colour schemes: what a point's colour shows.

use crate::PointBatch;

/// What a point's colour shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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

/// Colour of ASPRS class `c` (LAS 1.4 table 17 names them; the colours are the usual ones).
pub fn class_colour(c: u8) -> [u8; 3] {
    match c {
        0 => [128, 128, 128],
        1 => [170, 170, 170],
        2 => [166, 120, 72],
        3 => [144, 238, 144],
        4 => [60, 179, 113],
        5 => [0, 110, 0],
        6 => [230, 90, 60],
        7 => [255, 0, 255],
        8 => [255, 255, 0],
        9 => [40, 100, 255],
        10 => [150, 75, 0],
        11 => [90, 90, 90],
        12 => [255, 215, 0],
        13 => [255, 255, 255],
        14 => [200, 200, 200],
        15 => [255, 140, 0],
        16 => [200, 100, 200],
        17 => [140, 140, 200],
        18 => [255, 0, 0],
        c => palette(c as u32),
    }
}

/// A distinct colour for a small integer (return numbers, sources, levels).
fn palette(i: u32) -> [u8; 3] {
    const P: [[u8; 3]; 10] = [
        [230, 25, 75],
        [60, 180, 75],
        [255, 225, 25],
        [0, 130, 200],
        [245, 130, 48],
        [145, 30, 180],
        [70, 240, 240],
        [240, 50, 230],
        [210, 245, 60],
        [250, 190, 212],
    ];
    P[i as usize % P.len()]
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
            Some(c) => c[..n].iter().map(|&c| rgba(class_colour(c))).collect(),
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
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Attribute, Schema};

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
}
