//! The user guide covers the program (issue 44): every subcommand and every option that
//! `myriad --help` and each command's `--help` list appears in `docs/guide/`, and the README's
//! two set-up commands are the ones the guide gives and `.ci/run` runs.

use std::path::Path;
use std::process::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .parent()
        .unwrap()
}

fn help(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_myriad"))
        .args(args)
        .arg("--help")
        .output()
        .unwrap();
    assert!(out.status.success(), "{args:?} --help");
    String::from_utf8(out.stdout).unwrap()
}

/// The names under "Commands:" of a help text (without `help`).
fn commands(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .filter(|c| c != "help")
        .collect()
}

/// The long options of a help text (without `--help` and `--version`).
fn options(help: &str) -> Vec<String> {
    help.lines()
        .map(str::trim_start)
        .filter(|l| l.starts_with('-'))
        .filter_map(|l| {
            l.split([' ', ','])
                .find(|t| t.starts_with("--"))
                .map(|t| t.split(['=', '<']).next().unwrap().to_string())
        })
        .filter(|o| o != "--help" && o != "--version")
        .collect()
}

fn guide() -> String {
    let dir = root().join("docs/guide");
    let mut pages: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    pages.sort();
    assert!(pages.len() >= 10, "{} guide pages", pages.len());
    pages
        .iter()
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn every_command_and_option_is_in_the_guide() {
    let text = guide();
    let mut missing = Vec::new();
    for c in commands(&help(&[])) {
        let subs = commands(&help(&[&c]));
        if subs.is_empty() {
            if !text.contains(&format!("myriad {c}")) && !text.contains(&format!("`{c}`")) {
                missing.push(c.clone());
            }
            for o in options(&help(&[&c])) {
                if !text.contains(&o) {
                    missing.push(format!("{c} {o}"));
                }
            }
        }
        for s in subs {
            if !text.contains(&format!("{c} {s}")) {
                missing.push(format!("{c} {s}"));
            }
            for o in options(&help(&[&c, &s])) {
                if !text.contains(&o) {
                    missing.push(format!("{c} {s} {o}"));
                }
            }
        }
    }
    assert!(
        missing.is_empty(),
        "not in docs/guide/: {}",
        missing.join(", ")
    );
}

#[test]
fn the_readme_set_up_is_the_guide_s_and_ci_s() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let set_up: Vec<&str> = readme
        .lines()
        .skip_while(|l| !l.starts_with("## Set-up"))
        .filter(|l| l.starts_with("    cargo "))
        .take(2)
        .map(str::trim)
        .collect();
    assert_eq!(set_up.len(), 2, "two commands under the README's set-up");
    assert!(
        set_up[0].contains("synth") && set_up[0].contains("render"),
        "{}",
        set_up[0]
    );
    assert!(set_up[1].starts_with("cargo test"), "{}", set_up[1]);
    let guide = std::fs::read_to_string(root().join("docs/guide/README.md")).unwrap();
    for c in &set_up {
        assert!(
            guide.lines().any(|l| l.trim() == *c),
            "the guide does not give: {c}"
        );
    }
    let ci = std::fs::read_to_string(root().join(".ci/run")).unwrap();
    let last = ci
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap()
        .trim();
    assert_eq!(
        last, set_up[1],
        ".ci/run must end by running the README's test command"
    );
    assert!(
        readme.lines().count() <= 200,
        "README of {} lines",
        readme.lines().count()
    );
}
