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

use myriad_build::growing::{Growing, Shown};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Snapshots kept answerable after a newer one is served.
pub const KEPT: usize = 4;

/// What a name being built serves.
pub struct Live {
    preview: PathBuf,
    growing: Mutex<Option<Arc<Growing>>>,
    /// The build's end: the dataset, or `None` when it failed (what was served stays).
    ended: Mutex<Option<Option<PathBuf>>>,
    kept: Mutex<VecDeque<Shown>>,
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
}

impl Live {
    /// A name that serves the dataset at `preview` until its build shows more.
    pub fn new(preview: &Path) -> Arc<Live> {
        Arc::new(Live {
            preview: preview.to_path_buf(),
            growing: Mutex::new(None),
            ended: Mutex::new(None),
            kept: Mutex::new(VecDeque::new()),
        })
    }

    /// The build, whose snapshots are served from now on.
    pub fn building(&self, g: Arc<Growing>) {
        *self.growing.lock().expect("live lock") = Some(g);
    }

    /// The build ended: its dataset (served from now on), or `None` (it failed: the last
    /// version served stays).
    pub fn ended(&self, dataset: Option<PathBuf>) {
        *self.ended.lock().expect("live lock") = Some(dataset);
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
