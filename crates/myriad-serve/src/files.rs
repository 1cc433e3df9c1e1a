//! Answers for the files of the catalog: the validator (`ETag`, `If-None-Match`, `If-Range`),
//! the ranges (one read at once up to [`READ_AT_ONCE`], several merged where they overlap and
//! sent as `multipart/byteranges`), and bodies streamed from the file in [`CHUNK`]s through the
//! connection's memory [`Budget`]. An object on S3 or a web server is answered the same way, its
//! bytes read from there by range requests as they are sent. A dataset being built
//! ([`crate::live`]) is answered with the version asked for ([`answer_dataset`]): its file, or
//! its snapshot held in memory.

use crate::conn::{Budget, Owned};
use crate::live::{Live, Version};
use crate::range::{self, Ranges};
use crate::{BOUNDARY, Body, CHUNK, catalog, full, status};
use bytes::Bytes;
use http_body_util::{BodyExt, StreamBody};
use hyper::body::{Frame, Incoming};
use hyper::header::{self, HeaderValue};
use hyper::{Method, Request, Response, StatusCode};
use myriad_format::ByteSource;
use std::collections::VecDeque;
use std::io;
use std::sync::Arc;

/// One range up to this size is read in one go with the file's opening (one trip to the
/// blocking pool for most requests); larger answers stream in [`CHUNK`]s.
const READ_AT_ONCE: u64 = 4 << 20;

/// What one request for a file comes to, decided on a blocking thread with the file open.
struct Plan {
    len: u64,
    etag: String,
    answer: Answer,
}

enum Answer {
    NotModified,
    Unsatisfiable,
    /// The whole file, or one range: read (`Some`, within the bytes taken from the budget
    /// beforehand) or to be streamed from the file.
    One {
        range: Option<(u64, u64)>,
        data: Option<Vec<u8>>,
        file: Arc<dyn ByteSource>,
    },
    /// Several ranges (overlapping ones merged), to be streamed.
    Many(Vec<(u64, u64)>, Arc<dyn ByteSource>),
}

/// Ranges sorted and merged where they overlap or touch, when any do (RFC 9110 lets a server
/// coalesce them); as asked otherwise.
fn merge_ranges(mut v: Vec<(u64, u64)>) -> Vec<(u64, u64)> {
    let mut sorted = v.clone();
    sorted.sort_unstable();
    if sorted.windows(2).all(|w| w[1].0 > w[0].1.saturating_add(1)) {
        return v;
    }
    v.clear();
    for (a, b) in sorted {
        match v.last_mut() {
            Some(last) if a <= last.1.saturating_add(1) => last.1 = last.1.max(b),
            _ => v.push((a, b)),
        }
    }
    v
}

/// Where a served file's bytes come from: a file, or an object on S3 or a web server opened
/// at the given time.
#[derive(Clone)]
enum Source {
    Path(std::path::PathBuf),
    Remote(Arc<myriad_format::remote::HttpBytes>, u128),
}

/// The bytes of `source` and their validator: a file's from its length and time, an object's
/// from its length and when it was opened (an object replaced since makes every read fail:
/// `HttpBytes` asks with `If-Range`).
fn open(source: Source) -> io::Result<(Arc<dyn ByteSource>, String)> {
    match source {
        Source::Path(path) => {
            let file = std::fs::File::open(path)?;
            let meta = file.metadata()?;
            let bytes = myriad_format::FileBytes::of(file)?;
            let len = bytes.len();
            let mtime = meta
                .modified()
                .ok()
                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                .map_or(0, |d| d.as_nanos());
            Ok((Arc::new(bytes), format!("\"{len:x}-{mtime:x}\"")))
        }
        Source::Remote(r, opened) => {
            if let Some(m) = r.changed() {
                return Err(io::Error::other(m));
            }
            let etag = format!("\"{:x}-r{opened:x}\"", r.len());
            Ok((r, etag))
        }
    }
}

