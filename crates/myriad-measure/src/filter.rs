//! Filters: which points a command or a view keeps, by ASPRS class and by ranges of any
//! attribute (extra-bytes dimensions included). A filter never changes a dataset: it is applied
//! to the points read, so the level of detail is drawn from the points kept.
//!
//! Syntax, as `--classes` and `--where` take it:
//! - classes: numbers or names, separated by commas: `2,6`, `ground,building`, `2-6`;
//! - conditions: `NAME OP VALUE` with `<`, `<=`, `>`, `>=`, `=` (or `==`) and `!=`, or
//!   `NAME=LOW..HIGH` (both ends kept); several separated by commas or ` and `, all must hold:
//!   `intensity>100`, `return_number=1`, `gps_time=1000..2000, z>=120`. Names are the
//!   dataset's attribute names (`myriad info` lists them), `x`, `y`, `z`, `red`, `green`,
//!   `blue`, or an extra-bytes dimension's name.

use myriad_core::{Attribute, Column, PointBatch, Schema};

pub use myriad_core::classes::ASPRS_NAMES as CLASS_NAMES;

/// The name of class `c` in the class scheme in force (the ASPRS table's by default).
pub fn class_name(c: u8) -> String {
    myriad_core::classes::current().name(c).to_string()
}

/// A class given by name: its number (spaces, dashes and underscores alike; the names of the
/// scheme in force, the ASPRS table's, and a few of the usual short names).
fn class_by_name(name: &str) -> Option<u8> {
    let norm = |s: &str| s.to_ascii_lowercase().replace(['-', '_'], " ");
    let n = norm(name);
    let alias = match n.as_str() {
        "noise" => Some(7),
        "road" => Some(11),
        "vegetation" => Some(5),
        "bridge" => Some(17),
        _ => None,
    };
    let scheme = myriad_core::classes::current();
    (scheme.names.iter().position(|c| norm(c) == n))
        .or_else(|| CLASS_NAMES.iter().position(|c| norm(c) == n))
        .map(|i| i as u8)
        .or(alias)
}

/// A comparison.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Op {
    Lt,
    Le,
    Gt,
    Ge,
    Eq,
    Ne,
    /// Between two values, both kept.
    Within(f64),
}

/// One condition on one attribute: `name op value`.
#[derive(Debug, Clone, PartialEq)]
pub struct Condition {
    pub name: String,
    pub op: Op,
    pub value: f64,
}

impl Condition {
    fn holds(&self, v: f64) -> bool {
        match self.op {
            Op::Lt => v < self.value,
            Op::Le => v <= self.value,
            Op::Gt => v > self.value,
            Op::Ge => v >= self.value,
            Op::Eq => v == self.value,
            Op::Ne => v != self.value,
            Op::Within(hi) => self.value <= v && v <= hi,
        }
    }
}

/// What to keep: a set of classes (all when `None`) and conditions that must all hold.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Filter {
    pub classes: Option<Vec<u8>>,
    pub conditions: Vec<Condition>,
}

fn number(s: &str, what: &str) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("\"{}\": {what} is not a number", s.trim()))
}

impl Filter {
    /// Keeps everything.
    pub fn all() -> Filter {
        Filter::default()
    }

    pub fn is_all(&self) -> bool {
        self.classes.is_none() && self.conditions.is_empty()
    }

    /// `--classes` as a user writes it: `2,6`, `ground,building`, `3-5`.
    pub fn parse_classes(s: &str) -> Result<Vec<u8>, String> {
        let mut out = Vec::new();
        for t in s.split(',').map(str::trim) {
            if t.is_empty() {
                return Err(format!("\"{s}\": an empty class in the list"));
            }
            let one = |t: &str| -> Result<u8, String> {
                match t.parse::<u32>() {
                    Ok(v) if v <= 255 => Ok(v as u8),
                    Ok(v) => Err(format!("class {v}: classes go from 0 to 255")),
                    Err(_) => class_by_name(t).ok_or_else(|| {
                        format!(
                            "\"{t}\": no such class (numbers 0-255, or one of: {})",
                            CLASS_NAMES.join(", ")
                        )
                    }),
                }
            };
            match t.split_once('-') {
                Some((a, b)) if a.trim().parse::<u32>().is_ok() => {
                    let (a, b) = (one(a.trim())?, one(b.trim())?);
                    if a > b {
                        return Err(format!("\"{t}\": the range runs backwards"));
                    }
                    out.extend(a..=b);
                }
                _ => out.push(one(t)?),
            }
        }
        out.sort_unstable();
        out.dedup();
        Ok(out)
    }

