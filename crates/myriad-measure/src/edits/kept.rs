//! Changing a dataset's edits file: every change (`myriad classify` and `ground`, the window's
//! edit tool, `serve --edit`'s clients) reads, changes and writes the file while it holds an
//! exclusive `flock` on a lock file beside it (`.NAME.edits.json.lock`), so that no two
//! programs, or two clients of one server, lose each other's edits; the file is replaced
//! atomically, and only with what reads back.

use super::{Action, Edit, Layer, NO_REMOVAL, read, sidecar_for};
use myriad_format::Metadata;
use serde_json::Value;
use std::fs::File;
use std::path::Path;

/// Where the edits of a dataset in a folder that takes no files may be kept instead.
const ELSEWHERE: &str =
    "edits are kept beside the dataset: copy it to a folder you can write to edit it";

/// Why a change was not made.
#[derive(Debug, Clone, PartialEq)]
pub enum Refused {
    /// An edit the dataset could not be read with.
    Invalid(String),
    /// Nothing to undo or redo.
    Nothing(String),
    /// The file could not hold the layer with it.
    TooLarge(String),
    /// The file could not be read or written.
    Failed(String),
}

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refused::Invalid(m)
            | Refused::Nothing(m)
            | Refused::TooLarge(m)
            | Refused::Failed(m) => f.write_str(m),
        }
    }
}

/// A change a viewer asks of a dataset's edits.
#[derive(Debug, Clone, PartialEq)]
pub enum Change {
    Add(Edit),
    Undo,
    Redo,
}

impl Change {
    /// A change from its JSON: `{"add": EDIT}` (an edit as the file keeps it), `{"undo": true}`
    /// or `{"redo": true}`; an error names the member at fault.
    pub fn parse(text: &str) -> Result<Change, String> {
        let v: Value = serde_json::from_str(text)
            .map_err(|e| format!("line {} column {}: {e}", e.line(), e.column()))?;
        let o = v.as_object().ok_or("not a JSON object")?;
        match (o.len(), o.get("add"), o.get("undo"), o.get("redo")) {
            (1, Some(e), _, _) => Ok(Change::Add(Edit::from_json(e, "add")?)),
            (1, _, Some(Value::Bool(true)), _) => Ok(Change::Undo),
            (1, _, _, Some(Value::Bool(true))) => Ok(Change::Redo),
            _ => Err(
                "one of {\"add\": EDIT}, {\"undo\": true}, {\"redo\": true}, not something else"
                    .into(),
            ),
        }
    }

    /// Makes the change to the edits of the dataset at `dataset` (`meta`: its metadata): an
    /// edit is first checked as a reader will read it ([`admit`]); undo and redo need an edit
    /// to undo or redo. The layer after it, and what was done.
    pub fn apply(self, dataset: &Path, meta: &Metadata) -> Result<(Layer, String), Refused> {
        let sidecar = sidecar_for(dataset);
        if let Change::Add(e) = &self {
            admit(e, meta, &sidecar).map_err(Refused::Invalid)?;
        }
        let (mut nothing, mut large) = (false, false);
        let made =
            change(&sidecar, |layer| match self {
                Change::Add(e) => {
                    let what = format!("edit {}: {}", layer.edits.len() + 1, e.describe());
                    layer.crs = meta.crs.clone();
                    layer.push(e);
                    if let Err(m) = Layer::parse(&layer.to_json()) {
                        large = true;
                        return Err(format!(
                            "{}: the edit cannot be kept: {m}",
                            sidecar.display()
                        ));
                    }
                    Ok(what)
                }
                Change::Undo => (layer.undo().map(|e| format!("undone: {}", e.describe())))
                    .ok_or_else(|| {
                        nothing = true;
                        format!("{}: no edit to undo", sidecar.display())
                    }),
                Change::Redo => (layer.redo().map(|e| format!("redone: {}", e.describe())))
                    .ok_or_else(|| {
                        nothing = true;
                        format!("{}: no edit to redo", sidecar.display())
                    }),
            });
        made.map_err(|m| match (nothing, large) {
            (true, _) => Refused::Nothing(m),
            (_, true) => Refused::TooLarge(m),
            _ => Refused::Failed(m),
        })
    }
}

