//! What long commands print as they go and at the end: a progress bar per phase, and a build's
//! last lines (peak memory, skipped points); and the worker threads LAZ decoding gets.

use indicatif::{ProgressBar, ProgressStyle};
use myriad_build::convert;
use myriad_core::units::thousands;
use std::sync::Mutex;

/// A progress bar per phase on a terminal (indicatif draws nothing when stderr is not one).
pub(crate) struct Bar {
    bar: Mutex<Option<ProgressBar>>,
}

impl Bar {
    pub(crate) fn new() -> Bar {
        Bar {
            bar: Mutex::new(None),
        }
    }

    pub(crate) fn clear(&self) {
        if let Some(b) = self.bar.lock().unwrap().take() {
            b.finish_and_clear();
        }
    }
}

impl convert::Report for Bar {
    fn phase(&self, name: &'static str, total: u64) {
        let b = ProgressBar::new(total);
        let unit = match name {
            "merging" => "nodes",
            "writing" => "steps",
            _ => "points",
        };
        b.set_style(
            ProgressStyle::with_template(&format!(
                "{{prefix:>9}} [{{bar:40}}] {{human_pos}}/{{human_len}} {unit} {{per_sec:0}} ETA {{eta}}"
            ))
            .expect("valid template")
            .progress_chars("=> "),
        );
        b.set_prefix(name);
        if let Some(old) = self.bar.lock().unwrap().replace(b) {
            old.finish_and_clear();
        }
    }
    fn advance(&self, n: u64) {
        if let Some(b) = &*self.bar.lock().unwrap() {
            b.inc(n);
        }
    }
}

/// LAZ decompression runs on rayon's global pool: it gets the build's number of threads.
pub(crate) fn global_threads(t: usize) {
    rayon::ThreadPoolBuilder::new()
        .num_threads(t.max(1))
        .build_global()
        .ok();
}

/// A build summary's last lines: peak memory, and the points skipped for NaN or infinite
/// coordinates (when there were any).
/// Prints a command's summary as one JSON object, with this process's peak memory and CPU
/// seconds (`peak_rss_bytes`, `cpu_seconds`) added.
pub(crate) fn print_json(mut v: serde_json::Value) {
    v["peak_rss_bytes"] = serde_json::json!(myriad_io::process::peak_rss_bytes());
    v["cpu_seconds"] = serde_json::json!(myriad_io::process::cpu_seconds());
    println!("{v}");
}

pub(crate) fn print_memory_and_skipped(skipped: u64) {
    if let Some(c) = myriad_io::process::cpu_seconds() {
        println!("  cpu         {c:.2} s (all threads)");
    }
    if let Some(p) = myriad_io::process::peak_rss_bytes() {
        println!("  memory      {:.0} MB peak resident", p as f64 / 1e6);
    }
    if skipped > 0 {
        println!(
            "  skipped     {} with NaN/infinite coordinates",
            thousands(skipped)
        );
    }
}
