//! The modules of mimic_stream import each other without a circle: reads `src/`, builds the
//! graph of which module names which (`use crate::…`, `use super::…`, a child module's path, a
//! path inside a function body), and fails naming the circle when there is one. Comments,
//! string literals and a file's `#[cfg(test)]` tail are not read.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// A module's path below the crate root (`[]` is `lib.rs`).
type Module = Vec<String>;

/// Which module names which.
type Graph = BTreeMap<Module, BTreeSet<Module>>;

/// The source with comments and string and char literals blanked, cut at `#[cfg(test)]`.
fn code_of(source: &str) -> String {
    let source = source.split("#[cfg(test)]").next().unwrap_or_default();
    let b: Vec<char> = source.chars().collect();
    let mut out = String::with_capacity(b.len());
    let mut k = 0;
    while k < b.len() {
        let c = b[k];
        let next = b.get(k + 1).copied();
        if c == '/' && next == Some('/') {
            while k < b.len() && b[k] != '\n' {
                k += 1;
            }
        } else if c == '/' && next == Some('*') {
            k += 2;
            while k + 1 < b.len() && !(b[k] == '*' && b[k + 1] == '/') {
                k += 1;
            }
            k += 2;
            out.push(' ');
        } else if c == 'r' && (next == Some('"') || next == Some('#')) && !ident_char(prev(&b, k)) {
            // A raw string: r"…", r#"…"#.
            let mut j = k + 1;
            let mut hashes = 0;
            while b.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if b.get(j) != Some(&'"') {
                out.push(c);
                k += 1;
                continue;
            }
            j += 1;
            loop {
                if j >= b.len() {
                    break;
                }
                if b[j] == '"' && (1..=hashes).all(|h| b.get(j + h) == Some(&'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            k = j;
            out.push_str("\"\"");
        } else if c == '"' {
            k += 1;
            while k < b.len() && b[k] != '"' {
                k += if b[k] == '\\' { 2 } else { 1 };
            }
            k += 1;
            out.push_str("\"\"");
        } else if c == '\'' {
            // A char literal ('x', '\n', '\u{..}'), else a lifetime.
            if next == Some('\\') {
                k += 2;
                while k < b.len() && b[k] != '\'' {
                    k += 1;
                }
                k += 1;
                out.push_str("' '");
            } else if b.get(k + 2) == Some(&'\'') {
                k += 3;
                out.push_str("' '");
            } else {
                out.push(c);
                k += 1;
            }
        } else {
            out.push(c);
            k += 1;
        }
    }
    out
}

/// The char before `k`, or a space.
fn prev(b: &[char], k: usize) -> char {
    if k == 0 { ' ' } else { b[k - 1] }
}

/// True for a char of an identifier.
fn ident_char(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// A token of code: an identifier, `::`, or one other char.
#[derive(Debug, PartialEq)]
enum Tok {
    Ident(String),
    Path,
    Other(char),
}

/// The tokens of blanked code.
fn tokens(code: &str) -> Vec<Tok> {
    let b: Vec<char> = code.chars().collect();
    let mut out = Vec::new();
    let mut k = 0;
    while k < b.len() {
        let c = b[k];
        if ident_char(c) {
            let start = k;
            while k < b.len() && ident_char(b[k]) {
                k += 1;
            }
            out.push(Tok::Ident(b[start..k].iter().collect()));
        } else if c == ':' && b.get(k + 1) == Some(&':') {
            out.push(Tok::Path);
            k += 2;
        } else {
            if !c.is_whitespace() {
                out.push(Tok::Other(c));
            }
            k += 1;
        }
    }
    out
}

/// The module that `segments`, read in module `at`, ends in: its deepest module prefix, or
/// `None` for a path that names no module of the crate (another crate, a local item).
fn resolve(modules: &BTreeSet<Module>, at: &Module, segments: &[String]) -> Option<Module> {
    let mut base = at.clone();
    let mut rest = segments;
    let child = |base: &Module, name: &str| {
        let mut m = base.clone();
        m.push(name.to_string());
        modules.contains(&m).then_some(m)
    };
    match rest.first().map(String::as_str) {
        Some("crate") => {
            base = Vec::new();
            rest = &rest[1..];
        }
        Some("self") => rest = &rest[1..],
        Some("super") => {
            while rest.first().map(String::as_str) == Some("super") {
                base.pop()?;
                rest = &rest[1..];
            }
        }
        Some(first) => {
            child(&base, first)?;
        }
        None => return None,
    }
    for s in rest {
        match child(&base, s) {
            Some(m) => base = m,
            None => break,
        }
    }
    Some(base)
}

/// Reads the path starting at token `k` (prefix `prefix`, in module `at`) into `found`, with
/// each item of a `{…}` group; returns the token after the path.
fn read_path(
    toks: &[Tok],
    mut k: usize,
    prefix: Vec<String>,
    modules: &BTreeSet<Module>,
    at: &Module,
    found: &mut BTreeSet<Module>,
) -> usize {
    let mut segments = prefix;
    loop {
        match toks.get(k) {
            Some(Tok::Ident(s)) => {
                segments.push(s.clone());
                k += 1;
            }
            Some(Tok::Other('{')) => {
                // A group: each item is a path below what came before.
                k += 1;
                let mut item_start = true;
                while let Some(t) = toks.get(k) {
                    match t {
                        Tok::Other('}') => {
                            k += 1;
                            break;
                        }
                        Tok::Other(',') => {
                            item_start = true;
                            k += 1;
                        }
                        Tok::Ident(_) if item_start => {
                            item_start = false;
                            k = read_path(toks, k, segments.clone(), modules, at, found);
                        }
                        _ => k += 1,
                    }
                }
                return k;
            }
            _ => break,
        }
        if toks.get(k) != Some(&Tok::Path) {
            break;
        }
        k += 1;
    }
    // A path that goes on as `self` in a group (`use super::state::{self, …}`).
    if segments.last().map(String::as_str) == Some("self") && segments.len() > 1 {
        segments.pop();
    }
    if let Some(m) = resolve(modules, at, &segments) {
        found.insert(m);
    }
    k
}

/// The modules that the code of module `at` names (itself left out).
fn named_by(code: &str, at: &Module, modules: &BTreeSet<Module>) -> BTreeSet<Module> {
    let toks = tokens(code);
    let mut found = BTreeSet::new();
    let mut k = 0;
    while k < toks.len() {
        let starts_path = matches!(toks.get(k), Some(Tok::Ident(_)))
            && toks.get(k + 1) == Some(&Tok::Path)
            && (k == 0 || toks[k - 1] != Tok::Path);
        if starts_path {
            k = read_path(&toks, k, Vec::new(), modules, at, &mut found);
        } else {
            k += 1;
        }
    }
    found.remove(at);
    found
}

/// The import graph of the crate whose files are `files` (module path, source).
fn graph(files: &[(Module, String)]) -> Graph {
    let modules: BTreeSet<Module> = files.iter().map(|(m, _)| m.clone()).collect();
    files
        .iter()
        .map(|(m, src)| (m.clone(), named_by(&code_of(src), m, &modules)))
        .collect()
}

/// A circle of the graph (its modules, the first again at the end), if it has one.
fn circle(g: &Graph) -> Option<Vec<Module>> {
    /// Depth-first search from `m`; `path` is the modules on the way down.
    fn visit(
        g: &Graph,
        m: &Module,
        done: &mut BTreeSet<Module>,
        path: &mut Vec<Module>,
    ) -> Option<Vec<Module>> {
        if let Some(i) = path.iter().position(|p| p == m) {
            let mut c = path[i..].to_vec();
            c.push(m.clone());
            return Some(c);
        }
        if done.contains(m) {
            return None;
        }
        path.push(m.clone());
        for n in g.get(m).into_iter().flatten() {
            if let Some(c) = visit(g, n, done, path) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(m.clone());
        None
    }
    let mut done = BTreeSet::new();
    g.keys()
        .find_map(|m| visit(g, m, &mut done, &mut Vec::new()))
}

/// A module's path as Rust writes it.
fn name(m: &Module) -> String {
    std::iter::once("crate")
        .chain(m.iter().map(String::as_str))
        .collect::<Vec<_>>()
        .join("::")
}

/// Every `.rs` file below `dir`, with its module path.
fn crate_files(root: &Path, dir: &Path, out: &mut Vec<(Module, String)>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .expect("src is readable")
        .map(|e| e.expect("a directory entry").path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            crate_files(root, &p, out);
            continue;
        }
        if p.extension().and_then(|e| e.to_str()) != Some("rs") {
            continue;
        }
        let rel = p.strip_prefix(root).expect("below src");
        let mut m: Module = rel
            .with_extension("")
            .components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .collect();
        if matches!(m.last().map(String::as_str), Some("mod" | "lib")) {
            m.pop();
        }
        out.push((m, std::fs::read_to_string(&p).expect("a source file")));
    }
}

/// A synthetic crate: (module path, source).
fn synthetic(files: &[(&str, &str)]) -> Vec<(Module, String)> {
    files
        .iter()
        .map(|(m, s)| {
            let m: Module = m
                .split("::")
                .filter(|x| !x.is_empty())
                .map(String::from)
                .collect();
            (m, (*s).to_string())
        })
        .collect()
}

/// Module path from `a::b`.
fn m(path: &str) -> Module {
    path.split("::").map(String::from).collect()
}

#[test]
fn the_modules_of_mimic_stream_import_each_other_without_a_circle() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    crate_files(&root, &root, &mut files);
    assert!(files.len() > 20, "{} files read", files.len());
    let g = graph(&files);
    // The reading sees imports (a sample that must stay true of the server).
    let accept = &g[&m("server::accept")];
    assert!(accept.contains(&m("server::session")), "{accept:?}");
    assert!(accept.contains(&m("lines")), "{accept:?}");
    if let Some(c) = circle(&g) {
        let names: Vec<String> = c.iter().map(name).collect();
        panic!(
            "import circle: {} (move what both sides need into a module below them)",
            names.join(" -> ")
        );
    }
}

#[test]
fn a_circle_through_use_lines_groups_and_inline_paths_is_found() {
    let files = synthetic(&[
        ("", "mod a; mod b; pub use a::X;"),
        (
            "a",
            "use crate::b::{self, Y};\n// use crate::c;\npub struct X;",
        ),
        ("b", "pub struct Y; fn f() { super::c::g(); }"),
        ("c", "fn g() { let s = \"crate::b\"; }\nuse super::a::X;"),
    ]);
    let g = graph(&files);
    assert_eq!(g[&m("a")], BTreeSet::from([m("b")]));
    assert_eq!(g[&m("b")], BTreeSet::from([m("c")]));
    assert_eq!(g[&m("c")], BTreeSet::from([m("a")]));
    let c = circle(&g).expect("a -> b -> c -> a");
    assert_eq!(c.len(), 4, "{c:?}");
    // Without c's import of a, no circle (the root re-exporting a child is none).
    let files = synthetic(&[
        ("", "mod a; mod b; pub use a::X;"),
        ("a", "use crate::b::{self, Y};\npub struct X;"),
        ("b", "pub struct Y; fn f() { super::c::g(); }"),
        ("c", "fn g() {}"),
    ]);
    assert_eq!(circle(&graph(&files)), None);
}

#[test]
fn a_child_naming_its_parent_is_an_import() {
    let files = synthetic(&[
        ("", "mod s;"),
        ("s", "mod k; use k::run; pub struct Server;"),
        (
            "s::k",
            "use super::Server;\n#[cfg(test)]\nmod tests { use super::*; }",
        ),
    ]);
    let g = graph(&files);
    assert_eq!(g[&m("s::k")], BTreeSet::from([m("s")]));
    assert!(circle(&g).is_some());
}