    /// One `--where` text: conditions separated by commas or ` and `.
    pub fn parse_where(s: &str) -> Result<Vec<Condition>, String> {
        let text = s
            .replace(" and ", ",")
            .replace(" AND ", ",")
            .replace("&&", ",");
        let mut out = Vec::new();
        for t in text.split(',').map(str::trim) {
            if t.is_empty() {
                return Err(format!("\"{s}\": an empty condition"));
            }
            let ops = ["<=", ">=", "!=", "==", "<", ">", "="];
            let Some((at, op)) = ops
                .iter()
                .filter_map(|op| t.find(op).map(|i| (i, *op)))
                .min_by_key(|(i, op)| (*i, std::cmp::Reverse(op.len())))
            else {
                return Err(format!(
                    "\"{t}\": expected NAME OP VALUE (OP one of < <= > >= = !=) or NAME=LOW..HIGH"
                ));
            };
            let name = t[..at].trim().to_ascii_lowercase();
            let rest = t[at + op.len()..].trim();
            if name.is_empty() {
                return Err(format!("\"{t}\": no attribute name before {op}"));
            }
            let (op, value) = match op {
                "=" | "==" if rest.contains("..") => {
                    let (lo, hi) = rest.split_once("..").expect("checked");
                    let (lo, hi) = (number(lo, "the low end")?, number(hi, "the high end")?);
                    if lo > hi {
                        return Err(format!("\"{t}\": the range runs backwards"));
                    }
                    (Op::Within(hi), lo)
                }
                "<" => (Op::Lt, number(rest, "the value")?),
                "<=" => (Op::Le, number(rest, "the value")?),
                ">" => (Op::Gt, number(rest, "the value")?),
                ">=" => (Op::Ge, number(rest, "the value")?),
                "!=" => (Op::Ne, number(rest, "the value")?),
                _ => (Op::Eq, number(rest, "the value")?),
            };
            out.push(Condition { name, op, value });
        }
        Ok(out)
    }

    /// A filter from the command line's `--classes` and `--where` values.
    pub fn parse(classes: Option<&str>, wheres: &[String]) -> Result<Filter, String> {
        let mut f = Filter {
            classes: classes.map(Filter::parse_classes).transpose()?,
            conditions: Vec::new(),
        };
        for w in wheres {
            f.conditions.extend(Filter::parse_where(w)?);
        }
        Ok(f)
    }

    /// The filter against a dataset's attributes: an attribute the dataset lacks is an error
    /// naming it and listing those it has.
    /// This filter for a dataset of `schema`: its classes left out where the dataset has no
    /// classification (a class scheme's hidden classes hide nothing there).
    pub fn for_schema(&self, schema: &Schema) -> Filter {
        let mut f = self.clone();
        if !schema.has(&Attribute::Classification) {
            f.classes = None;
        }
        f
    }

    /// This filter keeping no point of a class `scheme` hides, where it names no classes and
    /// the dataset of `schema` has them.
    pub fn hiding(&self, scheme: &myriad_core::classes::Scheme, schema: &Schema) -> Filter {
        let mut f = self.clone();
        if f.classes.is_none()
            && schema.has(&Attribute::Classification)
            && !scheme.hidden_classes().is_empty()
        {
            f.classes = Some((0..=255u8).filter(|&c| !scheme.is_hidden(c)).collect());
        }
        f
    }

    pub fn bind(&self, schema: &Schema) -> Result<Bound, String> {
        let names = || {
            let mut n = vec!["x".to_string(), "y".into(), "z".into()];
            n.extend(schema.attributes.iter().map(|a| match a {
                Attribute::Extra(d) => d.name.to_ascii_lowercase(),
                a => a.name(),
            }));
            n.join(", ")
        };
        if self.classes.is_some() && !schema.has(&Attribute::Classification) {
            return Err(format!(
                "--classes: this dataset has no classification (it has: {})",
                names()
            ));
        }
        let mut fields = Vec::new();
        for c in &self.conditions {
            let field = Column::find(&c.name, schema).ok_or_else(|| {
                format!(
                    "--where: this dataset has no attribute \"{}\" (it has: {})",
                    c.name,
                    names()
                )
            })?;
            fields.push((field, c.clone()));
        }
        let mut classes = None;
        if let Some(list) = &self.classes {
            let mut set = [false; 256];
            for &c in list {
                set[c as usize] = true;
            }
            classes = Some(set);
        }
        Ok(Bound { classes, fields })
    }
}

/// A [`Filter`] resolved against one dataset's columns.
#[derive(Debug, Clone)]
pub struct Bound {
    classes: Option<[bool; 256]>,
    fields: Vec<(Column, Condition)>,
}

impl Bound {
    /// Keeps everything.
    pub fn all() -> Bound {
        Bound {
            classes: None,
            fields: Vec::new(),
        }
    }

    pub fn is_all(&self) -> bool {
        self.classes.is_none() && self.fields.is_empty()
    }

