//! `myriad serve`: datasets, and folders of exported COPC and Potree files, over HTTP for
//! browsers and other viewers. HTTP/1.1 and HTTP/2 by `hyper` on `tokio`; what this crate adds
//! is what point-cloud readers need of a file server: byte ranges (one range: 206 with
//! `Content-Range`; several: `multipart/byteranges`; none satisfiable or malformed: 416), HEAD,
//! `ETag` with `If-Range` and `If-None-Match`, CORS with the preflight that `Range` forces, and
//! an index page (gzip where the client takes it).
//!
//! It is read-only and serves the files of its [`Catalog`] alone: a request's path is looked
//! up among the names the catalog made when it started, never joined to a folder, so `..` and
//! its encodings find nothing. Connections are bounded (`Options::max_connections`; more wait
//! to be accepted), a client has `Options::header_timeout` to send its request head and
//! `Options::max_header_bytes` for it (431 beyond), and a failing connection ends alone.

pub mod browser;
mod catalog;
pub mod download;
pub mod range;
mod viewer;

pub use catalog::{Catalog, Kind, href};

use bytes::Bytes;
use futures_util::TryStreamExt;
use http_body_util::{BodyExt, Full, StreamBody, combinators::BoxBody};
use hyper::body::{Frame, Incoming};
use hyper::header::{self, HeaderValue};
use hyper::{Method, Request, Response, StatusCode};
use hyper_util::rt::{TokioExecutor, TokioIo, TokioTimer};
use range::Ranges;
use std::convert::Infallible;
use std::io;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::io::AsyncReadExt;

type Body = BoxBody<Bytes, io::Error>;

/// Limits of the server.
#[derive(Debug, Clone, Copy)]
pub struct Options {
    /// Connections served at once; more wait in the listen queue.
    pub max_connections: usize,
    /// Time a client has to send its request head (slow clients are dropped).
    pub header_timeout: Duration,
    /// Most bytes of a request head (at least 8192).
    pub max_header_bytes: usize,
    /// A line on stderr for each request answered: method, path, range, status, bytes.
    pub log: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            max_connections: 512,
            header_timeout: Duration::from_secs(10),
            max_header_bytes: 16 << 10,
            log: false,
        }
    }
}

/// Most bytes of a multi-range answer (it is assembled in memory).
const MAX_MULTIPART: u64 = 64 << 20;
const BOUNDARY: &str = "myriad-byteranges-7d1f3a";

/// A running server; dropping it stops it.
pub struct Server {
    pub addr: SocketAddr,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Server {
    /// Binds `bind` (port 0: any free port) and serves `catalog` on a thread of its own.
    pub fn start(catalog: Catalog, bind: SocketAddr, options: Options) -> io::Result<Server> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .thread_name("myriad-serve")
            .build()?;
        let listener = runtime.block_on(tokio::net::TcpListener::bind(bind))?;
        let addr = listener.local_addr()?;
        let (stop, stopped) = tokio::sync::oneshot::channel();
        let catalog = Arc::new(catalog);
        let thread = std::thread::Builder::new()
            .name("myriad-serve-accept".into())
            .spawn(move || runtime.block_on(accept(listener, catalog, options, stopped)))?;
        Ok(Server {
            addr,
            stop: Some(stop),
            thread: Some(thread),
        })
    }

