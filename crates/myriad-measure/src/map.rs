//! A map beside the view: where a dataset lies on a web map of tiles (the XYZ scheme of
//! OpenStreetMap and most tile servers, Web Mercator, 256-pixel tiles; WMTS's
//! GoogleMapsCompatible tile matrix set is the same grid). A dataset's coordinates are carried to
//! the map by an affine fitted to points PROJ moved to longitude and latitude ([`Georef::fit`]):
//! over the few kilometres a scan spans, the projection's curvature is far below a map pixel,
//! and the viewers then need no PROJ for each frame (the web viewer's page none at all).

/// Web Mercator's latitude limit, degrees.
pub const MAX_LAT: f64 = 85.051_128_779_806_6;
/// Pixels a tile's side.
pub const TILE: f64 = 256.0;
/// The deepest zoom asked of a tile server.
pub const MAX_ZOOM: u32 = 22;

/// Longitude and latitude (degrees) to Web Mercator's unit square: x east from 0 at 180 W, y
/// south from 0 at the top.
pub fn to_unit(lon: f64, lat: f64) -> [f64; 2] {
    let lat = lat.clamp(-MAX_LAT, MAX_LAT).to_radians();
    [
        (lon + 180.0) / 360.0,
        (1.0 - (lat.tan() + 1.0 / lat.cos()).ln() / std::f64::consts::PI) / 2.0,
    ]
}

/// The unit square back to longitude and latitude.
pub fn from_unit(m: [f64; 2]) -> (f64, f64) {
    let lon = m[0] * 360.0 - 180.0;
    let n = std::f64::consts::PI * (1.0 - 2.0 * m[1]);
    (lon, n.sinh().atan().to_degrees())
}

/// Metres a unit of the square spans at latitude `lat` (WGS 84's equator).
pub fn metres_per_unit(lat: f64) -> f64 {
    2.0 * std::f64::consts::PI * 6_378_137.0 * lat.to_radians().cos()
}

/// The tile holding `m` at zoom `z`.
pub fn tile_of(m: [f64; 2], z: u32) -> (u32, u32) {
    let n = (1u64 << z) as f64;
    let c = |v: f64| (v * n).floor().clamp(0.0, n - 1.0) as u32;
    (c(m[0]), c(m[1]))
}

/// A tile's address from a template: `{z}`, `{x}`, `{y}` (XYZ), `{-y}` (TMS, counted from the
/// south), or WMTS's `{TileMatrix}`, `{TileCol}`, `{TileRow}`.
pub fn tile_url(template: &str, z: u32, x: u32, y: u32) -> String {
    let flipped = (1u32 << z) - 1 - y;
    template
        .replace("{z}", &z.to_string())
        .replace("{TileMatrix}", &z.to_string())
        .replace("{x}", &x.to_string())
        .replace("{TileCol}", &x.to_string())
        .replace("{-y}", &flipped.to_string())
        .replace("{y}", &y.to_string())
        .replace("{TileRow}", &y.to_string())
}

/// Whether `template` names a tile (a web address with its column, row and zoom).
pub fn check_template(template: &str) -> Result<(), String> {
    let has = |a: &str, b: &str| template.contains(a) || template.contains(b);
    if !(template.starts_with("http://") || template.starts_with("https://")) {
        return Err(format!(
            "{template}: a tile address starts with http:// or https://"
        ));
    }
    if !(has("{z}", "{TileMatrix}")
        && has("{x}", "{TileCol}")
        && (has("{y}", "{TileRow}") || template.contains("{-y}")))
    {
        return Err(format!(
            "{template}: a tile address names {{z}}, {{x}} and {{y}} (or WMTS's {{TileMatrix}}, {{TileCol}}, {{TileRow}})"
        ));
    }
    Ok(())
}

/// A dataset's plan coordinates carried to Web Mercator's unit square: an affine, fitted by
/// least squares.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Georef {
    /// unit x = a[0] + a[1] x + a[2] y; unit y = a[3] + a[4] x + a[5] y (x, y from `origin`).
    pub a: [f64; 6],
    pub origin: [f64; 2],
}

