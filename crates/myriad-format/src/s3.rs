//! `s3://BUCKET/KEY`: objects on Amazon S3 or an S3-compatible server (SeaweedFS, MinIO, Ceph)
//! read by range requests as datasets on a web server are ([`crate::remote::HttpBytes`]), each
//! request signed with AWS Signature Version 4.
//!
//! Credentials and the server come from the environment as the AWS tools read them:
//! `AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`, `AWS_SESSION_TOKEN` (temporary credentials),
//! `AWS_REGION` or `AWS_DEFAULT_REGION` (else us-east-1), and `AWS_ENDPOINT_URL_S3` or
//! `AWS_ENDPOINT_URL` for a server other than AWS's (else `https://s3.REGION.amazonaws.com`).
//! Objects are addressed by path (`ENDPOINT/BUCKET/KEY`), which every S3-compatible server
//! takes. Without credentials, requests go unsigned (public buckets).
//!
//! The signature is written here rather than taken from the AWS SDK: it is a short function of
//! HMAC-SHA256 and SHA-256, which `ring` (already in the tree under rustls) provides, while the
//! SDK's `aws-sigv4` brings its own runtime; the requests themselves stay `ureq`'s, with the
//! retries, limits and version checks that HTTP datasets have.

use myriad_core::{Error, Result};
use ring::{digest, hmac};
use std::io::{Read, Write};
use std::path::Path;
use std::time::{Duration, SystemTime};

/// Objects up to this size are written with one `PUT`; larger ones in parts of this size
/// (S3's multipart upload: parts of 5 MiB and more, up to 10,000 of them).
const PART: usize = 16 << 20;

/// A bucket and a key, from `s3://BUCKET/KEY`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    pub bucket: String,
    pub key: String,
}

/// Whether `path` is `s3://...`.
pub fn is_s3(path: &Path) -> bool {
    path.to_str().is_some_and(|s| s.starts_with("s3://"))
}

/// `s3://BUCKET/KEY` (a key of at least one character).
pub fn parse(s: &str) -> Option<Location> {
    let rest = s.strip_prefix("s3://")?;
    let (bucket, key) = rest.split_once('/')?;
    (!bucket.is_empty() && !key.is_empty()).then(|| Location {
        bucket: bucket.to_string(),
        key: key.to_string(),
    })
}

/// Where requests go and what signs them.
#[derive(Debug, Clone)]
pub struct Config {
    /// `http(s)://HOST[:PORT]`, without a trailing slash.
    pub endpoint: String,
    pub region: String,
    /// Access key, secret key and session token; `None`: unsigned requests.
    pub credentials: Option<(String, String, Option<String>)>,
}

impl Config {
    /// The configuration the environment gives (see the module's text).
    pub fn from_env() -> Config {
        let var = |k: &str| std::env::var(k).ok().filter(|v| !v.trim().is_empty());
        let region = var("AWS_REGION")
            .or_else(|| var("AWS_DEFAULT_REGION"))
            .unwrap_or_else(|| "us-east-1".into());
        let endpoint = var("AWS_ENDPOINT_URL_S3")
            .or_else(|| var("AWS_ENDPOINT_URL"))
            .unwrap_or_else(|| format!("https://s3.{region}.amazonaws.com"));
        let credentials = match (var("AWS_ACCESS_KEY_ID"), var("AWS_SECRET_ACCESS_KEY")) {
            (Some(a), Some(s)) => Some((a, s, var("AWS_SESSION_TOKEN"))),
            _ => None,
        };
        Config {
            endpoint: endpoint.trim_end_matches('/').to_string(),
            region,
            credentials,
        }
    }

    /// The object's URL (path style).
    pub fn url(&self, at: &Location) -> String {
        format!(
            "{}/{}/{}",
            self.endpoint,
            encode(&at.bucket, false),
            encode(&at.key, false)
        )
    }

