//! Measurements in world units (002 section 3.4): the length of a polyline, the height between
//! two points, the area of a polygon as seen from above (its projection on the horizontal plane,
//! as surveyors give a parcel's area).

/// What a measurement measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Distance,
    Height,
    Area,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    pub kind: Kind,
    pub points: Vec<[f64; 3]>,
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

impl Measurement {
    pub fn new(kind: Kind) -> Measurement {
        Measurement {
            kind,
            points: Vec::new(),
        }
    }

    /// Adds a point; a height takes two (a third starts over from it).
    pub fn add(&mut self, p: [f64; 3]) {
        if self.kind == Kind::Height && self.points.len() == 2 {
            self.points.clear();
        }
        self.points.push(p);
    }

    /// Length of each segment (for a polygon, the closing one too).
    pub fn segments(&self) -> Vec<f64> {
        let mut s: Vec<f64> = self.points.windows(2).map(|w| dist(w[0], w[1])).collect();
        if self.kind == Kind::Area && self.points.len() >= 3 {
            s.push(dist(self.points[self.points.len() - 1], self.points[0]));
        }
        s
    }

    /// The figure: total length, height difference (second minus first) or area.
    pub fn value(&self) -> Option<f64> {
        let p = &self.points;
        match self.kind {
            Kind::Distance => (p.len() >= 2).then(|| self.segments().iter().sum()),
            Kind::Height => (p.len() == 2).then(|| p[1][2] - p[0][2]),
            Kind::Area => (p.len() >= 3).then(|| {
                // Shoelace on x, y, relative to the first point (large coordinates).
                let o = p[0];
                let mut twice = 0.0;
                for i in 0..p.len() {
                    let a = p[i];
                    let b = p[(i + 1) % p.len()];
                    twice += (a[0] - o[0]) * (b[1] - o[1]) - (b[0] - o[0]) * (a[1] - o[1]);
                }
                twice.abs() / 2.0
            }),
        }
    }

    /// The figure as a label: "12.345 m", "3.210 m up", "1,234.5 m²" (units as the data's).
    pub fn label(&self) -> Option<String> {
        let v = self.value()?;
        Some(match self.kind {
            Kind::Distance => format!("{v:.3}"),
            Kind::Height => format!("{:+.3} height", v),
            Kind::Area => format!("{v:.2} area"),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    }
}