impl Georef {
    /// The affine through `pairs` of (dataset x, y) and (longitude, latitude); at least three
    /// not on a line.
    pub fn fit(pairs: &[([f64; 2], (f64, f64))]) -> Option<Georef> {
        if pairs.len() < 3 {
            return None;
        }
        let n = pairs.len() as f64;
        let origin = [
            pairs.iter().map(|p| p.0[0]).sum::<f64>() / n,
            pairs.iter().map(|p| p.0[1]).sum::<f64>() / n,
        ];
        // Normal equations of [1, x, y] against each unit coordinate.
        let mut m = [[0.0f64; 3]; 3];
        let mut r = [[0.0f64; 3]; 2];
        for (xy, (lon, lat)) in pairs {
            let v = [1.0, xy[0] - origin[0], xy[1] - origin[1]];
            let u = to_unit(*lon, *lat);
            for i in 0..3 {
                for j in 0..3 {
                    m[i][j] += v[i] * v[j];
                }
                r[0][i] += v[i] * u[0];
                r[1][i] += v[i] * u[1];
            }
        }
        let (ax, ay) = (solve3(m, r[0])?, solve3(m, r[1])?);
        let g = Georef {
            a: [ax[0], ax[1], ax[2], ay[0], ay[1], ay[2]],
            origin,
        };
        g.a.iter().all(|v| v.is_finite()).then_some(g)
    }

    /// A point of the dataset on the unit square.
    pub fn to_unit(&self, x: f64, y: f64) -> [f64; 2] {
        let (x, y) = (x - self.origin[0], y - self.origin[1]);
        let a = &self.a;
        [a[0] + a[1] * x + a[2] * y, a[3] + a[4] * x + a[5] * y]
    }

    /// A point of the unit square in the dataset's plan coordinates.
    pub fn from_unit(&self, m: [f64; 2]) -> [f64; 2] {
        let a = &self.a;
        let det = a[1] * a[5] - a[2] * a[4];
        let (u, v) = (m[0] - a[0], m[1] - a[3]);
        [
            self.origin[0] + (a[5] * u - a[2] * v) / det,
            self.origin[1] + (a[1] * v - a[4] * u) / det,
        ]
    }

    /// The angle, degrees clockwise, from the map's north to the dataset's +y (grid
    /// convergence with the map's own): where the north arrow points over the view.
    pub fn north_of_y(&self) -> f64 {
        // The dataset's +y on the map: (a[2], a[5]) in unit coordinates, y down.
        self.a[2].atan2(-self.a[5]).to_degrees()
    }
}

/// The georeference of a dataset of `bounds` through `lonlat` (a point of the dataset to
/// longitude, latitude and height, as PROJ moves it): an affine through a 5 x 5 grid of its
/// plan at mid height. `None` where a point does not move.
pub fn georef_of(
    bounds: &myriad_core::Aabb,
    mut lonlat: impl FnMut([f64; 3]) -> Option<[f64; 3]>,
) -> Option<Georef> {
    let (lo, hi) = (bounds.min, bounds.max);
    let z = (lo[2] + hi[2]) / 2.0;
    let mut pairs = Vec::with_capacity(25);
    for i in 0..5 {
        for j in 0..5 {
            let x = lo[0] + (hi[0] - lo[0]).max(1.0) * i as f64 / 4.0;
            let y = lo[1] + (hi[1] - lo[1]).max(1.0) * j as f64 / 4.0;
            let [lon, lat, _] = lonlat([x, y, z])?;
            pairs.push(([x, y], (lon, lat)));
        }
    }
    Georef::fit(&pairs)
}

fn solve3(m: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(m);
    if d.abs() < 1e-300 {
        return None;
    }
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut c = m;
        for (row, &bv) in c.iter_mut().zip(&b) {
            row[k] = bv;
        }
        *o = det(c) / d;
    }
    Some(out)
}

/// A view of the map: its centre on the unit square, its zoom, its size in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapView {
    pub centre: [f64; 2],
    pub zoom: u32,
    pub width: f64,
    pub height: f64,
}

impl MapView {
    /// The deepest zoom at which `lo`..`hi` (unit square) fits in `width` x `height` pixels
    /// with a margin.
    pub fn fitting(lo: [f64; 2], hi: [f64; 2], width: f64, height: f64) -> MapView {
        let span = ((hi[0] - lo[0]) / width)
            .max((hi[1] - lo[1]) / height)
            .max(1e-12);
        // Pixels of the whole square at zoom z: 256 * 2^z; the box in 80 % of the view.
        let z = (0.8 / (span * TILE))
            .log2()
            .floor()
            .clamp(0.0, MAX_ZOOM as f64) as u32;
        MapView {
            centre: [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0],
            zoom: z,
            width,
            height,
        }
    }

