//! A dataset served while it is built (`myriad serve SCAN` before the scan has a dataset): its
//! name answers at once with the scan's preview (a small dataset of a sample read without
//! decoding it), then with the build's snapshots as they come (`myriad_build::growing`: the
//! chunks built so far, the preview where they are not), then with the finished dataset.
//!
//! Each of these is a version: `preview`, a snapshot's number, `final`. Every answer for the
//! name says which version it is (`X-Myriad-Version`) and whether the build still runs
//! (`X-Myriad-Building: yes|no`); a request may name the version it reads (`/d/NAME?v=3`), so a
//! viewer's reads never mix two versions: the last [`KEPT`] snapshots stay answerable, older
//! ones are 410 Gone (the viewer opens the current one again). A snapshot is served by single
//! ranges of at most 4 MiB (what readers of a dataset ask for); the whole file waits for the end.
//!
//! A viewer asks `/build/NAME?since=V&focus=X,Y,Z` once a second ([`Live::changes`]): the newest
//! version, and which of its nodes are new against the version `V` it draws, so that it keeps
//! every node it has whose page is still the same (the build only appends to its file: a page
//! written before a snapshot is the same bytes in every later version); `focus`, where its camera
//! looks, is where the build goes next ([`Growing::set_focus`]). The changes are answered here
//! ([`answer_changes`]), the versions' bytes with the catalog's other files (`answer_dataset` in
//! `files.rs`, from what [`Live`] holds); the router only finds the name.

use crate::{Body, full, percent_decode, status};
use hyper::header::{self, HeaderValue};
use hyper::{Response, StatusCode};
use myriad_build::growing::{Growing, Shown};
use myriad_core::NodeKey;
use myriad_format::{ByteSource, Dataset, NodeEntry};
use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Snapshots kept answerable after a newer one is served.
pub const KEPT: usize = 4;

/// Answers of [`Live::changes`] kept (viewers ask every second, most of them the same).
const ANSWERS: usize = 8;

/// The nodes of a version that are new against an older one (`None`: all of them).
pub(crate) type NewNodes = Option<Arc<Vec<NodeKey>>>;

/// What a name being built serves.
pub struct Live {
    /// The preview, and the build's generation: 0, then one more each time the scan changed
    /// after its dataset was built and is built again ([`Live::restart`]).
    preview: Mutex<(PathBuf, u32)>,
    growing: Mutex<Option<Arc<Growing>>>,
    /// The build's end: the dataset, or `None` when it failed.
    ended: Mutex<Option<Option<PathBuf>>>,
    /// Why the build failed (one line), once it did: every answer for the name says so.
    failure: Mutex<Option<String>>,
    kept: Mutex<VecDeque<Shown>>,
    /// Answers of [`Live::changes`]: (since, version, new nodes).
    answers: Mutex<VecDeque<(String, String, NewNodes)>>,
}

/// One version of a name being built, of the build's generation.
pub(crate) enum Version {
    Preview(PathBuf, u32),
    Snapshot(Shown, u32),
    Final(PathBuf, u32),
}

impl Version {
    /// Its name in `X-Myriad-Version` and `?v=`: `preview`, the snapshot's number, `final`;
    /// after a rebuild, `~G` after it (a name of an earlier generation is then gone).
    pub(crate) fn name(&self) -> String {
        let (base, g) = match self {
            Version::Preview(_, g) => ("preview".to_string(), *g),
            Version::Snapshot(s, g) => (s.version.to_string(), *g),
            Version::Final(_, g) => ("final".to_string(), *g),
        };
        if g == 0 { base } else { format!("{base}~{g}") }
    }

    /// Its length in bytes.
    pub(crate) fn len(&self) -> u64 {
        match self {
            Version::Preview(p, _) | Version::Final(p, _) => {
                std::fs::metadata(p).map_or(0, |m| m.len())
            }
            Version::Snapshot(s, _) => s.bytes.len(),
        }
    }
}

