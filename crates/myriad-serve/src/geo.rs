//! `GET /geo/NAME?at=X,Y,Z`: the longitude, latitude (degrees) and ellipsoidal height (metres,
//! WGS 84) of a point in the dataset's coordinates, through PROJ (`myriad_io::proj`), for the web
//! viewer's picked point: `{"lon":..,"lat":..,"h":..}`. `GET /geo/NAME?footprint`: where the
//! dataset lies on a web map (`myriad_measure::map`): the affine from its plan to Web
//! Mercator's unit square (`{"a": [6], "origin": [x, y]}`) and its bounds in plan, for the web
//! viewer's map. A malformed question: 400; a dataset without a CRS: 422; a point that does not
//! transform: 422; no PROJ on the server: 503.
//!
//! One transform per dataset, made on its first question and kept (PROJ's objects serve one
//! thread at a time: each behind a lock); questions run on the blocking pool.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

type Cached = Result<Arc<Mutex<myriad_io::proj::Geographic>>, (u16, String)>;

#[derive(Default)]
pub(crate) struct Geo {
    by_path: Mutex<HashMap<PathBuf, Cached>>,
}

/// What `/geo/` is asked.
#[derive(Debug, PartialEq)]
pub(crate) enum Question {
    /// A point's longitude, latitude and height.
    At([f64; 3]),
    /// The dataset's place on a web map.
    Footprint,
}

/// The question of a query: `at=X,Y,Z` or `footprint`.
pub(crate) fn question(query: &str) -> Result<Question, String> {
    if query.split('&').any(|kv| kv == "footprint") {
        return Ok(Question::Footprint);
    }
    parse(query).map(Question::At)
}

/// The point `at=X,Y,Z` names.
pub(crate) fn parse(query: &str) -> Result<[f64; 3], String> {
    let at = query
        .split('&')
        .find_map(|kv| kv.strip_prefix("at="))
        .ok_or("give the point as ?at=X,Y,Z")?;
    let v: Vec<f64> = at
        .split(',')
        .map(|c| c.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("at={at}: three numbers, X,Y,Z"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([x, y, z]),
        _ => Err(format!("at={at}: three finite numbers, X,Y,Z")),
    }
}

impl Geo {
    fn transform(&self, dataset: &Path) -> Cached {
        let mut m = self.by_path.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(c) = m.get(dataset) {
            return c.clone();
        }
        let made = match myriad_format::Dataset::open_stored(dataset) {
            Err(e) => Err((500, e.to_string())),
            Ok(ds) => match ds.meta.crs.clone() {
                None => Err((422, "the dataset names no coordinate system".into())),
                Some(crs) => match myriad_io::proj::Geographic::new(&crs) {
                    Ok(g) => Ok(Arc::new(Mutex::new(g))),
                    Err(e) if !myriad_io::proj::available() => Err((503, e)),
                    Err(e) => Err((422, e)),
                },
            },
        };
        m.insert(dataset.to_path_buf(), made.clone());
        made
    }

    /// The answer's status and body.
    pub(crate) fn answer(&self, dataset: &Path, q: Question) -> (u16, String) {
        let at = match q {
            Question::At(at) => at,
            Question::Footprint => return self.footprint(dataset),
        };
        match self.transform(dataset) {
            Err(e) => e,
            Ok(g) => match g.lock().unwrap_or_else(|e| e.into_inner()).of(at) {
                Some([lon, lat, h]) => (
                    200,
                    serde_json::json!({"lon": lon, "lat": lat, "h": h}).to_string(),
                ),
                None => (422, format!("{at:?} does not transform to WGS 84")),
            },
        }
    }
}

impl Geo {
    fn footprint(&self, dataset: &Path) -> (u16, String) {
        let g = match self.transform(dataset) {
            Err(e) => return e,
            Ok(g) => g,
        };
        let b = match myriad_format::Dataset::open_stored(dataset) {
            Ok(ds) => ds.meta.bounds,
            Err(e) => return (500, e.to_string()),
        };
        let mut t = g.lock().unwrap_or_else(|e| e.into_inner());
        match myriad_measure::map::georef_of(&b, |p| t.of(p)) {
            Some(r) => (
                200,
                serde_json::json!({
                    "a": r.a, "origin": r.origin,
                    "bounds": [b.min[0], b.min[1], b.max[0], b.max[1]],
                })
                .to_string(),
            ),
            None => (
                422,
                "the dataset's extent does not transform to WGS 84".into(),
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn points_are_three_finite_numbers() {
        assert_eq!(super::parse("at=1,2.5,-3").unwrap(), [1.0, 2.5, -3.0]);
        assert!(super::parse("at=1,2").is_err());
        assert!(super::parse("at=1,2,NaN").is_err());
        assert!(super::parse("x=1").unwrap_err().contains("?at="));
    }
}