    /// The headers that sign a request of `method` to `url` with a body whose SHA-256 is
    /// `payload` (hex, or `UNSIGNED-PAYLOAD`), at `now`, covering also the headers `extra`
    /// (sent as they are by the caller): `x-amz-date`, `x-amz-content-sha256`,
    /// `x-amz-security-token` with temporary credentials, and `Authorization`. Empty without
    /// credentials. `url`'s query string, if any, must be in canonical order already.
    pub fn sign(
        &self,
        method: &str,
        url: &str,
        payload: &str,
        extra: &[(&str, &str)],
        now: SystemTime,
    ) -> Vec<(String, String)> {
        let Some((access, secret, token)) = &self.credentials else {
            return Vec::new();
        };
        let (date, stamp) = amz_date(now);
        let after_scheme = url.split_once("://").map_or(url, |x| x.1);
        let (host, rest) = match after_scheme.find('/') {
            Some(i) => (&after_scheme[..i], &after_scheme[i..]),
            None => (after_scheme, "/"),
        };
        let (path, query) = rest.split_once('?').unwrap_or((rest, ""));
        let mut headers = vec![
            ("host".to_string(), host.to_string()),
            ("x-amz-content-sha256".to_string(), payload.to_string()),
            ("x-amz-date".to_string(), stamp.clone()),
        ];
        if let Some(t) = token {
            headers.push(("x-amz-security-token".to_string(), t.clone()));
        }
        headers.extend(
            extra
                .iter()
                .map(|(k, v)| (k.to_ascii_lowercase(), v.to_string())),
        );
        headers.sort();
        let signed: Vec<&str> = headers.iter().map(|h| h.0.as_str()).collect();
        let signed = signed.join(";");
        let canonical = format!(
            "{method}\n{path}\n{query}\n{}\n{signed}\n{payload}",
            headers
                .iter()
                .map(|(k, v)| format!("{k}:{}\n", v.trim()))
                .collect::<String>()
        );
        let scope = format!("{date}/{}/s3/aws4_request", self.region);
        let to_sign = format!(
            "AWS4-HMAC-SHA256\n{stamp}\n{scope}\n{}",
            hex(digest::digest(&digest::SHA256, canonical.as_bytes()).as_ref())
        );
        let mac = |key: &[u8], data: &str| {
            hmac::sign(&hmac::Key::new(hmac::HMAC_SHA256, key), data.as_bytes())
        };
        let k = mac(format!("AWS4{secret}").as_bytes(), &date);
        let k = mac(k.as_ref(), &self.region);
        let k = mac(k.as_ref(), "s3");
        let k = mac(k.as_ref(), "aws4_request");
        let signature = hex(mac(k.as_ref(), &to_sign).as_ref());
        let mut out: Vec<(String, String)> = headers
            .into_iter()
            .filter(|h| h.0.starts_with("x-amz-"))
            .collect();
        out.push((
            "Authorization".to_string(),
            format!(
                "AWS4-HMAC-SHA256 Credential={access}/{scope}, SignedHeaders={signed}, Signature={signature}"
            ),
        ));
        out
    }
}

/// Requests to one S3 server: whole objects copied to and from files (inputs a command reads
/// as files, outputs it writes as files). Datasets are read by range requests instead
/// ([`crate::remote::HttpBytes`]).
pub struct Client {
    config: Config,
    agent: ureq::Agent,
}

/// An answer: its status, its `ETag`, and its body (or for a download, nothing).
struct Answer {
    status: u16,
    etag: Option<String>,
    body: String,
}

impl Client {
    pub fn from_env() -> Result<Client> {
        let tls = crate::tls::trusted().map_err(Error::Invalid)?;
        let agent = ureq::Agent::config_builder()
            .tls_config(tls)
            .http_status_as_error(false)
            .timeout_connect(Some(Duration::from_secs(10)))
            .timeout_recv_response(Some(Duration::from_secs(120)))
            .build()
            .into();
        Ok(Client {
            config: Config::from_env(),
            agent,
        })
    }

    /// One signed request (`query` canonical: keys sorted, values encoded); for a `GET` with
    /// `to`, the body goes there.
    fn request(
        &self,
        method: &str,
        at: &Location,
        query: &str,
        body: &[u8],
        to: Option<&mut dyn Write>,
    ) -> std::result::Result<Answer, String> {
        let mut url = self.config.url(at);
        if !query.is_empty() {
            url = format!("{url}?{query}");
        }
        let payload = sha256_hex(body);
        let headers = self
            .config
            .sign(method, &url, &payload, &[], SystemTime::now());
        let result = match method {
            "GET" | "HEAD" | "DELETE" => {
                let mut r = match method {
                    "GET" => self.agent.get(&url),
                    "HEAD" => self.agent.head(&url),
                    _ => self.agent.delete(&url),
                };
                for (k, v) in &headers {
                    r = r.header(k.as_str(), v.as_str());
                }
                r.call()
            }
            _ => {
                let mut r = match method {
                    "PUT" => self.agent.put(&url),
                    _ => self.agent.post(&url),
                };
                for (k, v) in &headers {
                    r = r.header(k.as_str(), v.as_str());
                }
                r.send(body)
            }
        };
        let mut r = result.map_err(|e| format!("{e}"))?;
        let status = r.status().as_u16();
        let etag = r
            .headers()
            .get("etag")
            .and_then(|v| v.to_str().ok())
            .map(str::to_string);
        let mut text = String::new();
        match to {
            Some(out) if status == 200 => {
                std::io::copy(&mut r.body_mut().as_reader(), out).map_err(|e| e.to_string())?;
            }
            _ if method != "HEAD" => {
                text = r
                    .body_mut()
                    .with_config()
                    .limit(1 << 20)
                    .read_to_string()
                    .unwrap_or_default();
            }
            _ => {}
        }
        Ok(Answer {
            status,
            etag,
            body: text,
        })
    }

