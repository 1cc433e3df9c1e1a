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
    preview: PathBuf,
    growing: Mutex<Option<Arc<Growing>>>,
    /// The build's end: the dataset, or `None` when it failed.
    ended: Mutex<Option<Option<PathBuf>>>,
    /// Why the build failed (one line), once it did: every answer for the name says so.
    failure: Mutex<Option<String>>,
    kept: Mutex<VecDeque<Shown>>,
    /// Answers of [`Live::changes`]: (since, version, new nodes).
    answers: Mutex<VecDeque<(String, String, NewNodes)>>,
}

/// One version of a name being built.
pub(crate) enum Version {
    Preview(PathBuf),
    Snapshot(Shown),
    Final(PathBuf),
}

impl Version {
    /// Its name in `X-Myriad-Version` and `?v=`.
    pub(crate) fn name(&self) -> String {
        match self {
            Version::Preview(_) => "preview".into(),
            Version::Snapshot(s) => s.version.to_string(),
            Version::Final(_) => "final".into(),
        }
    }

    /// Its length in bytes.
    pub(crate) fn len(&self) -> u64 {
        match self {
            Version::Preview(p) | Version::Final(p) => std::fs::metadata(p).map_or(0, |m| m.len()),
            Version::Snapshot(s) => s.bytes.len(),
        }
    }
}

/// The nodes of `now` whose pages are not those of `old` (`None`: all of them: `old` is the
/// preview, a snapshot held in memory alone, or over another cube). A node of `old` is kept
/// when its page lies in the part of the build's file written before `old` was taken and `now`
/// has the same page for it.
fn new_nodes(old: &Version, now: &Version) -> Option<Vec<NodeKey>> {
    let Version::Snapshot(o) = old else {
        return None;
    };
    let written = o.bytes.prefix();
    let then = o.dataset.clone();
    let later = match now {
        Version::Snapshot(s) => s.dataset.clone(),
        Version::Final(p) => Arc::new(Dataset::open(p).ok()?),
        Version::Preview(_) => return None,
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
            preview: preview.to_path_buf(),
            growing: Mutex::new(None),
            ended: Mutex::new(None),
            failure: Mutex::new(None),
            kept: Mutex::new(VecDeque::new()),
            answers: Mutex::new(VecDeque::new()),
        })
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
        if let Some(Some(p)) = &*self.ended.lock().expect("live lock") {
            return Version::Final(p.clone());
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
            Some(s) => Version::Snapshot(s.clone()),
            None => Version::Preview(self.preview.clone()),
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
        match v {
            "preview" => Some(Version::Preview(self.preview.clone())),
            "final" => match &*self.ended.lock().expect("live lock") {
                Some(Some(p)) => Some(Version::Final(p.clone())),
                _ => None,
            },
            n => {
                let n: u64 = n.parse().ok()?;
                self.current();
                let kept = self.kept.lock().expect("live lock");
                kept.iter()
                    .find(|s| s.version == n)
                    .map(|s| Version::Snapshot(s.clone()))
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
