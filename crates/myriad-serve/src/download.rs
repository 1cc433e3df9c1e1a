//! `GET /x/NAME?box=MINX,MINY,MINZ,MAXX,MAXY,MAXZ[&spacing=S]`: the original points of a served
//! dataset inside a box (at a level of detail), as a LAZ file in the input's point format, made
//! by `extract` on a blocking thread into a temporary file in the server's scratch folder that
//! is unlinked once open and streamed from there. At most [`MAX_AT_ONCE`] run at a time; the
//! others wait. A box of more than `Limits::max_points` points is refused (413), and an
//! extraction whose client has left stops at its next node.

use myriad_build::extract::{CANCELLED, ExtractOptions, TOO_MANY_POINTS, extract_within};
use myriad_core::Aabb;
use myriad_format::Dataset;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

pub const MAX_AT_ONCE: usize = 2;

/// What a download asks for, from the query string.
#[derive(Debug, Clone, PartialEq)]
pub struct Query {
    pub bbox: Aabb,
    pub spacing: Option<f64>,
}

/// Parses `box=...&spacing=...` (values percent-decoded); the error is the answer's text.
pub fn parse_query(q: &str) -> Result<Query, String> {
    let mut bbox = None;
    let mut spacing = None;
    for pair in q.split('&').filter(|p| !p.is_empty()) {
        let (k, v) = pair.split_once('=').unwrap_or((pair, ""));
        let v = crate::percent_decode(v).ok_or("malformed query")?;
        match k {
            "box" => {
                let n: Vec<f64> = v
                    .split(',')
                    .map(|t| t.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| format!("box \"{v}\": expected six numbers"))?;
                if n.len() != 6 || n.iter().any(|x| !x.is_finite()) {
                    return Err(format!("box \"{v}\": expected six finite numbers"));
                }
                if (0..3).any(|a| n[a] > n[a + 3]) {
                    return Err(format!("box \"{v}\": a minimum is above its maximum"));
                }
                bbox = Some(Aabb::new([n[0], n[1], n[2]], [n[3], n[4], n[5]]));
            }
            "spacing" => {
                let s: f64 = v
                    .parse()
                    .map_err(|_| format!("spacing \"{v}\": not a number"))?;
                if !(s.is_finite() && s > 0.0) {
                    return Err(format!("spacing \"{v}\": must be positive"));
                }
                spacing = Some(s);
            }
            other => return Err(format!("unknown parameter \"{other}\"")),
        }
    }
    Ok(Query {
        bbox: bbox.ok_or("a box is needed: ?box=minx,miny,minz,maxx,maxy,maxz")?,
        spacing,
    })
}

/// Where a download is made and how large it may be.
pub struct Limits {
    pub max_points: u64,
    pub scratch: PathBuf,
}

/// Why a download was not made.
#[derive(Debug, PartialEq)]
pub enum Failed {
    /// More points than `Limits::max_points` (the answer's text).
    TooLarge(String),
    /// The client left.
    Cancelled,
    Other(String),
}

/// Extracts into a temporary file, opens it and unlinks it: the open file and its points.
pub fn run(
    dataset: &Path,
    q: &Query,
    limits: &Limits,
    cancelled: &dyn Fn() -> bool,
) -> Result<(std::fs::File, u64), Failed> {
    static SERIAL: AtomicU64 = AtomicU64::new(0);
    let tmp: PathBuf = limits.scratch.join(format!(
        "box-{}.laz",
        SERIAL.fetch_add(1, Ordering::Relaxed)
    ));
    let ds = Dataset::open(dataset).map_err(|e| Failed::Other(e.to_string()))?;
    let o = ExtractOptions {
        bbox: Some(q.bbox),
        spacing: q.spacing,
        force: true,
        ..Default::default()
    };
    let summary = extract_within(&ds, &tmp, &o, limits.max_points, cancelled).map_err(|e| {
        let m = e.to_string();
        if m.contains(CANCELLED) {
            Failed::Cancelled
        } else if m.contains(TOO_MANY_POINTS) {
            Failed::TooLarge(m)
        } else {
            Failed::Other(m)
        }
    });
    let file = std::fs::File::open(&tmp).map_err(|e| Failed::Other(e.to_string()));
    let _ = std::fs::remove_file(&tmp);
    let summary = summary?;
    Ok((file?, summary.points))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn queries() {
        let q = parse_query("box=-1,-2,-3,4,5,6&spacing=0.5").unwrap();
        assert_eq!(q.bbox, Aabb::new([-1.0, -2.0, -3.0], [4.0, 5.0, 6.0]));
        assert_eq!(q.spacing, Some(0.5));
        assert_eq!(
            parse_query("box=0%2C0%2C0%2C1%2C1%2C1").unwrap().bbox,
            Aabb::new([0.0; 3], [1.0; 3])
        );
        for bad in [
            "",
            "spacing=1",
            "box=1,2,3",
            "box=1,1,1,0,0,0",
            "box=0,0,0,1,1,nan",
            "box=0,0,0,1,1,1&spacing=-1",
            "box=0,0,0,1,1,1&x=1",
            "box=%zz",
        ] {
            assert!(parse_query(bad).is_err(), "{bad}");
        }
    }
}
