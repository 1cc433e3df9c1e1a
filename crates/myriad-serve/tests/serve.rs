//! The server as clients meet it, over raw TCP so that every byte of a request is the test's:
//! ranges (one, several, past the end, malformed), HEAD, ETag with If-Range and If-None-Match,
//! the CORS preflight, the index, and bad requests (methods, `..` and its encodings, huge
//! headers, slow clients), each with its status while the server keeps serving.

use myriad_serve::{Catalog, Options, Server};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::time::Duration;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("myriad-serve-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

struct Answer {
    status: u16,
    head: String,
    body: Vec<u8>,
}

impl Answer {
    fn header(&self, name: &str) -> Option<String> {
        self.head.lines().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            k.eq_ignore_ascii_case(name).then(|| v.trim().to_string())
        })
    }
}

/// Sends `request` as it is and reads the answer (the connection closed after it).
fn send(server: &Server, request: &str) -> Answer {
    let mut s = TcpStream::connect(server.addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    s.write_all(request.as_bytes()).unwrap();
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    let split = out
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("an answer head");
    let head = String::from_utf8_lossy(&out[..split]).to_string();
    let status = head.split(' ').nth(1).unwrap().parse().unwrap();
    Answer {
        status,
        head,
        body: out[split + 4..].to_vec(),
    }
}

fn get(server: &Server, path: &str, extra: &str) -> Answer {
    send(
        server,
        &format!("GET {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n{extra}\r\n"),
    )
}

#[test]
fn ranges_validators_cors_and_bad_requests() {
    let d = dir("ranges");
    let data: Vec<u8> = (0..100_000u32).map(|i| (i * 7 % 251) as u8).collect();
    let file = d.join("site.myr");
    std::fs::write(&file, &data).unwrap();
    let potree = d.join("potree");
    std::fs::create_dir_all(potree.join("sub")).unwrap();
    std::fs::write(potree.join("metadata.json"), b"{}").unwrap();
    std::fs::write(potree.join("sub/octree.bin"), b"0123456789").unwrap();
    std::fs::write(potree.join(".partial"), b"hidden").unwrap();
    let catalog = Catalog::new(&[file.clone(), potree.clone()]).unwrap();
    let names: Vec<&str> = catalog.names().map(|n| n.0).collect();
    assert_eq!(
        names,
        ["potree/metadata.json", "potree/sub/octree.bin", "site.myr"]
    );
    let options = Options {
        max_connections: 8,
        header_timeout: Duration::from_millis(500),
        max_header_bytes: 8192,
        ..Options::default()
    };
    // (Retried as below: the other test's server may be starting at the same moment.)
    let mut catalog = Some(catalog);
    let mut server = None;
    for _ in 0..50 {
        let c = catalog
            .take()
            .unwrap_or_else(|| Catalog::new(&[file.clone(), potree.clone()]).unwrap());
        if let Ok(s) = Server::start(c, "127.0.0.1:0".parse().unwrap(), options.clone()) {
            server = Some(s);
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let server = server.expect("the server started");

    // The whole file.
    let a = get(&server, "/d/site.myr", "");
    assert_eq!(a.status, 200);
    assert_eq!(a.body, data);
    assert_eq!(a.header("accept-ranges").as_deref(), Some("bytes"));
    // No page of another origin reads it unless the user said so (--allow-origin).
    assert_eq!(a.header("access-control-allow-origin"), None);
    let a = get(&server, "/d/site.myr", "Origin: https://evil.example\r\n");
    assert_eq!(
        (a.status, a.header("access-control-allow-origin")),
        (200, None)
    );
    let etag = a.header("etag").unwrap();
    // One range.
    let a = get(&server, "/d/site.myr", "Range: bytes=1000-1999\r\n");
    assert_eq!(a.status, 206);
    assert_eq!(a.body, &data[1000..2000]);
    assert_eq!(
        a.header("content-range").as_deref(),
        Some("bytes 1000-1999/100000")
    );
    let a = get(&server, "/d/site.myr", "Range: bytes=-10\r\n");
    assert_eq!((a.status, &a.body[..]), (206, &data[99_990..]));
    // Several: multipart/byteranges with each part's Content-Range.
    let a = get(&server, "/d/site.myr", "Range: bytes=0-9, 50000-50004\r\n");
    assert_eq!(a.status, 206);
    let ct = a.header("content-type").unwrap();
    assert!(ct.starts_with("multipart/byteranges; boundary="), "{ct}");
    let body = String::from_utf8_lossy(&a.body);
    assert!(body.contains("Content-Range: bytes 0-9/100000"));
    assert!(body.contains("Content-Range: bytes 50000-50004/100000"));
    assert!(a.body.windows(5).any(|w| w == &data[50000..50005]));
    // Past the end, malformed: 416 with the length.
    for bad in ["bytes=100000-", "bytes=5-1", "bytes=x-y", "bytes="] {
        let a = get(&server, "/d/site.myr", &format!("Range: {bad}\r\n"));
        assert_eq!(a.status, 416, "{bad}");
        assert_eq!(a.header("content-range").as_deref(), Some("bytes */100000"));
    }
    // HEAD: the headers of GET, no body.
    let a = send(
        &server,
        "HEAD /d/site.myr HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\nRange: bytes=0-99\r\n\r\n",
    );
    assert_eq!((a.status, a.body.len()), (206, 0));
    assert_eq!(a.header("content-length").as_deref(), Some("100"));
    // Validators.
    let a = get(
        &server,
        "/d/site.myr",
        &format!("If-None-Match: {etag}\r\n"),
    );
    assert_eq!((a.status, a.body.len()), (304, 0));
    let a = get(
        &server,
        "/d/site.myr",
        &format!("Range: bytes=0-9\r\nIf-Range: {etag}\r\n"),
    );
    assert_eq!((a.status, a.body.len()), (206, 10));
    let a = get(
        &server,
        "/d/site.myr",
        "Range: bytes=0-9\r\nIf-Range: \"another-version\"\r\n",
    );
    assert_eq!((a.status, a.body.len()), (200, data.len()));
    // The preflight a cross-origin Range request forces.
    let a = send(
        &server,
        "OPTIONS /d/site.myr HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\nOrigin: http://elsewhere\r\n\
         Access-Control-Request-Method: GET\r\nAccess-Control-Request-Headers: range, content-type\r\n\r\n",
    );
    assert_eq!(a.status, 204);
    let allowed = a.header("access-control-allow-headers").unwrap();
    assert!(allowed.contains("Range") && allowed.contains("Content-Type"));
    assert_eq!(
        a.header("access-control-allow-origin"),
        None,
        "not an allowed origin"
    );
    // A page whose name was rebound to this loopback server (DNS rebinding): refused.
    let a = send(
        &server,
        "GET /d/site.myr HTTP/1.1\r\nHost: evil.example:80\r\nConnection: close\r\n\r\n",
    );
    assert_eq!(a.status, 421);
    for host in ["127.0.0.1:9", "[::1]:9", "LOCALHOST"] {
        let a = send(
            &server,
            &format!(
                "GET /d/site.myr HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\nRange: bytes=0-0\r\n\r\n"
            ),
        );
        assert_eq!(a.status, 206, "{host}");
    }
    // A folder's files under its name; hidden ones not at all.
    let a = get(&server, "/d/potree/sub/octree.bin", "Range: bytes=2-4\r\n");
    assert_eq!((a.status, &a.body[..]), (206, &b"234"[..]));
    assert_eq!(get(&server, "/d/potree/.partial", "").status, 404);
    // The index, gzip where asked for.
    let a = get(&server, "/", "Accept-Encoding: gzip, br\r\n");
    assert_eq!(a.status, 200);
    assert_eq!(a.header("content-encoding").as_deref(), Some("gzip"));
    let mut html = String::new();
    flate2::read::GzDecoder::new(&a.body[..])
        .read_to_string(&mut html)
        .unwrap();
    assert!(html.contains("href=\"/d/site.myr\""), "{html}");
    // The web viewer: its page for a dataset of the catalog only, its files compiled in, gzip
    // where asked for.
    assert!(html.contains("href=\"/view/site.myr\""), "{html}");
    let a = get(&server, "/view/site.myr", "");
    assert_eq!(a.status, 200);
    assert!(String::from_utf8_lossy(&a.body).contains("/viewer/viewer.js"));
    for p in [
        "/view/nothing.myr",
        "/view/potree/metadata.json",
        "/viewer/",
        "/viewer/../site.myr",
    ] {
        assert_eq!(get(&server, p, "").status, 404, "{p}");
    }
    let wasm = std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("viewer/myriad_web.wasm"))
        .unwrap();
    let a = get(
        &server,
        "/viewer/myriad_web.wasm",
        "Accept-Encoding: gzip\r\n",
    );
    assert_eq!(
        a.header("content-type").as_deref(),
        Some("application/wasm")
    );
    assert_eq!(a.header("content-encoding").as_deref(), Some("gzip"));
    assert!(
        a.body.len() < wasm.len() / 2,
        "{} bytes gzipped",
        a.body.len()
    );
    let mut unzipped = Vec::new();
    flate2::read::GzDecoder::new(&a.body[..])
        .read_to_end(&mut unzipped)
        .unwrap();
    assert_eq!(unzipped, wasm);
    let a = get(&server, "/viewer/worker.js", "");
    assert_eq!((a.status, a.header("content-encoding")), (200, None));
    assert!(String::from_utf8_lossy(&a.body).contains("myr_read"));

    // Paths that would leave the catalog find nothing; nothing outside it is read.
    std::fs::write(d.join("secret.txt"), b"secret").unwrap();
    for p in [
        "/d/../secret.txt",
        "/d/potree/../site.myr",
        "/d/%2e%2e/secret.txt",
        "/d/potree/%2E%2E/%2E%2E/secret.txt",
        "/d/%2fetc%2fpasswd",
        "/d/potree%2f..%2fsecret.txt",
        "/secret.txt",
        "/d/",
    ] {
        let a = get(&server, p, "");
        assert!(a.status == 404 || a.status == 400, "{p}: {}", a.status);
        assert!(!a.body.windows(6).any(|w| w == b"secret"), "{p}");
    }
    assert_eq!(get(&server, "/d/%zz", "").status, 400);
    // Writing methods: 405 with Allow.
    let a = send(
        &server,
        "PUT /d/site.myr HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\nContent-Length: 0\r\n\r\n",
    );
    assert_eq!(a.status, 405);
    assert_eq!(a.header("allow").as_deref(), Some("GET, HEAD, OPTIONS"));
    // A huge header: 431, and the server goes on.
    let huge = format!("X-Junk: {}\r\n", "a".repeat(64 << 10));
    let a = get(&server, "/d/site.myr", &huge);
    assert_eq!(a.status, 431);
    // Garbage instead of a request: 400.
    let a = send(&server, "NOT HTTP AT ALL\r\n\r\n");
    assert_eq!(a.status, 400);
    // Slow clients (a request head never finished) are dropped after the header timeout, and
    // while more of them than the server's connections wait, it still answers once they go.
    let slow: Vec<TcpStream> = (0..12)
        .map(|_| {
            let mut s = TcpStream::connect(server.addr).unwrap();
            s.write_all(b"GET /d/site.myr HTTP/1.1\r\nHost: localhost\r\n")
                .unwrap();
            s
        })
        .collect();
    let t = std::time::Instant::now();
    let a = get(&server, "/d/site.myr", "Range: bytes=0-0\r\n");
    assert_eq!(a.status, 206);
    assert!(t.elapsed() < Duration::from_secs(15), "{:?}", t.elapsed());
    drop(slow);
    let a = get(&server, "/d/site.myr", "Range: bytes=99999-\r\n");
    assert_eq!((a.status, a.body.len()), (206, 1));
    drop(server);
    std::fs::remove_dir_all(&d).unwrap();
}

fn put(server: &Server, path: &str, body: &str) -> Answer {
    send(
        server,
        &format!(
            "PUT {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
            body.len()
        ),
    )
}

#[test]
fn saved_work_is_shown_and_saved_only_with_edit() {
    let d = dir("work");
    let file = d.join("site.myr");
    std::fs::write(&file, b"not a dataset, here").unwrap();
    let sidecar = d.join("site.work.json");
    // (Retried: a server starting at the same moment in this process, the other test's,
    // briefly holds the scratch folders' locks while it looks for stale ones.)
    let start = |edit: bool| {
        for _ in 0..50 {
            if let Ok(s) = Server::start(
                Catalog::new(std::slice::from_ref(&file)).unwrap(),
                "127.0.0.1:0".parse().unwrap(),
                Options {
                    edit,
                    ..Options::default()
                },
            ) {
                return s;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        panic!("the server did not start");
    };
    let body = r#"{"myriad":"work","version":1,"crs":"EPSG:9999","annotations":[{"position":[1,2,3],"title":"gate","text":"north"}],"measurements":[{"kind":"distance","points":[[0,0,0],[3,4,0]]}]}"#;

    // Read-only: the work (none yet) is shown, not changed.
    let ro = start(false);
    let a = get(&ro, "/work/site.myr", "");
    assert_eq!(a.status, 200);
    let v: serde_json::Value = serde_json::from_slice(&a.body).unwrap();
    assert_eq!(v["editable"], false);
    assert_eq!(v["annotations"], serde_json::json!([]));
    assert_eq!(a.header("cache-control").as_deref(), Some("no-store"));
    assert_eq!(put(&ro, "/work/site.myr", body).status, 403);
    assert!(!sidecar.exists());
    assert_eq!(get(&ro, "/work/nothing.myr", "").status, 404);
    drop(ro);

    // With --edit: saved (the server's labels back), shown to the next client; the CRS
    // stays the one kept (here the sidecar's, the file having none) whatever a client sends.
    std::fs::write(
        &sidecar,
        r#"{"myriad":"work","version":1,"crs":"EPSG:9999"}"#,
    )
    .unwrap();
    let rw = start(true);
    let a = put(&rw, "/work/site.myr", body);
    assert_eq!(a.status, 200, "{}", String::from_utf8_lossy(&a.body));
    let v: serde_json::Value = serde_json::from_slice(&a.body).unwrap();
    assert_eq!(v["measurements"][0]["value"], 5.0);
    let saved = std::fs::read_to_string(&sidecar).unwrap();
    assert!(saved.contains("\"gate\""), "{saved}");
    let v: serde_json::Value =
        serde_json::from_slice(&get(&rw, "/work/site.myr", "").body).unwrap();
    assert_eq!(
        (v["editable"].clone(), v["annotations"][0]["title"].clone()),
        (true.into(), "gate".into())
    );
    let other = body.replace("EPSG:9999", "EPSG:1");
    assert_eq!(put(&rw, "/work/site.myr", &other).status, 200);
    let saved = std::fs::read_to_string(&sidecar).unwrap();
    assert!(
        saved.contains("EPSG:9999") && !saved.contains("EPSG:1\""),
        "{saved}"
    );

    // Bad work: 400 naming the line or member, the file as it was; too large: 413.
    let before = std::fs::read(&sidecar).unwrap();
    let a = put(&rw, "/work/site.myr", "{\n\"myriad\": \"work\",\n");
    assert_eq!(a.status, 400);
    assert!(
        String::from_utf8_lossy(&a.body).contains("line 3"),
        "{}",
        String::from_utf8_lossy(&a.body)
    );
    let a = put(
        &rw,
        "/work/site.myr",
        r#"{"myriad":"work","version":1,"measurements":[{"kind":"area","points":[]}]}"#,
    );
    assert_eq!(a.status, 400);
    assert!(String::from_utf8_lossy(&a.body).contains("measurements[0]"));
    let big = send(
        &rw,
        "PUT /work/site.myr HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\nContent-Length: 99999999\r\n\r\n",
    );
    assert_eq!(big.status, 413);
    assert_eq!(
        put(&rw, "/d/site.myr", body).status,
        405,
        "files stay read-only"
    );
    assert_eq!(std::fs::read(&sidecar).unwrap(), before);
    assert_eq!(get(&rw, "/d/site.myr", "").status, 200, "still serving");

    // Only the server's own pages write: a PUT from a page of another origin is refused (a
    // local server with --edit and a web page open elsewhere), and so is one naming another
    // host (DNS rebinding); its own origin's goes through.
    let port = rw.addr.port();
    let from = |origin: &str, host: &str| {
        send(
            &rw,
            &format!(
                "PUT /work/site.myr HTTP/1.1\r\nHost: {host}\r\nOrigin: {origin}\r\nConnection: close\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
                body.len()
            ),
        )
    };
    let own = format!("localhost:{port}");
    assert_eq!(from("https://evil.example", &own).status, 403);
    assert_eq!(from("https://evil.example", "evil.example").status, 421);
    assert_eq!(std::fs::read(&sidecar).unwrap(), before, "nothing written");
    assert_eq!(from(&format!("http://{own}"), &own).status, 200);
    // The preflight never offers PUT, even to an origin allowed to read.
    drop(rw);
    let open = Server::start(
        Catalog::new(std::slice::from_ref(&file)).unwrap(),
        "127.0.0.1:0".parse().unwrap(),
        Options {
            edit: true,
            allow_origins: vec!["https://viewer.example".into()],
            ..Options::default()
        },
    )
    .unwrap();
    let a = send(
        &open,
        "OPTIONS /work/site.myr HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\nOrigin: https://viewer.example\r\nAccess-Control-Request-Method: PUT\r\n\r\n",
    );
    assert_eq!(
        a.header("access-control-allow-methods").as_deref(),
        Some("GET, HEAD, OPTIONS")
    );
    let a = get(&open, "/d/site.myr", "Origin: https://viewer.example\r\n");
    assert_eq!(
        a.header("access-control-allow-origin").as_deref(),
        Some("https://viewer.example")
    );
    let a = get(&open, "/d/site.myr", "Origin: https://other.example\r\n");
    assert_eq!(a.header("access-control-allow-origin"), None);
}
