//! A polygon or a line from a file (`--polygon @area.geojson`, `--line @road.wkt`): a parcel or a
//! road from a GIS has thousands of vertices, more than a command line holds. Three forms:
//! - GeoJSON: a geometry, a Feature or a FeatureCollection holding one Polygon (or a
//!   MultiPolygon of one) or one LineString (or a MultiLineString of one); the legacy `crs`
//!   member's EPSG code is kept for the caller's check;
//! - WKT: `POLYGON ((x y, ...))`, `LINESTRING (x y, ...)`, their MULTI forms of one part, Z and
//!   M ordinates ignored, an `SRID=N;` prefix (EWKT) kept as the EPSG code;
//! - CSV or plain text: one vertex a line, x and y the first two numbers (or the columns a
//!   header names x and y, easting and northing, or lon and lat), separated by commas,
//!   semicolons, tabs or spaces; `#` comments and blank lines skipped.
//!
//! Every error is one line naming the file and where (line and column, or byte).

use myriad_core::Aabb;
use serde_json::Value;

/// What a command asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Want {
    Polygon,
    Line,
}

impl Want {
    fn name(self) -> &'static str {
        match self {
            Want::Polygon => "a polygon",
            Want::Line => "a line",
        }
    }
}

/// Vertices read from a file, and the EPSG code it names (if any).
#[derive(Debug, Clone, PartialEq)]
pub struct Shape {
    pub points: Vec<[f64; 2]>,
    pub epsg: Option<u32>,
}

/// At most this many vertices (a county's boundary has some hundreds of thousands).
pub const MAX_VERTICES: usize = 10_000_000;

/// The shape in `text` (from `name`, which names it in errors; its extension picks the form,
/// or the text's first character where it has none of .geojson, .json, .wkt, .csv, .txt).
pub fn parse(text: &str, name: &str, want: Want) -> Result<Shape, String> {
    let ext = name.rsplit_once('.').map(|(_, e)| e.to_ascii_lowercase());
    let t = text.trim_start();
    let word: String = t.chars().take_while(char::is_ascii_alphabetic).collect();
    let is_wkt = [
        "POLYGON",
        "MULTIPOLYGON",
        "LINESTRING",
        "MULTILINESTRING",
        "SRID",
    ]
    .iter()
    .any(|k| word.eq_ignore_ascii_case(k));
    let r = match ext.as_deref() {
        Some("geojson" | "json") => geojson(text, want),
        Some("wkt") => wkt(text, want),
        Some("csv" | "txt" | "xy" | "xyz") => csv(text),
        _ if t.starts_with('{') => geojson(text, want),
        _ if is_wkt => wkt(text, want),
        _ => csv(text),
    };
    let s = r.map_err(|e| format!("{name}: {e}"))?;
    if s.points.len() > MAX_VERTICES {
        return Err(format!(
            "{name}: {} vertices, more than {MAX_VERTICES}",
            s.points.len()
        ));
    }
    let least = if want == Want::Polygon { 3 } else { 2 };
    if s.points.len() < least {
        return Err(format!(
            "{name}: {} vertices; {} needs at least {least}",
            s.points.len(),
            want.name()
        ));
    }
    Ok(s)
}

/// Whether every vertex lies near the data (within its own size around its box): a file in
/// other coordinates (longitude and latitude, another projection, feet for metres) is named
/// even where the two CRSs cannot be compared by EPSG code.
pub fn near_the_data(points: impl IntoIterator<Item = [f64; 2]>, b: &Aabb) -> Result<(), String> {
    let s = b.size();
    let margin = s[0].max(s[1]).max(s[2]).max(1.0);
    for p in points {
        if (0..2).any(|i| p[i] < b.min[i] - margin || p[i] > b.max[i] + margin) {
            return Err(format!(
                "its point {:.3}, {:.3} lies far outside the dataset ({:.3}, {:.3} to {:.3}, {:.3}): \
                 another coordinate system? reproject it first",
                p[0], p[1], b.min[0], b.min[1], b.max[0], b.max[1]
            ));
        }
    }
    Ok(())
}

