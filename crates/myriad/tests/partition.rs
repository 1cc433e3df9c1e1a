//! A build beyond one machine (issue 18): `plan`, `convert --plan --part`, `merge`, and the same
//! run by a one-node Slurm cluster (scripts/slurm-local.sh; skipped where Slurm is not installed).
//! The merged dataset holds the records of the inputs, each once, and is the dataset a
//! one-machine `convert --plan` makes.

mod common;
use common::{holds, make_plan, myriad, ok, s, tempdir, two_scans};
use myriad_format::Dataset;
use std::path::{Path, PathBuf};
use std::process::Command;

#[test]
fn parts_built_apart_merge_to_the_one_machine_build() {
    let d = tempdir("partition");
    let (west, east, want) = two_scans(&d);
    let plan = make_plan(&d, &[&west, &east], "plan.json");
    let parts = d.join("parts");
    let mut opened = Vec::new();
    for i in 0..4 {
        // Each way an engine names the index: a number, Slurm, Kubernetes, AWS Batch.
        let mut c = Command::new(env!("CARGO_BIN_EXE_myriad"));
        c.args([
            "convert",
            "--plan",
            s(&plan),
            "-o",
            s(&parts),
            "--json",
            "--part",
        ]);
        match i {
            0 => c.arg("0"),
            1 => c.arg("auto").env("SLURM_ARRAY_TASK_ID", "1"),
            2 => c.arg("auto").env("JOB_COMPLETION_INDEX", "2"),
            _ => c.arg("auto").env("AWS_BATCH_JOB_ARRAY_INDEX", "3"),
        };
        let out = c.output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["part"], i);
        opened.push(v["inputs_read"].as_u64().unwrap());
        // Each part is a dataset of its own.
        let part = parts.join(format!("part-{i}.myr"));
        assert!(ok(&["verify", s(&part)]).contains("ok"));
    }
    // A part reads only the scans that reach its cells: the west's first cells, the east's last.
    assert_eq!(opened.first(), Some(&1), "{opened:?}");
    assert_eq!(opened.last(), Some(&1), "{opened:?}");

    // Rerunning a part replaces it with the same bytes.
    let tops = parts.join("part-2.tops");
    let before = std::fs::read(&tops).unwrap();
    ok(&[
        "convert",
        "--plan",
        s(&plan),
        "--part",
        "2",
        "-o",
        s(&parts),
    ]);
    assert!(std::fs::read(&tops).unwrap() == before);

    // By default the merge links the parts' files; --single-file copies their pages.
    let merged = d.join("merged.myr");
    let out = ok(&["merge", s(&plan), s(&parts), "-o", s(&merged), "--json"]);
    let m: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(m["points"], 300_000);
    assert_eq!(m["pages_copied"], 0, "{m}");
    assert!(m["pages_linked"].as_u64().unwrap() > 0, "{m}");
    assert_eq!(m["files_linked"], 4, "{m}");
    holds(&merged, &want);
    let said = ok(&["verify", s(&merged)]);
    assert!(said.contains("ok") && said.contains("in 5 files"), "{said}");
    let single = d.join("single.myr");
    let out = ok(&[
        "merge",
        s(&plan),
        s(&parts),
        "-o",
        s(&single),
        "--json",
        "--single-file",
    ]);
    let m1: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(m1["pages_copied"], m["pages_linked"], "{m1}");
    assert_eq!(m1["files_linked"], 0, "{m1}");
    assert!(m1["bytes"].as_u64() > m["bytes"].as_u64());
    holds(&single, &want);

    // The same as the whole plan on one machine: the same nodes and points in each.
    let one = d.join("one.myr");
    ok(&["convert", "--plan", s(&plan), "-o", s(&one)]);
    let (a, b) = (
        Dataset::open(&merged).unwrap(),
        Dataset::open(&one).unwrap(),
    );
    let (mut x, _) = a.nodes();
    let (mut y, _) = b.nodes();
    x.sort_by_key(|e| e.key);
    y.sort_by_key(|e| e.key);
    assert_eq!(x.len(), y.len());
    for (p, q) in x.iter().zip(&y) {
        assert_eq!((p.key, p.points, &p.prefix), (q.key, q.points, &q.prefix));
        assert!(
            a.node_page(p).unwrap() == b.node_page(q).unwrap(),
            "{:?}",
            p.key
        );
    }
    holds(&one, &want);

    // Served, the dataset of five files renders the one-machine build's pixels over HTTP (its
    // parts found beside it, by the URLs its relative paths give them).
    let server = common::serve(&[s(&merged), s(&one)], std::process::Stdio::inherit());
    assert!(
        server.lines[0].contains("serving 6 files"),
        "{:?}",
        server.lines
    );
    let render = |input: &str, out: &Path| {
        let mut args = common::render_cpu(input, s(out), ("160", "120"));
        args.push("--force");
        ok(&args)
    };
    let (png_one, png_merged) = (d.join("one.png"), d.join("merged.png"));
    render(&format!("{}/d/one.myr", server.base), &png_one);
    render(&format!("{}/d/merged.myr", server.base), &png_merged);
    assert_eq!(
        common::decode_png(&png_one).2,
        common::decode_png(&png_merged).2
    );
    drop(server);

    // A part missing: `verify` names it in one line, exit 1.
    let part = parts.join("part-2.myr");
    std::fs::rename(&part, d.join("aside.myr")).unwrap();
    let r = myriad(&["verify", s(&merged)]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("part-2.myr"), "{}", r.stderr);
    assert_eq!(r.stderr.trim().lines().count(), 1, "{}", r.stderr);
    // ... and `serve` will not serve the dataset without it.
    let r = myriad(&["serve", s(&merged), "--bind", "127.0.0.1:0"]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("part-2.myr"), "{}", r.stderr);
    std::fs::rename(d.join("aside.myr"), &part).unwrap();

    // A missing part: one line naming it, exit 1, no output.
    std::fs::remove_file(parts.join("part-1.tops")).unwrap();
    let out2 = d.join("out2.myr");
    let r = myriad(&["merge", s(&plan), s(&parts), "-o", s(&out2)]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("part-1.tops") && r.stderr.contains("--part 1"),
        "{}",
        r.stderr
    );
    assert_eq!(r.stderr.trim().lines().count(), 1, "{}", r.stderr);
    assert!(!out2.exists());
    let r = myriad(&[
        "convert",
        "--plan",
        s(&plan),
        "--part",
        "9",
        "-o",
        s(&parts),
    ]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("parts 0 to 3"), "{}", r.stderr);
    let r = myriad(&[
        "convert",
        "--plan",
        s(&plan),
        "--part",
        "auto",
        "-o",
        s(&parts),
    ]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("SLURM_ARRAY_TASK_ID"), "{}", r.stderr);
    let _ = std::fs::remove_dir_all(&d);
}

