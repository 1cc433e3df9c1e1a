//! Class scheme files (`--classes-scheme FILE`, and the `"classes"` of a dataset's saved work):
//! the classes whose name, colour or visibility differ from the ASPRS table's, by number:
//!
//! ```json
//! {"classes": {
//!   "2": {"name": "terrain", "colour": "#8b5a2b"},
//!   "7": {"hidden": false},
//!   "64": {"name": "solar panels", "colour": [20, 60, 220], "hidden": true}
//! }}
//! ```
//!
//! Each member is optional (`color` is read as `colour`); a colour is `#RRGGBB` or three numbers
//! from 0 to 255. Classes not named keep the default's name, colour and visibility.

use myriad_core::classes::Scheme;
use serde_json::{Map, Value, json};

/// The most bytes a scheme file may have (256 classes with long names fit many times).
pub const MAX_BYTES: usize = 1 << 20;

/// A scheme from a file's text; an error names the line (broken JSON) or the member.
pub fn parse(text: &str) -> Result<Scheme, String> {
    if text.len() > MAX_BYTES {
        return Err(format!("larger than {MAX_BYTES} bytes: not a class scheme"));
    }
    let v: Value = serde_json::from_str(text)
        .map_err(|e| format!("line {} column {}: {e}", e.line(), e.column()))?;
    match v.get("classes") {
        Some(c) if v.is_object() => from_json(c),
        _ => Err("not a class scheme (no \"classes\" object)".into()),
    }
}

/// A scheme from the `"classes"` object (class number to its entry).
pub fn from_json(v: &Value) -> Result<Scheme, String> {
    let o = v
        .as_object()
        .ok_or_else(|| "classes: not an object of class numbers".to_string())?;
    let mut s = Scheme::asprs();
    for (k, e) in o {
        let c: u8 = k
            .trim()
            .parse()
            .map_err(|_| format!("classes.{k}: not a class number (0 to 255)"))?;
        let at = |m: &str| format!("classes.{k}.{m}");
        let e = e
            .as_object()
            .ok_or_else(|| format!("classes.{k}: not an object"))?;
        for (m, x) in e {
            match m.as_str() {
                "name" => {
                    let n = x
                        .as_str()
                        .filter(|n| !n.trim().is_empty() && n.len() <= 200)
                        .ok_or_else(|| format!("{}: a name of 1 to 200 bytes", at(m)))?;
                    s.names[c as usize] = n.trim().to_string();
                }
                "colour" | "color" => s.colours[c as usize] = colour(x).map_err(|e| at(m) + e)?,
                "hidden" => {
                    s.hidden[c as usize] = x
                        .as_bool()
                        .ok_or_else(|| format!("{}: true or false", at(m)))?
                }
                _ => {
                    return Err(format!(
                        "{}: unknown (name, colour and hidden are read)",
                        at(m)
                    ));
                }
            }
        }
    }
    Ok(s)
}

fn colour(v: &Value) -> Result<[u8; 3], &'static str> {
    const WHAT: &str = ": a colour is \"#RRGGBB\" or [R, G, B] from 0 to 255";
    match v {
        Value::String(h) => {
            let h = h.trim().strip_prefix('#').ok_or(WHAT)?;
            let byte = |i: usize| {
                h.get(i..i + 2)
                    .and_then(|b| u8::from_str_radix(b, 16).ok())
                    .ok_or(WHAT)
            };
            if h.len() != 6 {
                return Err(WHAT);
            }
            Ok([byte(0)?, byte(2)?, byte(4)?])
        }
        Value::Array(a) if a.len() == 3 => {
            let mut c = [0u8; 3];
            for (o, x) in c.iter_mut().zip(a) {
                *o = x.as_u64().filter(|&x| x <= 255).ok_or(WHAT)? as u8;
            }
            Ok(c)
        }
        _ => Err(WHAT),
    }
}

/// The `"classes"` object of `s`: the classes that differ from the default, each whole.
pub fn to_json(s: &Scheme) -> Value {
    let mut o = Map::new();
    for c in s.changed() {
        let [r, g, b] = s.colour(c);
        o.insert(
            c.to_string(),
            json!({"name": s.name(c), "colour": format!("#{r:02x}{g:02x}{b:02x}"), "hidden": s.is_hidden(c)}),
        );
    }
    Value::Object(o)
}

/// Every class of `s` with its name, colour and visibility: what a viewer's legend lists.
pub fn table(s: &Scheme) -> Value {
    Value::Array(
        (0..=255u8)
            .map(|c| json!({"class": c, "name": s.name(c), "colour": s.colour(c), "hidden": s.is_hidden(c)}))
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scheme_changes_only_the_classes_it_names() {
        let s = parse(
            r##"{"classes": {"2": {"name": "terrain", "colour": "#102030"},
                 "7": {"hidden": false}, "64": {"name": "panels", "color": [1, 2, 3], "hidden": true}}}"##,
        )
        .unwrap();
        assert_eq!(s.name(2), "terrain");
        assert_eq!(s.colour(2), [16, 32, 48]);
        assert_eq!(s.name(6), "building");
        assert_eq!(s.hidden_classes(), vec![18, 64]);
        assert_eq!(s.colour(64), [1, 2, 3]);
        assert_eq!(s.changed(), vec![2, 7, 64]);
        // Written and read back: the same scheme.
        let again = from_json(&to_json(&s)).unwrap();
        assert_eq!(again, s);
        for (bad, says) in [
            (
                r#"{"classes": {"300": {}}}"#,
                "classes.300: not a class number",
            ),
            (
                r##"{"classes": {"2": {"colour": "#12345"}}}"##,
                "classes.2.colour: a colour",
            ),
            (
                r#"{"classes": {"2": {"colour": [1, 2, 256]}}}"#,
                "classes.2.colour",
            ),
            (
                r##"{"classes": {"2": {"colr": "#123456"}}}"##,
                "classes.2.colr: unknown",
            ),
            (
                r#"{"classes": {"2": {"hidden": 1}}}"#,
                "classes.2.hidden: true or false",
            ),
            (r#"{"classes": {"2": {"name": ""}}}"#, "classes.2.name"),
            ("{\"classes\":\n {", "line 2"),
            (r#"{"class": {}}"#, "not a class scheme"),
        ] {
            let e = parse(bad).unwrap_err();
            assert!(e.starts_with(says), "{bad}: {e}");
        }
    }
}