    /// Whether point `i` of `b` is kept (a point whose batch lacks a column is not).
    pub fn keeps(&self, b: &PointBatch, i: usize) -> bool {
        if let Some(set) = &self.classes {
            match &b.classification {
                Some(c) if set[c[i] as usize] => {}
                _ => return false,
            }
        }
        self.fields.iter().all(|(f, c)| c.holds(f.value(b, i)))
    }

    /// One flag per point of `b`.
    pub fn mask(&self, b: &PointBatch) -> Vec<bool> {
        (0..b.len()).map(|i| self.keeps(b, i)).collect()
    }

    /// Drops the points the filter does not keep.
    pub fn retain(&self, b: &mut PointBatch) {
        if !self.is_all() {
            let keep = self.mask(b);
            b.retain_mask(&keep);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use myriad_core::{ExtraDim, ExtraType};

    fn batch() -> PointBatch {
        let schema = Schema::new(vec![Attribute::Intensity, Attribute::Classification]);
        let mut b = PointBatch::with_schema(&schema, 4);
        for (i, (int, class)) in [(10u16, 2u8), (200, 2), (150, 6), (5, 9)]
            .iter()
            .enumerate()
        {
            b.positions.push([i as f64, 0.0, i as f64 * 10.0]);
            b.intensity.as_mut().unwrap().push(*int);
            b.classification.as_mut().unwrap().push(*class);
        }
        b
    }

    #[test]
    fn classes_by_number_name_and_range() {
        assert_eq!(Filter::parse_classes("2,6").unwrap(), vec![2, 6]);
        assert_eq!(
            Filter::parse_classes("ground, Building,high-vegetation").unwrap(),
            vec![2, 5, 6]
        );
        assert_eq!(Filter::parse_classes("3-5,2").unwrap(), vec![2, 3, 4, 5]);
        let e = Filter::parse_classes("2,grond").unwrap_err();
        assert!(e.starts_with("\"grond\": no such class"), "{e}");
        assert!(Filter::parse_classes("300").unwrap_err().contains("300"));
        assert!(Filter::parse_classes("2,,3").is_err());
    }

    #[test]
    fn conditions_parse_and_hold() {
        let b = batch();
        let keep = |c: Option<&str>, w: &[&str]| {
            let w: Vec<String> = w.iter().map(|s| s.to_string()).collect();
            let f = Filter::parse(c, &w).unwrap();
            f.bind(&b.schema()).unwrap().mask(&b)
        };
        assert_eq!(keep(None, &["intensity>100"]), [false, true, true, false]);
        assert_eq!(
            keep(None, &["intensity >= 10 and z<25"]),
            [true, true, true, false]
        );
        assert_eq!(
            keep(Some("2"), &["intensity=5..150"]),
            [true, false, false, false]
        );
        assert_eq!(
            keep(None, &["classification!=2"]),
            [false, false, true, true]
        );
        assert_eq!(keep(Some("ground,water"), &[]), [true, true, false, true]);
        assert_eq!(keep(None, &[]), [true; 4]);
    }

    #[test]
    fn bad_conditions_name_the_value() {
        let e = Filter::parse_where("intensity~3").unwrap_err();
        assert!(
            e.starts_with("\"intensity~3\": expected NAME OP VALUE"),
            "{e}"
        );
        let e = Filter::parse_where("gps_time=5..1").unwrap_err();
        assert!(e.contains("backwards"), "{e}");
        let e = Filter::parse_where("intensity>lots").unwrap_err();
        assert!(e.starts_with("\"lots\""), "{e}");
        let f = Filter::parse(None, &["amplitude>3".into()]).unwrap();
        let e = f.bind(&batch().schema()).unwrap_err();
        assert!(
            e.contains("no attribute \"amplitude\"") && e.contains("intensity"),
            "{e}"
        );
        let f = Filter::parse(Some("2"), &[]).unwrap();
        assert!(f.bind(&Schema::new(vec![])).is_err());
    }

    #[test]
    fn extra_bytes_conditions() {
        let d = ExtraDim {
            name: "Amplitude".into(),
            data_type: ExtraType::U16,
            offset: 1,
            description: String::new(),
            scale: Some(0.5),
            add_offset: None,
        };
        let schema = Schema {
            attributes: vec![Attribute::Extra(d)],
            extra_bytes: 3,
        };
        let mut b = PointBatch::with_schema(&schema, 2);
        b.positions = vec![[0.0; 3], [1.0; 3]];
        b.extra_bytes = Some(vec![0, 10, 0, 0, 100, 0]);
        b.extra_stride = 3;
        let f = Filter::parse(None, &["amplitude>=20".into()]).unwrap();
        assert_eq!(f.bind(&schema).unwrap().mask(&b), [false, true]);
    }
}
