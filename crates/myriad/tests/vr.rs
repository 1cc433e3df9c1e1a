//! `view --vr` against a real OpenXR runtime: Monado (../shared/tools/monado) with its simulated
//! headset and null compositor, Vulkan on lavapipe (PLATFORM.md). Skipped, saying why, where
//! Monado or the OpenXR loader is missing.

mod common;
use common::*;
use std::path::Path;

#[test]
fn view_vr_runs_a_session_under_the_simulated_headset() {
    let monado = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/tools/monado");
    let manifest = monado.join("openxr_monado.json");
    if !manifest.exists() {
        eprintln!("SKIPPED: {} not found", manifest.display());
        return;
    }
    let d = tempdir("vr");
    let las = synth(&d, "v.las", 100_000);
    let ds = d.join("v.myr");
    ok(&["convert", s(&las), "-o", s(&ds)]);
    let run_with = |runtime: &Path, frames: &str, extra: &[&str]| {
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_myriad"))
            .args([
                "view",
                s(&ds),
                "--vr",
                "--vr-frames",
                frames,
                "--budget",
                "50k",
            ])
            .args(extra)
            .env("XR_RUNTIME_JSON", runtime)
            .env("XRT_COMPOSITOR_NULL", "1")
            .env("SIMULATED_ENABLE", "1")
            .env("SIMULATED_LEFT", "simple")
            .env("SIMULATED_RIGHT", "simple")
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // The output read as it comes (the runtime logs a lot), and a session that hangs fails
        // the test instead of blocking CI.
        let read = |mut r: Box<dyn std::io::Read + Send>| {
            std::thread::spawn(move || {
                let mut text = String::new();
                let _ = r.read_to_string(&mut text);
                text
            })
        };
        let out = read(Box::new(child.stdout.take().unwrap()));
        let err = read(Box::new(child.stderr.take().unwrap()));
        let t = std::time::Instant::now();
        let status = loop {
            if let Some(status) = child.try_wait().unwrap() {
                break status;
            }
            if t.elapsed() > std::time::Duration::from_secs(240) {
                let _ = child.kill();
                panic!("view --vr did not end within 240 s");
            }
            std::thread::sleep(std::time::Duration::from_millis(100));
        };
        (
            status.code().unwrap_or(-1),
            out.join().unwrap(),
            err.join().unwrap(),
        )
    };
    let run = |runtime: &Path, frames: &str| run_with(runtime, frames, &[]);
    // No runtime there: a clear message and exit code 1, not a crash.
    let (code, _, err) = run(&d.join("none.json"), "10");
    if err.contains("no OpenXR loader") {
        eprintln!("SKIPPED: no OpenXR loader (apt-get install libopenxr-loader1)");
        return;
    }
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("no OpenXR runtime"), "{err}");
    // Monado: the session reaches FOCUSED, 300 frames go to the runtime with both eyes' views,
    // the head the runtime reports moves and the views follow it, the session ends when asked.
    let (code, out, err) = run(&manifest, "300");
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("session reached FOCUSED"), "{out}");
    assert!(
        out.contains("300 frames submitted with 2 views each"),
        "{out}"
    );
    assert!(out.contains("ended cleanly"), "{out}");
    let moved = number_after(&out, "head moved between ");
    assert!(moved > 0, "{out}");
    // The images follow the head: most frames differ from the one before.
    let changed = number_after(&out, "the image changed in ");
    assert!(changed * 2 > moved, "{out}");
    // The simulated controllers are bound and located (they press no buttons).
    assert!(number_after(&out, "controllers located in ") > 0, "{out}");
    // The runtime's hidden-area mesh (Monado has one): masked, no pixel under it lit; what
    // reaches the swapchains is the frame drawn (read back from them), but for the mesh's rim.
    let (hidden, lit) = (
        number_after(&out, "hidden-area mesh masks "),
        number_after(&out, "pixels ("),
    );
    assert!(hidden > 0 && lit == 0, "{out}");
    let differ = number_after(&out, "differ from it in ");
    assert!(differ * 1000 <= changed * 320 * 240, "{out}");
    assert!(out.contains("drawing on the CPU"), "{out}");
    // On the runtime's (software) device itself: the compute or quad path draws into a
    // texture the eyes' swapchain images are cut from on the GPU.
    let mut gpu_run = run_with(&manifest, "20", &["--gpu"]);
    let out = std::mem::take(&mut gpu_run.1);
    assert_eq!(gpu_run.0, 0, "{out}\n{}", gpu_run.2);
    assert!(
        out.contains("20 frames submitted with 2 views each"),
        "{out}"
    );
    assert!(
        out.contains("drawing on it") && out.contains("ended cleanly"),
        "{out}"
    );
    assert!(
        number_after(&out, "differ from it in ") * 1000 <= 20 * 320 * 240,
        "{out}"
    );
}

/// The number in `out` just after `key`.
fn number_after(out: &str, key: &str) -> u64 {
    out.split(key)
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|n| n.trim_end_matches(',').parse().ok())
        .unwrap_or_else(|| panic!("no number after {key:?} in {out}"))
}
