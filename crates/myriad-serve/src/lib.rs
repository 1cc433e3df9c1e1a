//! `myriad serve`: datasets, and folders of exported COPC and Potree files, over HTTP for
//! browsers and other viewers. HTTP/1.1 and HTTP/2 by `hyper` on `tokio`; what this crate adds
//! is what point-cloud readers need of a file server: byte ranges (one range: 206 with
//! `Content-Range`; several: `multipart/byteranges`; none satisfiable or malformed: 416), HEAD,
//! `ETag` with `If-Range` and `If-None-Match`, CORS with the preflight that `Range` forces, and
//! an index page (gzip where the client takes it).
//!
//! It serves the files of its [`Catalog`] alone, read-only but for datasets' saved work with
//! `Options::edit` ([`work`]): a request's path is looked
//! up among the names the catalog made when it started, never joined to a folder, so `..` and
//! its encodings find nothing. Connections are bounded (`Options::max_connections`; when full,
//! the connection idle the longest is shed for a new one), a client has
//! `Options::header_timeout` to send its request head and `Options::max_header_bytes` for it
//! (431 beyond), idle connections close after `Options::idle_timeout`, and a failing
//! connection ends alone ([`conn`] says how). Answers stream from the files (multi-range ones
//! too, their overlapping ranges merged) through a memory budget per connection and in all.
//! A client that hangs up costs nothing: SIGPIPE is ignored, and its unfinished work is
//! dropped. A private server ([`access`], `Server::start_with`) answers only the requests that
//! carry its token, its one-time link's cookie or a signed link (401, or 403 for an expired
//! link, before anything of a dataset is read).

pub mod access;
pub mod browser;
mod catalog;
mod conn;
pub mod download;
mod edits;
mod files;
mod geo;
pub mod live;
mod photos;
pub mod range;
pub mod tls;
pub mod viewer;
mod work;

pub use catalog::{Catalog, Kind, href};

use bytes::Bytes;
use conn::Budget;
use http_body_util::{BodyExt, Full, combinators::BoxBody};
use hyper::body::Incoming;
use hyper::header::{self, HeaderValue};
use hyper::{Method, Request, Response, StatusCode};
use hyper_util::rt::{TokioExecutor, TokioIo, TokioTimer};
use std::collections::VecDeque;
use std::convert::Infallible;
use std::io;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;
use tokio::sync::Semaphore;

type Body = BoxBody<Bytes, io::Error>;

/// Limits of the server.
#[derive(Debug, Clone)]
pub struct Options {
    /// Connections served at once; when full, the connection idle the longest is closed for a
    /// new one (a new one that finds none idle waits up to `header_timeout`).
    pub max_connections: usize,
    /// Time a client has from connecting to send its first request head (silent and slow
    /// clients are dropped).
    pub header_timeout: Duration,
    /// A connection on which nothing moved for this long while no request of it is being
    /// worked on is closed (keep-alive, clients that stop reading).
    pub idle_timeout: Duration,
    /// Most bytes of a request head (at least 8192).
    pub max_header_bytes: usize,
    /// Most bytes of file data held in memory by all answers at once.
    pub max_memory: usize,
    /// Most points a box download (`/x/`) may hold: a larger box is answered 413.
    pub max_box_points: u64,
    /// Stop on SIGINT and SIGTERM (removing the server's temporary files) instead of dying.
    pub stop_on_signals: bool,
    /// A line on stderr for each request answered: method, path, range, status, bytes.
    pub log: bool,
    /// Clients may save a dataset's work (PUT `/work/NAME`), which replaces its sidecar.
    pub edit: bool,
    /// Origins whose pages may read the answers (CORS: `https://host:port`, or `*` for any);
    /// none by default: pages of other origins read nothing. No origin but the server's own
    /// ever writes.
    pub allow_origins: Vec<String>,
    /// Names this server answers to besides loopback ones when bound to a loopback address (a
    /// reverse proxy's public name, passed on in `Host`).
    pub server_names: Vec<String>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            max_connections: 512,
            header_timeout: Duration::from_secs(10),
            idle_timeout: Duration::from_secs(30),
            max_header_bytes: 16 << 10,
            max_memory: 256 << 20,
            max_box_points: 20_000_000,
            stop_on_signals: false,
            log: false,
            edit: false,
            allow_origins: Vec::new(),
            server_names: Vec::new(),
        }
    }
}

