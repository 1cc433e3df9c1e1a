//! `GET /photos/NAME`: the photos and panoramas kept with a dataset (`myriad photos`: the list
//! `NAME.photos.json`, as JSON; `{"photos": []}` where none), for the web viewer's markers;
//! `GET /photos/NAME?file=FILE`: an image the list names, from `NAME.photos/` (range requests as
//! for datasets); any other name 404, so nothing else beside the dataset is served.

use crate::catalog::Kind;
use crate::{Body, Budget, Shared, status};
use hyper::body::Incoming;
use hyper::{Request, Response, StatusCode};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::SystemTime;

/// The largest photos list read.
const MAX_LIST: u64 = myriad_measure::photos::MAX_BYTES as u64;

type Photos = Arc<Vec<myriad_measure::photos::Photo>>;

/// The lists read, by path, with the length and time they had: a list is read and parsed again
/// only when it changed (every image request asks for it). At most [`CACHED`] lists kept.
type Kept = std::sync::Mutex<HashMap<PathBuf, (u64, SystemTime, Photos)>>;

fn cache() -> &'static Kept {
    static C: std::sync::OnceLock<Kept> = std::sync::OnceLock::new();
    C.get_or_init(Default::default)
}

const CACHED: usize = 64;

/// The photos list at `list` (none there: empty).
fn read_list(list: &Path) -> Result<Photos, String> {
    let m = match std::fs::metadata(list) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Arc::new(Vec::new())),
        Err(e) => return Err(e.to_string()),
        Ok(m) if m.len() > MAX_LIST => {
            return Err(format!("a photos list of more than {MAX_LIST} bytes"));
        }
        Ok(m) => m,
    };
    let stamp = (m.len(), m.modified().unwrap_or(SystemTime::UNIX_EPOCH));
    let kept = cache()
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .get(list)
        .cloned();
    if let Some((len, time, p)) = kept
        && (len, time) == stamp
    {
        return Ok(p);
    }
    let text = std::fs::read_to_string(list).map_err(|e| e.to_string())?;
    let p = Arc::new(myriad_measure::photos::parse(&text)?);
    let mut c = cache().lock().unwrap_or_else(|p| p.into_inner());
    if c.len() >= CACHED {
        c.clear();
    }
    c.insert(list.to_path_buf(), (stamp.0, stamp.1, p.clone()));
    Ok(p)
}

pub(crate) async fn get(
    shared: &Arc<Shared>,
    budget: &Budget,
    name: &str,
    req: &Request<Incoming>,
) -> Response<Body> {
    let head = req.method() == hyper::Method::HEAD;
    let Some(f) = (shared.catalog.file(name)).filter(|f| f.kind == Kind::Dataset) else {
        return status(StatusCode::NOT_FOUND, "no such dataset");
    };
    // On S3 or the web, or being built (photos are kept beside a finished dataset): none.
    let Some(f) = crate::settled(f).filter(|f| f.remote.is_none()) else {
        return crate::work::changing(r#"{"photos": []}"#.into(), head);
    };
    let list = myriad_measure::photos::sidecar_for(&f.path);
    let read = tokio::task::spawn_blocking(move || read_list(&list)).await;
    let photos = match read {
        Ok(Ok(p)) => p,
        Ok(Err(e)) => return status(StatusCode::INTERNAL_SERVER_ERROR, &format!("photos: {e}")),
        Err(_) => return status(StatusCode::INTERNAL_SERVER_ERROR, "failed"),
    };
    let asked = (req.uri().query().unwrap_or("").split('&'))
        .find_map(|kv| kv.strip_prefix("file="))
        .map(crate::percent_decode);
    let Some(asked) = asked else {
        return crate::work::changing(myriad_measure::photos::to_text(&photos), head);
    };
    // Only an image the list names (its names hold no folder: `photos::parse` refuses them).
    match asked {
        Some(a) if photos.iter().any(|p| p.file == a) => {
            let mut file = f.at(myriad_measure::photos::folder_for(&f.path).join(&a));
            file.content_type = if a.to_ascii_lowercase().ends_with(".png") {
                "image/png"
            } else {
                "image/jpeg"
            };
            match crate::files::file(&file, budget, req).await {
                Ok(r) => r,
                Err(e) => status(StatusCode::NOT_FOUND, &format!("{a}: {e}")),
            }
        }
        _ => status(
            StatusCode::NOT_FOUND,
            "no image of that name in this dataset's photos",
        ),
    }
}