    /// Serves until the process ends.
    pub fn wait(mut self) {
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

async fn accept(
    listener: tokio::net::TcpListener,
    catalog: Arc<Catalog>,
    o: Options,
    mut stop: tokio::sync::oneshot::Receiver<()>,
) {
    let slots = Arc::new(tokio::sync::Semaphore::new(o.max_connections.max(1)));
    loop {
        let permit = tokio::select! {
            p = slots.clone().acquire_owned() => p.expect("semaphore open"),
            _ = &mut stop => return,
        };
        let stream = tokio::select! {
            r = listener.accept() => match r {
                Ok((s, _)) => s,
                Err(_) => {
                    // Out of descriptors or the like: wait, keep serving.
                    tokio::time::sleep(Duration::from_millis(20)).await;
                    continue;
                }
            },
            _ = &mut stop => return,
        };
        let _ = stream.set_nodelay(true);
        let catalog = catalog.clone();
        tokio::spawn(async move {
            let _permit = permit;
            let service =
                hyper::service::service_fn(move |req| handle(catalog.clone(), req, o.log));
            let mut b = hyper_util::server::conn::auto::Builder::new(TokioExecutor::new());
            b.http1()
                .timer(TokioTimer::new())
                .header_read_timeout(o.header_timeout)
                .max_buf_size(o.max_header_bytes.max(8192));
            b.http2().timer(TokioTimer::new());
            let _ = b.serve_connection(TokioIo::new(stream), service).await;
        });
    }
}

fn full(b: impl Into<Bytes>) -> Body {
    Full::new(b.into()).map_err(|e| match e {}).boxed()
}

fn status(code: StatusCode, text: &str) -> Response<Body> {
    let mut r = Response::new(full(format!("{text}\n")));
    *r.status_mut() = code;
    r.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/plain; charset=utf-8"),
    );
    r
}

/// CORS for every answer: any origin may read, and see the headers range readers need.
fn cors(r: &mut Response<Body>) {
    let h = r.headers_mut();
    h.insert(
        header::ACCESS_CONTROL_ALLOW_ORIGIN,
        HeaderValue::from_static("*"),
    );
    h.insert(
        header::ACCESS_CONTROL_EXPOSE_HEADERS,
        HeaderValue::from_static("Content-Range, Content-Length, Accept-Ranges, ETag"),
    );
}

/// `%XX` decoded; `None` where an escape is broken or the result is not UTF-8.
pub(crate) fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Box downloads running at once.
static DOWNLOADS: tokio::sync::Semaphore = tokio::sync::Semaphore::const_new(download::MAX_AT_ONCE);

async fn handle(
    catalog: Arc<Catalog>,
    req: Request<Incoming>,
    log: bool,
) -> Result<Response<Body>, Infallible> {
    let mut r = route(&catalog, &req).await;
    cors(&mut r);
    if log {
        let text =
            |v: Option<&HeaderValue>| v.and_then(|v| v.to_str().ok()).unwrap_or("-").to_string();
        eprintln!(
            "{} {} range={} {} {}",
            req.method(),
            req.uri(),
            text(req.headers().get(header::RANGE)),
            r.status().as_u16(),
            text(r.headers().get(header::CONTENT_LENGTH)),
        );
    }
    Ok(r)
}

async fn route(catalog: &Catalog, req: &Request<Incoming>) -> Response<Body> {
    let method = req.method();
    if ![Method::GET, Method::HEAD, Method::OPTIONS].contains(method) {
        let mut r = status(
            StatusCode::METHOD_NOT_ALLOWED,
            "read-only: GET, HEAD, OPTIONS",
        );
        r.headers_mut().insert(
            header::ALLOW,
            HeaderValue::from_static("GET, HEAD, OPTIONS"),
        );
        return r;
    }
    if method == Method::OPTIONS {
        let mut r = Response::new(full(Bytes::new()));
        *r.status_mut() = StatusCode::NO_CONTENT;
        let h = r.headers_mut();
        h.insert(
            header::ACCESS_CONTROL_ALLOW_METHODS,
            HeaderValue::from_static("GET, HEAD, OPTIONS"),
        );
        h.insert(
            header::ACCESS_CONTROL_ALLOW_HEADERS,
            HeaderValue::from_static("Range, If-Range, If-None-Match, Content-Type"),
        );
        h.insert(
            header::ACCESS_CONTROL_MAX_AGE,
            HeaderValue::from_static("86400"),
        );
        return r;
    }
    let path = req.uri().path();
    if path == "/" || path == "/index.html" {
        return asset(
            catalog.index_html().as_bytes(),
            None,
            "text/html; charset=utf-8",
            req,
        );
    }
    if let Some(name) = path.strip_prefix("/viewer/") {
        return match viewer::file(name) {
            Some(a) => asset(a.bytes, Some(a), a.content_type, req),
            None => status(StatusCode::NOT_FOUND, "not found"),
        };
    }
    if let Some(name) = path.strip_prefix("/view/") {
        return match percent_decode(name).and_then(|n| catalog.file(&n).map(|f| f.kind)) {
            Some(Kind::Dataset) => {
                let a = viewer::page();
                asset(a.bytes, Some(a), a.content_type, req)
            }
            _ => status(StatusCode::NOT_FOUND, "no such dataset"),
        };
    }
    if let Some(name) = path.strip_prefix("/x/") {
        let Some(name) = percent_decode(name) else {
            return status(StatusCode::BAD_REQUEST, "malformed path");
        };
        return match catalog.file(&name) {
            Some(f) if f.kind == Kind::Dataset => {
                box_download(f, &name, req.uri().query().unwrap_or("")).await
            }
            _ => status(StatusCode::NOT_FOUND, "no such dataset"),
        };
    }
    let Some(name) = path.strip_prefix("/d/") else {
        return status(StatusCode::NOT_FOUND, "not found");
    };
    let Some(name) = percent_decode(name) else {
        return status(StatusCode::BAD_REQUEST, "malformed path");
    };
    match catalog.file(&name) {
        Some(f) => match file(f, req).await {
            Ok(r) => r,
            Err(e) => status(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
        },
        None => status(StatusCode::NOT_FOUND, "not found"),
    }
}

/// A page or file of the server's own: gzip-compressed where the client takes it (`cached`
/// keeps the compressed bytes of a file compiled in).
fn asset(
    bytes: &[u8],
    cached: Option<&'static viewer::Asset>,
    content_type: &'static str,
    req: &Request<Incoming>,
) -> Response<Body> {
    let gzip = req
        .headers()
        .get(header::ACCEPT_ENCODING)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.split(',').any(|e| e.trim().starts_with("gzip")));
    let body = match (gzip, cached) {
        (true, Some(a)) => Bytes::from_static(a.gzip()),
        (true, None) => Bytes::from(viewer::gzip(bytes)),
        (false, _) => Bytes::copy_from_slice(bytes),
    };
    let len = body.len();
    let mut r = Response::new(if req.method() == Method::HEAD {
        full(Bytes::new())
    } else {
        full(body)
    });
    let h = r.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    h.insert(header::CONTENT_LENGTH, HeaderValue::from(len));
    h.insert(header::VARY, HeaderValue::from_static("Accept-Encoding"));
    if gzip {
        h.insert(header::CONTENT_ENCODING, HeaderValue::from_static("gzip"));
    }
    r
}

/// Ranges up to this size are read in one go on a blocking thread; larger answers stream.
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
    /// The whole file, or one range: read (`Some`) or to be streamed from the file, which is
    /// positioned at its start.
    One {
        range: Option<(u64, u64)>,
        data: Option<Vec<u8>>,
        file: std::fs::File,
    },
    /// Several ranges, read.
    Many(Vec<((u64, u64), Vec<u8>)>),
    TooLarge,
}

