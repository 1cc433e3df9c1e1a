//! Camera paths: views (an eye and a target) at times, flown through by a curve that passes
//! through each view at its time (Catmull-Rom, the ends held), for `render --path` and both
//! viewers. Kept with a dataset's saved work (`"paths"`), or alone in a file:
//!
//! ```json
//! {"myriad": "path", "name": "along the river",
//!  "views": [{"position": [x, y, z], "target": [x, y, z], "time": 0},
//!            {"position": [x, y, z], "target": [x, y, z], "time": 4.5}]}
//! ```
//!
//! A view without `"time"` comes [`GAP`] seconds after the one before it.

use serde_json::{Value, json};

/// The largest coordinate saved work holds (a billion kilometres, or feet): past any projected or
/// geocentric system, and small enough that distances, areas and a camera's direction between
/// two such points stay finite.
pub const MAX_COORD: f64 = 1e12;
/// The most bytes a path file may have.
pub const MAX_BYTES: usize = 4 << 20;
/// The longest name of a path.
pub const MAX_NAME: usize = 200;

/// A camera: where it is and what it looks at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    pub position: [f64; 3],
    pub target: [f64; 3],
}

/// Seconds between views whose time is not given (and between views a viewer records).
pub const GAP: f64 = 2.0;
/// Most views of a path.
pub const MAX_VIEWS: usize = 10_000;
/// The longest path, in seconds (a day).
pub const MAX_SECONDS: f64 = 86_400.0;

/// One view of a path and the time it is reached, in seconds from the start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Key {
    pub view: View,
    pub time: f64,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct CameraPath {
    pub name: String,
    pub keys: Vec<Key>,
}

impl CameraPath {
    /// Seconds from the first view to the last.
    pub fn duration(&self) -> f64 {
        match (self.keys.first(), self.keys.last()) {
            (Some(a), Some(b)) => b.time - a.time,
            _ => 0.0,
        }
    }

    /// Adds `view` [`GAP`] seconds after the last (at 0 first).
    pub fn push(&mut self, view: View) {
        let time = self.keys.last().map_or(0.0, |k| k.time + GAP);
        self.keys.push(Key { view, time });
    }

    /// The view at `t` seconds from the start (held before the first and after the last).
    pub fn at(&self, t: f64) -> View {
        let k = &self.keys;
        assert!(!k.is_empty(), "a path of no views");
        let t = k[0].time + t;
        if k.len() == 1 || t <= k[0].time {
            return k[0].view;
        }
        let last = k.len() - 1;
        if t >= k[last].time {
            return k[last].view;
        }
        let i = k.partition_point(|key| key.time <= t) - 1;
        let u = (t - k[i].time) / (k[i + 1].time - k[i].time);
        let get = |j: isize| k[j.clamp(0, last as isize) as usize].view;
        let (p0, p1, p2, p3) = (
            get(i as isize - 1),
            k[i].view,
            k[i + 1].view,
            get(i as isize + 2),
        );
        View {
            position: catmull_rom(p0.position, p1.position, p2.position, p3.position, u),
            target: catmull_rom(p0.target, p1.target, p2.target, p3.target, u),
        }
    }

    /// The views of frames `fps` a second from the first view to the last, both included.
    pub fn frames(&self, fps: f64) -> Vec<View> {
        let n = (self.duration() * fps + 1e-9).floor() as usize + 1;
        (0..n).map(|i| self.at(i as f64 / fps)).collect()
    }

    pub fn to_json(&self) -> Value {
        json!({
            "name": self.name,
            "views": self.keys.iter().map(|k| json!({
                "position": k.view.position, "target": k.view.target, "time": k.time,
            })).collect::<Vec<_>>(),
        })
    }

    /// The path as a file of its own.
    pub fn to_file(&self) -> String {
        let mut v = self.to_json();
        v["myriad"] = json!("path");
        format!("{v:#}\n")
    }

    /// A path from a file's text; an error names the line or the member.
    pub fn parse(text: &str) -> Result<CameraPath, String> {
        if text.len() > MAX_BYTES {
            return Err(format!(
                "larger than {} bytes: not a camera path",
                MAX_BYTES
            ));
        }
        let v: Value = serde_json::from_str(text)
            .map_err(|e| format!("line {} column {}: {e}", e.line(), e.column()))?;
        if v.get("views").is_none() {
            return Err("not a camera path (no \"views\" list)".into());
        }
        CameraPath::from_json(&v, "")
    }

