//! `GET /x/NAME?box=MINX,MINY,MINZ,MAXX,MAXY,MAXZ[&spacing=S][&hide=6,7][&where=CONDITIONS]`, or
//! `?line=X1,Y1,X2,Y2[,...]&width=W`: the original points of a served dataset inside a box (at a
//! level of detail) or a cross-section's corridor (a profile's points, as `myriad profile` cuts
//! them), but for the hidden classes and the points that fail the conditions (`--where`'s
//! syntax), as a LAZ file in the input's point format, made
//! by `extract` on a blocking thread into a temporary file in the server's scratch folder that
//! is unlinked once open and streamed from there. At most [`MAX_AT_ONCE`] run at a time; the
//! others wait. A box of more than `Limits::max_points` points is refused (413), and an
//! extraction whose client has left stops at its next node.

use myriad_build::extract::{CANCELLED, ExtractOptions, TOO_MANY_POINTS, extract_within};
use myriad_core::Aabb;
use myriad_format::Dataset;
use myriad_measure::{Corridor, Filter};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

pub const MAX_AT_ONCE: usize = 2;

/// Lowers the calling thread's priority for work a client asks for that may take seconds of a
/// core, on Linux (threads have priorities of their own there): the idle policy (`SCHED_IDLE`: it
/// runs only where no other thread waits, and a core running it counts as free when a range
/// reader's thread wakes), else nice 19.
pub fn background_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: sched_setscheduler and setpriority read only the parameter we pass; on Linux a
    // pid or `who` of 0 is the calling thread.
    unsafe {
        let param = libc::sched_param { sched_priority: 0 };
        if libc::sched_setscheduler(0, libc::SCHED_IDLE, &param) != 0 {
            libc::setpriority(libc::PRIO_PROCESS, 0, 19);
        }
    }
}

/// Waits while another thread of this server, not a download's, is running or ready to run
/// (serving the ranges viewers read), checked every 5 ms, until `given_up` or for `most` in all: the idle policy
/// alone still cost range readers 5 % of their requests and a third more p99 on 2 cores (as much
/// as two idle-class busy loops do); a node not started while they work costs them nothing. Not
/// on Linux: returns at once.
pub fn yield_while_busy(most: std::time::Duration, given_up: &dyn Fn() -> bool) {
    let start = std::time::Instant::now();
    while start.elapsed() < most && !given_up() && others_running() {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

/// Whether a thread of this process other than the caller and the downloads' (named
/// `myriad-extract`) is running or ready to run.
fn others_running() -> bool {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: gettid takes nothing and cannot fail.
        let me = unsafe { libc::gettid() }.to_string();
        let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
            return false;
        };
        // Another download's thread is not the server's work: two would hold each other back.
        tasks.flatten().any(|t| {
            t.file_name().to_str() != Some(me.as_str())
                && std::fs::read_to_string(t.path().join("stat"))
                    .ok()
                    .and_then(|st| {
                        let (name, rest) = st.rsplit_once(") ")?;
                        Some(rest.starts_with('R') && !name.ends_with("(myriad-extract"))
                    })
                    .unwrap_or(false)
        })
    }
    #[cfg(not(target_os = "linux"))]
    false
}

/// What a download asks for, from the query string.
#[derive(Debug, Clone)]
pub struct Query {
    pub bbox: Option<Aabb>,
    pub corridor: Option<Corridor>,
    pub spacing: Option<f64>,
    /// ASPRS classes left out.
    pub hide: Vec<u8>,
    /// Conditions the points kept meet.
    pub conditions: Vec<myriad_measure::filter::Condition>,
}