/// Opens the file, takes its validator, resolves the request's ranges and reads what is small
/// (one trip to the blocking pool for most requests).
fn plan(
    path: &std::path::Path,
    range: Option<String>,
    if_range: Option<String>,
    if_none_match: Option<String>,
    head: bool,
) -> io::Result<Plan> {
    use std::io::Seek;
    use std::os::unix::fs::FileExt;
    let mut file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    let len = meta.len();
    let mtime = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    let etag = format!("\"{len:x}-{mtime:x}\"");
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
    let read = |a: u64, b: u64| -> io::Result<Vec<u8>> {
        let mut buf = vec![0; (b - a + 1) as usize];
        file.read_exact_at(&mut buf, a)?;
        Ok(buf)
    };
    let answer = match ranges {
        Ranges::Unsatisfiable => Answer::Unsatisfiable,
        Ranges::Whole => Answer::One {
            range: None,
            data: None,
            file,
        },
        Ranges::Some(v) if v.len() == 1 => {
            let (a, b) = v[0];
            let data = (!head && b - a < READ_AT_ONCE)
                .then(|| read(a, b))
                .transpose()?;
            file.seek(io::SeekFrom::Start(a))?;
            Answer::One {
                range: Some((a, b)),
                data,
                file,
            }
        }
        Ranges::Some(v) => {
            if v.iter().map(|(a, b)| b - a + 1).sum::<u64>() > MAX_MULTIPART {
                Answer::TooLarge
            } else {
                Answer::Many(
                    v.into_iter()
                        .map(|(a, b)| Ok(((a, b), read(a, b)?)))
                        .collect::<io::Result<_>>()?,
                )
            }
        }
    };
    Ok(Plan { len, etag, answer })
}

