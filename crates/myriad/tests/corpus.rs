//! The corpus of crafted inputs (`tests/corpus/`, made by `examples/make_corpus/`; its README
//! lists the classes): every file through each command that `cases.tsv` names, as a user runs
//! the binary. Each run must give the exit code and the text the case expects (a failure: exactly
//! one `error:` line naming the file), never panic, stay under a memory and a time cap, leave the
//! input byte for byte as it was, and leave no output behind when it fails. A dataset that
//! `convert` made of an odd input must then verify, extract and render.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Peak resident memory allowed to one command on these small files (measured by `wait4`).
const MEMORY_CAP_KB: i64 = 512 * 1024;
/// Address space allowed to one command (`RLIMIT_AS`): an allocation sized from a damaged
/// header fails at once instead of being reserved and touched lazily.
const ADDRESS_SPACE_CAP: u64 = 4 << 30;
/// Wall time allowed to one command (they take milliseconds; this catches hangs).
const TIME_CAP: Duration = Duration::from_secs(30);

struct Case {
    file: String,
    command: String,
    exit: i32,
    expect: String,
}

fn cases(dir: &Path) -> Vec<Case> {
    let text = std::fs::read_to_string(dir.join("cases.tsv")).expect("cases.tsv");
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split('\t').collect();
            assert_eq!(f.len(), 4, "cases.tsv line {l:?}");
            Case {
                file: f[0].into(),
                command: f[1].into(),
                exit: f[2].parse().expect("exit code"),
                expect: f[3].into(),
            }
        })
        .collect()
}

struct Outcome {
    code: i32,
    stdout: String,
    stderr: String,
    max_rss_kb: i64,
}