/// The EPSG code of a name such as `urn:ogc:def:crs:EPSG::2994` or `EPSG:2994`.
fn epsg_of(name: &str) -> Option<u32> {
    let i = name.to_ascii_uppercase().rfind("EPSG:")?;
    name[i + 5..].trim_start_matches(':').trim().parse().ok()
}

fn geojson(text: &str, want: Want) -> Result<Shape, String> {
    let v: Value = serde_json::from_str(text)
        .map_err(|e| format!("line {} column {}: {e}", e.line(), e.column()))?;
    let epsg = v["crs"]["properties"]["name"].as_str().and_then(epsg_of);
    let mut parts: Vec<Vec<[f64; 2]>> = Vec::new();
    let mut others = Vec::new();
    collect(&v, want, &mut parts, &mut others)?;
    match parts.len() {
        1 => Ok(Shape {
            points: parts.pop().expect("one"),
            epsg,
        }),
        0 if others.is_empty() => Err(format!("no geometry; {} is needed", want.name())),
        0 => Err(format!("a {}, not {}", others.join(", a "), want.name())),
        n => Err(format!("{n} parts; one is needed (split the file)")),
    }
}

fn collect(
    v: &Value,
    want: Want,
    parts: &mut Vec<Vec<[f64; 2]>>,
    others: &mut Vec<String>,
) -> Result<(), String> {
    let ty = v["type"].as_str().unwrap_or("");
    let c = &v["coordinates"];
    match (ty, want) {
        ("FeatureCollection", _) => {
            for f in v["features"]
                .as_array()
                .ok_or("a FeatureCollection without features")?
            {
                collect(f, want, parts, others)?;
            }
        }
        ("Feature", _) => {
            if !v["geometry"].is_null() {
                collect(&v["geometry"], want, parts, others)?;
            }
        }
        ("GeometryCollection", _) => {
            for g in v["geometries"]
                .as_array()
                .ok_or("a GeometryCollection without geometries")?
            {
                collect(g, want, parts, others)?;
            }
        }
        ("Polygon", Want::Polygon) => parts.push(polygon_rings(c)?),
        ("MultiPolygon", Want::Polygon) => {
            for p in c.as_array().ok_or("a MultiPolygon without coordinates")? {
                parts.push(polygon_rings(p)?);
            }
        }
        ("LineString", Want::Line) => parts.push(positions(c)?),
        ("MultiLineString", Want::Line) => {
            for l in c
                .as_array()
                .ok_or("a MultiLineString without coordinates")?
            {
                parts.push(positions(l)?);
            }
        }
        ("", _) => return Err("not GeoJSON (no \"type\")".into()),
        (t, _) => others.push(t.to_string()),
    }
    Ok(())
}

/// A Polygon's outer ring; holes are refused (a volume's footprint has one ring).
fn polygon_rings(c: &Value) -> Result<Vec<[f64; 2]>, String> {
    let rings = c.as_array().ok_or("a Polygon without coordinates")?;
    match rings.len() {
        0 => Err("a Polygon without rings".into()),
        1 => positions(&rings[0]),
        n => Err(format!(
            "a Polygon with {} hole{}; one ring is needed",
            n - 1,
            if n == 2 { "" } else { "s" }
        )),
    }
}

fn positions(c: &Value) -> Result<Vec<[f64; 2]>, String> {
    let a = c.as_array().ok_or("coordinates that are not a list")?;
    a.iter()
        .enumerate()
        .map(|(i, p)| {
            let x = p[0].as_f64().filter(|v| v.is_finite());
            let y = p[1].as_f64().filter(|v| v.is_finite());
            match (x, y) {
                (Some(x), Some(y)) => Ok([x, y]),
                _ => Err(format!("position {} is not two finite numbers: {p}", i + 1)),
            }
        })
        .collect()
}