/// The cluster of scripts/slurm-local.sh, stopped when dropped.
struct Slurm(PathBuf);

impl Slurm {
    fn script() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/slurm-local.sh")
    }

    /// Starts one, or says why not.
    fn start(dir: &Path) -> Result<Slurm, String> {
        let out = Command::new("sh")
            .arg(Slurm::script())
            .args(["start", s(dir)])
            .output()
            .map_err(|e| e.to_string())?;
        if !out.status.success() {
            return Err(String::from_utf8_lossy(&out.stderr).trim().to_string());
        }
        Ok(Slurm(dir.to_path_buf()))
    }

    fn myriad(&self, args: &[&str]) -> common::Run {
        let out = Command::new(env!("CARGO_BIN_EXE_myriad"))
            .args(args)
            .env("SLURM_CONF", self.0.join("slurm.conf"))
            .output()
            .unwrap();
        common::Run {
            code: out.status.code().unwrap_or(-1),
            stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
            stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        }
    }
}

impl Drop for Slurm {
    fn drop(&mut self) {
        let _ = Command::new("sh")
            .arg(Slurm::script())
            .args(["stop", s(&self.0)])
            .status();
    }
}

#[test]
fn slurm_runs_the_parts_as_an_array_and_a_failed_part_fails_the_merge() {
    let d = tempdir("slurm");
    let slurm = match Slurm::start(&d.join("cluster")) {
        Ok(c) => c,
        Err(why) => {
            eprintln!("SKIPPED: no one-node Slurm cluster here ({why})");
            return;
        }
    };
    let (west, east, want) = two_scans(&d);
    let plan = make_plan(&d, &[&west, &east], "plan.json");
    let out = d.join("city.myr");
    // The two scans each meet several parts: a scatter job decompresses their chunks once
    // before the parts.
    let chunked = std::fs::read_to_string(&plan).unwrap();
    let chunked: serde_json::Value = serde_json::from_str(&chunked).unwrap();
    assert_eq!(chunked["chunked"].as_array().unwrap().len(), 2);
    let r = slurm.myriad(&["slurm", s(&plan), "-o", s(&out), "--wait"]);
    assert_eq!(r.code, 0, "{}{}", r.stdout, r.stderr);
    assert!(r.stdout.contains("4 array tasks"), "{}", r.stdout);
    assert!(r.stdout.contains("scatter job"), "{}", r.stdout);
    holds(&out, &want);
    assert!(
        !d.join("city.myr.parts/exchange").exists(),
        "the merge removes the scatter tasks' records"
    );
    // The merge left the parts' pages in city.myr.parts/ and links them.
    let files = Dataset::open(&out).unwrap().files().to_vec();
    assert_eq!(files.len(), 4, "{files:?}");
    assert!(
        files
            .iter()
            .all(|f| f.path.starts_with("city.myr.parts/part-"))
    );
    // Every scatter task and part ran as an array task, its log next to the parts.
    let logs = |what: &str| {
        std::fs::read_dir(d.join("city.myr.parts"))
            .unwrap()
            .filter(|e| {
                let n = e.as_ref().unwrap().file_name();
                let n = n.to_string_lossy();
                n.starts_with("slurm-") && !n.contains("merge") && n.contains(what)
            })
            .count()
    };
    assert_eq!((logs("scatter"), logs("_")), (4, 8));

    // An input gone before the build runs: the scatter tasks that read it fail, the parts and
    // the merge do not run, and `slurm --wait` says which.
    let gone = d.join("east-copy.laz");
    std::fs::copy(&east, &gone).unwrap();
    let plan2 = make_plan(&d, &[&west, &gone], "plan2.json");
    std::fs::remove_file(&gone).unwrap();
    let out2 = d.join("broken.myr");
    let r = slurm.myriad(&["slurm", s(&plan2), "-o", s(&out2), "--wait"]);
    assert_eq!(r.code, 1, "{}{}", r.stdout, r.stderr);
    assert!(
        r.stderr.contains("not merged") && r.stderr.contains("scatter task 3 FAILED"),
        "{}",
        r.stderr
    );
    assert!(!out2.exists());
    drop(slurm);
    let _ = std::fs::remove_dir_all(&d);
}

