//! `/work/NAME`: a served dataset's saved work (`myriad_measure::work`, the sidecar beside it)
//! for the web viewer. GET answers it (an empty one where none is saved yet), with
//! `"editable"` saying whether PUT is taken: only with `serve --edit`, since any client of the
//! server may then change the file. A PUT's body is at most `work::MAX_BYTES`, read within
//! [`BODY_TIMEOUT`], by at most [`PUTS_AT_ONCE`] clients at once (more are answered 503), and
//! must parse as work (else 400 naming the line or member); it replaces the sidecar atomically,
//! keeping the dataset's CRS whatever the body says.

use crate::catalog::{File, Kind};
use crate::{Body, Shared, full, status};
use http_body_util::{BodyExt, Limited};
use hyper::body::Incoming;
use hyper::header::{self, HeaderValue};
use hyper::{Method, Request, Response, StatusCode};
use myriad_measure::work::{MAX_BYTES, Work};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

/// A PUT's body must arrive within this.
pub const BODY_TIMEOUT: Duration = Duration::from_secs(30);
/// PUT bodies held at once.
pub const PUTS_AT_ONCE: usize = 4;

fn json(w: &Work, editable: bool, head: bool) -> Response<Body> {
    let mut v = w.to_json();
    v["editable"] = editable.into();
    changing(v.to_string(), head)
}

/// JSON of something that changes (saved work, edits): never answered from a cache; `head`:
/// its headers alone.
pub(crate) fn changing(text: String, head: bool) -> Response<Body> {
    let len = text.len();
    let mut r = Response::new(full(if head { String::new() } else { text }));
    let h = r.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    h.insert(header::CONTENT_LENGTH, HeaderValue::from(len));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    r
}

/// A request's body as text, at most `max` bytes, arrived within [`BODY_TIMEOUT`]; else the
/// answer (413 naming `what`, 408, 400).
pub(crate) async fn text_body(
    req: Request<Incoming>,
    max: usize,
    what: &str,
) -> Result<String, Box<Response<Body>>> {
    let too_large = || {
        Box::new(status(
            StatusCode::PAYLOAD_TOO_LARGE,
            &format!("{what} is at most {max} bytes"),
        ))
    };
    let declared = (req.headers().get(header::CONTENT_LENGTH))
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    if declared.is_some_and(|n| n > max as u64) {
        return Err(too_large());
    }
    let body = Limited::new(req.into_body(), max);
    let bytes = match tokio::time::timeout(BODY_TIMEOUT, body.collect()).await {
        Err(_) => {
            return Err(Box::new(status(
                StatusCode::REQUEST_TIMEOUT,
                "the body did not arrive in time",
            )));
        }
        Ok(Err(e))
            if e.downcast_ref::<http_body_util::LengthLimitError>()
                .is_some() =>
        {
            return Err(too_large());
        }
        Ok(Err(e)) => return Err(Box::new(status(StatusCode::BAD_REQUEST, &e.to_string()))),
        Ok(Ok(c)) => c.to_bytes(),
    };
    String::from_utf8(bytes.to_vec())
        .map_err(|_| Box::new(status(StatusCode::BAD_REQUEST, "not UTF-8")))
}

/// The saved work, its CRS the sidecar's where it has one, else the dataset's own.
fn load(dataset: &Path, sidecar: &Path) -> Result<Work, String> {
    let mut w = myriad_measure::files::load_work(sidecar, None).map_err(|e| e.to_string())?;
    if w.crs.is_none() {
        // A dataset that does not open has its errors said where it is read (/d/).
        w.crs = myriad_format::Dataset::open(dataset)
            .ok()
            .and_then(|d| d.meta.crs.clone());
    }
    Ok(w)
}

fn paths(f: &File) -> (PathBuf, PathBuf) {
    (f.path.clone(), f.work.clone().expect("a dataset's file"))
}

pub(crate) async fn get(shared: &Arc<Shared>, name: &str, head: bool) -> Response<Body> {
    let Some(f) = shared
        .catalog
        .file(name)
        .filter(|f| f.kind == Kind::Dataset)
    else {
        return status(StatusCode::NOT_FOUND, "no such dataset");
    };
    if f.work.is_none() {
        // A dataset on S3 or a web server: no saved work, none to be saved.
        return json(&Work::default(), false, head);
    }
    let (path, sidecar) = paths(f);
    match tokio::task::spawn_blocking(move || load(&path, &sidecar)).await {
        Ok(Ok(w)) => json(&w, shared.options.edit, head),
        Ok(Err(e)) => status(StatusCode::INTERNAL_SERVER_ERROR, &e),
        Err(_) => status(StatusCode::INTERNAL_SERVER_ERROR, "failed"),
    }
}

pub(crate) async fn put(
    shared: &Arc<Shared>,
    name: &str,
    req: Request<Incoming>,
) -> Response<Body> {
    debug_assert_eq!(req.method(), Method::PUT);
    let Some(f) = shared
        .catalog
        .file(name)
        .filter(|f| f.kind == Kind::Dataset)
    else {
        return status(StatusCode::NOT_FOUND, "no such dataset");
    };
    if f.work.is_none() {
        return status(
            StatusCode::FORBIDDEN,
            "read-only: work is saved beside datasets on the server's disk, not on S3 or the web",
        );
    }
    if !shared.options.edit {
        return status(
            StatusCode::FORBIDDEN,
            "read-only: `myriad serve --edit` lets viewers save their work",
        );
    }
    let Ok(_permit) = shared.puts.try_acquire() else {
        return status(StatusCode::SERVICE_UNAVAILABLE, "busy: try again");
    };
    let text = match text_body(req, MAX_BYTES, "work").await {
        Ok(t) => t,
        Err(r) => return *r,
    };
    let mut w = match Work::parse(&text) {
        Ok(w) => w,
        Err(e) => return status(StatusCode::BAD_REQUEST, &format!("work: {e}")),
    };
    let (path, sidecar) = paths(f);
    let lock = shared.saving.clone();
    let saved = tokio::task::spawn_blocking(move || {
        let _one = lock.lock().unwrap_or_else(|p| p.into_inner());
        w.crs = load(&path, &sidecar)?.crs;
        myriad_measure::files::save_work(&sidecar, &w).map_err(|e| e.to_string())?;
        Ok::<Work, String>(w)
    })
    .await;
    match saved {
        Ok(Ok(w)) => json(&w, true, false),
        Ok(Err(e)) => status(StatusCode::INTERNAL_SERVER_ERROR, &e),
        Err(_) => status(StatusCode::INTERNAL_SERVER_ERROR, "failed"),
    }
}
