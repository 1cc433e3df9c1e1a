//! Datasets over HTTP: a [`ByteSource`] that reads byte ranges with `Range` requests, so that
//! a dataset on a web server opens as a file does and only the pages a command needs cross the
//! network. The `ureq` crate makes the requests (blocking, one per read, connections kept
//! alive and shared by the threads that read); this type adds what a dataset reader needs of
//! them: a server that ignores `Range` is refused at once with an error that says so, failed
//! reads are retried with backoff, at most [`MAX_IN_FLIGHT`] requests are out at a time, and the
//! bytes fetched are counted.
//!
//! Every read is of one version of the resource: the first answer's `ETag` goes with every later
//! request as `If-Range` (a server whose file changed answers with the whole new file instead
//! of the range), and each answer's ETag and length are compared with the first's. Once the
//! resource has changed, this read and every later one fail with [`CHANGED`], and
//! [`ByteSource::changed`] says so: a command stops there, never mixing pages of two versions.
//!
//! A private server's token goes with every request: [`set_headers`] (the command line's
//! `--header "NAME: VALUE"`), else the environment's `MYRIAD_HEADER` (headers, one a line) and
//! `MYRIAD_TOKEN` (as `Authorization: Bearer TOKEN`). A 401 or 403 answer says what to give.
//! `https://` is checked against Mozilla's roots, or only against the certificates of the PEM
//! file `MYRIAD_CA_CERT` names (a server's own, self-signed one; [`crate::tls`], which S3's
//! requests share).

use crate::ByteSource;
use crate::tls::trusted;
use myriad_core::{Error, Result};
use std::io;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Condvar, Mutex};
use std::time::Duration;

/// Most requests a source has out at once (the loader threads and the selection share them).
pub const MAX_IN_FLIGHT: usize = 8;
/// Attempts per read: a failed connection, a timeout or a 5xx/429 answer is tried again.
const ATTEMPTS: u32 = 4;
/// The start of the error of a read after the resource changed on its server.
pub const CHANGED: &str = "changed on the server while it was read";

static HEADERS: std::sync::OnceLock<Vec<(String, String)>> = std::sync::OnceLock::new();

/// `NAME: VALUE` as a header (the name checked).
pub fn parse_header(s: &str) -> std::result::Result<(String, String), String> {
    let (k, v) = s
        .split_once(':')
        .ok_or_else(|| format!("--header \"{s}\": NAME: VALUE expected"))?;
    let k = k.trim();
    if k.is_empty()
        || !k
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"-_".contains(&b))
    {
        return Err(format!("--header \"{s}\": \"{k}\" is not a header name"));
    }
    if v.bytes().any(|b| b == b'\r' || b == b'\n') {
        return Err(format!("--header \"{k}\": a value of one line"));
    }
    Ok((k.to_string(), v.trim().to_string()))
}

/// The headers every request sends from now on (the first call wins; call it before
/// opening anything).
pub fn set_headers(h: Vec<(String, String)>) {
    let _ = HEADERS.set(h);
}

/// The headers requests carry: [`set_headers`]'s, else the environment's.
fn headers() -> &'static [(String, String)] {
    HEADERS.get_or_init(|| {
        let mut out = Vec::new();
        if let Ok(t) = std::env::var("MYRIAD_TOKEN")
            && !t.trim().is_empty()
        {
            out.push(("Authorization".into(), format!("Bearer {}", t.trim())));
        }
        if let Ok(h) = std::env::var("MYRIAD_HEADER") {
            out.extend(h.lines().filter(|l| !l.trim().is_empty()).filter_map(|l| {
                parse_header(l)
                    .map_err(|e| eprintln!("warning: MYRIAD_HEADER: {e}"))
                    .ok()
            }));
        }
        out
    })
}

/// Whether `path` names a dataset on a web server or in S3-compatible storage (`s3://`, read
/// through its HTTP interface, [`crate::s3`]) rather than a file.
pub fn is_url(path: &Path) -> bool {
    path.to_str().is_some_and(|s| {
        s.starts_with("http://") || s.starts_with("https://") || s.starts_with("s3://")
    })
}

