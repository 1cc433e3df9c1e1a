//! Measurements on picked points, in the dataset's units or converted for display: a point,
//! a distance along a polyline (with its segments), a height between two points, an area as
//! seen from above (its projection on the horizontal plane, as surveyors give a parcel's area),
//! the angle at the middle of three points, the circle through three points, and an azimuth
//! (the bearing of the second point from the first, clockwise from grid north). A CRS's length
//! unit is read by [`crate::crs`] ([`metres_per_unit`], kept here under its old path too).

pub use crate::crs::metres_per_unit;
use crate::crs::unit_name;

/// What a measurement measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Point,
    Distance,
    Height,
    Area,
    Angle,
    Circle,
    Azimuth,
}

impl Kind {
    pub const ALL: [Kind; 7] = [
        Kind::Point,
        Kind::Distance,
        Kind::Height,
        Kind::Area,
        Kind::Angle,
        Kind::Circle,
        Kind::Azimuth,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Kind::Point => "point",
            Kind::Distance => "distance",
            Kind::Height => "height",
            Kind::Area => "area",
            Kind::Angle => "angle",
            Kind::Circle => "circle",
            Kind::Azimuth => "azimuth",
        }
    }

    /// Points it takes; `None`: as many as clicked (a polyline, a polygon).
    pub fn points(self) -> Option<usize> {
        match self {
            Kind::Point => Some(1),
            Kind::Height | Kind::Azimuth => Some(2),
            Kind::Angle | Kind::Circle => Some(3),
            Kind::Distance | Kind::Area => None,
        }
    }
}

/// Units lengths are shown in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Units {
    /// Those of the dataset's coordinates, unconverted.
    Data,
    Metres,
    /// International feet (0.3048 m).
    Feet,
    /// US survey feet (1200/3937 m).
    UsFeet,
}

impl Units {
    /// Metres per unit (`None` for the data's own).
    pub fn metres(self) -> Option<f64> {
        match self {
            Units::Data => None,
            Units::Metres => Some(1.0),
            Units::Feet => Some(0.3048),
            Units::UsFeet => Some(1200.0 / 3937.0),
        }
    }

    pub fn suffix(self) -> &'static str {
        match self {
            Units::Data => "",
            Units::Metres => " m",
            Units::Feet => " ft",
            Units::UsFeet => " US ft",
        }
    }
}

/// The name of the unit of a CRS's coordinates ([`unit_name`] of [`metres_per_unit`]).
pub fn crs_units(crs: Option<&str>) -> &'static str {
    unit_name(crs.and_then(metres_per_unit))
}

/// The ellipsoid a geographic CRS measures on (longitude, latitude in degrees as x, y): its
/// semi-major axis and flattening from the WKT's SPHEROID or ELLIPSOID, WGS 84's where it names
/// none. `None` for any other CRS, whose lengths are straight lines in its own units.
pub fn earth(crs: Option<&str>) -> Option<(f64, f64)> {
    let crs = crs?;
    if crate::crs::describe(crs).kind != "geographic" {
        return None;
    }
    let wgs84 = (6_378_137.0, 1.0 / 298.257_223_563);
    let found = ["SPHEROID[", "ELLIPSOID["].iter().find_map(|k| {
        let rest = &crs[crs.find(k)? + k.len()..];
        let mut parts = rest
            .split(',')
            .skip(1)
            .map(|v| v.trim().trim_end_matches(']'));
        let a: f64 = parts.next()?.parse().ok()?;
        let inv_f: f64 = parts.next()?.parse().ok()?;
        (a > 6e6 && a < 7e6).then_some((a, if inv_f > 0.0 { 1.0 / inv_f } else { 0.0 }))
    });
    Some(found.unwrap_or(wgs84))
}

