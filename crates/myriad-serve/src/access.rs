//! Private serving (`serve --token-file F`): who may read what the server serves. A request is
//! let through when it carries one of the file's tokens (`Authorization: Bearer TOKEN`), the
//! session cookie a one-time link set (`/login/CODE`, printed when the server starts; a code
//! works once), or a link signed for one dataset that has not expired (`?expires=UNIX&sig=HEX`
//! on `/view/NAME`, `/d/NAME`, `/x/NAME`, `/geo/NAME`, `/work/NAME`, `/edits/NAME` or `/photos/NAME`; the page's
//! own requests then carry a cookie with that signature). Signatures and the session cookie are HMAC-SHA256 (`ring`) under
//! a key derived from the token file, so a link signed by `serve --sign` holds for every server
//! started with the same file, and none holds once the file's tokens change. The viewer's code
//! (`/viewer/...`) and CORS preflights are public: they hold nothing of a dataset.
//!
//! A missing or wrong token or signature is answered 401, an expired link 403, before anything
//! of the dataset is read.

use myriad_core::units::{hex, unhex};
use ring::hmac;
use std::collections::HashSet;
use std::sync::Mutex;

/// The cookie a one-time link sets (every dataset), and the one a signed link sets (its dataset).
pub const SESSION_COOKIE: &str = "myriad_session";
pub const LINK_COOKIE: &str = "myriad_link";

/// How long a session from a one-time link lasts (seconds): 12 hours.
pub const SESSION_SECONDS: u64 = 12 * 3600;

/// Tokens, the signing key and the one-time codes not used yet.
pub struct Access {
    /// Each token's tag under `key`: a token is checked by its tag, in constant time.
    tags: Vec<hmac::Tag>,
    key: hmac::Key,
    codes: Mutex<HashSet<String>>,
    /// Cookies marked `Secure` (the server speaks TLS).
    pub secure: bool,
}

/// What a request may have.
#[derive(Debug, PartialEq)]
pub enum Verdict {
    Allowed,
    /// A signed link used: allowed, and this cookie value set (until the link's time) for the
    /// page's own requests.
    AllowedSetting(String, u64),
    /// No token, cookie or signature: 401.
    Missing,
    /// A token, cookie or signature that is not right: 401.
    Wrong,
    /// A signed link past its time: 403.
    Expired(u64),
}

/// The dataset a path is about (`/view/NAME`, `/d/NAME`, `/x/NAME`, `/geo/NAME`, `/work/NAME`,
/// `/edits/NAME`, decoded).
pub fn dataset_of(path: &str) -> Option<String> {
    [
        "/view/", "/d/", "/x/", "/geo/", "/work/", "/edits/", "/photos/",
    ]
    .iter()
    .find_map(|p| path.strip_prefix(p))
    .and_then(crate::percent_decode)
}

