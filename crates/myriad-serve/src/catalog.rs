//! What a server serves: named once, at start. A file is served under its file name; a folder
//! (an exported Potree dataset, a folder of COPC files) under its name followed by each file's
//! path inside it. A dataset or scan on S3-compatible storage or a web server (`s3://BUCKET/KEY`,
//! `http(s)://`) is served under its last name, its ranges read from there as they are asked
//! for. Requests are answered from these names alone.

use myriad_core::{Error, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What a served name is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A Myriad dataset (`.myr`).
    Dataset,
    /// A COPC or LAS/LAZ file.
    Scan,
    /// A file of an exported folder (Potree's metadata.json, octree.bin, hierarchy.bin).
    Export,
}

#[derive(Clone)]
pub(crate) struct File {
    pub(crate) path: PathBuf,
    pub(crate) content_type: &'static str,
    pub(crate) kind: Kind,
    /// A dataset's saved work (`myriad_measure::work`): the sidecar beside what was given.
    pub(crate) work: Option<PathBuf>,
    /// A dataset being built: what the name serves now (`path` is its preview).
    pub(crate) live: Option<std::sync::Arc<crate::live::Live>>,
    /// Where `path` is a URL (`s3://`, `http(s)://`): the object, open, its ranges read as
    /// asked for (its requests signed for S3), and when it was opened (nanoseconds since
    /// 1970: part of its validator).
    pub(crate) remote: Option<(Arc<myriad_format::remote::HttpBytes>, u128)>,
    len: u64,
}

impl File {
    /// The same file served from `path` (a version of a dataset being built).
    pub(crate) fn at(&self, path: PathBuf) -> File {
        File {
            path,
            live: None,
            ..self.clone()
        }
    }
}

/// The files a server answers for, by the name in their URL (`/d/NAME`).
#[derive(Default)]
pub struct Catalog {
    files: BTreeMap<String, File>,
}

/// The name `rel` (a path relative to the file served as `name`) is served under: `.` and `..`
/// taken out; `None` where it leaves the served names' root.
fn served_name(name: &str, rel: &str) -> Option<String> {
    let mut segs: Vec<&str> = name.split('/').collect();
    segs.pop();
    for s in rel.split('/') {
        match s {
            "" | "." => {}
            ".." => {
                segs.pop()?;
            }
            s => segs.push(s),
        }
    }
    Some(segs.join("/"))
}

/// Files at most this deep in a served folder, and at most this many.
const MAX_DEPTH: usize = 8;
const MAX_FILES: usize = 100_000;

fn content_type(path: &Path) -> &'static str {
    match path.extension().and_then(|e| e.to_str()) {
        Some("json") => "application/json",
        Some("html") => "text/html; charset=utf-8",
        Some("js" | "mjs") => "text/javascript",
        Some("glb") => "model/gltf-binary",
        Some("wasm") => "application/wasm",
        Some("svg") => "image/svg+xml",
        Some("css") => "text/css",
        Some("png") => "image/png",
        _ => "application/octet-stream",
    }
}

impl Catalog {
    /// The catalog of `inputs`: files (served under their file name) and folders (every file
    /// below, under the folder's name and its path there). Two inputs with the same name are
    /// an error, as is an input that is neither.
    pub fn new(inputs: &[PathBuf]) -> Result<Catalog> {
        let mut c = Catalog::default();
        for input in inputs {
            c.add_input(input)?;
        }
        Ok(c)
    }

