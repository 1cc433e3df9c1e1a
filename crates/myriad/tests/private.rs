//! Private serving (issue 46): `serve --token-file` answers only requests with a token, the
//! one-time link's cookie or a signed link (401 without, 403 for an expired link, nothing of
//! the dataset sent), over HTTP/1.1 and HTTP/2; dataset commands pass the token
//! (`--header`, `MYRIAD_TOKEN`); the web viewer opens a private dataset through the one-time
//! link and through a signed link in Chromium.

mod common;
use common::{myriad, s, serve, tempdir};
use myriad_serve::browser::{self, Browser};
use std::process::{Command, Stdio};
use std::time::Duration;

const TOKEN: &str = "c2f1a9e07b4d46e1a3b8f0d5e2c7a614";

struct Answer {
    status: u16,
    body: Vec<u8>,
    cookie: Option<String>,
    /// The whole Set-Cookie field ("" without one).
    set_cookie: String,
}

fn get(url: &str, headers: &[(&str, &str)]) -> Answer {
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .max_redirects(0)
        .build()
        .into();
    let mut req = agent.get(url);
    for (k, v) in headers {
        req = req.header(*k, *v);
    }
    let mut r = req.call().unwrap();
    let set_cookie = (r.headers().get("set-cookie"))
        .map(|v| v.to_str().unwrap().to_string())
        .unwrap_or_default();
    let cookie =
        (!set_cookie.is_empty()).then(|| set_cookie.split(';').next().unwrap().to_string());
    Answer {
        status: r.status().as_u16(),
        body: r
            .body_mut()
            .with_config()
            .limit(1 << 30)
            .read_to_vec()
            .unwrap(),
        cookie,
        set_cookie,
    }
}