/// Whether `e` may join the edits of a dataset (`meta`; `sidecar`: its edits file): what would
/// make the dataset unreadable with it (a region that is no shape, a filter on columns the
/// dataset lacks, classes set where it has none, a missing surface, points removed from an
/// mwkd dataset) is refused now, in one line.
pub fn admit(e: &Edit, meta: &Metadata, sidecar: &Path) -> Result<(), String> {
    let single = Layer {
        edits: vec![e.clone()],
        ..Layer::default()
    };
    let dir = sidecar.parent().unwrap_or(Path::new("."));
    (single.compile(&meta.schema, dir))
        .map_err(|m| m.trim_start_matches("edits[0]: ").to_string())?;
    if e.action == Action::Remove && meta.structure == "mwkd" {
        return Err(NO_REMOVAL.into());
    }
    Ok(())
}

/// The edits file held against other programs changing it, until the value is dropped.
pub fn hold(sidecar: &Path) -> Result<File, String> {
    use std::os::fd::AsRawFd;
    let name = sidecar.file_name().unwrap_or_default().to_string_lossy();
    let lock = sidecar.with_file_name(format!(".{name}.lock"));
    let f = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock)
        .map_err(|e| format!("{}: {e} ({ELSEWHERE})", lock.display()))?;
    // SAFETY: flock on a descriptor this function owns; it blocks until the lock is free.
    if unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX) } != 0 {
        return Err(format!(
            "{}: {}",
            lock.display(),
            std::io::Error::last_os_error()
        ));
    }
    Ok(f)
}

/// Changes the layer in `sidecar` by `f` while holding it ([`hold`]): the file as it is now,
/// `f`'s change, the file replaced atomically if the layer reads back (an edit too large for
/// the file, or beyond what it holds, is refused: nothing kept). The layer written and `f`'s
/// answer; where `f` fails nothing is written.
pub fn change<T>(
    sidecar: &Path,
    f: impl FnOnce(&mut Layer) -> Result<T, String>,
) -> Result<(Layer, T), String> {
    let _held = hold(sidecar)?;
    let mut layer = read(sidecar)
        .map_err(|e| e.to_string())?
        .unwrap_or_default();
    let answer = f(&mut layer)?;
    let text = layer.to_json();
    if let Err(m) = Layer::parse(&text) {
        return Err(format!(
            "{}: the edit cannot be kept: {m}",
            sidecar.display()
        ));
    }
    crate::files::write_atomic(sidecar, true, |w| w.write_all(text.as_bytes()))
        .map_err(|e| format!("{e} ({ELSEWHERE})"))?;
    Ok((layer, answer))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn changes_parse_and_name_what_is_wrong() {
        assert_eq!(Change::parse(r#"{"undo": true}"#), Ok(Change::Undo));
        assert_eq!(Change::parse(r#"{"redo": true}"#), Ok(Change::Redo));
        match Change::parse(r#"{"add": {"polygon": [[0,0],[1,0],[1,1]], "to": 7}}"#) {
            Ok(Change::Add(e)) => assert_eq!(e.action, Action::Class(7)),
            other => panic!("{other:?}"),
        }
        for bad in [
            "{}",
            "[1]",
            r#"{"undo": false}"#,
            r#"{"undo": true, "redo": true}"#,
            r#"{"add": {"to": 300}}"#,
        ] {
            assert!(Change::parse(bad).is_err(), "{bad}");
        }
        let e = Change::parse("{\n\"add\": ").unwrap_err();
        assert!(e.starts_with("line 2"), "{e}");
    }
}