    /// A path from its JSON, `at` naming it in errors (`paths[2].`).
    pub fn from_json(v: &Value, at: &str) -> Result<CameraPath, String> {
        let name = match v.get("name") {
            None => String::new(),
            Some(Value::String(s)) if s.len() <= MAX_NAME => s.clone(),
            Some(_) => return Err(format!("{at}name: a text of at most 200 bytes")),
        };
        let views = v
            .get("views")
            .and_then(Value::as_array)
            .ok_or_else(|| format!("{at}views: not a list"))?;
        if views.is_empty() || views.len() > MAX_VIEWS {
            return Err(format!("{at}views: 1 to {MAX_VIEWS} views"));
        }
        let mut path = CameraPath {
            name,
            keys: Vec::with_capacity(views.len()),
        };
        for (i, k) in views.iter().enumerate() {
            let at = format!("{at}views[{i}]");
            let xyz = |m: &str| -> Result<[f64; 3], String> {
                let a = k.get(m).and_then(Value::as_array);
                let p: Option<Vec<f64>> = a.map(|a| a.iter().filter_map(Value::as_f64).collect());
                match p {
                    Some(p) if p.len() == 3 && p.iter().all(|x| x.abs() <= MAX_COORD) => {
                        Ok([p[0], p[1], p[2]])
                    }
                    _ => Err(format!("{at}.{m}: three numbers of at most 1e12")),
                }
            };
            let view = View {
                position: xyz("position")?,
                target: xyz("target")?,
            };
            if view.position == view.target {
                return Err(format!("{at}: its target is its position"));
            }
            let after = path.keys.last().map(|k| k.time);
            let time = match k.get("time") {
                None => after.map_or(0.0, |t| t + GAP),
                Some(t) => t
                    .as_f64()
                    .filter(|t| (0.0..=MAX_SECONDS).contains(t))
                    .ok_or_else(|| format!("{at}.time: seconds from 0 to {MAX_SECONDS}"))?,
            };
            if after.is_some_and(|a| time <= a) {
                return Err(format!(
                    "{at}.time: {time} s is not after the view before it"
                ));
            }
            path.keys.push(Key { view, time });
        }
        if path.duration() > MAX_SECONDS {
            return Err(format!("{at}views: longer than {MAX_SECONDS} s"));
        }
        Ok(path)
    }
}

fn catmull_rom(p0: [f64; 3], p1: [f64; 3], p2: [f64; 3], p3: [f64; 3], u: f64) -> [f64; 3] {
    let (u2, u3) = (u * u, u * u * u);
    std::array::from_fn(|i| {
        0.5 * (2.0 * p1[i]
            + (p2[i] - p0[i]) * u
            + (2.0 * p0[i] - 5.0 * p1[i] + 4.0 * p2[i] - p3[i]) * u2
            + (3.0 * p1[i] - p0[i] - 3.0 * p2[i] + p3[i]) * u3)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64) -> View {
        View {
            position: [x, 0.0, 10.0],
            target: [x, 10.0, 0.0],
        }
    }

    #[test]
    fn a_path_passes_through_its_views_at_their_times() {
        let mut p = CameraPath::default();
        for x in [0.0, 10.0, 30.0] {
            p.push(v(x));
        }
        assert_eq!(p.duration(), 4.0);
        assert_eq!(p.at(0.0), v(0.0));
        assert_eq!(p.at(2.0), v(10.0));
        assert_eq!(p.at(4.0), v(30.0));
        assert_eq!(p.at(9.0), v(30.0));
        let mid = p.at(1.0).position[0];
        assert!(mid > 0.0 && mid < 10.0, "{mid}");
        let f = p.frames(30.0);
        assert_eq!(f.len(), 121);
        assert_eq!(f[60], v(10.0));
        let back = CameraPath::parse(&p.to_file()).unwrap();
        assert_eq!(back, p);
        for (bad, says) in [
            (r#"{"views": []}"#, "views: 1 to"),
            (
                r#"{"views": [{"position": [0,0,0], "target": [0,0,1]}, {"position": [0,0,0], "target": [0,0,1], "time": 0}]}"#,
                "views[1].time: 0 s is not after",
            ),
            (
                r#"{"views": [{"position": [0,0], "target": [0,0,1]}]}"#,
                "views[0].position",
            ),
            (
                r#"{"views": [{"position": [0,0,1], "target": [0,0,1]}]}"#,
                "views[0]: its target",
            ),
            (r#"{"path": 1}"#, "not a camera path"),
        ] {
            let e = CameraPath::parse(bad).unwrap_err();
            assert!(e.starts_with(says), "{bad}: {e}");
        }
    }
}