/// The nodes of `now` whose pages are not those of `old` (`None`: all of them: `old` is the
/// preview, a snapshot held in memory alone, or over another cube). A node of `old` is kept
/// when its page lies in the part of the build's file written before `old` was taken and `now`
/// has the same page for it.
fn new_nodes(old: &Version, now: &Version) -> Option<Vec<NodeKey>> {
    let Version::Snapshot(o, _) = old else {
        return None;
    };
    let written = o.bytes.prefix();
    let then = o.dataset.clone();
    let later = match now {
        Version::Snapshot(s, _) => s.dataset.clone(),
        Version::Final(p, _) => Arc::new(Dataset::open(p).ok()?),
        Version::Preview(..) => return None,
    };
    if then.meta.root != later.meta.root {
        return None;
    }
    let (before, d) = then.nodes();
    if !d.is_empty() {
        return None;
    }
    let (after, d) = later.nodes();
    if !d.is_empty() {
        return None;
    }
    let same: HashMap<NodeKey, &NodeEntry> = (before.iter())
        .filter(|e| e.page.offset + e.page.length as u64 <= written)
        .map(|e| (e.key, e))
        .collect();
    let new = after.iter().filter(|e| {
        same.get(&e.key)
            .is_none_or(|o| o.page != e.page || o.points != e.points)
    });
    Some(new.map(|e| e.key).collect())
}

impl Live {
    /// A name that serves the dataset at `preview` until its build shows more.
    pub fn new(preview: &Path) -> Arc<Live> {
        Arc::new(Live {
            preview: Mutex::new((preview.to_path_buf(), 0)),
            growing: Mutex::new(None),
            ended: Mutex::new(None),
            failure: Mutex::new(None),
            kept: Mutex::new(VecDeque::new()),
            answers: Mutex::new(VecDeque::new()),
        })
    }

    /// A name whose dataset is built already: `dataset`, final, until [`Live::restart`].
    pub fn built(dataset: &Path) -> Arc<Live> {
        let live = Live::new(dataset);
        live.ended(Some(dataset.to_path_buf()));
        live
    }

    /// The scan changed after its dataset was built: from now on `preview` (of the scan as it
    /// is now) is served until a new build, of a new generation, shows more; every version of
    /// the earlier one is gone (410), so no reader mixes the two.
    pub fn restart(&self, preview: &Path) {
        let mut p = self.preview.lock().expect("live lock");
        *p = (preview.to_path_buf(), p.1 + 1);
        *self.growing.lock().expect("live lock") = None;
        *self.ended.lock().expect("live lock") = None;
        *self.failure.lock().expect("live lock") = None;
        self.kept.lock().expect("live lock").clear();
        self.answers.lock().expect("live lock").clear();
    }

    /// The dataset a finished build serves (`None` while building, or failed).
    pub fn dataset(&self) -> Option<PathBuf> {
        self.ended.lock().expect("live lock").clone().flatten()
    }

    /// The build, whose snapshots are served from now on.
    pub fn building(&self, g: Arc<Growing>) {
        *self.growing.lock().expect("live lock") = Some(g);
    }

    /// The build ended with its dataset, served from now on.
    pub fn ended(&self, dataset: Option<PathBuf>) {
        *self.ended.lock().expect("live lock") = Some(dataset);
    }

    /// The build failed (`why`, one line): from now on the name answers 500 saying so
    /// (`X-Myriad-Building: failed`, `X-Myriad-Failed`), `/build/` too; the preview it served is
    /// never passed off as the dataset.
    pub fn failed(&self, why: &str) {
        let line: String = (why.lines().next().unwrap_or(why).chars())
            .map(|c| {
                if c.is_ascii_graphic() || c == ' ' {
                    c
                } else {
                    '?'
                }
            })
            .take(300)
            .collect();
        *self.failure.lock().expect("live lock") = Some(line);
        self.ended(None);
    }

    /// Why the build failed, where it did.
    pub fn failure(&self) -> Option<String> {
        self.failure.lock().expect("live lock").clone()
    }

    /// Whether the build still runs.
    pub fn is_building(&self) -> bool {
        self.ended.lock().expect("live lock").is_none()
    }

    /// The newest version.
    pub(crate) fn current(&self) -> Version {
        let (preview, g) = self.preview.lock().expect("live lock").clone();
        if let Some(Some(p)) = &*self.ended.lock().expect("live lock") {
            return Version::Final(p.clone(), g);
        }
        let latest = (self.growing.lock().expect("live lock").as_ref()).and_then(|g| g.latest());
        let mut kept = self.kept.lock().expect("live lock");
        if let Some(s) = latest
            && kept.back().is_none_or(|k| k.version < s.version)
        {
            kept.push_back(s);
            while kept.len() > KEPT {
                kept.pop_front();
            }
        }
        match kept.back() {
            Some(s) => Version::Snapshot(s.clone(), g),
            None => Version::Preview(preview, g),
        }
    }