const BOUNDARY: &str = "myriad-byteranges-7d1f3a";
/// File data is read and written in pieces of this size.
const CHUNK: usize = 256 << 10;
/// Box downloads whose LAZ files wait to be sent or are being sent, at once (each is a
/// temporary file on disk); more wait their turn.
const SPOOLED_AT_ONCE: usize = 8;
/// The prefix of a server's folder of temporary files under the system's temporary folder.
const SCRATCH_PREFIX: &str = ".myriad-serve-scratch-";

/// What the server has done about its clients, counted since it started.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Stats {
    /// Box downloads whose extraction began, finished, was dropped because the client left,
    /// and refused as too large.
    pub downloads_started: u64,
    pub downloads_finished: u64,
    pub downloads_cancelled: u64,
    pub downloads_refused: u64,
    /// Connections closed for sending no request in time, for idling, because their client
    /// hung up during a request, and shed for a new client.
    pub closed_no_request: u64,
    pub closed_idle: u64,
    pub closed_hung_up: u64,
    pub shed: u64,
}

#[derive(Default)]
struct Counters([AtomicU64; 8]);

impl Counters {
    fn add(&self, i: usize) {
        self.0[i].fetch_add(1, Ordering::Relaxed);
    }
    fn get(&self) -> Stats {
        let g = |i: usize| self.0[i].load(Ordering::Relaxed);
        Stats {
            downloads_started: g(0),
            downloads_finished: g(1),
            downloads_cancelled: g(2),
            downloads_refused: g(3),
            closed_no_request: g(4),
            closed_idle: g(5),
            closed_hung_up: g(6),
            shed: g(7),
        }
    }
}

/// What every connection of a server shares.
struct Shared {
    catalog: Catalog,
    /// Bound to a loopback address: only requests naming a loopback host are answered (a page
    /// whose name was rebound to 127.0.0.1 names its own).
    loopback: bool,
    options: Options,
    memory: Arc<Semaphore>,
    registry: conn::Registry,
    counters: Counters,
    /// Box downloads extracting at once, and spooled at once.
    extracting: Arc<Semaphore>,
    spooled: Arc<Semaphore>,
    /// The server's temporary files (box downloads), removed when it stops; one a killed
    /// server left is removed by the next server to start.
    scratch: myriad_io::claim::Folder,
    /// Saved work's bodies being read at once, and one sidecar written at a time.
    puts: Semaphore,
    /// Edits' changes and layers being read, written or answered at once (`edits.rs`).
    edits: Semaphore,
    saving: Arc<std::sync::Mutex<()>>,
    /// Who may read (none: everyone).
    access: Option<access::Access>,
    /// TLS on every connection (none: plain HTTP).
    tls: Option<tls::TlsAcceptor>,
    /// Picked points to longitude and latitude (`/geo/`).
    geo: geo::Geo,
}