impl Access {
    /// The tokens of `text` (a token file: one a line, blank lines and `#` comments left out),
    /// each at least 16 characters.
    pub fn from_tokens(text: &str) -> Result<Access, String> {
        let tokens: Vec<&str> = text
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.starts_with('#'))
            .collect();
        if tokens.is_empty() {
            return Err("no token in it (one a line)".into());
        }
        if let Some((i, _)) = tokens.iter().enumerate().find(|(_, t)| t.len() < 16) {
            return Err(format!(
                "token {}: shorter than 16 characters (too easy to guess)",
                i + 1
            ));
        }
        // The key: every token, through SHA-256 (a new token file, a new key).
        let seed = ring::digest::digest(&ring::digest::SHA256, tokens.join("\n").as_bytes());
        let key = hmac::Key::new(hmac::HMAC_SHA256, seed.as_ref());
        let tags = tokens
            .iter()
            .map(|t| hmac::sign(&key, t.as_bytes()))
            .collect();
        Ok(Access {
            tags,
            key,
            codes: Mutex::default(),
            secure: false,
        })
    }

    /// A new one-time code for `/login/CODE` (128 random bits).
    pub fn one_time_code(&self) -> String {
        let mut b = [0u8; 16];
        ring::rand::SecureRandom::fill(&ring::rand::SystemRandom::new(), &mut b)
            .expect("the system's random numbers");
        let code = hex(&b);
        self.codes.lock().expect("codes lock").insert(code.clone());
        code
    }

    /// Takes a one-time code: whether it was one not used yet; the session cookie's value then.
    pub fn redeem(&self, code: &str) -> Option<String> {
        self.codes
            .lock()
            .expect("codes lock")
            .remove(code)
            .then(|| self.session(now() + SESSION_SECONDS))
    }

    /// Whether `code` is a one-time code not used yet (a HEAD request asks without spending it).
    pub fn is_code(&self, code: &str) -> bool {
        self.codes.lock().expect("codes lock").contains(code)
    }

    /// A new session's cookie value, each login its own: 128 random bits, the time it ends,
    /// and their signature (`NONCE.EXPIRES.SIG`).
    fn session(&self, expires: u64) -> String {
        let mut b = [0u8; 16];
        ring::rand::SecureRandom::fill(&ring::rand::SystemRandom::new(), &mut b)
            .expect("the system's random numbers");
        let nonce = hex(&b);
        let tag = hmac::sign(&self.key, format!("session\n{nonce}\n{expires}").as_bytes());
        format!("{nonce}.{expires}.{}", hex(tag.as_ref()))
    }

    /// Whether a session cookie's value is one this server signed, and not expired.
    fn session_holds(&self, v: &str, now: u64) -> bool {
        let mut parts = v.splitn(3, '.');
        let (Some(nonce), Some(expires), Some(sig)) = (parts.next(), parts.next(), parts.next())
        else {
            return false;
        };
        let (Some(e), Some(sig)) = (expires.parse::<u64>().ok(), unhex(sig)) else {
            return false;
        };
        let data = format!("session\n{nonce}\n{e}");
        hmac::verify(&self.key, data.as_bytes(), &sig).is_ok() && now < e
    }

    fn link_tag(&self, name: &str, expires: u64) -> hmac::Tag {
        hmac::sign(&self.key, format!("link\n{name}\n{expires}").as_bytes())
    }

    /// The query that signs dataset `name` until `expires` (seconds since 1970).
    pub fn sign(&self, name: &str, expires: u64) -> String {
        format!(
            "expires={expires}&sig={}",
            hex(self.link_tag(name, expires).as_ref())
        )
    }

    fn link_holds(&self, name: &str, expires: u64, sig: &str, now: u64) -> Verdict {
        let Some(sig) = unhex(sig) else {
            return Verdict::Wrong;
        };
        let data = format!("link\n{name}\n{expires}");
        if hmac::verify(&self.key, data.as_bytes(), &sig).is_err() {
            return Verdict::Wrong;
        }
        if now >= expires {
            return Verdict::Expired(expires);
        }
        Verdict::Allowed
    }

    /// What a request for `path?query` with these `Authorization` and `Cookie` headers may have
    /// at `now` (seconds since 1970).
    pub fn check(
        &self,
        path: &str,
        query: Option<&str>,
        authorization: Option<&str>,
        cookies: Option<&str>,
        now: u64,
    ) -> Verdict {
        let mut wrong = false;
        if let Some(a) = authorization {
            match a.strip_prefix("Bearer ") {
                Some(t) if self.token_holds(t.trim()) => return Verdict::Allowed,
                _ => wrong = true,
            }
        }
        let name = dataset_of(path);
        // A signed link.
        let (mut expires, mut sig) = (None, None);
        for pair in query.unwrap_or("").split('&') {
            match pair.split_once('=') {
                Some(("expires", v)) => expires = v.parse::<u64>().ok().or(Some(0)),
                Some(("sig", v)) => sig = Some(v.to_string()),
                _ => {}
            }
        }
        if let (Some(n), Some(e), Some(s)) = (&name, expires, &sig) {
            return match self.link_holds(n, e, s, now) {
                Verdict::Allowed => {
                    Verdict::AllowedSetting(format!("{}.{e}.{s}", crate::catalog::href(n)), e)
                }
                v => v,
            };
        }
        if expires.is_some() || sig.is_some() {
            return Verdict::Wrong;
        }
        // Cookies: the session, or a signed link's for this dataset.
        let mut link_verdict = None;
        for c in cookies.unwrap_or("").split(';').map(str::trim) {
            let Some((k, v)) = c.split_once('=') else {
                continue;
            };
            if k == SESSION_COOKIE {
                if self.session_holds(v, now) {
                    return Verdict::Allowed;
                }
                wrong = true;
            } else if k == LINK_COOKIE {
                let mut parts = v.rsplitn(3, '.');
                let (s, e, n) = (parts.next(), parts.next(), parts.next());
                let (Some(s), Some(e), Some(n)) = (s, e, n) else {
                    wrong = true;
                    continue;
                };
                let (n, e) = (crate::percent_decode(n), e.parse::<u64>().ok());
                let (Some(n), Some(e)) = (n, e) else {
                    wrong = true;
                    continue;
                };
                // A cookie for another dataset says nothing of this one.
                if name.as_deref() == Some(n.as_str()) {
                    link_verdict = Some(self.link_holds(&n, e, s, now));
                }
            }
        }
        match link_verdict {
            Some(v) => v,
            None if wrong => Verdict::Wrong,
            None => Verdict::Missing,
        }
    }

    fn token_holds(&self, t: &str) -> bool {
        // Every tag is tried (no early return): the time says nothing of which one matched.
        let mut ok = false;
        for tag in &self.tags {
            ok |= hmac::verify(&self.key, t.as_bytes(), tag.as_ref()).is_ok();
        }
        ok
    }

    /// The `Set-Cookie` value for a session (from a one-time link) or a signed link's cookie.
    pub fn cookie(&self, name: &str, value: &str, max_age: Option<u64>) -> String {
        let mut c = format!("{name}={value}; Path=/; HttpOnly; SameSite=Strict");
        if let Some(a) = max_age {
            c.push_str(&format!("; Max-Age={a}"));
        }
        if self.secure {
            c.push_str("; Secure");
        }
        c
    }
}