    /// Pixels of the whole unit square's side at this zoom.
    pub fn scale(&self) -> f64 {
        TILE * (1u64 << self.zoom) as f64
    }

    /// A point of the unit square in the view's pixels (from its top left).
    pub fn to_px(&self, m: [f64; 2]) -> [f64; 2] {
        let s = self.scale();
        [
            self.width / 2.0 + (m[0] - self.centre[0]) * s,
            self.height / 2.0 + (m[1] - self.centre[1]) * s,
        ]
    }

    /// A pixel of the view on the unit square.
    pub fn from_px(&self, p: [f64; 2]) -> [f64; 2] {
        let s = self.scale();
        [
            self.centre[0] + (p[0] - self.width / 2.0) / s,
            self.centre[1] + (p[1] - self.height / 2.0) / s,
        ]
    }

    /// The tiles the view shows: (x, y) at its zoom, with their top left in its pixels.
    pub fn tiles(&self) -> Vec<(u32, u32, [f64; 2])> {
        let n = 1u64 << self.zoom;
        let lo = self.from_px([0.0, 0.0]);
        let hi = self.from_px([self.width, self.height]);
        let range = |a: f64, b: f64| {
            let f = |v: f64| (v * n as f64).floor().clamp(0.0, n as f64 - 1.0) as u32;
            f(a)..=f(b)
        };
        let mut out = Vec::new();
        for y in range(lo[1], hi[1]) {
            for x in range(lo[0], hi[0]) {
                let corner = [x as f64 / n as f64, y as f64 / n as f64];
                out.push((x, y, self.to_px(corner)));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn web_mercator_and_tiles() {
        // Greenwich on the equator: the middle of the square.
        assert_eq!(to_unit(0.0, 0.0), [0.5, 0.5]);
        let (lon, lat) = from_unit(to_unit(15.0, 39.7));
        assert!((lon - 15.0).abs() < 1e-9 && (lat - 39.7).abs() < 1e-9);
        // The tile of Berlin (13.4050 E, 52.5200 N) at zoom 10: 550, 335 (OSM's wiki's formula).
        assert_eq!(tile_of(to_unit(13.405, 52.52), 10), (550, 335));
        assert_eq!(
            tile_url("https://t.example/{z}/{x}/{y}.png", 10, 550, 335),
            "https://t.example/10/550/335.png"
        );
        assert_eq!(tile_url("http://h/{z}/{x}/{-y}", 1, 0, 0), "http://h/1/0/1");
        assert!(check_template("https://t.example/{z}/{x}/{y}.png").is_ok());
        assert!(check_template("https://t.example/{z}/{x}.png").is_err());
        assert!(check_template("file:///{z}/{x}/{y}").is_err());
    }

    #[test]
    fn a_fitted_georef_goes_both_ways() {
        // A plane 1 unit = 1/1e6 of the square in x, y up is north (the square's y down).
        let pairs: Vec<([f64; 2], (f64, f64))> =
            [[0.0, 0.0], [100.0, 0.0], [0.0, 100.0], [100.0, 100.0]]
                .iter()
                .map(|&p| (p, from_unit([0.5 + p[0] * 1e-6, 0.3 - p[1] * 1e-6])))
                .collect();
        let g = Georef::fit(&pairs).unwrap();
        let m = g.to_unit(50.0, 50.0);
        assert!(
            (m[0] - 0.50005).abs() < 1e-9 && (m[1] - 0.29995).abs() < 1e-9,
            "{m:?}"
        );
        let back = g.from_unit(m);
        assert!((back[0] - 50.0).abs() < 1e-6 && (back[1] - 50.0).abs() < 1e-6);
        assert!(g.north_of_y().abs() < 1e-6);
        let v = MapView::fitting(g.to_unit(0.0, 100.0), g.to_unit(100.0, 0.0), 256.0, 256.0);
        let px = v.to_px(g.to_unit(50.0, 50.0));
        assert!((px[0] - 128.0).abs() < 1e-6 && (px[1] - 128.0).abs() < 1e-6);
        assert!(!v.tiles().is_empty());
    }
}