/// Opens the file, takes its validator, resolves the request's ranges and reads one range of
/// at most `read_up_to` bytes.
fn plan(
    source: Source,
    range: Option<String>,
    if_range: Option<String>,
    if_none_match: Option<String>,
    read_up_to: u64,
) -> io::Result<Plan> {
    let (file, etag) = open(source)?;
    let len = file.len();
    if if_none_match.is_some_and(|v| v.split(',').any(|t| t.trim() == etag || t.trim() == "*")) {
        return Ok(Plan {
            len,
            etag,
            answer: Answer::NotModified,
        });
    }
    // If-Range with another validator: the whole file (the ranges would be of another version).
    let ranges = match (range, if_range) {
        (Some(_), Some(v)) if v.trim() != etag => Ranges::Whole,
        (Some(h), _) => range::parse(&h, len),
        (None, _) => Ranges::Whole,
    };
    let answer = match ranges {
        Ranges::Unsatisfiable => Answer::Unsatisfiable,
        Ranges::Whole => Answer::One {
            range: None,
            data: None,
            file,
        },
        Ranges::Some(v) => {
            let v = merge_ranges(v);
            if v.len() == 1 {
                let (a, b) = v[0];
                let data = if b - a < read_up_to {
                    Some(file.read_at(a, (b - a + 1) as usize)?)
                } else {
                    None
                };
                Answer::One {
                    range: Some((a, b)),
                    data,
                    file,
                }
            } else {
                Answer::Many(v, file)
            }
        }
    };
    Ok(Plan { len, etag, answer })
}

/// The bytes a request's `Range` can come to when it is one range of known size (to take them
/// from the budget before the file is opened); 0 otherwise.
fn one_range_bytes(range: Option<&str>) -> u64 {
    let Some(specs) = range.and_then(|h| h.split_once('=')).map(|(_, s)| s.trim()) else {
        return 0;
    };
    if specs.contains(',') {
        return 0;
    }
    match specs.split_once('-') {
        Some(("", n)) => n.trim().parse().unwrap_or(0),
        Some((a, b)) if !b.trim().is_empty() => {
            match (a.trim().parse::<u64>(), b.trim().parse::<u64>()) {
                (Ok(a), Ok(b)) if b >= a => (b - a).saturating_add(1),
                _ => 0,
            }
        }
        _ => 0,
    }
}

/// One served file, as the request asks for it.
pub(crate) async fn file(
    f: &catalog::File,
    budget: &Budget,
    req: &Request<Incoming>,
) -> io::Result<Response<Body>> {
    let head = req.method() == Method::HEAD;
    let header = |h: header::HeaderName| {
        req.headers()
            .get(h)
            .and_then(|v| v.to_str().ok())
            .map(str::to_string)
    };
    let (range, if_range, if_none_match) = (
        header(header::RANGE),
        header(header::IF_RANGE),
        header(header::IF_NONE_MATCH),
    );
    // A small range is read with the opening: its bytes are taken from the budget first.
    let want = one_range_bytes(range.as_deref());
    let (held, read_up_to) = if !head && want > 0 && want <= READ_AT_ONCE {
        (Some(budget.take(want as usize).await), want)
    } else {
        (None, 0)
    };
    let source = match &f.remote {
        Some((r, opened)) => Source::Remote(r.clone(), *opened),
        None => Source::Path(f.path.clone()),
    };
    let Plan { len, etag, answer } = tokio::task::spawn_blocking(move || {
        plan(source, range, if_range, if_none_match, read_up_to)
    })
    .await
    .map_err(io::Error::other)??;
    let unsatisfiable = |text: &str| {
        let mut r = status(StatusCode::RANGE_NOT_SATISFIABLE, text);
        r.headers_mut().insert(
            header::CONTENT_RANGE,
            HeaderValue::from_str(&format!("bytes */{len}")).expect("ascii"),
        );
        r
    };
    let mut r = match answer {
        Answer::NotModified => {
            let mut r = Response::new(full(Bytes::new()));
            *r.status_mut() = StatusCode::NOT_MODIFIED;
            r
        }
        Answer::Unsatisfiable => unsatisfiable("range not satisfiable"),
        Answer::One { range, data, file } => {
            let (a, b) = range.unwrap_or((0, len.saturating_sub(1)));
            let n = if len == 0 { 0 } else { b - a + 1 };
            let body = match (head, data, held) {
                (true, _, _) => full(Bytes::new()),
                (false, Some(d), Some(h)) => full(Bytes::from_owner(Owned { data: d, _held: h })),
                (false, Some(d), None) => full(d),
                (false, None, _) => pieces(
                    file,
                    VecDeque::from([Piece::File(a, n)]),
                    budget.clone(),
                    None,
                ),
            };
            let mut r = Response::new(body);
            let h = r.headers_mut();
            h.insert(header::CONTENT_LENGTH, HeaderValue::from(n));
            if range.is_some() {
                *r.status_mut() = StatusCode::PARTIAL_CONTENT;
                r.headers_mut().insert(
                    header::CONTENT_RANGE,
                    HeaderValue::from_str(&format!("bytes {a}-{b}/{len}")).expect("ascii"),
                );
            }
            r
        }
        Answer::Many(parts, file) => {
            drop(held);
            let mut list = VecDeque::new();
            let mut n = 0u64;
            for (a, b) in parts {
                let head = format!(
                    "\r\n--{BOUNDARY}\r\nContent-Type: {}\r\nContent-Range: bytes {a}-{b}/{len}\r\n\r\n",
                    f.content_type
                );
                n += head.len() as u64 + (b - a + 1);
                list.push_back(Piece::Text(Bytes::from(head)));
                list.push_back(Piece::File(a, b - a + 1));
            }
            let tail = format!("\r\n--{BOUNDARY}--\r\n");
            n += tail.len() as u64;
            list.push_back(Piece::Text(Bytes::from(tail)));
            let body = if head {
                full(Bytes::new())
            } else {
                pieces(file, list, budget.clone(), None)
            };
            let mut r = Response::new(body);
            *r.status_mut() = StatusCode::PARTIAL_CONTENT;
            let h = r.headers_mut();
            h.insert(header::CONTENT_LENGTH, HeaderValue::from(n));
            h.insert(
                header::CONTENT_TYPE,
                HeaderValue::from_str(&format!("multipart/byteranges; boundary={BOUNDARY}"))
                    .expect("ascii"),
            );
            r
        }
    };
    let h = r.headers_mut();
    h.insert(header::ACCEPT_RANGES, HeaderValue::from_static("bytes"));
    h.insert(header::ETAG, HeaderValue::from_str(&etag).expect("ascii"));
    h.entry(header::CONTENT_TYPE)
        .or_insert(HeaderValue::from_static(f.content_type));
    Ok(r)
}