/// A resource read by HTTP range requests.
pub struct HttpBytes {
    url: String,
    /// Requests to S3 are signed with these (and carry no `--header`s).
    s3: Option<crate::s3::Config>,
    agent: ureq::Agent,
    len: u64,
    /// The first bytes, read when opening (the dataset header is read from them).
    head: Vec<u8>,
    slots: Mutex<usize>,
    freed: Condvar,
    requests: AtomicU64,
    fetched: AtomicU64,
    /// The first answer's validator (none when the server gives none: the length is compared).
    etag: Option<String>,
    /// Set once an answer came from another version.
    changed: Mutex<Option<String>>,
}

/// What went wrong with one request: worth another attempt or not.
enum Failure {
    Retry(String),
    Fatal(String),
}

impl HttpBytes {
    /// Asks for the first [`crate::HEADER_LEN`] bytes of `url` (kept: the dataset header): the
    /// answer must be 206 with a `Content-Range` that gives the resource's length.
    pub fn open(url: &str) -> Result<HttpBytes> {
        HttpBytes::open_with_head(url, crate::HEADER_LEN)
    }

    /// [`HttpBytes::open`] asking for the first `head` bytes in the opening request (kept):
    /// a COPC file's header and VLRs, or the whole of a small file, in one round trip.
    pub fn open_with_head(url: &str, head: usize) -> Result<HttpBytes> {
        if crate::s3::is_s3(Path::new(url)) {
            let at = crate::s3::parse(url)
                .ok_or_else(|| Error::Invalid(format!("{url}: not s3://BUCKET/KEY")))?;
            let config = crate::s3::Config::from_env();
            return HttpBytes::open_as(&config.url(&at), url, Some(config), head);
        }
        HttpBytes::open_as(url, url, None, head)
    }

    /// Opens `url`, naming it `name` in errors, its requests signed for S3 with `s3`.
    fn open_as(
        url: &str,
        name: &str,
        s3: Option<crate::s3::Config>,
        head: usize,
    ) -> Result<HttpBytes> {
        let tls = trusted().map_err(|e| Error::io(Path::new(name), io::Error::other(e)))?;
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .tls_config(tls)
            .http_status_as_error(false)
            .timeout_connect(Some(Duration::from_secs(10)))
            .timeout_recv_body(Some(Duration::from_secs(60)))
            .timeout_recv_response(Some(Duration::from_secs(30)))
            .build()
            .into();
        let mut h = HttpBytes {
            url: url.to_string(),
            s3,
            agent,
            len: u64::MAX,
            head: Vec::new(),
            slots: Mutex::new(MAX_IN_FLIGHT),
            freed: Condvar::new(),
            requests: AtomicU64::new(0),
            fetched: AtomicU64::new(0),
            etag: None,
            changed: Mutex::new(None),
        };
        let (head, total, etag) =
            (h.range(0, head.max(1))).map_err(|e| Error::io(Path::new(name), e))?;
        h.len = total;
        h.head = head;
        h.etag = etag;
        Ok(h)
    }

    /// Requests made and bytes received so far.
    pub fn stats(&self) -> (u64, u64) {
        (
            self.requests.load(Ordering::Relaxed),
            self.fetched.load(Ordering::Relaxed),
        )
    }