fn with_env(args: &[&str], token: Option<&str>) -> common::Run {
    let mut c = Command::new(env!("CARGO_BIN_EXE_myriad"));
    c.args(args).env_remove("MYRIAD_TOKEN");
    if let Some(t) = token {
        c.env("MYRIAD_TOKEN", t);
    }
    let out = c.output().unwrap();
    common::Run {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// `d/site.myr`, converted from a synthetic scan of `points`.
fn site(d: &std::path::Path, points: u64) -> std::path::PathBuf {
    let laz = common::synth(d, "site.laz", points);
    let myr = d.join("site.myr");
    let r = myriad(&["convert", s(&laz), "-o", s(&myr)]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    myr
}

#[test]
fn a_private_server_answers_only_its_token_its_links_and_their_cookies() {
    let d = tempdir("private");
    let myr = site(&d, 60_000);
    let file = std::fs::read(&myr).unwrap();
    let tokens = d.join("tokens");
    std::fs::write(&tokens, format!("# who may read\n{TOKEN}\n")).unwrap();
    // A bad token file: one line naming it.
    let short = d.join("short");
    std::fs::write(&short, "abc\n").unwrap();
    let r = myriad(&[
        "serve",
        s(&myr),
        "--token-file",
        s(&short),
        "--bind",
        "127.0.0.1:0",
    ]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("short: token 1: shorter than 16"),
        "{}",
        r.stderr
    );
    // Token files and certificates read with a bound: /dev/zero grew to gigabytes, and
    // /dev/urandom never ended; each is one line naming it.
    for (flag, dev) in [
        ("--token-file", "/dev/zero"),
        ("--tls-cert", "/dev/urandom"),
    ] {
        let mut args = vec!["serve", s(&myr), "--bind", "127.0.0.1:0", flag, dev];
        if flag == "--tls-cert" {
            args.extend(["--tls-key", s(&tokens)]);
        }
        let r = myriad(&args);
        assert_eq!(r.code, 1, "{flag} {dev}: {}", r.stderr);
        assert!(
            r.stderr.contains(&format!("{dev}: a device, not a file")),
            "{}",
            r.stderr
        );
        assert_eq!(r.stderr.trim().lines().count(), 1, "{}", r.stderr);
    }

    let server = serve(&[s(&myr), "--token-file", s(&tokens)], Stdio::null());
    let base = server.base.clone();
    let login = (server.lines.iter())
        .find_map(|l| l.split_whitespace().find(|w| w.contains("/login/")))
        .expect("a one-time link printed")
        .to_string();
    let data = format!("{base}/d/site.myr");
    let range = ("Range", "bytes=0-63");
    let bearer = format!("Bearer {TOKEN}");

    // Without the token, or with a wrong one: 401 and nothing of the dataset.
    for (url, h) in [
        (&data, vec![range]),
        (&format!("{base}/"), vec![]),
        (&format!("{base}/view/site.myr"), vec![]),
        (&format!("{base}/x/site.myr?box=0,0,0,1,1,1"), vec![]),
        (&format!("{base}/work/site.myr"), vec![]),
        (
            &data,
            vec![range, ("Authorization", "Bearer not-the-token-at-all")],
        ),
        (&data, vec![range, ("Cookie", "myriad_session=00ff")]),
    ] {
        let a = get(url, &h);
        assert_eq!(a.status, 401, "{url} {h:?}");
        assert!(!a.body.windows(16).any(|w| w == &file[..16]), "{url}");
    }
    // With it: the bytes. The viewer's code and preflights are public.
    let a = get(&data, &[range, ("Authorization", &bearer)]);
    assert_eq!((a.status, &a.body[..]), (206, &file[..64]));
    assert_eq!(get(&format!("{base}/viewer/viewer.js"), &[]).status, 200);
    let pre = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .build()
        .new_agent()
        .options(&data)
        .header("Origin", "http://elsewhere")
        .header("Access-Control-Request-Method", "GET")
        .call()
        .unwrap();
    assert_eq!(pre.status().as_u16(), 204);

    // HTTP/2 (curl, where installed): the same.
    if Command::new("curl").arg("--version").output().is_ok() {
        let curl = |auth: Option<&str>| {
            let mut c = Command::new("curl");
            c.args([
                "-s",
                "--http2-prior-knowledge",
                "-r",
                "0-63",
                "-o",
                "/dev/null",
            ])
            .args(["-w", "%{http_code} %{http_version}", &data]);
            if let Some(a) = auth {
                c.args(["-H", &format!("Authorization: {a}")]);
            }
            String::from_utf8(c.output().unwrap().stdout).unwrap()
        };
        assert_eq!(curl(Some(&bearer)), "206 2");
        assert_eq!(curl(None), "401 2");
    } else {
        eprintln!("note: no curl, HTTP/2 not tried");
    }

    // The one-time link: a HEAD (a link preview) does not spend it; a session cookie once,
    // ending in 12 hours, refused the second time.
    let head = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .max_redirects(0)
        .build()
        .new_agent()
        .head(&login)
        .call()
        .unwrap();
    assert_eq!(head.status().as_u16(), 200);
    let first = get(&login, &[]);
    assert_eq!(first.status, 303);
    let session = first.cookie.expect("a session cookie");
    assert!(session.starts_with("myriad_session="), "{session}");
    assert!(
        first.set_cookie.contains("Max-Age=43200"),
        "{}",
        first.set_cookie
    );
    assert_eq!(get(&login, &[]).status, 401);
    assert_eq!(
        get(&format!("{base}/"), &[("Cookie", &session)]).status,
        200
    );
    assert_eq!(get(&data, &[range, ("Cookie", &session)]).status, 206);

    // Signed links: for their dataset, until they expire; tampered ones refused.
    let sign = |expires: &str| {
        let r = myriad(&[
            "serve",
            s(&myr),
            "--token-file",
            s(&tokens),
            "--sign",
            &format!("{base}/view/site.myr"),
            "--expires",
            expires,
        ]);
        assert_eq!(r.code, 0, "{}", r.stderr);
        r.stdout.trim().to_string()
    };
    let link = sign("1h");
    let page = get(&link, &[]);
    assert_eq!(page.status, 200, "{link}");
    let cookie = page.cookie.expect("the link's cookie");
    assert_eq!(get(&data, &[range, ("Cookie", &cookie)]).status, 206);
    assert_eq!(get(&format!("{base}/"), &[("Cookie", &cookie)]).status, 401);
    let query = link.split_once('?').unwrap().1;
    assert_eq!(get(&format!("{data}?{query}"), &[range]).status, 206);
    let tampered = link.replace("sig=", "sig=00");
    assert_eq!(get(&tampered, &[]).status, 401);
    let short_lived = sign("1s");
    std::thread::sleep(Duration::from_millis(2100));
    let expired = get(&short_lived, &[]);
    assert_eq!(
        expired.status,
        403,
        "{}",
        String::from_utf8_lossy(&expired.body)
    );

    // Dataset commands on the URL: the token from the environment or --header.
    let png = d.join("r.png");
    let render = |token: Option<&str>, extra: &[&str]| {
        let _ = std::fs::remove_file(&png);
        let mut args = vec![
            "render",
            &data,
            "-o",
            s(&png),
            "--width",
            "200",
            "--height",
            "150",
        ];
        args.extend_from_slice(extra);
        with_env(&args, token)
    };
    let r = render(None, &[]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(
        r.stderr.contains("HTTP 401") && r.stderr.lines().count() == 1,
        "{}",
        r.stderr
    );
    let r = render(Some(TOKEN), &[]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let header = format!("Authorization: {bearer}");
    let r = render(None, &["--header", &header]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let r = with_env(&["info", &format!("{data}?{query}")], None);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        r.stdout.contains("60,000") || r.stdout.contains("60000"),
        "{}",
        r.stdout
    );

    // The web viewer through the one-time link, then through a signed link, in Chromium.
    let Some(exe) = browser::find() else {
        eprintln!("SKIPPED (the browser part): no Chromium (.ci/run installs it)");
        return;
    };
    let converged = "window.myriad && (myriad.state.converged || myriad.state.errors.length > 0) \
                     && myriad.state";
    let login = (server.lines.iter())
        .find_map(|l| l.split_whitespace().find(|w| w.contains("/login/")))
        .unwrap()
        .to_string();
    // (The test's own request used that code: a fresh server prints a fresh one.)
    drop(server);
    let server = serve(&[s(&myr), "--token-file", s(&tokens)], Stdio::null());
    let fresh = (server.lines.iter())
        .find_map(|l| l.split_whitespace().find(|w| w.contains("/login/")))
        .unwrap()
        .to_string();
    assert_ne!(fresh, login);
    let mut b = Browser::launch(&exe).unwrap();
    b.open(&fresh, 800, 600).unwrap();
    b.wait_for(
        "document.readyState === 'complete' && location.pathname === '/' && document.body.textContent.includes('site.myr')",
        Duration::from_secs(30),
    )
    .unwrap();
    b.open(
        &format!("{}/view/site.myr#renderer=webgl2", server.base),
        800,
        600,
    )
    .unwrap();
    let st = b.wait_for(converged, Duration::from_secs(240)).unwrap();
    assert_eq!(st["errors"], serde_json::json!([]), "{st}");
    assert!(st["points"].as_u64().unwrap() > 1000, "{st}");
    drop(b);
    let link = sign("1h").replace(&base, &server.base);
    let mut b = Browser::launch(&exe).unwrap();
    b.open(&format!("{link}#renderer=webgl2"), 800, 600)
        .unwrap();
    let st = b.wait_for(converged, Duration::from_secs(240)).unwrap();
    assert_eq!(st["errors"], serde_json::json!([]), "{st}");
    assert!(st["points"].as_u64().unwrap() > 1000, "{st}");
    drop(b);
    let _ = std::fs::remove_dir_all(&d);
}

/// `serve --tls-cert --tls-key` with a self-signed certificate (made by openssl, where
/// installed): HTTPS over HTTP/2 and HTTP/1.1 (curl told to trust it), `myriad render https://`
/// with the token and `MYRIAD_CA_CERT`, refused in one line without them; cookies `Secure`.
#[test]
fn a_private_server_over_tls() {
    let d = tempdir("private-tls");
    let (cert, key) = (d.join("cert.pem"), d.join("key.pem"));
    let made = Command::new("openssl")
        .args([
            "req",
            "-x509",
            "-newkey",
            "ec",
            "-pkeyopt",
            "ec_paramgen_curve:prime256v1",
        ])
        .args([
            "-nodes",
            "-days",
            "2",
            "-subj",
            "/CN=localhost",
            "-keyout",
            s(&key),
            "-out",
        ])
        .arg(&cert)
        .args(["-addext", "subjectAltName=DNS:localhost,IP:127.0.0.1"])
        .args(["-addext", "basicConstraints=critical,CA:FALSE"])
        .output();
    if !made.is_ok_and(|o| o.status.success()) {
        eprintln!("SKIPPED: no openssl to make a certificate (apt-get install openssl)");
        return;
    }
    let myr = site(&d, 20_000);
    let tokens = d.join("tokens");
    std::fs::write(&tokens, format!("{TOKEN}\n")).unwrap();
    // A key that is not one: one line naming the file.
    let r = myriad(&[
        "serve",
        s(&myr),
        "--tls-cert",
        s(&cert),
        "--tls-key",
        s(&tokens),
        "--bind",
        "127.0.0.1:0",
    ]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("tokens") && r.stderr.lines().count() == 1,
        "{}",
        r.stderr
    );
    let server = serve(
        &[
            s(&myr),
            "--token-file",
            s(&tokens),
            "--tls-cert",
            s(&cert),
            "--tls-key",
            s(&key),
        ],
        Stdio::null(),
    );
    assert!(server.base.starts_with("https://"), "{}", server.base);
    let data = format!("{}/d/site.myr", server.base);
    if Command::new("curl").arg("--version").output().is_ok() {
        let curl = |version: &str, auth: bool| {
            let mut c = Command::new("curl");
            c.args([
                "-s",
                version,
                "--cacert",
                s(&cert),
                "-r",
                "0-63",
                "-o",
                "/dev/null",
            ])
            .args(["-w", "%{http_code} %{http_version}", &data]);
            if auth {
                c.args(["-H", &format!("Authorization: Bearer {TOKEN}")]);
            }
            String::from_utf8(c.output().unwrap().stdout).unwrap()
        };
        assert_eq!(curl("--http2", true), "206 2");
        assert_eq!(curl("--http1.1", true), "206 1.1");
        assert_eq!(curl("--http2", false), "401 2");
        let login = (server.lines.iter())
            .find_map(|l| l.split_whitespace().find(|w| w.contains("/login/")))
            .unwrap()
            .to_string();
        let head = Command::new("curl")
            .args(["-s", "-i", "--cacert", s(&cert), &login])
            .output()
            .unwrap();
        let head = String::from_utf8_lossy(&head.stdout).to_ascii_lowercase();
        assert!(
            head.contains("set-cookie: myriad_session=") && head.contains("; secure"),
            "{head}"
        );
    } else {
        eprintln!("note: no curl, HTTP/2 over TLS not tried");
    }
    let png = d.join("r.png");
    let run = |env: &[(&str, &str)]| {
        let _ = std::fs::remove_file(&png);
        let mut c = Command::new(env!("CARGO_BIN_EXE_myriad"));
        c.args([
            "render",
            &data,
            "-o",
            s(&png),
            "--width",
            "200",
            "--height",
            "150",
        ])
        .env_remove("MYRIAD_TOKEN")
        .env_remove("MYRIAD_CA_CERT");
        for (k, v) in env {
            c.env(k, v);
        }
        c.output().unwrap()
    };
    let ca = s(&cert).to_string();
    let o = run(&[("MYRIAD_TOKEN", TOKEN), ("MYRIAD_CA_CERT", &ca)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(png.exists());
    let o = run(&[("MYRIAD_TOKEN", TOKEN)]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        e.contains("MYRIAD_CA_CERT") && e.lines().count() == 1,
        "{e}"
    );
    let o = run(&[("MYRIAD_CA_CERT", &ca)]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("HTTP 401") && e.lines().count() == 1, "{e}");
    drop(server);
    let _ = std::fs::remove_dir_all(&d);
}
