//! ARCHITECTURE.md's invariants on imports, checked on the sources: crates import only crates
//! on floors below their own (their `[dependencies]` and the `myriad_*` paths of their
//! `src/`), and inside a crate no modules import each other in a circle (a child may use its
//! parent's and ancestors' items: those edges are left out). Test code (`tests/`, modules after
//! `#[cfg(test)]`, files named `*tests.rs`) is not checked.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The floors, bottom first: a crate imports only crates of lower floors.
const FLOORS: [&[&str]; 10] = [
    &["myriad-core"],
    &["myriad-io"],
    &["myriad-format", "myriad-synth"],
    &["myriad-measure"],
    &["myriad-build"],
    &["myriad-lod"],
    &["myriad-render", "myriad-web"],
    &["myriad-viewer", "myriad-serve"],
    &["myriad-bench"],
    &["myriad"],
];

fn floor(name: &str) -> usize {
    let name = name.replace('_', "-");
    (FLOORS.iter().position(|f| f.contains(&name.as_str())))
        .unwrap_or_else(|| panic!("{name}: on no floor of ARCHITECTURE.md (add it to FLOORS)"))
}

fn crates_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// The `.rs` files under `dir`, recursively, sorted.
fn sources(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// The code of `text` before its first `#[cfg(test)]` line, without comments, strings and
/// character literals.
fn code(text: &str) -> String {
    let text = match text.find("\n#[cfg(test)]") {
        Some(i) => &text[..i],
        None => text,
    };
    let b: Vec<char> = text.chars().collect();
    let (mut out, mut i) = (String::new(), 0);
    while i < b.len() {
        let c = b[i];
        let next = b.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            while i < b.len() && b[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            i += 2;
            while i + 1 < b.len() && !(b[i] == '*' && b[i + 1] == '/') {
                i += 1;
            }
            i += 2;
        } else if c == 'r' && (next == Some('"') || next == Some('#')) && !ident_before(&b, i) {
            // A raw string: r"..." or r#"..."#.
            let mut j = i + 1;
            let mut hashes = 0;
            while b.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if b.get(j) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            j += 1;
            let end: String = std::iter::once('"')
                .chain((0..hashes).map(|_| '#'))
                .collect();
            let end: Vec<char> = end.chars().collect();
            while j < b.len() && b[j..].iter().take(end.len()).ne(end.iter()) {
                j += 1;
            }
            i = j + end.len();
            out.push_str("\"\"");
        } else if c == '"' {
            i += 1;
            while i < b.len() && b[i] != '"' {
                i += if b[i] == '\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("\"\"");
        } else if c == '\'' {
            // A character literal ('a', '\n', '\u{1F600}'), else a lifetime.
            let close = (1..=10).find(|k| b.get(i + k) == Some(&'\''));
            match close {
                Some(k) if k == 2 || (b.get(i + 1) == Some(&'\\')) => i += k + 1,
                _ => {
                    out.push(c);
                    i += 1;
                }
            }
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

fn ident_before(b: &[char], i: usize) -> bool {
    i > 0 && (b[i - 1].is_alphanumeric() || b[i - 1] == '_')
}

#[derive(Debug, PartialEq, Clone)]
enum Tok {
    Ident(String),
    Path,
    Open,
    Close,
    Comma,
    Other,
}

fn tokens(code: &str) -> Vec<Tok> {
    let b: Vec<char> = code.chars().collect();
    let (mut out, mut i) = (Vec::new(), 0);
    while i < b.len() {
        let c = b[i];
        if c.is_alphabetic() || c == '_' {
            let s = i;
            while i < b.len() && (b[i].is_alphanumeric() || b[i] == '_') {
                i += 1;
            }
            out.push(Tok::Ident(b[s..i].iter().collect()));
            continue;
        }
        if c == ':' && b.get(i + 1) == Some(&':') {
            out.push(Tok::Path);
            i += 2;
            continue;
        }
        match c {
            '{' => out.push(Tok::Open),
            '}' => out.push(Tok::Close),
            ',' => out.push(Tok::Comma),
            c if c.is_whitespace() => {}
            _ => out.push(Tok::Other),
        }
        i += 1;
    }
    out
}

/// The paths that start at `t[at]` (an identifier followed by `::`): one, or several where a
/// `{...}` group follows; each as its segments.
fn paths_at(t: &[Tok], at: usize) -> Vec<Vec<String>> {
    let mut prefix = Vec::new();
    let mut i = at;
    loop {
        match t.get(i) {
            Some(Tok::Ident(s)) => prefix.push(s.clone()),
            _ => return vec![prefix],
        }
        match (t.get(i + 1), t.get(i + 2)) {
            (Some(Tok::Path), Some(Tok::Ident(_))) => i += 2,
            (Some(Tok::Path), Some(Tok::Open)) => {
                // A group: each item's paths, after the prefix.
                let mut out = Vec::new();
                let mut j = i + 3;
                let mut depth = 0;
                let mut item_start = true;
                while let Some(tok) = t.get(j) {
                    match tok {
                        Tok::Open => depth += 1,
                        Tok::Close if depth == 0 => break,
                        Tok::Close => depth -= 1,
                        Tok::Comma if depth == 0 => {
                            item_start = true;
                            j += 1;
                            continue;
                        }
                        Tok::Ident(_) if item_start && depth == 0 => {
                            for p in paths_at(t, j) {
                                out.push(prefix.iter().cloned().chain(p).collect());
                            }
                        }
                        _ => {}
                    }
                    item_start = false;
                    j += 1;
                }
                return out;
            }
            _ => return vec![prefix],
        }
    }
}

/// A crate's modules by the file that holds each: `lib.rs` is `[]`, `a/b.rs` and
/// `a/b/mod.rs` are `[a, b]`.
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap();
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().to_string())
        .collect();
    let last = parts.pop().unwrap();
    let stem = last.trim_end_matches(".rs");
    if !(stem == "mod" || (parts.is_empty() && (stem == "lib" || stem == "main"))) {
        parts.push(stem.to_string());
    }
    parts
}

/// The longest module of `modules` that `path` (absolute, within the crate) names.
fn resolve(modules: &BTreeSet<Vec<String>>, path: &[String]) -> Vec<String> {
    (0..=path.len())
        .rev()
        .map(|n| path[..n].to_vec())
        .find(|p| modules.contains(p))
        .unwrap_or_default()
}

/// A circle in `edges` (module -> modules it imports), if there is one.
fn circle(edges: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>) -> Option<Vec<Vec<String>>> {
    fn visit(
        m: &Vec<String>,
        edges: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        state: &mut BTreeMap<Vec<String>, u8>,
        stack: &mut Vec<Vec<String>>,
    ) -> Option<Vec<Vec<String>>> {
        state.insert(m.clone(), 1);
        stack.push(m.clone());
        for n in edges.get(m).into_iter().flatten() {
            match state.get(n) {
                Some(1) => {
                    let at = stack.iter().position(|s| s == n).unwrap();
                    return Some(stack[at..].to_vec());
                }
                Some(_) => {}
                None => {
                    if let Some(c) = visit(n, edges, state, stack) {
                        return Some(c);
                    }
                }
            }
        }
        stack.pop();
        state.insert(m.clone(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for m in edges.keys() {
        if !state.contains_key(m) {
            let mut stack = Vec::new();
            if let Some(c) = visit(m, edges, &mut state, &mut stack) {
                return Some(c);
            }
        }
    }
    None
}

struct Crate {
    name: String,
    src: PathBuf,
    files: Vec<PathBuf>,
}

fn crates() -> Vec<Crate> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(crates_dir()).unwrap().flatten() {
        let src = e.path().join("src");
        if !src.is_dir() {
            continue;
        }
        let files = sources(&src)
            .into_iter()
            .filter(|f| !f.to_string_lossy().ends_with("tests.rs"))
            .collect();
        let name = e.file_name().to_string_lossy().to_string();
        out.push(Crate { name, src, files });
    }
    out.sort_by(|a, b| a.name.cmp(&b.name));
    assert!(out.len() >= 13, "{} crates found", out.len());
    out
}

fn name(m: &[String]) -> String {
    if m.is_empty() {
        "crate".into()
    } else {
        m.join("::")
    }
}

/// The imports of each module of `c` by other modules of it, without a child's of its
/// ancestors.
fn module_edges(c: &Crate) -> BTreeMap<Vec<String>, BTreeSet<Vec<String>>> {
    let modules: BTreeSet<Vec<String>> = c.files.iter().map(|f| module_of(&c.src, f)).collect();
    let mut edges: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    for f in &c.files {
        let me = module_of(&c.src, f);
        let t = tokens(&code(&std::fs::read_to_string(f).unwrap()));
        for i in 0..t.len() {
            let Tok::Ident(first) = &t[i] else { continue };
            let after_path = i > 0 && t[i - 1] == Tok::Path;
            if after_path || t.get(i + 1) != Some(&Tok::Path) {
                continue;
            }
            for p in paths_at(&t, i) {
                // The path from the crate's root.
                let mut abs = match first.as_str() {
                    "crate" => Vec::new(),
                    "self" => me.clone(),
                    "super" => me[..me.len().saturating_sub(1)].to_vec(),
                    _ => continue,
                };
                let mut rest = &p[1..];
                while rest.first().is_some_and(|s| s == "super") {
                    abs.pop();
                    rest = &rest[1..];
                }
                abs.extend(rest.iter().cloned());
                let to = resolve(&modules, &abs);
                // A module's own items, and its ancestors' (a child using its parent's types).
                if me.starts_with(&to) {
                    continue;
                }
                edges.entry(me.clone()).or_default().insert(to);
            }
        }
    }
    edges
}

#[test]
fn no_modules_of_a_crate_import_each_other_in_a_circle() {
    let mut circles = Vec::new();
    for c in crates() {
        if let Some(found) = circle(&module_edges(&c)) {
            let names: Vec<String> = found.iter().map(|m| name(m)).collect();
            circles.push(format!(
                "{}: {} -> {}",
                c.name,
                names.join(" -> "),
                names[0]
            ));
        }
    }
    assert!(
        circles.is_empty(),
        "import circles:\n{}",
        circles.join("\n")
    );
}

#[test]
fn crates_import_only_crates_on_floors_below_their_own() {
    let mut up = Vec::new();
    for c in crates() {
        let own = floor(&c.name);
        // Cargo.toml's dependencies, of any target (not dev-dependencies: tests may use any
        // crate).
        let manifest = std::fs::read_to_string(c.src.parent().unwrap().join("Cargo.toml")).unwrap();
        let deps = (manifest.split("\n["))
            .filter(|s| {
                let header = s.lines().next().unwrap_or("");
                header.ends_with("dependencies]") && !header.ends_with("dev-dependencies]")
            })
            .flat_map(|s| s.lines().skip(1));
        for line in deps {
            let dep = line.split(['.', ' ', '=']).next().unwrap_or("");
            if dep.starts_with("myriad-") && floor(dep) >= own {
                up.push(format!("{}/Cargo.toml: {dep}", c.name));
            }
        }
        // The myriad_* paths of its sources.
        for f in &c.files {
            let t = tokens(&code(&std::fs::read_to_string(f).unwrap()));
            for w in t.windows(2) {
                if let [Tok::Ident(s), Tok::Path] = w
                    && s.starts_with("myriad_")
                    && s.replace('_', "-") != c.name
                    && floor(s) >= own
                {
                    up.push(format!("{}: {s}", f.display()));
                }
            }
        }
    }
    up.sort();
    up.dedup();
    assert!(up.is_empty(), "imports up a floor:\n{}", up.join("\n"));
}

/// The checker itself finds what it must: a circle through a group import, and none through a
/// child's use of its parent.
#[test]
fn the_checker_sees_group_imports_and_spares_children() {
    let t = tokens(&code(
        "use crate::{a::X, b::{self, Y}}; // crate::c::Z\nlet s = \"crate::d\";",
    ));
    let paths = paths_at(&t, 1);
    assert_eq!(
        paths,
        vec![
            vec!["crate".to_string(), "a".into(), "X".into()],
            vec!["crate".to_string(), "b".into(), "self".into()],
            vec!["crate".to_string(), "b".into(), "Y".into()],
        ]
    );
    let m = |s: &str| -> Vec<String> { s.split("::").map(String::from).collect() };
    let mut edges = BTreeMap::new();
    edges.insert(m("a"), BTreeSet::from([m("b")]));
    edges.insert(m("b"), BTreeSet::from([m("c")]));
    assert_eq!(circle(&edges), None);
    edges.insert(m("c"), BTreeSet::from([m("a")]));
    assert_eq!(circle(&edges), Some(vec![m("a"), m("b"), m("c")]));
}

/// The viewer's window state is small values each owned by one file: only `app.rs` adds
/// methods to `App` (ARCHITECTURE.md's myriad-viewer invariant).
#[test]
fn only_the_viewers_app_file_adds_methods_to_app() {
    let src = crates_dir().join("myriad-viewer/src");
    let adding: Vec<String> = sources(&src)
        .into_iter()
        .filter(|f| {
            let t = tokens(&code(&std::fs::read_to_string(f).unwrap()));
            t.windows(3).any(|w| {
                w[0] == Tok::Ident("impl".into())
                    && w[1] == Tok::Ident("App".into())
                    && matches!(w[2], Tok::Open | Tok::Other)
            })
        })
        .map(|f| f.strip_prefix(&src).unwrap().display().to_string())
        .collect();
    assert_eq!(adding, vec!["app.rs".to_string()], "files with `impl App`");
}