/// A snapshot of a dataset being built ([`crate::live`]): `HEAD`, and single ranges of at most
/// [`READ_AT_ONCE`] bytes; anything else waits for the finished dataset (503).
pub(crate) async fn snapshot(
    s: &myriad_build::growing::Shown,
    content_type: &'static str,
    budget: &Budget,
    req: &Request<Incoming>,
) -> Response<Body> {
    let len = s.bytes.len();
    let etag = format!("\"build-{}-{len:x}\"", s.version);
    let range = (req.headers().get(header::RANGE)).and_then(|v| v.to_str().ok());
    let mut r = if req.method() == Method::HEAD {
        let mut r = Response::new(full(Bytes::new()));
        r.headers_mut()
            .insert(header::CONTENT_LENGTH, HeaderValue::from(len));
        r
    } else {
        match range.map(|h| range::parse(h, len)) {
            Some(Ranges::Some(v)) if v.len() == 1 && v[0].1 - v[0].0 < READ_AT_ONCE => {
                let (a, b) = v[0];
                let n = b - a + 1;
                let held = budget.take(n as usize).await;
                let bytes = s.bytes.clone();
                let read = tokio::task::spawn_blocking(move || bytes.read_at(a, n as usize)).await;
                match read {
                    Ok(Ok(data)) => {
                        let mut r =
                            Response::new(full(Bytes::from_owner(Owned { data, _held: held })));
                        *r.status_mut() = StatusCode::PARTIAL_CONTENT;
                        let h = r.headers_mut();
                        h.insert(header::CONTENT_LENGTH, HeaderValue::from(n));
                        h.insert(
                            header::CONTENT_RANGE,
                            HeaderValue::from_str(&format!("bytes {a}-{b}/{len}")).expect("ascii"),
                        );
                        r
                    }
                    Ok(Err(e)) => status(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
                    Err(e) => status(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
                }
            }
            Some(Ranges::Unsatisfiable) => {
                let mut r = status(StatusCode::RANGE_NOT_SATISFIABLE, "range not satisfiable");
                r.headers_mut().insert(
                    header::CONTENT_RANGE,
                    HeaderValue::from_str(&format!("bytes */{len}")).expect("ascii"),
                );
                r
            }
            _ => {
                let mut r = status(
                    StatusCode::SERVICE_UNAVAILABLE,
                    "this dataset is being built: single ranges of at most 4 MiB are served until it is done",
                );
                r.headers_mut()
                    .insert(header::RETRY_AFTER, HeaderValue::from_static("5"));
                r
            }
        }
    };
    let h = r.headers_mut();
    h.insert(header::ACCEPT_RANGES, HeaderValue::from_static("bytes"));
    h.insert(header::ETAG, HeaderValue::from_str(&etag).expect("ascii"));
    h.entry(header::CONTENT_TYPE)
        .or_insert(HeaderValue::from_static(content_type));
    r
}

/// `/d/NAME` of a name being built: the version asked for (`?v=`), else the newest, its name
/// in `X-Myriad-Version` and whether the build runs in `X-Myriad-Building`; 410 Gone for a
/// version no longer kept.
pub(crate) async fn answer_dataset(
    f: &catalog::File,
    live: &Live,
    budget: &Budget,
    req: &Request<Incoming>,
) -> Response<Body> {
    if let Some(why) = live.failure() {
        let mut r = status(
            StatusCode::INTERNAL_SERVER_ERROR,
            &format!("its build failed: {why}"),
        );
        let h = r.headers_mut();
        h.insert("x-myriad-building", HeaderValue::from_static("failed"));
        if let Ok(v) = HeaderValue::from_str(&why) {
            h.insert("x-myriad-failed", v);
        }
        return r;
    }
    let asked = (req.uri().query().unwrap_or("").split('&'))
        .find_map(|p| p.strip_prefix("v="))
        .map(str::to_string);
    let version = match &asked {
        Some(v) => live.version(v),
        None => Some(live.current()),
    };
    let Some(version) = version else {
        return status(
            StatusCode::GONE,
            "that version of the dataset is gone (it is being built): open it again",
        );
    };
    let mut r = match &version {
        Version::Preview(p, _) | Version::Final(p, _) => {
            match file(&f.at(p.clone()), budget, req).await {
                Ok(r) => r,
                Err(e) => status(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
            }
        }
        Version::Snapshot(s, _) => snapshot(s, f.content_type, budget, req).await,
    };
    let h = r.headers_mut();
    if let Ok(v) = HeaderValue::from_str(&version.name()) {
        h.insert("x-myriad-version", v);
    }
    h.insert(
        "x-myriad-building",
        HeaderValue::from_static(if live.is_building() { "yes" } else { "no" }),
    );
    r
}

/// A piece of an answer's body: text of its own, or bytes of the file (offset, length).
pub(crate) enum Piece {
    Text(Bytes),
    File(u64, u64),
}

/// A body of `list`'s pieces in order, the file's read in [`CHUNK`]s as the client takes them,
/// each held in the budget until written; `keep` lives as long as the body.
pub(crate) fn pieces(
    file: Arc<dyn ByteSource>,
    list: VecDeque<Piece>,
    budget: Budget,
    keep: Option<tokio::sync::OwnedSemaphorePermit>,
) -> Body {
    let chunks = futures_util::stream::unfold(
        (list, file, budget, keep),
        |(mut list, file, budget, keep)| async move {
            let piece = list.pop_front()?;
            let bytes = match piece {
                Piece::Text(b) => Ok(b),
                Piece::File(at, len) => {
                    let n = len.min(CHUNK as u64);
                    if n < len {
                        list.push_front(Piece::File(at + n, len - n));
                    }
                    let held = budget.take(n as usize).await;
                    let f = file.clone();
                    let read = tokio::task::spawn_blocking(move || f.read_at(at, n as usize))
                        .await
                        .map_err(io::Error::other)
                        .and_then(|r| r);
                    read.map(|data| Bytes::from_owner(Owned { data, _held: held }))
                }
            };
            if bytes.is_err() {
                // Nothing more after a failed read: the client sees a short body.
                list.clear();
            }
            Some((bytes.map(Frame::data), (list, file, budget, keep)))
        },
    );
    StreamBody::new(chunks).boxed()
}