/// WKT as nested lists of coordinate tuples.
enum Node {
    List(Vec<Node>, usize),
    Tuple(Vec<f64>),
}

struct Wkt<'a> {
    s: &'a [u8],
    at: usize,
}

impl Wkt<'_> {
    fn skip(&mut self) {
        while self.at < self.s.len() && self.s[self.at].is_ascii_whitespace() {
            self.at += 1;
        }
    }

    fn word(&mut self) -> String {
        self.skip();
        let start = self.at;
        while self.at < self.s.len() && self.s[self.at].is_ascii_alphabetic() {
            self.at += 1;
        }
        String::from_utf8_lossy(&self.s[start..self.at]).to_ascii_uppercase()
    }

    fn list(&mut self, depth: usize) -> Result<Node, String> {
        self.skip();
        let open = self.at;
        if self.s.get(self.at) != Some(&b'(') {
            return Err(format!("byte {}: \"(\" expected", self.at));
        }
        if depth > 4 {
            return Err(format!("byte {}: lists nested too deep", self.at));
        }
        self.at += 1;
        let mut items = Vec::new();
        loop {
            self.skip();
            items.push(if self.s.get(self.at) == Some(&b'(') {
                self.list(depth + 1)?
            } else {
                self.tuple()?
            });
            self.skip();
            match self.s.get(self.at) {
                Some(b',') => self.at += 1,
                Some(b')') => {
                    self.at += 1;
                    return Ok(Node::List(items, open));
                }
                _ => return Err(format!("byte {}: \",\" or \")\" expected", self.at)),
            }
        }
    }

    fn tuple(&mut self) -> Result<Node, String> {
        let mut v = Vec::new();
        loop {
            self.skip();
            let start = self.at;
            while self.at < self.s.len()
                && (self.s[self.at].is_ascii_alphanumeric() || b"+-.".contains(&self.s[self.at]))
            {
                self.at += 1;
            }
            if start == self.at {
                break;
            }
            let t = String::from_utf8_lossy(&self.s[start..self.at]);
            match t.parse::<f64>() {
                Ok(x) if x.is_finite() => v.push(x),
                _ => return Err(format!("byte {start}: \"{t}\" is not a finite number")),
            }
        }
        if v.len() < 2 {
            return Err(format!("byte {}: a vertex needs x and y", self.at));
        }
        Ok(Node::Tuple(v))
    }
}