    /// The request, its failure (no answer, or an answer other than `want`) as an error naming
    /// the object.
    fn expect(
        &self,
        method: &str,
        at: &Location,
        query: &str,
        body: &[u8],
        to: Option<&mut dyn Write>,
        want: u16,
    ) -> Result<Answer> {
        let name = format!("s3://{}/{}", at.bucket, at.key);
        let a = self
            .request(method, at, query, body, to)
            .map_err(|e| Error::Invalid(format!("{name}: {e}")))?;
        if a.status == want {
            return Ok(a);
        }
        let hint = match a.status {
            401 | 403 => {
                " (credentials from AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY and AWS_SESSION_TOKEN; \
                 the server from AWS_ENDPOINT_URL_S3 or AWS_ENDPOINT_URL)"
            }
            404 => " (no such object or bucket)",
            _ => "",
        };
        Err(Error::Invalid(format!(
            "{name}: {method} answered HTTP {}: {}{hint}",
            a.status,
            message(&a.body)
        )))
    }

    /// Whether the object exists.
    pub fn exists(&self, at: &Location) -> Result<bool> {
        match self.expect("HEAD", at, "", b"", None, 200) {
            Ok(_) => Ok(true),
            Err(e) if e.to_string().contains("HTTP 404") => Ok(false),
            Err(e) => Err(e),
        }
    }

    /// Copies the object to the file `to` (written whole, then moved to its name). Its bytes.
    pub fn download(&self, at: &Location, to: &Path) -> Result<u64> {
        let file = myriad_io::atomic::AtomicFile::create(to, true)?;
        let mut out = std::io::BufWriter::new(file.open_write()?);
        self.expect("GET", at, "", b"", Some(&mut out), 200)?;
        let f = out
            .into_inner()
            .map_err(|e| Error::io(to, e.into_error()))?;
        f.sync_all().map_err(|e| Error::io(to, e))?;
        let n = f.metadata().map_err(|e| Error::io(to, e))?.len();
        file.commit()?;
        Ok(n)
    }

    /// Writes the file `from` as the object: one `PUT` up to [`PART`] bytes, else a multipart
    /// upload (aborted when a part fails). The object appears whole or not at all. Its bytes.
    pub fn upload(&self, from: &Path, at: &Location) -> Result<u64> {
        let mut f = std::fs::File::open(from).map_err(|e| Error::io(from, e))?;
        let len = f.metadata().map_err(|e| Error::io(from, e))?.len();
        let mut buf = vec![0u8; PART.min(len as usize)];
        if len as usize <= PART {
            f.read_exact(&mut buf).map_err(|e| Error::io(from, e))?;
            self.expect("PUT", at, "", &buf, None, 200)?;
            return Ok(len);
        }
        let created = self.expect("POST", at, "uploads=", b"", None, 200)?;
        let id = tag(&created.body, "UploadId").ok_or_else(|| {
            Error::Invalid(format!(
                "s3://{}/{}: no UploadId in the server's answer",
                at.bucket, at.key
            ))
        })?;
        let id_q = encode(&id, true);
        let parts = (|| -> Result<Vec<String>> {
            let mut etags = Vec::new();
            let mut left = len;
            while left > 0 {
                let n = (left as usize).min(PART);
                f.read_exact(&mut buf[..n])
                    .map_err(|e| Error::io(from, e))?;
                let q = format!("partNumber={}&uploadId={id_q}", etags.len() + 1);
                let a = self.expect("PUT", at, &q, &buf[..n], None, 200)?;
                etags.push(a.etag.unwrap_or_default());
                left -= n as u64;
            }
            Ok(etags)
        })();
        let etags = match parts {
            Ok(e) => e,
            Err(e) => {
                let _ = self.request("DELETE", at, &format!("uploadId={id_q}"), b"", None);
                return Err(e);
            }
        };
        let mut xml = String::from("<CompleteMultipartUpload>");
        for (i, e) in etags.iter().enumerate() {
            xml.push_str(&format!(
                "<Part><PartNumber>{}</PartNumber><ETag>{e}</ETag></Part>",
                i + 1
            ));
        }
        xml.push_str("</CompleteMultipartUpload>");
        let done = self.expect(
            "POST",
            at,
            &format!("uploadId={id_q}"),
            xml.as_bytes(),
            None,
            200,
        );
        // S3 may answer 200 with an error document after a while.
        match done {
            Ok(a) if !a.body.contains("<Error>") => Ok(len),
            Ok(a) => {
                let _ = self.request("DELETE", at, &format!("uploadId={id_q}"), b"", None);
                Err(Error::Invalid(format!(
                    "s3://{}/{}: the upload did not complete: {}",
                    at.bucket,
                    at.key,
                    message(&a.body)
                )))
            }
            Err(e) => {
                let _ = self.request("DELETE", at, &format!("uploadId={id_q}"), b"", None);
                Err(e)
            }
        }
    }
}