/// Seconds since 1970.
pub fn now() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0)
}

/// A duration as `serve --expires` takes it: `90s`, `30m`, `24h`, `7d` (a bare number: seconds).
pub fn parse_duration(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let (n, unit) = match t.find(|c: char| !c.is_ascii_digit()) {
        Some(i) => (&t[..i], &t[i..]),
        None => (t, "s"),
    };
    let n: u64 = n
        .parse()
        .map_err(|_| format!("--expires \"{s}\": a number and s, m, h or d (24h)"))?;
    let k = match unit {
        "s" => 1,
        "m" => 60,
        "h" => 3600,
        "d" => 86_400,
        _ => {
            return Err(format!(
                "--expires \"{s}\": a number and s, m, h or d (24h)"
            ));
        }
    };
    n.checked_mul(k)
        .filter(|&v| v > 0 && v <= MAX_EXPIRES)
        .ok_or_else(|| format!("--expires \"{s}\": from 1s to 3650d"))
}

/// The longest a signed link holds: ten years (a longer one would wrap past the clock's range
/// and be printed already expired).
pub const MAX_EXPIRES: u64 = 3650 * 86_400;

#[cfg(test)]
mod tests {
    use super::*;

    const TOKENS: &str = "# readers\nabcdefghijklmnop0123\n\nzyxwvutsrqponmlk9876\n";