#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    pub kind: Kind,
    pub points: Vec<[f64; 3]>,
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The circle through three points: its centre, radius and the normal of its plane; `None`
/// when they are on one line.
pub fn circle(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> Option<([f64; 3], f64, [f64; 3])> {
    // Relative to `a` (large coordinates).
    let (u, v) = (sub(b, a), sub(c, a));
    let n = cross(u, v);
    let nn = dot(n, n);
    if nn <= 1e-18 * dot(u, u) * dot(v, v) {
        return None;
    }
    // centre - a = (|u|² (v × n) + |v|² (n × u)) / (2 |n|²)
    let (vn, nu) = (cross(v, n), cross(n, u));
    let (uu, vv) = (dot(u, u), dot(v, v));
    let o: [f64; 3] = std::array::from_fn(|k| (uu * vn[k] + vv * nu[k]) / (2.0 * nn));
    let centre = [a[0] + o[0], a[1] + o[1], a[2] + o[2]];
    let len = nn.sqrt();
    Some((centre, dot(o, o).sqrt(), n.map(|x| x / len)))
}

impl Measurement {
    pub fn new(kind: Kind) -> Measurement {
        Measurement {
            kind,
            points: Vec::new(),
        }
    }

    /// Adds a point; a measurement of a fixed count of points starts over from the point past
    /// it.
    pub fn add(&mut self, p: [f64; 3]) {
        if self.kind.points().is_some_and(|n| self.points.len() >= n) {
            self.points.clear();
        }
        self.points.push(p);
    }

    /// Whether it has every point it takes (a polyline: two, a polygon: three, at least).
    pub fn complete(&self) -> bool {
        let n = self.points.len();
        match self.kind.points() {
            Some(k) => n == k,
            None => n >= if self.kind == Kind::Area { 3 } else { 2 },
        }
    }

    /// Length of each segment (for a polygon, the closing one too).
    pub fn segments(&self) -> Vec<f64> {
        let mut s: Vec<f64> = self.points.windows(2).map(|w| dist(w[0], w[1])).collect();
        if self.kind == Kind::Area && self.points.len() >= 3 {
            s.push(dist(self.points[self.points.len() - 1], self.points[0]));
        }
        s
    }

    /// The figure, in the data's units: total length, height difference (second minus
    /// first), area, angle (degrees), circle radius, azimuth (degrees), or a point's height.
    pub fn value(&self) -> Option<f64> {
        if !self.complete() {
            return None;
        }
        let p = &self.points;
        Some(match self.kind {
            Kind::Point => p[0][2],
            Kind::Distance => self.segments().iter().sum(),
            Kind::Height => p[1][2] - p[0][2],
            Kind::Area => {
                // Shoelace on x, y, relative to the first point (large coordinates).
                let o = p[0];
                let mut twice = 0.0;
                for i in 0..p.len() {
                    let a = p[i];
                    let b = p[(i + 1) % p.len()];
                    twice += (a[0] - o[0]) * (b[1] - o[1]) - (b[0] - o[0]) * (a[1] - o[1]);
                }
                twice.abs() / 2.0
            }
            Kind::Angle => {
                let (u, v) = (sub(p[0], p[1]), sub(p[2], p[1]));
                let c = dot(u, v) / (dot(u, u) * dot(v, v)).sqrt();
                c.clamp(-1.0, 1.0).acos().to_degrees()
            }
            Kind::Circle => circle(p[0], p[1], p[2])?.1,
            Kind::Azimuth => {
                let (dx, dy) = (p[1][0] - p[0][0], p[1][1] - p[0][1]);
                (dx.atan2(dy).to_degrees() + 360.0) % 360.0
            }
        })
    }

    /// Segment lengths in metres along the ellipsoid `earth` (x, y longitude and latitude in
    /// degrees, z heights in metres): the geodesic's length with the height difference.
    pub fn segments_on(&self, earth: (f64, f64)) -> Vec<f64> {
        use geographiclib_rs::{Geodesic, InverseGeodesic};
        let g = Geodesic::new(earth.0, earth.1);
        let len = |a: [f64; 3], b: [f64; 3]| {
            let s: f64 = g.inverse(a[1], a[0], b[1], b[0]);
            (s * s + (b[2] - a[2]).powi(2)).sqrt()
        };
        let p = &self.points;
        let mut s: Vec<f64> = p.windows(2).map(|w| len(w[0], w[1])).collect();
        if self.kind == Kind::Area && p.len() >= 3 {
            s.push(len(p[p.len() - 1], p[0]));
        }
        s
    }

    /// The figure on the ellipsoid `earth` (a geographic CRS): lengths in metres along
    /// geodesics, areas in square metres on the ellipsoid, azimuths the geodesic's at the first
    /// point; angles and circles in the plane tangent at the first point.
    pub fn value_on(&self, earth: (f64, f64)) -> Option<f64> {
        use geographiclib_rs::{Geodesic, InverseGeodesic, PolygonArea, Winding};
        if !self.complete() {
            return None;
        }
        let g = Geodesic::new(earth.0, earth.1);
        let p = &self.points;
        Some(match self.kind {
            Kind::Distance => self.segments_on(earth).iter().sum(),
            Kind::Area => {
                let mut a = PolygonArea::new(&g, Winding::CounterClockwise);
                for q in p {
                    a.add_point(q[1], q[0]);
                }
                a.compute(false).1.abs()
            }
            Kind::Azimuth => {
                let (azi1, _, _): (f64, f64, f64) = g.inverse(p[0][1], p[0][0], p[1][1], p[1][0]);
                (azi1 + 360.0) % 360.0
            }
            Kind::Angle | Kind::Circle => self.tangent(earth).value()?,
            Kind::Point | Kind::Height => self.value()?,
        })
    }

    /// The points in metres in the plane tangent to the ellipsoid at the first point (east,
    /// north, up): for angles and circles, which are local.
    fn tangent(&self, earth: (f64, f64)) -> Measurement {
        let o = self.points.first().copied().unwrap_or_default();
        let (a, f) = earth;
        let e2 = f * (2.0 - f);
        let lat = o[1].to_radians();
        let w = (1.0 - e2 * lat.sin().powi(2)).sqrt();
        let (north, east) = (a * (1.0 - e2) / w.powi(3), a / w * lat.cos());
        Measurement {
            kind: self.kind,
            points: self
                .points
                .iter()
                .map(|q| {
                    [
                        (q[0] - o[0]).to_radians() * east,
                        (q[1] - o[1]).to_radians() * north,
                        q[2] - o[2],
                    ]
                })
                .collect(),
        }
    }

    /// The label of a measurement in a geographic CRS (`earth`, see [`earth`]): lengths in
    /// metres, or in `units` where it names a unit; a point as its longitude and latitude.
    pub fn label_on(&self, units: Units, earth: (f64, f64)) -> Option<String> {
        let v = self.value_on(earth)?;
        let (to, suffix) = match units.metres() {
            Some(m) => (m, units.suffix()),
            None => (1.0, " m"),
        };
        Some(match self.kind {
            Kind::Distance => format!("{:.3}{suffix}", v / to),
            Kind::Area => format!("{:.2}{suffix}² area", v / to / to),
            Kind::Azimuth => format!("{v:.2}° from north"),
            Kind::Angle => format!("{v:.2}°"),
            Kind::Circle => {
                let p = &self.points;
                let (c, _, _) = circle(p[0], p[1], p[2])?;
                format!(
                    "radius {:.3}{suffix}, centre {:.8}°, {:.8}°",
                    v / to,
                    c[0],
                    c[1]
                )
            }
            Kind::Point => {
                let p = self.points[0];
                format!("{:.8}°, {:.8}°, {:.3}{suffix}", p[0], p[1], p[2] / to)
            }
            Kind::Height => format!("{:+.3}{suffix} height", v / to),
        })
    }

    /// The label in whichever way the CRS measures: on the ellipsoid `earth` where it is
    /// geographic, else straight, `data_metres` per unit.
    pub fn label_for(
        &self,
        units: Units,
        data_metres: Option<f64>,
        earth: Option<(f64, f64)>,
    ) -> Option<String> {
        match earth {
            Some(e) => self.label_on(units, e),
            None => self.label(units, data_metres),
        }
    }

    /// The figure as a label, lengths in `units` (`data_metres`: metres per unit of the
    /// dataset's coordinates, when its CRS says; lengths stay as they are without).
    pub fn label(&self, units: Units, data_metres: Option<f64>) -> Option<String> {
        let v = self.value()?;
        let scale = match (units.metres(), data_metres) {
            (Some(to), Some(from)) => Some(from / to),
            _ => None,
        };
        let suffix = if scale.is_some() { units.suffix() } else { "" };
        let len = |x: f64| format!("{:.3}{suffix}", x * scale.unwrap_or(1.0));
        Some(match self.kind {
            Kind::Point => {
                let p = self.points[0];
                format!("{:.3}, {:.3}, {}", p[0], p[1], len(p[2]))
            }
            Kind::Distance => len(v),
            Kind::Height => format!("{:+.3}{suffix} height", v * scale.unwrap_or(1.0)),
            Kind::Area => {
                let s = scale.unwrap_or(1.0);
                let sq = if scale.is_some() { "²" } else { "" };
                format!("{:.2}{suffix}{sq} area", v * s * s)
            }
            Kind::Angle => format!("{v:.2}°"),
            Kind::Circle => {
                let (c, _, _) = circle(self.points[0], self.points[1], self.points[2])?;
                format!(
                    "radius {}, centre {:.3}, {:.3}, {:.3}",
                    len(v),
                    c[0],
                    c[1],
                    c[2]
                )
            }
            Kind::Azimuth => format!("{v:.2}° from north"),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geodesic_figures_in_a_geographic_crs() {
        let wgs84 = r#"GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]]"#;
        let e = earth(Some(wgs84)).unwrap();
        assert_eq!(e, (6_378_137.0, 1.0 / 298.257223563));
        assert_eq!(earth(Some("EPSG:32633")), None);
        assert_eq!(earth(None), None);
        // A degree of latitude at the equator: 110,574.389 m on WGS 84 (GeographicLib).
        let mut d = Measurement::new(Kind::Distance);
        d.add([15.0, 0.0, 0.0]);
        d.add([15.0, 1.0, 0.0]);
        assert!(
            (d.value_on(e).unwrap() - 110_574.389).abs() < 1e-3,
            "{:?}",
            d.value_on(e)
        );
        assert_eq!(d.label_on(Units::Data, e).unwrap(), "110574.389 m");
        // Due east along the equator: azimuth 90; a 0.01-degree square near 45 N: its area.
        let mut z = Measurement::new(Kind::Azimuth);
        z.add([0.0, 0.0, 0.0]);
        z.add([1.0, 0.0, 0.0]);
        assert!((z.value_on(e).unwrap() - 90.0).abs() < 1e-9);
        let mut a = Measurement::new(Kind::Area);
        for p in [[10.0, 45.0], [10.01, 45.0], [10.01, 45.01], [10.0, 45.01]] {
            a.add([p[0], p[1], 0.0]);
        }
        let area = a.value_on(e).unwrap();
        // 787.8 m east by 1111.4 m north, about.
        assert!((area - 787.8 * 1111.4).abs() < 0.002 * area, "{area}");
        let mut r = Measurement::new(Kind::Angle);
        for p in [[10.01, 45.0], [10.0, 45.0], [10.0, 45.01]] {
            r.add([p[0], p[1], 0.0]);
        }
        assert!((r.value_on(e).unwrap() - 90.0).abs() < 0.01);
    }

    #[test]
    fn distance_height_and_area() {
        let mut d = Measurement::new(Kind::Distance);
        assert_eq!(d.value(), None);
        d.add([500000.0, 4400000.0, 10.0]);
        d.add([500003.0, 4400004.0, 10.0]);
        d.add([500003.0, 4400004.0, 22.0]);
        assert_eq!(d.segments(), vec![5.0, 12.0]);
        assert_eq!(d.value(), Some(17.0));

        let mut h = Measurement::new(Kind::Height);
        h.add([0.0, 0.0, 100.0]);
        assert_eq!(h.value(), None);
        h.add([30.0, 40.0, 92.5]);
        assert_eq!(h.value(), Some(-7.5));
        // A third point starts a new height.
        h.add([0.0, 0.0, 1.0]);
        assert_eq!(h.points.len(), 1);

        // A 1524 m (5000 ft) square tile seen from above, corners at different heights.
        let mut a = Measurement::new(Kind::Area);
        for (x, y, z) in [(0.0, 0.0, 5.0), (1524.0, 0.0, 9.0), (1524.0, 1524.0, 1.0)] {
            a.add([5170845.0 + x, 3964547.0 + y, z]);
        }
        assert!((a.value().unwrap() - 1524.0 * 1524.0 / 2.0).abs() < 1e-3);
        a.add([5170845.0, 3964547.0 + 1524.0, 3.0]);
        assert!((a.value().unwrap() - 1524.0 * 1524.0).abs() < 1e-3);
        assert_eq!(a.segments().len(), 4, "closed");
        // In feet, from metres: 1524 m is 5000 ft.
        let l = a.label(Units::Feet, Some(1.0)).unwrap();
        assert_eq!(l, "25000000.00 ft² area");
    }

    #[test]
    fn angle_circle_azimuth_and_units() {
        let mut g = Measurement::new(Kind::Angle);
        for p in [
            [500010.0, 4400000.0, 3.0],
            [500000.0, 4400000.0, 3.0],
            [500000.0, 4400010.0, 3.0],
        ] {
            g.add(p);
        }
        assert!((g.value().unwrap() - 90.0).abs() < 1e-9);
        // Three points of a circle of radius 5 about (500100, 4400100, 20), tilted.
        let c = [500100.0, 4400100.0, 20.0];
        let on = |t: f64| {
            [
                c[0] + 5.0 * t.cos(),
                c[1] + 5.0 * t.sin() * 0.6,
                c[2] + 5.0 * t.sin() * 0.8,
            ]
        };
        let (centre, r, n) = circle(on(0.1), on(1.7), on(4.0)).unwrap();
        assert!((r - 5.0).abs() < 1e-9 && (0..3).all(|k| (centre[k] - c[k]).abs() < 1e-7));
        assert!((n[0].abs()) < 1e-9 && (n[1].abs() - 0.8).abs() < 1e-9);
        assert!(circle([0.0; 3], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]).is_none());
        let mut z = Measurement::new(Kind::Azimuth);
        z.add([10.0, 10.0, 0.0]);
        z.add([0.0, 10.0, 5.0]);
        assert!((z.value().unwrap() - 270.0).abs() < 1e-9, "west");
        z.add([0.0, 0.0, 0.0]);
        z.add([1.0, 1.0, 0.0]);
        assert!((z.value().unwrap() - 45.0).abs() < 1e-9);
        // 100 US survey feet of data in metres and international feet.
        let mut d = Measurement::new(Kind::Distance);
        d.add([0.0; 3]);
        d.add([100.0, 0.0, 0.0]);
        let us = 1200.0 / 3937.0;
        assert_eq!(d.label(Units::Metres, Some(us)).unwrap(), "30.480 m");
        assert_eq!(d.label(Units::Feet, Some(us)).unwrap(), "100.000 ft");
        assert_eq!(d.label(Units::Data, Some(us)).unwrap(), "100.000");
        assert_eq!(
            d.label(Units::Metres, None).unwrap(),
            "100.000",
            "unknown units: unconverted"
        );
    }
}