    /// Reads `len` bytes at `offset` (retrying); also returns the resource's whole length and
    /// validator.
    fn range(&self, offset: u64, len: usize) -> io::Result<(Vec<u8>, u64, Option<String>)> {
        if let Some(m) = self.changed.lock().expect("changed lock").clone() {
            return Err(io::Error::other(m));
        }
        {
            let mut free = self.slots.lock().expect("slots lock");
            while *free == 0 {
                free = self.freed.wait(free).expect("slots lock");
            }
            *free -= 1;
        }
        let mut result = Err(io::Error::other("no attempt made"));
        for attempt in 0..ATTEMPTS {
            if attempt > 0 {
                std::thread::sleep(Duration::from_millis(100 << attempt));
            }
            match self.attempt(offset, len) {
                Ok(r) => {
                    result = Ok(r);
                    break;
                }
                Err(Failure::Fatal(m)) => {
                    result = Err(io::Error::other(m));
                    break;
                }
                Err(Failure::Retry(m)) => {
                    result = Err(io::Error::other(format!(
                        "{m} (after {} attempts)",
                        attempt + 1
                    )))
                }
            }
        }
        *self.slots.lock().expect("slots lock") += 1;
        self.freed.notify_one();
        result
    }

    /// Marks the resource as changed; the error every read gives from now on.
    fn changed_now(&self, why: String) -> Failure {
        let m = format!("{CHANGED} ({why}): start again");
        *self.changed.lock().expect("changed lock") = Some(m.clone());
        Failure::Fatal(m)
    }

    fn attempt(
        &self,
        offset: u64,
        len: usize,
    ) -> std::result::Result<(Vec<u8>, u64, Option<String>), Failure> {
        let last = offset + len.max(1) as u64 - 1;
        self.requests.fetch_add(1, Ordering::Relaxed);
        let mut req = self
            .agent
            .get(&self.url)
            .header("Range", format!("bytes={offset}-{last}"))
            .header("Accept-Encoding", "identity");
        if let Some(e) = &self.etag {
            req = req.header("If-Range", e);
        }
        match &self.s3 {
            Some(s3) => {
                for (k, v) in s3.sign(
                    "GET",
                    &self.url,
                    "UNSIGNED-PAYLOAD",
                    &[],
                    std::time::SystemTime::now(),
                ) {
                    req = req.header(k.as_str(), v.as_str());
                }
            }
            None => {
                for (k, v) in headers() {
                    req = req.header(k.as_str(), v.as_str());
                }
            }
        }
        let mut r = req.call().map_err(|e| {
            let m = e.to_string();
            if m.contains("certificate") {
                // Not worth another attempt.
                Failure::Fatal(format!(
                    "{m} (a server's own certificate is trusted with MYRIAD_CA_CERT=CERT.pem)"
                ))
            } else {
                Failure::Retry(m)
            }
        })?;
        let status = r.status().as_u16();
        let etag = r
            .headers()
            .get("etag")
            .and_then(|v| v.to_str().ok())
            .map(str::to_string);
        match status {
            206 => {}
            200 if self.etag.is_some() => {
                return Err(self.changed_now(format!(
                    "a whole file came for If-Range {}",
                    self.etag.as_deref().unwrap_or_default()
                )));
            }
            200 => {
                return Err(Failure::Fatal(
                    "the server ignores Range requests (it answered 200 with the whole file); \
                     serve the dataset with `myriad serve` or a server that supports Range"
                        .into(),
                ));
            }
            416 => {
                return Err(Failure::Fatal(format!(
                    "bytes {offset}-{last} lie past the end of the resource (416)"
                )));
            }
            // A dataset whose build failed on `myriad serve`: said, not retried.
            500 if r
                .headers()
                .get("x-myriad-building")
                .is_some_and(|v| v == "failed") =>
            {
                let why = (r.headers().get("x-myriad-failed"))
                    .and_then(|v| v.to_str().ok())
                    .unwrap_or("no reason given")
                    .to_string();
                return Err(Failure::Fatal(format!(
                    "HTTP 500: its build on the server failed: {why}"
                )));
            }
            429 | 500..=599 => return Err(Failure::Retry(format!("HTTP {status}"))),
            401 | 403 if self.s3.is_some() => {
                let why = r.body_mut().read_to_string().unwrap_or_default();
                return Err(Failure::Fatal(format!(
                    "HTTP {status}: {} (S3 credentials come from AWS_ACCESS_KEY_ID, \
                     AWS_SECRET_ACCESS_KEY and AWS_SESSION_TOKEN; the server from \
                     AWS_ENDPOINT_URL_S3 or AWS_ENDPOINT_URL, the region from AWS_REGION)",
                    crate::s3::message(&why)
                )));
            }
            404 if self.s3.is_some() => {
                return Err(Failure::Fatal(format!(
                    "no such object at {} (HTTP 404)",
                    self.url
                )));
            }
            401 | 403 => {
                let why = r.body_mut().read_to_string().unwrap_or_default();
                return Err(Failure::Fatal(format!(
                    "HTTP {status}: {} (a private server: give its token with --header \
                     \"Authorization: Bearer TOKEN\" or MYRIAD_TOKEN, or a signed link)",
                    why.trim()
                )));
            }
            s => return Err(Failure::Fatal(format!("HTTP {s}"))),
        }
        let range = r
            .headers()
            .get("content-range")
            .and_then(|v| v.to_str().ok())
            .map(str::to_string)
            .ok_or_else(|| Failure::Fatal("a 206 answer without Content-Range".into()))?;
        let (start, total) = parse_content_range(&range)
            .ok_or_else(|| Failure::Fatal(format!("unreadable Content-Range \"{range}\"")))?;
        if start != offset {
            return Err(Failure::Fatal(format!(
                "asked for bytes from {offset}, got them from {start}"
            )));
        }
        // Not the first request: the same version as the first's, or nothing.
        if self.len != u64::MAX {
            if let (Some(was), Some(now)) = (&self.etag, &etag)
                && was != now
            {
                return Err(self.changed_now(format!("ETag {was}, now {now}")));
            }
            if total != self.len {
                return Err(self.changed_now(format!("{} bytes, now {total}", self.len)));
            }
        }
        let body = r
            .body_mut()
            .with_config()
            .limit(len as u64 + 1)
            .read_to_vec()
            .map_err(|e| Failure::Retry(e.to_string()))?;
        self.fetched.fetch_add(body.len() as u64, Ordering::Relaxed);
        let want = len.min(total.saturating_sub(offset) as usize);
        if body.len() != want {
            return Err(Failure::Retry(format!(
                "{} bytes came for {want} asked",
                body.len()
            )));
        }
        Ok((body, total, etag))
    }
}