/// A running server; dropping it stops it.
pub struct Server {
    pub addr: SocketAddr,
    shared: Arc<Shared>,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Server {
    /// Binds `bind` (port 0: any free port) and serves `catalog` on a thread of its own.
    pub fn start(catalog: Catalog, bind: SocketAddr, options: Options) -> io::Result<Server> {
        Server::start_with(catalog, bind, options, None, None)
    }

    /// [`Server::start`], private where `access` says who may read, over TLS where `tls` is
    /// given (its cookies then marked `Secure`).
    pub fn start_with(
        catalog: Catalog,
        bind: SocketAddr,
        options: Options,
        mut access: Option<access::Access>,
        tls: Option<tls::TlsAcceptor>,
    ) -> io::Result<Server> {
        if let Some(a) = &mut access {
            a.secure = tls.is_some();
        }
        // A client that hangs up while its answer is written must cost a failed write, not
        // the process (hyper writes with writev, which has no MSG_NOSIGNAL).
        #[cfg(unix)]
        // SAFETY: setting a signal's disposition to "ignore" has no preconditions.
        unsafe {
            libc::signal(libc::SIGPIPE, libc::SIG_IGN);
        }
        let tmp = std::env::temp_dir();
        myriad_io::claim::remove_stale_folders(&tmp, SCRATCH_PREFIX);
        remove_stale_partials(&tmp);
        let scratch = myriad_io::claim::Folder::create(&tmp, SCRATCH_PREFIX)
            .map_err(|e| io::Error::other(e.to_string()))?;
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .thread_name("myriad-serve")
            .build()?;
        let listener = runtime.block_on(tokio::net::TcpListener::bind(bind))?;
        let addr = listener.local_addr()?;
        let (stop, stopped) = tokio::sync::oneshot::channel();
        let memory = options.max_memory.max(conn::PER_CONNECTION) >> 10;
        let shared = Arc::new(Shared {
            catalog,
            loopback: addr.ip().is_loopback(),
            options,
            memory: Arc::new(Semaphore::new(memory)),
            registry: conn::Registry::default(),
            counters: Counters::default(),
            extracting: Arc::new(Semaphore::new(download::MAX_AT_ONCE)),
            spooled: Arc::new(Semaphore::new(SPOOLED_AT_ONCE)),
            scratch,
            puts: Semaphore::new(work::PUTS_AT_ONCE),
            edits: Semaphore::new(edits::AT_ONCE),
            saving: Arc::default(),
            access,
            tls,
            geo: geo::Geo::default(),
        });
        let s = shared.clone();
        let thread = std::thread::Builder::new()
            .name("myriad-serve-accept".into())
            .spawn(move || {
                runtime.block_on(accept(listener, s, stopped));
                // Connections still open are dropped with the runtime.
                runtime.shutdown_timeout(Duration::from_secs(1));
            })?;
        Ok(Server {
            addr,
            shared,
            stop: Some(stop),
            thread: Some(thread),
        })
    }

    /// What the server has done about its clients so far.
    pub fn stats(&self) -> Stats {
        self.shared.counters.get()
    }

    /// A new one-time link's path (`/login/CODE`) for a private server.
    pub fn one_time_link(&self) -> Option<String> {
        (self.shared.access.as_ref()).map(|a| format!("/login/{}", a.one_time_code()))
    }

    /// The folder of the server's temporary files.
    pub fn scratch(&self) -> &std::path::Path {
        self.shared.scratch.path()
    }

    /// Serves until the process ends, or until SIGINT or SIGTERM with
    /// `Options::stop_on_signals`; the server's temporary files are removed then.
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

/// Removes the partial downloads that servers before the scratch folder left in `tmp`.
fn remove_stale_partials(tmp: &std::path::Path) {
    let Ok(entries) = std::fs::read_dir(tmp) else {
        return;
    };
    for e in entries.flatten() {
        let n = e.file_name();
        let n = n.to_string_lossy();
        if n.starts_with(".myriad-serve-")
            && n.ends_with(".partial")
            && e.path().is_file()
            && myriad_io::claim::is_stale_file(&e.path())
        {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

async fn signalled(on: bool) {
    if !on {
        return std::future::pending().await;
    }
    use tokio::signal::unix::{SignalKind, signal};
    match (
        signal(SignalKind::interrupt()),
        signal(SignalKind::terminate()),
    ) {
        (Ok(mut i), Ok(mut t)) => {
            tokio::select! {
                _ = i.recv() => {}
                _ = t.recv() => {}
            }
        }
        _ => std::future::pending().await,
    }
}

async fn accept(
    listener: tokio::net::TcpListener,
    shared: Arc<Shared>,
    mut stop: tokio::sync::oneshot::Receiver<()>,
) {
    let o = shared.options.clone();
    let slots = Arc::new(Semaphore::new(o.max_connections.max(1)));
    let signals = signalled(o.stop_on_signals);
    tokio::pin!(signals);
    'accept: loop {
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
            _ = &mut signals => return,
        };
        // Full: shed the idlest connection for this one, or wait for a slot (a while).
        let permit = match slots.clone().try_acquire_owned() {
            Ok(p) => p,
            Err(_) => {
                let waited = std::time::Instant::now();
                loop {
                    if shared.registry.shed_idlest() {
                        shared.counters.add(7);
                    }
                    tokio::select! {
                        p = slots.clone().acquire_owned() => break p.expect("semaphore open"),
                        _ = tokio::time::sleep(conn::SHED_AFTER) => {
                            if waited.elapsed() > o.header_timeout {
                                continue 'accept;
                            }
                        }
                        _ = &mut stop => return,
                        _ = &mut signals => return,
                    }
                }
            }
        };
        let _ = stream.set_nodelay(true);
        let shared = shared.clone();
        tokio::spawn(async move {
            let _permit = permit;
            use std::os::fd::AsRawFd;
            let fd = stream.as_raw_fd();
            let activity = conn::Activity::new();
            shared.registry.add(&activity);
            let io = conn::Watched {
                inner: stream,
                activity: activity.clone(),
            };
            let budget = Budget::new(shared.memory.clone());
            let (s, a) = (shared.clone(), activity.clone());
            let service = hyper::service::service_fn(move |req| {
                let busy = a.request();
                handle(s.clone(), budget.clone(), req, busy, fd)
            });
            let mut b = hyper_util::server::conn::auto::Builder::new(TokioExecutor::new());
            b.http1()
                .timer(TokioTimer::new())
                .header_read_timeout(o.header_timeout)
                .max_buf_size(o.max_header_bytes.max(8192));
            b.http2()
                .timer(TokioTimer::new())
                .max_concurrent_streams(32)
                .max_header_list_size(o.max_header_bytes.max(8192) as u32);
            // The TLS handshake, where there is one, under the same watch as a first request.
            let tls = shared.tls.clone();
            let served = async move {
                match tls {
                    None => {
                        let _ = b.serve_connection(TokioIo::new(io), service).await;
                    }
                    Some(acceptor) => {
                        if let Ok(s) = acceptor.accept(io).await {
                            let _ = b.serve_connection(TokioIo::new(s), service).await;
                        }
                    }
                }
            };
            let why = conn::watch(served, &activity, fd, o.header_timeout, o.idle_timeout).await;
            match why {
                conn::Closed::NoRequest => shared.counters.add(4),
                conn::Closed::Idle => shared.counters.add(5),
                conn::Closed::HungUp => shared.counters.add(6),
                conn::Closed::Done | conn::Closed::Shed => {}
            }
        });
    }
}

pub(crate) fn full(b: impl Into<Bytes>) -> Body {
    Full::new(b.into()).map_err(|e| match e {}).boxed()
}

pub(crate) fn status(code: StatusCode, text: &str) -> Response<Body> {
    let mut r = Response::new(full(format!("{text}\n")));
    *r.status_mut() = code;
    r.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/plain; charset=utf-8"),
    );
    r
}

/// CORS: a page of another origin reads an answer only where the user allowed its origin
/// (`--allow-origin`), and then sees the headers range readers need.
fn cors(r: &mut Response<Body>, origin: Option<&str>, allowed: &[String]) {
    let h = r.headers_mut();
    h.append(header::VARY, HeaderValue::from_static("Origin"));
    let Some(origin) = origin else { return };
    let value = if allowed.iter().any(|a| a == "*") {
        HeaderValue::from_static("*")
    } else if allowed.iter().any(|a| a.eq_ignore_ascii_case(origin)) {
        match HeaderValue::from_str(origin) {
            Ok(v) => v,
            Err(_) => return,
        }
    } else {
        return;
    };
    h.insert(header::ACCESS_CONTROL_ALLOW_ORIGIN, value);
    h.insert(
        header::ACCESS_CONTROL_EXPOSE_HEADERS,
        HeaderValue::from_static(
            "Content-Range, Content-Length, Accept-Ranges, ETag, X-Myriad-Version, X-Myriad-Building, X-Myriad-Failed",
        ),
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

async fn handle(
    shared: Arc<Shared>,
    budget: Budget,
    req: Request<Incoming>,
    _busy: conn::Busy,
    fd: std::os::fd::RawFd,
) -> Result<Response<Body>, Infallible> {
    let range = req.headers().get(header::RANGE).cloned();
    let (method, uri) = (req.method().clone(), req.uri().clone());
    let put = method == Method::PUT && uri.path().starts_with("/work/");
    let post = method == Method::POST && uri.path().starts_with("/edits/");
    let origin = (req.headers().get(header::ORIGIN))
        .and_then(|v| v.to_str().ok())
        .map(str::to_string);
    let mut cookie = None;
    let denied = match &shared.access {
        _ if let Some(r) = misdirected(&shared, &req) => Some(r),
        _ if (put || post)
            && let Some(r) = foreign_write(&req, origin.as_deref()) =>
        {
            Some(r)
        }
        Some(a) => match admit(a, &req) {
            Ok(c) => {
                cookie = c;
                None
            }
            Err(r) => Some(*r),
        },
        None => None,
    };
    let mut r = if let Some(r) = denied {
        r
    } else if put {
        match percent_decode(&uri.path()["/work/".len()..]) {
            Some(name) => work::put(&shared, &name, req).await,
            None => status(StatusCode::BAD_REQUEST, "malformed path"),
        }
    } else if post {
        match percent_decode(&uri.path()["/edits/".len()..]) {
            Some(name) => edits::post(&shared, &name, req).await,
            None => status(StatusCode::BAD_REQUEST, "malformed path"),
        }
    } else {
        route(&shared, &budget, &req, fd).await
    };
    if let Some(c) = cookie.and_then(|c| HeaderValue::from_str(&c).ok()) {
        r.headers_mut().append(header::SET_COOKIE, c);
    }
    cors(&mut r, origin.as_deref(), &shared.options.allow_origins);
    if shared.options.log {
        let text =
            |v: Option<&HeaderValue>| v.and_then(|v| v.to_str().ok()).unwrap_or("-").to_string();
        eprintln!(
            "{} {} range={} {} {}",
            method,
            uri,
            text(range.as_ref()),
            r.status().as_u16(),
            text(r.headers().get(header::CONTENT_LENGTH)),
        );
    }
    Ok(r)
}

/// The host a request names (`Host`, or HTTP/2's authority), without its port.
fn host_of(req: &Request<Incoming>) -> Option<String> {
    let h = (req.headers().get(header::HOST))
        .and_then(|v| v.to_str().ok())
        .map(str::to_string)
        .or_else(|| req.uri().authority().map(|a| a.as_str().to_string()))?;
    let h = h.trim().to_ascii_lowercase();
    Some(match h.strip_prefix('[') {
        // [::1]:8080
        Some(v6) => v6.split(']').next().unwrap_or("").to_string(),
        None => h
            .rsplit_once(':')
            .map_or(h.clone(), |(host, _)| host.to_string()),
    })
}

/// A server bound to a loopback address answers only requests that name a loopback host: a
/// page whose own name was rebound to 127.0.0.1 (DNS rebinding) names its own, and is refused
/// (421). A request naming no host (HTTP/1.0) is answered.
fn misdirected(shared: &Shared, req: &Request<Incoming>) -> Option<Response<Body>> {
    if !shared.loopback {
        return None;
    }
    let host = host_of(req)?;
    let local = host == "localhost"
        || host.ends_with(".localhost")
        || host
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback());
    (!local).then(|| {
        status(
            StatusCode::MISDIRECTED_REQUEST,
            &format!(
                "this server on a loopback address answers localhost (and --server-name), not {host:?}"
            ),
        )
    })
}

/// Saved work is written only by pages of the server's own origin: a PUT whose `Origin` is
/// another (a page elsewhere, whatever CORS allows it to read) is refused (403). Browsers send
/// `Origin` with every PUT; a client without one (curl, with the token where the server is
/// private) is taken.
fn foreign_write(req: &Request<Incoming>, origin: Option<&str>) -> Option<Response<Body>> {
    let origin = origin?;
    let host = (req.headers().get(header::HOST))
        .and_then(|v| v.to_str().ok())
        .map(str::to_string)
        .or_else(|| req.uri().authority().map(|a| a.as_str().to_string()))
        .unwrap_or_default();
    let own = origin
        .split_once("://")
        .is_some_and(|(_, rest)| rest.eq_ignore_ascii_case(&host));
    (!own).then(|| {
        status(
            StatusCode::FORBIDDEN,
            &format!(
                "a page of {origin} cannot write here: only this server's own pages save work"
            ),
        )
    })
}

/// Whether a private server answers `req`: `Ok` with a cookie to set (a one-time link's
/// session, a signed link's), or the answer that refuses it (401, 403; a one-time link's
/// redirect).
fn admit(
    a: &access::Access,
    req: &Request<Incoming>,
) -> Result<Option<String>, Box<Response<Body>>> {
    use access::Verdict;
    let path = req.uri().path();
    if req.method() == Method::OPTIONS || path.starts_with("/viewer/") {
        return Ok(None);
    }
    if let Some(code) = path.strip_prefix("/login/") {
        // A HEAD (a link preview, a checker) asks without spending the link.
        if req.method() == Method::HEAD {
            return Err(Box::new(match a.is_code(code) {
                true => status(StatusCode::OK, "a one-time link: open it to sign in"),
                false => unauthorized("this one-time link was used already, or is not one"),
            }));
        }
        return Err(Box::new(match a.redeem(code) {
            Some(session) => {
                let mut r = status(StatusCode::SEE_OTHER, "signed in");
                let h = r.headers_mut();
                h.insert(header::LOCATION, HeaderValue::from_static("/"));
                let age = Some(access::SESSION_SECONDS);
                if let Ok(c) =
                    HeaderValue::from_str(&a.cookie(access::SESSION_COOKIE, &session, age))
                {
                    h.insert(header::SET_COOKIE, c);
                }
                r
            }
            None => unauthorized("this one-time link was used already, or is not one"),
        }));
    }
    let h = req.headers();
    let auth = h.get(header::AUTHORIZATION).and_then(|v| v.to_str().ok());
    // HTTP/2 may send the cookies as several fields.
    let cookies: Vec<&str> = (h.get_all(header::COOKIE).iter())
        .filter_map(|v| v.to_str().ok())
        .collect();
    let cookies = cookies.join("; ");
    let now = access::now();
    match a.check(path, req.uri().query(), auth, Some(&cookies), now) {
        Verdict::Allowed => Ok(None),
        Verdict::AllowedSetting(v, until) => Ok(Some(a.cookie(
            access::LINK_COOKIE,
            &v,
            Some(until.saturating_sub(now)),
        ))),
        Verdict::Missing => Err(Box::new(unauthorized(
            "private: give the token (Authorization: Bearer TOKEN), or open the one-time or signed link",
        ))),
        Verdict::Wrong => Err(Box::new(unauthorized(
            "the token, cookie or link signature is not right",
        ))),
        Verdict::Expired(t) => Err(Box::new(status(
            StatusCode::FORBIDDEN,
            &format!(
                "this link expired {} s ago; ask for a new one",
                now.saturating_sub(t)
            ),
        ))),
    }
}

fn unauthorized(text: &str) -> Response<Body> {
    let mut r = status(StatusCode::UNAUTHORIZED, text);
    r.headers_mut().insert(
        header::WWW_AUTHENTICATE,
        HeaderValue::from_static("Bearer realm=\"myriad\""),
    );
    r
}

/// `fd`: the connection's socket (whether its client is still there before long work starts).
async fn route(
    shared: &Arc<Shared>,
    budget: &Budget,
    req: &Request<Incoming>,
    fd: std::os::fd::RawFd,
) -> Response<Body> {
    let catalog = &shared.catalog;
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
            // Never PUT: pages of other origins do not write (`foreign_write`).
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
    if let Some(name) = path.strip_prefix("/edits/") {
        return match percent_decode(name) {
            Some(name) => edits::get(shared, budget, &name, req).await,
            None => status(StatusCode::BAD_REQUEST, "malformed path"),
        };
    }
    if let Some(name) = path.strip_prefix("/photos/") {
        return match percent_decode(name) {
            Some(name) => photos::get(shared, budget, &name, req).await,
            None => status(StatusCode::BAD_REQUEST, "malformed path"),
        };
    }
    if let Some(name) = path.strip_prefix("/work/") {
        return match percent_decode(name) {
            Some(name) => work::get(shared, &name, method == Method::HEAD).await,
            None => status(StatusCode::BAD_REQUEST, "malformed path"),
        };
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
    if let Some(name) = path.strip_prefix("/geo/") {
        let Some(name) = percent_decode(name) else {
            return status(StatusCode::BAD_REQUEST, "malformed path");
        };
        let at = match geo::question(req.uri().query().unwrap_or("")) {
            Ok(q) => q,
            Err(m) => return status(StatusCode::BAD_REQUEST, &m),
        };
        return match catalog.file(&name) {
            Some(f) if f.kind == Kind::Dataset => {
                let Some(f) = settled(f) else {
                    return being_built();
                };
                let (s, path) = (shared.clone(), f.path.clone());
                let (code, body) = tokio::task::spawn_blocking(move || s.geo.answer(&path, at))
                    .await
                    .unwrap_or((500, "the question failed".into()));
                if code != 200 {
                    let code =
                        StatusCode::from_u16(code).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
                    return status(code, &body);
                }
                let mut r = Response::new(full(body));
                r.headers_mut().insert(
                    header::CONTENT_TYPE,
                    HeaderValue::from_static("application/json"),
                );
                r
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
                let Some(f) = settled(f) else {
                    return being_built();
                };
                let query = req.uri().query().unwrap_or("");
                box_download(shared, budget, &f, &name, query, fd).await
            }
            _ => status(StatusCode::NOT_FOUND, "no such dataset"),
        };
    }
    if let Some(name) = path.strip_prefix("/build/") {
        let Some(name) = percent_decode(name) else {
            return status(StatusCode::BAD_REQUEST, "malformed path");
        };
        return match catalog.file(&name).and_then(|f| f.live.clone()) {
            Some(live) => live::answer_changes(live, req.uri().query().unwrap_or("")).await,
            None => status(
                StatusCode::NOT_FOUND,
                "no dataset of that name is being built",
            ),
        };
    }
    let Some(name) = path.strip_prefix("/d/") else {
        return status(StatusCode::NOT_FOUND, "not found");
    };
    let Some(name) = percent_decode(name) else {
        return status(StatusCode::BAD_REQUEST, "malformed path");
    };
    let Some(f) = catalog.file(&name) else {
        return status(StatusCode::NOT_FOUND, "not found");
    };
    let Some(live) = &f.live else {
        return match files::file(f, budget, req).await {
            Ok(r) => r,
            Err(e) => status(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
        };
    };
    files::answer_dataset(f, live, budget, req).await
}

/// A served dataset as it is for good: itself, or a built one's finished dataset; `None` while
/// it is being built.
pub(crate) fn settled(f: &catalog::File) -> Option<catalog::File> {
    match &f.live {
        None => Some(f.clone()),
        Some(l) => match l.current() {
            live::Version::Final(p, _) => Some(f.at(p)),
            _ => None,
        },
    }
}

pub(crate) fn being_built() -> Response<Body> {
    let mut r = status(
        StatusCode::SERVICE_UNAVAILABLE,
        "this dataset is being built: ask again when it is done",
    );
    r.headers_mut()
        .insert(header::RETRY_AFTER, HeaderValue::from_static("5"));
    r
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

/// Sets its flag when dropped: the request it belongs to was abandoned (or is done).
struct CancelOnDrop(Arc<AtomicBool>);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

/// The points of a dataset in a box, as LAZ ([`download`]).
async fn box_download(
    shared: &Arc<Shared>,
    budget: &Budget,
    f: &catalog::File,
    name: &str,
    query: &str,
    fd: std::os::fd::RawFd,
) -> Response<Body> {
    let q = match download::parse_query(query) {
        Ok(q) => q,
        Err(m) => return status(StatusCode::BAD_REQUEST, &m),
    };
    // A place for its file first (held until it is sent), then a turn to extract.
    let spooled = shared
        .spooled
        .clone()
        .acquire_owned()
        .await
        .expect("never closed");
    // The turn goes with the extraction's thread: one whose client left holds it until it stops
    // at its next node, so abandoned extractions never run beside the next ones.
    let turn = shared
        .extracting
        .clone()
        .acquire_owned()
        .await
        .expect("never closed");
    // A client that left while it waited (its connection's watchdog may not have seen it yet)
    // does not start an extraction.
    if conn::peer_closed(fd) {
        return status(StatusCode::SERVICE_UNAVAILABLE, "cancelled");
    }
    let cancelled = Arc::new(AtomicBool::new(false));
    let _cancel = CancelOnDrop(cancelled.clone());
    shared.counters.add(0);
    let limits = download::Limits {
        max_points: shared.options.max_box_points,
        scratch: shared.scratch.path().to_path_buf(),
    };
    let path = f.path.clone();
    let s = shared.clone();
    // On a thread of its own at a lower priority: the costliest requests a client can make
    // must not slow the ranges every viewer reads (with them at the same priority, 64 clients
    // on 2 cores got 0.77 x their requests/s beside 8 downloads).
    let (done, made) = tokio::sync::oneshot::channel();
    let spawned = std::thread::Builder::new()
        .name("myriad-extract".into())
        .spawn(move || {
            download::background_priority();
            let _turn = turn;
            // Between nodes: gone, or wait (a second at most) while the server's other threads
            // are at work.
            let gone = || cancelled.load(Ordering::Relaxed);
            let between = || {
                download::yield_while_busy(Duration::from_secs(1), &gone);
                gone()
            };
            let r = download::run(&path, &q, &limits, &between);
            if matches!(r, Err(download::Failed::Cancelled)) {
                s.counters.add(2);
            }
            let _ = done.send(r);
        });
    if let Err(e) = spawned {
        return status(StatusCode::SERVICE_UNAVAILABLE, &format!("no thread: {e}"));
    }
    let made = made.await;
    let (file, points) = match made {
        Ok(Ok(r)) => r,
        Ok(Err(download::Failed::TooLarge(m))) => {
            shared.counters.add(3);
            return status(StatusCode::PAYLOAD_TOO_LARGE, &m);
        }
        Ok(Err(download::Failed::Cancelled)) => {
            return status(StatusCode::SERVICE_UNAVAILABLE, "cancelled");
        }
        Ok(Err(download::Failed::Bad(m))) => {
            return status(StatusCode::BAD_REQUEST, &m);
        }
        Ok(Err(download::Failed::Other(m))) => {
            return status(StatusCode::INTERNAL_SERVER_ERROR, &m);
        }
        Err(e) => return status(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
    };
    shared.counters.add(1);
    let file = match myriad_format::FileBytes::of(file) {
        Ok(f) => f,
        Err(e) => return status(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
    };
    let len = myriad_format::ByteSource::len(&file);
    let stem = name.trim_end_matches(".myr").replace(['"', '/', '\\'], "_");
    let body = files::pieces(
        Arc::new(file),
        VecDeque::from([files::Piece::File(0, len)]),
        budget.clone(),
        Some(spooled),
    );
    let mut r = Response::new(body);
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