    #[test]
    fn tokens_cookies_and_signed_links() {
        let a = Access::from_tokens(TOKENS).unwrap();
        let check = |path, q, auth, cookie| a.check(path, q, auth, cookie, 1_000);
        assert_eq!(check("/d/a.myr", None, None, None), Verdict::Missing);
        let bearer = Some("Bearer zyxwvutsrqponmlk9876");
        assert_eq!(check("/d/a.myr", None, bearer, None), Verdict::Allowed);
        let wrong = Some("Bearer zyxwvutsrqponmlk9877");
        assert_eq!(check("/d/a.myr", None, wrong, None), Verdict::Wrong);
        assert_eq!(check("/", None, Some("Basic x"), None), Verdict::Wrong);
        // One-time codes work once; the session cookie they give opens everything.
        let code = a.one_time_code();
        let session = a.redeem(&code).unwrap();
        assert!(a.redeem(&code).is_none());
        let cookie = format!("other=1; {SESSION_COOKIE}={session}");
        assert_eq!(check("/", None, None, Some(&cookie)), Verdict::Allowed);
        let forged = format!("{SESSION_COOKIE}={}", "0".repeat(64));
        assert_eq!(check("/", None, None, Some(&forged)), Verdict::Wrong);
        // Each login its own session, which ends: after SESSION_SECONDS, or with its end
        // changed, refused.
        let code = a.one_time_code();
        assert!(
            a.is_code(&code) && a.is_code(&code),
            "asking does not spend it"
        );
        let other = a.redeem(&code).unwrap();
        assert_ne!(other, session);
        let c = format!("{SESSION_COOKIE}={other}");
        assert_eq!(check("/", None, None, Some(&c)), Verdict::Allowed);
        let later = now() + SESSION_SECONDS + 1;
        assert_eq!(a.check("/", None, None, Some(&c), later), Verdict::Wrong);
        let (nonce, rest) = other.split_once('.').unwrap();
        let (_, sig) = rest.split_once('.').unwrap();
        let stretched = format!("{SESSION_COOKIE}={nonce}.{}.{sig}", u64::MAX);
        assert_eq!(check("/", None, None, Some(&stretched)), Verdict::Wrong);
        // A signed link: its dataset only, until it expires; its cookie the same.
        let q = a.sign("a b.myr", 2_000);
        let v = check("/view/a%20b.myr", Some(&q), None, None);
        let Verdict::AllowedSetting(link, 2_000) = v else {
            panic!("{v:?}")
        };
        let c = format!("{LINK_COOKIE}={link}");
        assert_eq!(
            check("/d/a%20b.myr", None, None, Some(&c)),
            Verdict::Allowed
        );
        assert_eq!(
            check("/d/other.myr", None, None, Some(&c)),
            Verdict::Missing
        );
        assert_eq!(check("/", None, None, Some(&c)), Verdict::Missing);
        assert_eq!(
            a.check("/d/a%20b.myr", None, None, Some(&c), 2_000),
            Verdict::Expired(2_000)
        );
        assert_eq!(
            a.check("/d/a%20b.myr", Some(&q), None, None, 3_000),
            Verdict::Expired(2_000)
        );
        let later = q.replace("expires=2000", "expires=9000");
        assert_eq!(
            check("/d/a%20b.myr", Some(&later), None, None),
            Verdict::Wrong
        );
        assert_eq!(check("/d/other.myr", Some(&q), None, None), Verdict::Wrong);
        // Another token file: nothing of the first holds.
        let b = Access::from_tokens("ponmlkjihgfedcba4567").unwrap();
        assert_eq!(
            b.check("/d/a%20b.myr", Some(&q), None, None, 1_000),
            Verdict::Wrong
        );
        assert!(b.check("/", None, None, Some(&cookie), 1_000) == Verdict::Wrong);
        // Bad token files.
        assert!(Access::from_tokens("# none\n\n").is_err());
        assert!(Access::from_tokens("short").err().unwrap().contains("16"));
    }

    #[test]
    fn durations() {
        assert_eq!(parse_duration("24h"), Ok(86_400));
        assert_eq!(parse_duration("90"), Ok(90));
        assert_eq!(parse_duration("7d"), Ok(604_800));
        assert!(parse_duration("1y").is_err());
        assert!(parse_duration("0s").is_err());
        assert!(parse_duration("h").is_err());
        // A link past the clock's range wrapped and was printed already expired.
        assert_eq!(parse_duration("3650d"), Ok(MAX_EXPIRES));
        for long in ["3651d", "18446744073709551615", "9999999999999h"] {
            assert!(parse_duration(long).is_err(), "{long}");
        }
    }
}