/// `bytes START-END/TOTAL`: start and total.
fn parse_content_range(v: &str) -> Option<(u64, u64)> {
    let rest = v.trim().strip_prefix("bytes ")?;
    let (span, total) = rest.split_once('/')?;
    let (start, _) = span.split_once('-')?;
    Some((start.trim().parse().ok()?, total.trim().parse().ok()?))
}

impl ByteSource for HttpBytes {
    fn len(&self) -> u64 {
        self.len
    }
    fn read_at(&self, offset: u64, len: usize) -> io::Result<Vec<u8>> {
        if offset.saturating_add(len as u64) > self.len {
            return Err(io::Error::new(
                io::ErrorKind::UnexpectedEof,
                "range past the end of the resource",
            ));
        }
        if len == 0 {
            return Ok(Vec::new());
        }
        if offset.saturating_add(len as u64) <= self.head.len() as u64 {
            return Ok(self.head[offset as usize..offset as usize + len].to_vec());
        }
        self.range(offset, len).map(|(b, _, _)| b)
    }
    fn fetched(&self) -> Option<(u64, u64)> {
        Some(self.stats())
    }
    fn changed(&self) -> Option<String> {
        self.changed.lock().expect("changed lock").clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn content_ranges_and_urls() {
        assert_eq!(parse_content_range("bytes 0-63/1000"), Some((0, 1000)));
        assert_eq!(parse_content_range("bytes 10-19/*"), None);
        assert_eq!(parse_content_range("items 0-1/2"), None);
        assert!(is_url(Path::new("http://127.0.0.1:8080/d/ky.myr")));
        assert!(!is_url(Path::new("ky.myr")));
    }
}