/// Parts of one plan built at the same time into one folder, each the first process of a PID
/// namespace of its own (as in containers, or on other nodes where PIDs repeat): none removes
/// or shares another's spill folder, and the merge holds every record once. Needs `unshare`
/// and the right to make namespaces (root, as in CI); skipped otherwise.
#[test]
fn parts_at_once_in_separate_pid_namespaces_keep_their_work() {
    let probe = Command::new("unshare")
        .args(["--pid", "--fork", "--mount-proc", "true"])
        .output();
    if !probe.is_ok_and(|o| o.status.success()) {
        eprintln!("SKIPPED: unshare --pid is not available here (needs root)");
        return;
    }
    let d = tempdir("partition-pidns");
    let (west, east, want) = two_scans(&d);
    let plan = make_plan(&d, &[&west, &east], "plan.json");
    let parts = d.join("parts");
    std::fs::create_dir_all(&parts).unwrap();
    // Three rounds of the four parts at once: each round, every part is PID 1 and spills into
    // the shared folder while the others start, run and finish around it.
    for round in 0..3 {
        let children: Vec<_> = (0..4)
            .map(|i| {
                Command::new("unshare")
                    .args(["--pid", "--fork", "--mount-proc"])
                    .arg(env!("CARGO_BIN_EXE_myriad"))
                    .args(["convert", "--plan", s(&plan), "-o", s(&parts), "--force"])
                    .args(["--part", &i.to_string(), "--threads", "1"])
                    .stdout(std::process::Stdio::null())
                    .stderr(std::process::Stdio::piped())
                    .spawn()
                    .unwrap()
            })
            .collect();
        for (i, c) in children.into_iter().enumerate() {
            let out = c.wait_with_output().unwrap();
            assert!(
                out.status.success(),
                "round {round}, part {i}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        let left: Vec<String> = std::fs::read_dir(&parts)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
            .filter(|n| n.starts_with('.'))
            .collect();
        assert!(left.is_empty(), "left behind: {left:?}");
    }
    let merged = d.join("merged.myr");
    ok(&["merge", s(&plan), s(&parts), "-o", s(&merged)]);
    holds(&merged, &want);
}