fn wkt(text: &str, want: Want) -> Result<Shape, String> {
    let mut p = Wkt {
        s: text.as_bytes(),
        at: 0,
    };
    let mut epsg = None;
    let t = text.trim_start();
    if t.get(..5).is_some_and(|h| h.eq_ignore_ascii_case("SRID=")) {
        let semi = t.find(';').ok_or("SRID= without \";\"")?;
        let code = t.get(5..semi).unwrap_or("");
        epsg = Some(
            code.trim()
                .parse::<u32>()
                .map_err(|_| format!("SRID \"{code}\" is not a number"))?,
        );
        p.at = text.len() - t.len() + semi + 1;
    }
    let kind = p.word();
    let mut dims = p.word();
    if !dims.is_empty() && !matches!(dims.as_str(), "Z" | "M" | "ZM") {
        return Err(format!("\"{kind} {dims}\": not WKT"));
    }
    dims.clear();
    let node = p.list(0)?;
    p.skip();
    if p.at < text.len() {
        return Err(format!("byte {}: text after the geometry", p.at));
    }
    let ring = |n: &Node| -> Result<Vec<[f64; 2]>, String> {
        match n {
            Node::List(items, at) => items
                .iter()
                .map(|i| match i {
                    Node::Tuple(v) => Ok([v[0], v[1]]),
                    Node::List(_, a) => Err(format!("byte {a}: a vertex expected")),
                })
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| format!("{e} (list at byte {at})")),
            Node::Tuple(_) => Err("a list of vertices expected".into()),
        }
    };
    let one = |items: &[Node], what: &str| -> Result<usize, String> {
        match items.len() {
            1 => Ok(0),
            0 => Err(format!("an empty {what}")),
            n => Err(format!(
                "a {what} of {n} parts; one is needed (split the file)"
            )),
        }
    };
    let points = match (kind.as_str(), want, &node) {
        ("POLYGON", Want::Polygon, Node::List(rings, _)) => {
            if rings.len() > 1 {
                return Err(format!(
                    "a POLYGON with {} hole(s); one ring is needed",
                    rings.len() - 1
                ));
            }
            ring(&rings[0])?
        }
        ("MULTIPOLYGON", Want::Polygon, Node::List(polys, _)) => {
            let k = one(polys, "MULTIPOLYGON")?;
            match &polys[k] {
                Node::List(rings, _) if rings.len() == 1 => ring(&rings[0])?,
                Node::List(rings, _) => {
                    return Err(format!(
                        "a POLYGON with {} hole(s); one ring is needed",
                        rings.len().saturating_sub(1)
                    ));
                }
                Node::Tuple(_) => return Err("a MULTIPOLYGON of vertices".into()),
            }
        }
        ("LINESTRING", Want::Line, n) => ring(n)?,
        ("MULTILINESTRING", Want::Line, Node::List(lines, _)) => {
            let k = one(lines, "MULTILINESTRING")?;
            ring(&lines[k])?
        }
        (k, w, _) => return Err(format!("a WKT {k}, not {}", w.name())),
    };
    Ok(Shape { points, epsg })
}