/// The text of the first `<NAME>` element of an XML answer.
fn tag(xml: &str, name: &str) -> Option<String> {
    let (_, rest) = xml.split_once(&format!("<{name}>"))?;
    let (v, _) = rest.split_once(&format!("</{name}>"))?;
    Some(v.to_string())
}

/// An S3 error document's message, else the text's first line (at most 200 characters).
pub(crate) fn message(body: &str) -> String {
    let m = tag(body, "Message").unwrap_or_else(|| body.to_string());
    m.lines()
        .next()
        .unwrap_or("")
        .trim()
        .chars()
        .take(200)
        .collect()
}

/// The SHA-256 of `bytes`, in hex (a request body's, for [`Config::sign`]).
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(digest::digest(&digest::SHA256, bytes).as_ref())
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// URI-encodes as SigV4 asks: unreserved characters kept, `/` kept unless `slash`, the rest as
/// `%XX`.
fn encode(s: &str, slash: bool) -> String {
    let mut out = String::with_capacity(s.len());
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || b"-_.~".contains(&b) || (b == b'/' && !slash) {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// `YYYYMMDD` and `YYYYMMDDTHHMMSSZ` of `t`, in UTC.
fn amz_date(t: SystemTime) -> (String, String) {
    let secs = t
        .duration_since(SystemTime::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Days since 1970-01-01 to a civil date (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    let date = format!("{y:04}{m:02}{d:02}");
    let stamp = format!(
        "{date}T{:02}{:02}{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    );
    (date, stamp)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn locations_and_urls() {
        assert_eq!(
            parse("s3://scans/city/ky.myr"),
            Some(Location {
                bucket: "scans".into(),
                key: "city/ky.myr".into()
            })
        );
        assert_eq!(parse("s3://scans/"), None);
        assert_eq!(parse("s3://scans"), None);
        assert_eq!(parse("http://x/y"), None);
        let c = Config {
            endpoint: "http://127.0.0.1:8333".into(),
            region: "us-east-1".into(),
            credentials: None,
        };
        assert_eq!(
            c.url(&parse("s3://b/a dir/k+1.myr").unwrap()),
            "http://127.0.0.1:8333/b/a%20dir/k%2B1.myr"
        );
        assert!(
            c.sign(
                "GET",
                "http://127.0.0.1:8333/b/k",
                "UNSIGNED-PAYLOAD",
                &[],
                SystemTime::now()
            )
            .is_empty()
        );
    }

    #[test]
    fn dates_in_utc() {
        let at = |s: u64| amz_date(SystemTime::UNIX_EPOCH + Duration::from_secs(s));
        assert_eq!(at(0), ("19700101".into(), "19700101T000000Z".into()));
        // 2013-05-24T00:00:00Z, and 2024-02-29T23:59:59Z (a leap day).
        assert_eq!(at(1_369_353_600).1, "20130524T000000Z");
        assert_eq!(at(1_709_251_199).1, "20240229T235959Z");
    }

    /// The example of AWS's documentation ("Signature Calculations for the Authorization
    /// Header", GET Object): its keys, time and request give its signature.
    #[test]
    fn the_signature_of_aws_s_example() {
        let c = Config {
            endpoint: "https://examplebucket.s3.amazonaws.com".into(),
            region: "us-east-1".into(),
            credentials: Some((
                "AKIAIOSFODNN7EXAMPLE".into(),
                "wJalrXUtnFEMI/K7MDENG/bPxRfiCYEXAMPLEKEY".into(),
                None,
            )),
        };
        let now = SystemTime::UNIX_EPOCH + Duration::from_secs(1_369_353_600);
        let empty = sha256_hex(b"");
        assert_eq!(
            empty,
            "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
        );
        let h = c.sign(
            "GET",
            "https://examplebucket.s3.amazonaws.com/test.txt",
            &empty,
            &[("Range", "bytes=0-9")],
            now,
        );
        let auth = &h.iter().find(|x| x.0 == "Authorization").unwrap().1;
        assert_eq!(
            auth,
            "AWS4-HMAC-SHA256 Credential=AKIAIOSFODNN7EXAMPLE/20130524/us-east-1/s3/aws4_request, \
             SignedHeaders=host;range;x-amz-content-sha256;x-amz-date, \
             Signature=f0e8bdb87c964420e857bd35b5d6ed310bd44f0170aba48dd91039c6036bdb41"
        );
        assert!(h.contains(&("x-amz-date".into(), "20130524T000000Z".into())));
    }
}