    /// The newest version, and its nodes that are new against version `since` (what a viewer
    /// drawing `since` must load again; `None`: all). Reads hierarchies: run it off the async
    /// threads.
    pub(crate) fn changes(&self, since: &str) -> (Version, NewNodes) {
        let now = self.current();
        let to = now.name();
        if since == to {
            return (now, Some(Arc::new(Vec::new())));
        }
        let cached = (self.answers.lock().expect("live lock").iter())
            .find(|(s, t, _)| s == since && *t == to)
            .map(|(_, _, n)| n.clone());
        if let Some(new) = cached {
            return (now, new);
        }
        let new = (self.version(since))
            .and_then(|old| new_nodes(&old, &now))
            .map(Arc::new);
        let mut answers = self.answers.lock().expect("live lock");
        answers.push_back((since.to_string(), to, new.clone()));
        while answers.len() > ANSWERS {
            answers.pop_front();
        }
        (now, new)
    }

    /// Builds the chunks nearest `p` next (where a viewer looks).
    pub(crate) fn focus(&self, p: [f64; 3]) {
        if let Some(g) = &*self.growing.lock().expect("live lock") {
            g.set_focus(Some(p));
        }
    }

    /// The version named `v`, while it is answerable.
    pub(crate) fn version(&self, v: &str) -> Option<Version> {
        let (base, asked) = match v.split_once('~') {
            Some((b, g)) => (b, g.parse::<u32>().ok().filter(|&g| g > 0)?),
            None => (v, 0),
        };
        let (preview, g) = self.preview.lock().expect("live lock").clone();
        if asked != g {
            return None;
        }
        match base {
            "preview" => Some(Version::Preview(preview, g)),
            "final" => match &*self.ended.lock().expect("live lock") {
                Some(Some(p)) => Some(Version::Final(p.clone(), g)),
                _ => None,
            },
            n => {
                let n: u64 = n.parse().ok()?;
                self.current();
                let kept = self.kept.lock().expect("live lock");
                kept.iter()
                    .find(|s| s.version == n)
                    .map(|s| Version::Snapshot(s.clone(), g))
            }
        }
    }
}

/// `/build/NAME?since=V&focus=X,Y,Z` ([`Live::changes`]): the newest version of a dataset
/// being built, its length, whether the build still runs, and its nodes that are new against
/// version `V` (`null`: all); `focus` is where the asker looks, built next.
pub(crate) async fn answer_changes(live: Arc<Live>, query: &str) -> Response<Body> {
    let mut since = String::new();
    for p in query.split('&') {
        if let Some(v) = p.strip_prefix("since=") {
            since = percent_decode(v).unwrap_or_default();
        } else if let Some(v) = p.strip_prefix("focus=") {
            let xyz: Vec<f64> = match v.split(',').map(str::parse).collect() {
                Ok(xyz) => xyz,
                Err(_) => return status(StatusCode::BAD_REQUEST, "focus: three numbers, X,Y,Z"),
            };
            match <[f64; 3]>::try_from(xyz) {
                Ok(p) if p.iter().all(|v| v.is_finite()) => live.focus(p),
                _ => return status(StatusCode::BAD_REQUEST, "focus: three numbers, X,Y,Z"),
            }
        }
    }
    let l = live.clone();
    let answered = tokio::task::spawn_blocking(move || {
        let (now, new) = l.changes(&since);
        (now.name(), now.len(), new)
    });
    let Ok((version, len, new)) = answered.await else {
        return status(StatusCode::INTERNAL_SERVER_ERROR, "the question failed");
    };
    let new = new.map(|keys| {
        (keys.iter())
            .map(|k| [k.level, k.cell[0], k.cell[1], k.cell[2]])
            .collect::<Vec<_>>()
    });
    let body = serde_json::json!({
        "version": version,
        "building": live.is_building(),
        "failed": live.failure(),
        "length": len,
        "new": new,
    });
    let mut r = Response::new(full(body.to_string()));
    let h = r.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    r
}