fn csv(text: &str) -> Result<Shape, String> {
    let split = |l: &str| -> Vec<String> {
        l.split([',', ';', '\t', ' '])
            .map(|t| t.trim().trim_matches('"').to_string())
            .filter(|t| !t.is_empty())
            .collect()
    };
    let mut cols = (0, 1);
    let mut points = Vec::new();
    let mut header_seen = false;
    for (n, line) in text.lines().enumerate() {
        let l = line.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let f = split(l);
        let nums: Vec<Option<f64>> = f.iter().map(|t| t.parse::<f64>().ok()).collect();
        if !header_seen && points.is_empty() && nums.iter().any(|v| v.is_none()) {
            // A header: the columns it names x and y, else the first two.
            header_seen = true;
            let find = |names: &[&str]| {
                f.iter()
                    .position(|t| names.iter().any(|n| t.eq_ignore_ascii_case(n)))
            };
            if let (Some(x), Some(y)) = (
                find(&["x", "easting", "east", "lon", "longitude"]),
                find(&["y", "northing", "north", "lat", "latitude"]),
            ) {
                cols = (x, y);
            }
            continue;
        }
        let get = |i: usize| nums.get(i).copied().flatten().filter(|v| v.is_finite());
        match (get(cols.0), get(cols.1)) {
            (Some(x), Some(y)) => points.push([x, y]),
            _ => {
                return Err(format!(
                    "line {}: \"{}\": x and y expected (columns {} and {})",
                    n + 1,
                    l.chars().take(60).collect::<String>(),
                    cols.0 + 1,
                    cols.1 + 1
                ));
            }
        }
        if points.len() > MAX_VERTICES {
            break;
        }
    }
    Ok(Shape { points, epsg: None })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_three_forms_give_the_same_vertices() {
        let sq = vec![
            [0.0, 0.0],
            [10.0, 0.0],
            [10.0, 10.0],
            [0.0, 10.0],
            [0.0, 0.0],
        ];
        let gj = r#"{"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"urn:ogc:def:crs:EPSG::2994"}},
            "features":[{"type":"Feature","properties":{},"geometry":{"type":"Polygon","coordinates":[[[0,0],[10,0],[10,10],[0,10],[0,0]]]}}]}"#;
        let s = parse(gj, "a.geojson", Want::Polygon).unwrap();
        assert_eq!((s.points.clone(), s.epsg), (sq.clone(), Some(2994)));
        let w = parse(
            "SRID=2994;POLYGON Z ((0 0 1, 10 0 1, 10 10 2, 0 10 2, 0 0 1))",
            "a.wkt",
            Want::Polygon,
        )
        .unwrap();
        assert_eq!((w.points, w.epsg), (sq.clone(), Some(2994)));
        let m = parse(
            "MULTIPOLYGON (((0 0, 10 0, 10 10, 0 10, 0 0)))",
            "a",
            Want::Polygon,
        )
        .unwrap();
        assert_eq!(m.points, sq);
        let c = parse(
            "id;easting;northing\n1;0;0\n2;10;0\n\n# c\n3;10;10\n4;0;10\n5;0;0\n",
            "a.csv",
            Want::Polygon,
        )
        .unwrap();
        assert_eq!(c.points, sq);
        let plain = parse("0 0\n10 0\n10 10\n0 10\n0 0\n", "area.txt", Want::Polygon).unwrap();
        assert_eq!(plain.points, sq);
        let l = parse("LINESTRING (1 2, 3 4.5)", "road", Want::Line).unwrap();
        assert_eq!(l.points, vec![[1.0, 2.0], [3.0, 4.5]]);
    }

    #[test]
    fn bad_files_say_where_in_one_line() {
        let e = |t: &str, n: &str, w| parse(t, n, w).unwrap_err();
        assert!(
            e("{\"type\": ", "a.geojson", Want::Polygon).starts_with("a.geojson: line 1 column")
        );
        assert!(e("x,y\n1,2\n3,zz\n", "a.csv", Want::Line).contains("a.csv: line 3:"));
        let w = e("POLYGON ((0 0, 1 0, 1 1 0 0)", "a.wkt", Want::Polygon);
        assert!(w.starts_with("a.wkt: byte 28:"), "{w}");
        assert!(
            e("POLYGON ((0 0, 1 nan, 1 1, 0 0))", "a.wkt", Want::Polygon).contains("not a finite")
        );
        assert!(e("LINESTRING (0 0, 1 1)", "a.wkt", Want::Polygon).contains("not a polygon"));
        assert!(
            e(
                "POLYGON ((0 0, 9 0, 9 9, 0 0), (1 1, 2 1, 2 2, 1 1))",
                "a.wkt",
                Want::Polygon
            )
            .contains("1 hole")
        );
        let two = r#"{"type":"MultiLineString","coordinates":[[[0,0],[1,1]],[[2,2],[3,3]]]}"#;
        assert!(e(two, "r.json", Want::Line).contains("2 parts"));
        let pt = r#"{"type":"Point","coordinates":[0,0]}"#;
        assert!(e(pt, "p.geojson", Want::Line).contains("a Point, not a line"));
        assert!(e("1,2\n", "a.csv", Want::Line).contains("1 vertices"));
        assert!(e("POLYGON ((((((((0 0))))))))", "deep.wkt", Want::Polygon).contains("too deep"));
        for bad in [
            "",
            "POLYGON",
            "POLYGON (",
            "SRID=x;POLYGON ((0 0,1 1,1 0,0 0))",
            "\u{0}\u{ff}",
        ] {
            assert!(parse(bad, "f.wkt", Want::Polygon).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn far_points_are_named() {
        let b = Aabb::new([1000.0, 2000.0, 0.0], [1100.0, 2100.0, 10.0]);
        assert!(near_the_data([[1050.0, 2050.0], [950.0, 2190.0]], &b).is_ok());
        let e = near_the_data([[-122.6, 45.5]], &b).unwrap_err();
        assert!(e.contains("-122.600, 45.500 lies far outside"), "{e}");
    }
}