/// Parses `box=...&spacing=...` (values percent-decoded); the error is the answer's text.
pub fn parse_query(q: &str) -> Result<Query, String> {
    let mut bbox = None;
    let mut spacing = None;
    let (mut line, mut width, mut hide) = (None, None, Vec::new());
    let mut conditions = Vec::new();
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
            "line" => {
                line = Some(myriad_measure::corridor::parse_xy_list(&v, "line", 2)?);
            }
            "width" => {
                width = Some(
                    v.parse::<f64>()
                        .map_err(|_| format!("width \"{v}\": not a number"))?,
                );
            }
            "hide" => {
                for c in v.split(',').filter(|c| !c.is_empty()) {
                    hide.push(
                        c.trim()
                            .parse::<u8>()
                            .map_err(|_| format!("hide \"{v}\": class numbers 0 to 255"))?,
                    );
                }
            }
            // A signed link's (checked before).
            "expires" | "sig" => {}
            "where" => {
                conditions.extend(Filter::parse_where(&v).map_err(|e| format!("where: {e}"))?)
            }
            other => return Err(format!("unknown parameter \"{other}\"")),
        }
    }
    let corridor = match (line, width) {
        (Some(l), Some(w)) => Some(Corridor::new(&l, w)?),
        (None, None) => None,
        _ => return Err("a line needs its width: ?line=x1,y1,x2,y2&width=w".into()),
    };
    if bbox.is_none() && corridor.is_none() {
        return Err(
            "a box or a line is needed: ?box=minx,miny,minz,maxx,maxy,maxz or ?line=x1,y1,x2,y2&width=w"
                .into(),
        );
    }
    Ok(Query {
        bbox,
        corridor,
        spacing,
        hide,
        conditions,
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
    /// The query names what the dataset lacks (an attribute, classes): the answer's text.
    Bad(String),
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
    let filter = Filter {
        classes: (!q.hide.is_empty())
            .then(|| (0..=255u8).filter(|c| !q.hide.contains(c)).collect()),
        conditions: q.conditions.clone(),
    };
    filter
        .bind(&ds.meta.schema)
        .map_err(|e| Failed::Bad(e.trim_start_matches("--").to_string()))?;
    let o = ExtractOptions {
        bbox: q.bbox,
        region: (q.corridor.clone())
            .map(|c| std::sync::Arc::new(c) as std::sync::Arc<dyn myriad_measure::Region>),
        filter,
        spacing: q.spacing,
        force: true,
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

    /// A download's next node waits while another thread of the server works, and no longer
    /// than it was given (or once its client has gone).
    #[test]
    fn a_download_waits_while_the_server_works() {
        use std::sync::atomic::{AtomicBool, Ordering};
        use std::time::{Duration, Instant};
        let stop = std::sync::Arc::new(AtomicBool::new(false));
        let busy = {
            let stop = stop.clone();
            std::thread::spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    std::hint::spin_loop();
                }
            })
        };
        std::thread::sleep(Duration::from_millis(20));
        let t = Instant::now();
        yield_while_busy(Duration::from_millis(300), &|| false);
        let waited = t.elapsed();
        let t = Instant::now();
        yield_while_busy(Duration::from_secs(30), &|| true);
        let gone = t.elapsed();
        stop.store(true, Ordering::Relaxed);
        busy.join().unwrap();
        if cfg!(target_os = "linux") {
            assert!(waited >= Duration::from_millis(250), "{waited:?}");
        }
        assert!(waited < Duration::from_secs(5), "{waited:?}");
        assert!(gone < Duration::from_secs(1), "{gone:?}");
    }

    #[test]
    fn queries() {
        let q = parse_query("box=-1,-2,-3,4,5,6&spacing=0.5").unwrap();
        assert_eq!(q.bbox, Some(Aabb::new([-1.0, -2.0, -3.0], [4.0, 5.0, 6.0])));
        assert_eq!(q.spacing, Some(0.5));
        assert_eq!(
            parse_query("box=0%2C0%2C0%2C1%2C1%2C1").unwrap().bbox,
            Some(Aabb::new([0.0; 3], [1.0; 3]))
        );
        let q = parse_query("line=0,0,10,0,10,5&width=2&hide=6,7").unwrap();
        let w =
            parse_query("box=0,0,0,1,1,1&where=intensity%3E100%20and%20return_number=1").unwrap();
        assert_eq!(w.conditions.len(), 2);
        assert!(
            parse_query("box=0,0,0,1,1,1&where=intensity")
                .unwrap_err()
                .starts_with("where: ")
        );
        assert_eq!(q.corridor.unwrap().length(), 15.0);
        assert_eq!(q.hide, [6, 7]);
        for bad in [
            "",
            "spacing=1",
            "box=1,2,3",
            "box=1,1,1,0,0,0",
            "box=0,0,0,1,1,nan",
            "box=0,0,0,1,1,1&spacing=-1",
            "box=0,0,0,1,1,1&x=1",
            "box=%zz",
            "line=0,0,10,0",
            "line=0,0&width=1",
            "line=0,0,1,1&width=0",
            "box=0,0,0,1,1,1&hide=300",
        ] {
            assert!(parse_query(bad).is_err(), "{bad}");
        }
    }
}