/// Runs the binary, killing it at the time cap; reads its peak memory from `wait4`.
fn run(args: &[&str], cwd: &Path) -> Result<Outcome, String> {
    let mut command = Command::new(env!("CARGO_BIN_EXE_myriad"));
    // SAFETY: setrlimit is async-signal-safe; nothing else runs between fork and exec.
    unsafe {
        std::os::unix::process::CommandExt::pre_exec(&mut command, || {
            let cap = libc::rlimit {
                rlim_cur: ADDRESS_SPACE_CAP,
                rlim_max: ADDRESS_SPACE_CAP,
            };
            if libc::setrlimit(libc::RLIMIT_AS, &cap) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let mut child = command
        .args(args)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| e.to_string())?;
    let pid = child.id() as libc::pid_t;
    let (mut out, mut err) = (child.stdout.take().unwrap(), child.stderr.take().unwrap());
    let readers = (
        std::thread::spawn(move || {
            let mut s = String::new();
            std::io::Read::read_to_string(&mut out, &mut s).ok();
            s
        }),
        std::thread::spawn(move || {
            let mut s = String::new();
            std::io::Read::read_to_string(&mut err, &mut s).ok();
            s
        }),
    );
    let start = Instant::now();
    let (status, rss) = loop {
        let mut status = 0;
        let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
        // SAFETY: pid is our child; status and usage are valid for writing.
        let r = unsafe { libc::wait4(pid, &mut status, libc::WNOHANG, &mut usage) };
        if r == pid {
            break (status, usage.ru_maxrss);
        }
        if start.elapsed() > TIME_CAP {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("still running after {TIME_CAP:?}: killed"));
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let code = if libc::WIFEXITED(status) {
        libc::WEXITSTATUS(status)
    } else {
        return Err(format!("killed by signal {}", libc::WTERMSIG(status)));
    };
    Ok(Outcome {
        code,
        stdout: readers.0.join().unwrap(),
        stderr: readers.1.join().unwrap(),
        max_rss_kb: rss,
    })
}

/// What is wrong with one case's outcome, if anything.
fn check(corpus: &Path, c: &Case, scratch: &Path) -> Result<(), String> {
    for e in std::fs::read_dir(scratch).unwrap() {
        let _ = std::fs::remove_file(e.unwrap().path());
    }
    let input = corpus.join(&c.file);
    let before = std::fs::read(&input).map_err(|e| format!("{}: {e}", input.display()))?;
    let out = scratch.join(match c.command.as_str() {
        "convert" => "out.myr",
        "extract" => "out.las",
        _ => "out.png",
    });
    let file = c.file.as_str();
    let outs = out.to_str().unwrap();
    let args: Vec<&str> = match c.command.as_str() {
        "info" => vec!["info", "--json", file],
        "convert" => vec![
            "convert",
            file,
            "-o",
            outs,
            "--memory",
            "512MB",
            "--threads",
            "2",
        ],
        "verify" => vec!["verify", file],
        "extract" => vec!["extract", file, "-o", outs],
        "render" => vec![
            "render", file, "-o", outs, "--raster", "cpu", "--width", "64", "--height", "48",
        ],
        other => return Err(format!("unknown command {other}")),
    };
    let o = run(&args, corpus)?;
    let after = std::fs::read(&input).map_err(|e| e.to_string())?;
    if after != before {
        return Err("the input was modified".into());
    }
    if o.stderr.contains("panicked") || o.stdout.contains("panicked") {
        return Err(format!("panic: {}", o.stderr));
    }
    if o.max_rss_kb > MEMORY_CAP_KB {
        return Err(format!(
            "peak memory {} MB over the cap",
            o.max_rss_kb / 1024
        ));
    }
    if o.code != c.exit {
        return Err(format!(
            "exit code {}, expected {}; stderr: {}",
            o.code,
            c.exit,
            o.stderr.trim()
        ));
    }
    let leftovers: Vec<String> = std::fs::read_dir(scratch)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    if c.exit == 0 {
        if !o.stdout.contains(&c.expect) {
            return Err(format!(
                "{:?} not in the output: {}",
                c.expect,
                o.stdout.trim()
            ));
        }
        if c.command != "info" && c.command != "verify" && !out.exists() {
            return Err(format!("succeeded without writing {}", out.display()));
        }
        if c.command == "convert" {
            // What convert made of an odd but readable input works like any dataset.
            let (las, png) = (scratch.join("back.las"), scratch.join("back.png"));
            let (las, png) = (las.to_str().unwrap(), png.to_str().unwrap());
            for args in [
                &["verify", outs][..],
                &["extract", outs, "-o", las],
                &[
                    "render", outs, "-o", png, "--raster", "cpu", "--width", "64", "--height", "48",
                ],
            ] {
                let r = run(args, corpus)?;
                if r.code != 0 || r.max_rss_kb > MEMORY_CAP_KB {
                    return Err(format!(
                        "{} of the converted dataset: exit {}, {} MB: {}",
                        args[0],
                        r.code,
                        r.max_rss_kb / 1024,
                        r.stderr.trim()
                    ));
                }
            }
        }
    } else {
        let lines: Vec<&str> = o
            .stderr
            .lines()
            .filter(|l| !l.starts_with("warning:"))
            .collect();
        let [line] = lines.as_slice() else {
            return Err(format!("expected one error line, got {lines:?}"));
        };
        if !line.starts_with("error: ") || !line.contains(file) {
            return Err(format!("the error does not name {file}: {line}"));
        }
        if !line.contains(&c.expect) {
            return Err(format!("{:?} not in {line:?}", c.expect));
        }
        // Extraction from a damaged dataset salvages the rest, and says so in its error.
        let salvaged = c.command == "extract" && line.contains("lacks their points");
        if !leftovers.is_empty() && !salvaged {
            return Err(format!("failed but left {leftovers:?}"));
        }
    }
    Ok(())
}

#[test]
fn corpus_of_crafted_inputs() {
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    let cases = cases(&corpus);
    assert!(cases.len() > 100, "the corpus has {} cases", cases.len());
    let next = std::sync::atomic::AtomicUsize::new(0);
    let failures = std::sync::Mutex::new(Vec::new());
    let threads = std::thread::available_parallelism()
        .map_or(2, |n| n.get())
        .min(4);
    std::thread::scope(|s| {
        for t in 0..threads {
            let (cases, next, failures, corpus) = (&cases, &next, &failures, &corpus);
            s.spawn(move || {
                let scratch: PathBuf =
                    std::env::temp_dir().join(format!("myriad-corpus-{}-{t}", std::process::id()));
                let _ = std::fs::remove_dir_all(&scratch);
                std::fs::create_dir_all(&scratch).unwrap();
                loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some(c) = cases.get(i) else { break };
                    if let Err(e) = check(corpus, c, &scratch) {
                        failures
                            .lock()
                            .unwrap()
                            .push(format!("{} {}: {e}", c.command, c.file));
                    }
                }
                let _ = std::fs::remove_dir_all(&scratch);
            });
        }
    });
    let failures = failures.into_inner().unwrap();
    let files: std::collections::BTreeSet<&str> = cases.iter().map(|c| c.file.as_str()).collect();
    println!(
        "corpus: {} files, {} cases, {} failed",
        files.len(),
        cases.len(),
        failures.len()
    );
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