/// One served file, as the request asks for it.
async fn file(f: &catalog::File, req: &Request<Incoming>) -> io::Result<Response<Body>> {
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
    let path = f.path.clone();
    let Plan { len, etag, answer } =
        tokio::task::spawn_blocking(move || plan(&path, range, if_range, if_none_match, head))
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
        Answer::TooLarge => unsatisfiable("ranges too large"),
        Answer::One { range, data, file } => {
            let (a, b) = range.unwrap_or((0, len.saturating_sub(1)));
            let n = if len == 0 { 0 } else { b - a + 1 };
            let body = match (head, data) {
                (true, _) => full(Bytes::new()),
                (false, Some(d)) => full(d),
                (false, None) => stream(tokio::fs::File::from_std(file), n),
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
        Answer::Many(parts) => {
            let mut body = Vec::new();
            for ((a, b), data) in parts {
                body.extend_from_slice(
                    format!(
                        "\r\n--{BOUNDARY}\r\nContent-Type: {}\r\nContent-Range: bytes {a}-{b}/{len}\r\n\r\n",
                        f.content_type
                    )
                    .as_bytes(),
                );
                body.extend_from_slice(&data);
            }
            body.extend_from_slice(format!("\r\n--{BOUNDARY}--\r\n").as_bytes());
            let n = body.len();
            let mut r = Response::new(if head { full(Bytes::new()) } else { full(body) });
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

/// The points of a dataset in a box, as LAZ ([`download`]).
async fn box_download(f: &catalog::File, name: &str, query: &str) -> Response<Body> {
    let q = match download::parse_query(query) {
        Ok(q) => q,
        Err(m) => return status(StatusCode::BAD_REQUEST, &m),
    };
    let _turn = DOWNLOADS.acquire().await.expect("never closed");
    let path = f.path.clone();
    let made = tokio::task::spawn_blocking(move || download::run(&path, &q)).await;
    let (file, points) = match made {
        Ok(Ok(r)) => r,
        Ok(Err(m)) => return status(StatusCode::INTERNAL_SERVER_ERROR, &m),
        Err(e) => return status(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
    };
    let len = match file.metadata() {
        Ok(m) => m.len(),
        Err(e) => return status(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
    };
    let stem = name.trim_end_matches(".myr").replace(['"', '/', '\\'], "_");
    let mut r = Response::new(stream(tokio::fs::File::from_std(file), len));
    let h = r.headers_mut();
    h.insert(header::CONTENT_LENGTH, HeaderValue::from(len));
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/vnd.laszip"),
    );
    if let Ok(v) = HeaderValue::from_str(&format!("attachment; filename=\"{stem}-box.laz\"")) {
        h.insert(header::CONTENT_DISPOSITION, v);
    }
    h.insert("x-myriad-points", HeaderValue::from(points));
    r
}

/// `len` bytes of the file from where it stands, in chunks as the client takes them.
fn stream(file: tokio::fs::File, len: u64) -> Body {
    let chunks = tokio_util::io::ReaderStream::with_capacity(file.take(len), 256 << 10);
    StreamBody::new(chunks.map_ok(Frame::data)).boxed()
}
