//! `/edits/NAME`: a served dataset's edits (`myriad_measure::edits`: classes set and points
//! removed, kept beside it) for the web viewer, which applies them to the pages it decodes.
//! GET answers the layer (an empty one where there is none), with `"editable"` saying whether
//! POST is taken; `GET /edits/NAME?surface=FILE` answers a terrain surface a ground edit of the
//! layer names (with ranges: the viewer reads the tiles it needs). POST, only with `serve
//! --edit` and from the server's own pages, makes one change (`{"add": EDIT}`, `{"undo":
//! true}`, `{"redo": true}`) to the file as it is then, under the lock every program that
//! changes it takes: two clients editing at once each keep their edits. At most [`AT_ONCE`]
//! layers are read and answered, or changes read and made, at once (the others wait their turn,
//! [`QUEUE`] at most, then 503), so that a layer (up to 16 MB) costs the server a bounded amount
//! of memory whatever the clients. A change's body is at most [`MAX_CHANGE`] bytes, read within
//! `work::BODY_TIMEOUT`; an edit the dataset could not be read with is refused (400, one line),
//! and so is a ground edit (`myriad ground` makes those, with their surface); one the file could
//! not hold is 413; an undo with nothing to undo is 409.

use crate::catalog::{File, Kind};
use crate::{Body, Budget, Shared, settled, status};
use hyper::body::Incoming;
use hyper::{Request, Response, StatusCode};
use myriad_measure::edits::{Action, Change, Layer, Refused, read, sidecar_for};
use serde_json::Value;
use std::path::PathBuf;
use std::sync::Arc;

/// Layers and changes handled at once.
pub const AT_ONCE: usize = 2;
/// How long a request waits for its turn before it is answered 503.
pub const QUEUE: std::time::Duration = std::time::Duration::from_secs(10);
/// A change's body is at most this (a brush stroke of some ten thousand spheres).
pub const MAX_CHANGE: usize = 1 << 20;

fn json(layer: &Layer, editable: bool, done: Option<String>, head: bool) -> Response<Body> {
    let mut v: Value = serde_json::from_str(&layer.to_json()).expect("a layer's JSON");
    v["editable"] = editable.into();
    if let Some(d) = done {
        v["done"] = d.into();
    }
    crate::work::changing(v.to_string(), head)
}

/// The dataset of that name, as it is for good (a dataset being built has no edits yet).
pub(crate) fn dataset(shared: &Shared, name: &str) -> Result<File, Box<Response<Body>>> {
    let f = (shared.catalog.file(name))
        .filter(|f| f.kind == Kind::Dataset)
        .ok_or_else(|| Box::new(status(StatusCode::NOT_FOUND, "no such dataset")))?;
    let f = settled(f).ok_or_else(|| Box::new(crate::being_built()))?;
    if f.remote.is_some() {
        return Err(Box::new(status(
            StatusCode::FORBIDDEN,
            "read-only: edits are kept beside datasets on the server's disk, not on S3 or the web",
        )));
    }
    Ok(f)
}

pub(crate) async fn get(
    shared: &Arc<Shared>,
    budget: &Budget,
    name: &str,
    req: &Request<Incoming>,
) -> Response<Body> {
    let head = req.method() == hyper::Method::HEAD;
    let Some(f) = shared
        .catalog
        .file(name)
        .filter(|f| f.kind == Kind::Dataset)
    else {
        return status(StatusCode::NOT_FOUND, "no such dataset");
    };
    if f.remote.is_some() {
        // On S3 or a web server: no edits kept, none to be made.
        return json(&Layer::default(), false, None, head);
    }
    let f = match dataset(shared, name) {
        Ok(f) => f,
        Err(r) => return *r,
    };
    let Ok(Ok(_permit)) = tokio::time::timeout(QUEUE, shared.edits.acquire()).await else {
        return status(StatusCode::SERVICE_UNAVAILABLE, "busy: try again");
    };
    let sidecar = sidecar_for(&f.path);
    let surface = (req.uri().query().unwrap_or("").split('&'))
        .find_map(|kv| kv.strip_prefix("surface="))
        .map(crate::percent_decode);
    let s = sidecar.clone();
    let layer = match tokio::task::spawn_blocking(move || read(&s)).await {
        Ok(Ok(l)) => l.unwrap_or_default(),
        Ok(Err(e)) => return status(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
        Err(_) => return status(StatusCode::INTERNAL_SERVER_ERROR, "failed"),
    };
    let Some(surface) = surface else {
        return json(&layer, shared.options.edit, None, head);
    };
    // Only a surface the layer's edits name: never another file beside the dataset.
    let named = |s: &str| {
        (layer.edits.iter().chain(&layer.undone))
            .any(|e| matches!(&e.action, Action::Ground { surface, .. } if surface == s))
    };
    match surface {
        Some(s) if named(&s) && !s.contains('/') && !s.starts_with('.') => {
            let path: PathBuf = sidecar.with_file_name(&s);
            let mut file = f.at(path);
            file.content_type = "application/octet-stream";
            match crate::files::file(&file, budget, req).await {
                Ok(r) => r,
                Err(e) => status(StatusCode::NOT_FOUND, &format!("{s}: {e}")),
            }
        }
        _ => status(
            StatusCode::NOT_FOUND,
            "no surface of that name in this dataset's edits",
        ),
    }
}

pub(crate) async fn post(
    shared: &Arc<Shared>,
    name: &str,
    req: Request<Incoming>,
) -> Response<Body> {
    let f = match dataset(shared, name) {
        Ok(f) => f,
        Err(r) => return *r,
    };
    if !shared.options.edit {
        return status(
            StatusCode::FORBIDDEN,
            "read-only: `myriad serve --edit` lets viewers edit",
        );
    }
    // Editors at once wait their turn (a viewer's edit is not to fail because another is being
    // made), a while; the turn lasts until the change is made.
    let Ok(Ok(_permit)) = tokio::time::timeout(QUEUE, shared.edits.acquire()).await else {
        return status(StatusCode::SERVICE_UNAVAILABLE, "busy: try again");
    };
    let text = match crate::work::text_body(req, MAX_CHANGE, "a change").await {
        Ok(t) => t,
        Err(r) => return *r,
    };
    let change = match Change::parse(&text) {
        Ok(c) => c,
        Err(e) => return status(StatusCode::BAD_REQUEST, &format!("change: {e}")),
    };
    if let Change::Add(e) = &change
        && matches!(e.action, Action::Ground { .. })
    {
        return status(
            StatusCode::BAD_REQUEST,
            "change: a ground edit is made by `myriad ground`, with its surface",
        );
    }
    let path = f.path.clone();
    let made = tokio::task::spawn_blocking(move || {
        let ds = myriad_format::Dataset::open_stored(&path)
            .map_err(|e| Refused::Failed(e.to_string()))?;
        change.apply(&path, &ds.meta)
    })
    .await;
    match made {
        Ok(Ok((layer, done))) => json(&layer, true, Some(done), false),
        Ok(Err(Refused::Invalid(m))) => status(StatusCode::BAD_REQUEST, &m),
        Ok(Err(Refused::Nothing(m))) => status(StatusCode::CONFLICT, &m),
        Ok(Err(Refused::TooLarge(m))) => status(StatusCode::PAYLOAD_TOO_LARGE, &m),
        Ok(Err(Refused::Failed(m))) => status(StatusCode::INTERNAL_SERVER_ERROR, &m),
        Err(_) => status(StatusCode::INTERNAL_SERVER_ERROR, "failed"),
    }
}