    /// Adds a file (under its file name) or a folder (every file below it).
    pub fn add_input(&mut self, input: &Path) -> Result<()> {
        if myriad_format::remote::is_url(input) {
            return self.add_remote(input);
        }
        let meta = std::fs::metadata(input).map_err(|e| Error::io(input, e))?;
        let name = input
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| Error::Invalid(format!("{}: not a file name", input.display())))?
            .to_string();
        if meta.is_file() {
            self.add(name, input.to_path_buf(), None)
        } else if meta.is_dir() {
            self.add_folder(&name, input, 0)
        } else {
            Err(Error::Invalid(format!(
                "{}: neither a file nor a folder",
                input.display()
            )))
        }
    }

    /// Adds a file under a name of the caller's choosing (a scan's converted dataset), its
    /// saved work beside `source` (the scan).
    pub fn add_file_as(&mut self, name: &str, path: &Path, source: &Path) -> Result<()> {
        self.add(name.to_string(), path.to_path_buf(), None)?;
        if let Some(f) = self.files.get_mut(name).filter(|f| f.kind == Kind::Dataset) {
            f.work = Some(myriad_measure::work::sidecar_for(source));
        }
        Ok(())
    }

    /// Adds a dataset being built under `name` (`live` says what it serves as the build goes),
    /// its saved work beside `source` (the scan).
    pub fn add_live(
        &mut self,
        name: &str,
        live: std::sync::Arc<crate::live::Live>,
        preview: &Path,
        source: &Path,
    ) -> Result<()> {
        self.add_file_as(name, preview, source)?;
        if let Some(f) = self.files.get_mut(name) {
            f.live = Some(live);
        }
        Ok(())
    }

    /// Adds an object on S3 or a web server under its last name (a dataset's linked files
    /// beside it, as for a file).
    fn add_remote(&mut self, url: &Path) -> Result<()> {
        let text = url.to_string_lossy();
        let name = text
            .trim_end_matches('/')
            .rsplit('/')
            .next()
            .filter(|n| !n.is_empty() && !n.contains(':'))
            .ok_or_else(|| Error::Invalid(format!("{text}: no object name to serve it under")))?
            .to_string();
        self.add(name, url.to_path_buf(), None)
    }

    fn add(&mut self, name: String, path: PathBuf, kind: Option<Kind>) -> Result<()> {
        let remote = if myriad_format::remote::is_url(&path) {
            let url = path.to_string_lossy();
            let opened = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos());
            Some((
                Arc::new(myriad_format::remote::HttpBytes::open(&url)?),
                opened,
            ))
        } else {
            None
        };
        let len = match &remote {
            Some((r, _)) => myriad_format::ByteSource::len(r.as_ref()),
            None => std::fs::metadata(&path)
                .map_err(|e| Error::io(&path, e))?
                .len(),
        };
        let kind = kind.unwrap_or(if name.ends_with(".myr") {
            Kind::Dataset
        } else {
            Kind::Scan
        });
        if self.files.len() >= MAX_FILES {
            return Err(Error::Invalid(format!(
                "more than {MAX_FILES} files to serve"
            )));
        }
        if self.files.contains_key(&name) {
            return Err(Error::Invalid(format!(
                "{}: a file named \"{name}\" is served already",
                path.display()
            )));
        }
        // Saved work is kept beside a dataset on this machine's disk; one on S3 or a web
        // server has none (`/work/` answers it empty and read-only).
        let work = (kind == Kind::Dataset && remote.is_none())
            .then(|| myriad_measure::work::sidecar_for(&path));
        if kind == Kind::Dataset {
            self.add_linked(&name, &path)?;
        }
        self.files.insert(
            name,
            File {
                content_type: content_type(&path),
                path,
                kind,
                work,
                live: None,
                remote,
                len,
            },
        );
        Ok(())
    }

    /// The files a dataset of several files links (a merge's parts), under the names its
    /// relative paths give them beside `name`, so that a browser or `HttpBytes` resolving
    /// them against the dataset's URL finds them here.
    fn add_linked(&mut self, name: &str, path: &Path) -> Result<()> {
        let Ok(ds) = myriad_format::Dataset::open_stored(path) else {
            // Not a dataset (or a damaged one): served as given, its readers say what is wrong.
            return Ok(());
        };
        // Every file it links is the dataset part it was (length and header): nothing else
        // is served in their names.
        ds.check_files()?;
        let folder = path.parent().unwrap_or(Path::new(""));
        let url = myriad_format::remote::is_url(path).then(|| path.to_string_lossy());
        for f in ds.files() {
            let Some(linked) = served_name(name, &f.path) else {
                return Err(Error::Invalid(format!(
                    "{}: links {}, which lies above it: no URL beside the dataset reaches it \
                     (keep the parts in a folder beside or below it, or merge with --single-file)",
                    path.display(),
                    f.path
                )));
            };
            let at = match &url {
                Some(u) => PathBuf::from(myriad_format::linked::join_url(u, &f.path)),
                None => folder.join(&f.path),
            };
            match self.files.get(&linked) {
                Some(g) if g.path == at => {}
                _ => self.add(linked, at, Some(Kind::Export))?,
            }
        }
        Ok(())
    }

    fn add_folder(&mut self, prefix: &str, dir: &Path, depth: usize) -> Result<()> {
        if depth > MAX_DEPTH {
            return Ok(());
        }
        let mut entries: Vec<_> = std::fs::read_dir(dir)
            .map_err(|e| Error::io(dir, e))?
            .filter_map(|e| e.ok())
            .collect();
        entries.sort_by_key(|e| e.file_name());
        for e in entries {
            let Some(n) = e.file_name().to_str().map(str::to_string) else {
                continue;
            };
            // Hidden files (unfinished outputs among them) are not served.
            if n.starts_with('.') {
                continue;
            }
            let Ok(t) = e.file_type() else { continue };
            let name = format!("{prefix}/{n}");
            if t.is_file() {
                self.add(name, e.path(), Some(Kind::Export))?;
            } else if t.is_dir() {
                self.add_folder(&name, &e.path(), depth + 1)?;
            }
        }
        Ok(())
    }

    pub(crate) fn file(&self, name: &str) -> Option<&File> {
        self.files.get(name)
    }

    /// Every served name with its kind and size.
    pub fn names(&self) -> impl Iterator<Item = (&str, Kind, u64)> {
        self.files.iter().map(|(n, f)| (n.as_str(), f.kind, f.len))
    }

    pub(crate) fn index_html(&self) -> String {
        let escape = |s: &str| {
            s.replace('&', "&amp;")
                .replace('<', "&lt;")
                .replace('>', "&gt;")
                .replace('"', "&quot;")
        };
        let mut rows = String::new();
        for (name, kind, len) in self.names() {
            let what = match kind {
                Kind::Dataset => "Myriad dataset",
                Kind::Scan => "scan",
                Kind::Export => "exported file",
            };
            let view = match kind {
                Kind::Dataset => format!("<a href=\"/view/{}\">view</a>", href(name)),
                _ => String::new(),
            };
            rows.push_str(&format!(
                "<tr><td><a href=\"/d/{}\">{}</a></td><td>{what}</td><td>{len}</td><td>{view}</td></tr>\n",
                href(name),
                escape(name)
            ));
        }
        format!(
            "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>Myriad</title></head>\n\
             <body><h1>Served by Myriad</h1>\n<p>Each file answers HTTP range requests at \
             <code>/d/NAME</code>; <code>myriad render|info|extract http://HOST/d/NAME.myr</code> \
             reads a dataset from here, and <code>/view/NAME.myr</code> shows it in this browser.</p>\n<table><tr><th>name</th><th>kind</th><th>bytes</th><th></th></tr>\n\
             {rows}</table></body></html>\n"
        )
    }
}

/// A name as it goes into a URL path (percent-encoded but for unreserved characters and `/`).
pub fn href(s: &str) -> String {
    s.bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'/' => {
                (b as char).to_string()
            }
            b => format!("%{b:02X}"),
        })
        .collect()
}
