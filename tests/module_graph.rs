//! The import graphs of the library (`src/`) and of the experiments
//! program (`experiments/`), read from the sources: every `crate::…` path
//! (in `use` trees, braces included, and inline) and every `super::…` path
//! outside comments is an edge from the module of its file to the module it
//! names.
//!
//! - `src/`: the nodes are the library's top-level modules (`mesh`,
//!   `laplacian`, …; `a/b.rs` belongs to `a`); a name re-exported by
//!   `lib.rs` (`crate::Mesh`) counts as its module (`mesh`). The binary's
//!   files (`main.rs`, `cli/`) are another crate and left out. The layering
//!   of the README (imports point down) needs at least: no circle.
//! - `experiments/`: the nodes are `harness::NAME` (the harness's
//!   submodules) and `studies::NAME` (one per study; `studies/x/y.rs`
//!   belongs to `studies::x`); `main.rs`, which lists the studies, is the
//!   root and left out. No circle, no study importing another, and the
//!   harness importing no study.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Module → the modules it imports (itself left out).
type Graph = BTreeMap<String, BTreeSet<String>>;

/// The `.rs` files under `dir`, recursively, relative to `dir`.
fn rust_files(dir: &Path, rel: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir.join(rel)) else {
        return;
    };
    for entry in entries.flatten() {
        let name = rel.join(entry.file_name());
        if entry.path().is_dir() {
            rust_files(dir, &name, out);
        } else if name.extension().is_some_and(|e| e == "rs") {
            out.push(name);
        }
    }
}

/// `text` without `//` comments (doc links name modules without importing
/// them) and without the contents of string literals.
fn code_only(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        let mut in_string = false;
        let mut prev = ' ';
        let chars: Vec<char> = line.chars().collect();
        for (i, &c) in chars.iter().enumerate() {
            if !in_string && c == '/' && chars.get(i + 1) == Some(&'/') {
                break;
            }
            if c == '"' && prev != '\\' && prev != '\'' {
                in_string = !in_string;
                out.push(c);
            } else if !in_string {
                out.push(c);
            }
            prev = c;
        }
        out.push('\n');
    }
    // Brace characters would unbalance the inline-module scan.
    out.replace("'{'", "' '").replace("'}'", "' '")
}

/// The paths of a use tree starting at `s` (after a `crate::` or
/// `super::`): `a::b`, `a::{b, c::d}`, `{a, b}`, `self`, `*`; each path as
/// its segments (`self` gives the empty path: the prefix itself).
fn use_tree(s: &[char], pos: &mut usize) -> Vec<Vec<String>> {
    let skip_ws = |pos: &mut usize| {
        while *pos < s.len() && s[*pos].is_whitespace() {
            *pos += 1;
        }
    };
    skip_ws(pos);
    if s.get(*pos) == Some(&'{') {
        *pos += 1;
        let mut paths = Vec::new();
        loop {
            skip_ws(pos);
            match s.get(*pos) {
                None => return paths,
                Some('}') => {
                    *pos += 1;
                    return paths;
                }
                Some(',') => *pos += 1,
                Some(_) => {
                    let before = *pos;
                    paths.extend(use_tree(s, pos));
                    if *pos == before {
                        *pos += 1;
                    }
                }
            }
        }
    }
    let start = *pos;
    while *pos < s.len() && (s[*pos].is_alphanumeric() || s[*pos] == '_' || s[*pos] == '*') {
        *pos += 1;
    }
    let ident: String = s[start..*pos].iter().collect();
    if ident.is_empty() {
        return Vec::new();
    }
    if s.get(*pos) == Some(&':') && s.get(*pos + 1) == Some(&':') {
        *pos += 2;
        return use_tree(s, pos)
            .into_iter()
            .map(|mut p| {
                p.insert(0, ident.clone());
                p
            })
            .collect();
    }
    if ident == "self" {
        vec![Vec::new()]
    } else {
        vec![vec![ident]]
    }
}

/// The names of the inline modules (`mod NAME { … }`) enclosing each
/// byte of `code`, as a function of the byte offset.
fn inline_modules(code: &str) -> impl Fn(usize) -> Vec<String> {
    // (offset of `{`, offset of its `}`, module name if a `mod NAME {`).
    let mut blocks: Vec<(usize, usize, Option<String>)> = Vec::new();
    let mut open: Vec<usize> = Vec::new();
    for (i, c) in code.char_indices() {
        match c {
            '{' => {
                let head = code[..i].trim_end();
                let name: String = head
                    .chars()
                    .rev()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect::<Vec<_>>()
                    .into_iter()
                    .rev()
                    .collect();
                let is_mod = head[..head.len() - name.len()].trim_end().ends_with("mod");
                open.push(blocks.len());
                blocks.push((i, code.len(), is_mod.then_some(name)));
            }
            '}' => {
                if let Some(k) = open.pop() {
                    blocks[k].1 = i;
                }
            }
            _ => {}
        }
    }
    move |at| {
        blocks
            .iter()
            .filter(|(a, b, name)| name.is_some() && *a < at && at < *b)
            .filter_map(|(_, _, name)| name.clone())
            .collect()
    }
}

/// Every path named after `prefix` (`crate::` or `super::`) in `code`,
/// where the prefix starts a path (not `$crate::` or `a::super::`), with
/// the inline modules it stands in.
fn paths_after(code: &str, prefix: &str) -> Vec<(Vec<String>, Vec<String>)> {
    let chars: Vec<char> = code.chars().collect();
    let inline = inline_modules(code);
    let mut found = Vec::new();
    let mut from = 0;
    while let Some(at) = code[from..].find(prefix) {
        let at = from + at;
        from = at + prefix.len();
        let before = code[..at].chars().next_back();
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == '$' || c == ':') {
            continue;
        }
        let mut pos = code[..from].chars().count();
        let inside = inline(at);
        found.extend(
            use_tree(&chars, &mut pos)
                .into_iter()
                .map(|p| (inside.clone(), p)),
        );
    }
    found
}

/// How a crate's files and paths map to the nodes of its graph.
trait Layout {
    /// The module path of a file (relative to the crate's directory), or
    /// `None` if the file is left out.
    fn module_of(&self, file: &Path) -> Option<Vec<String>>;
    /// The node a full module path (from the crate root) belongs to, or
    /// `None` for the root.
    fn node(&self, path: &[String]) -> Option<String>;
}

/// The module path of `file` by Rust's rules: `a/b.rs` and `a/b/mod.rs`
/// are `a::b`; `lib.rs` and `main.rs` at the top are the root.
fn module_path(file: &Path) -> Vec<String> {
    let mut parts: Vec<String> = file
        .iter()
        .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    if parts.last().is_some_and(|p| p == "mod")
        || matches!(&parts[..], [p] if p == "lib" || p == "main")
    {
        parts.pop();
    }
    parts
}

/// The graph of the crate in `dir`.
fn graph(dir: &Path, layout: &impl Layout) -> Graph {
    let mut files = Vec::new();
    rust_files(dir, Path::new(""), &mut files);
    let mut g = Graph::new();
    for file in files {
        let Some(module) = layout.module_of(&file) else {
            continue;
        };
        let Some(from) = layout.node(&module) else {
            continue;
        };
        let text = std::fs::read_to_string(dir.join(&file)).unwrap();
        let code = code_only(&text);
        let targets = g.entry(from.clone()).or_default();
        // `super::` in the file's module is its parent; in an inline module
        // (`mod tests { use super::*; }`), the enclosing one.
        let supers = paths_after(&code, "super::")
            .into_iter()
            .map(|(inside, p)| {
                let mut full = module.clone();
                full.extend(inside);
                full.pop();
                full.extend(p);
                full
            });
        let crates = paths_after(&code, "crate::").into_iter().map(|(_, p)| p);
        for path in crates.chain(supers) {
            if let Some(to) = layout.node(&path)
                && to != from
            {
                targets.insert(to);
            }
        }
    }
    g
}

/// A circle of `g`, if any, as its nodes in order (first repeated last).
fn circle(g: &Graph) -> Option<Vec<String>> {
    /// Depth-first search; `stack` is the current path.
    fn visit<'a>(
        g: &'a Graph,
        node: &'a str,
        stack: &mut Vec<&'a str>,
        done: &mut BTreeSet<&'a str>,
    ) -> Option<Vec<String>> {
        if let Some(at) = stack.iter().position(|n| *n == node) {
            let mut c: Vec<String> = stack[at..].iter().map(|s| s.to_string()).collect();
            c.push(node.to_string());
            return Some(c);
        }
        if !done.insert(node) {
            return None;
        }
        stack.push(node);
        for next in g.get(node).into_iter().flatten() {
            if let Some(c) = visit(g, next, stack, done) {
                return Some(c);
            }
        }
        stack.pop();
        None
    }
    let mut done = BTreeSet::new();
    g.keys()
        .find_map(|n| visit(g, n, &mut Vec::new(), &mut done))
}

/// The library: top-level modules; `lib.rs`'s re-exports resolved.
struct Library {
    /// The top-level modules.
    modules: BTreeSet<String>,
    /// Name re-exported by `lib.rs` → its module.
    reexports: BTreeMap<String, String>,
}

impl Library {
    fn read(src: &Path) -> Library {
        let lib = code_only(&std::fs::read_to_string(src.join("lib.rs")).unwrap());
        let mut modules = BTreeSet::new();
        let mut reexports = BTreeMap::new();
        for statement in lib.split(';') {
            let s = statement.trim();
            let s = s.rsplit(['\n', '}', ']']).next().unwrap_or(s).trim();
            if let Some(name) = s.strip_prefix("pub mod ").or(s.strip_prefix("mod ")) {
                modules.insert(name.trim().to_string());
            }
        }
        for statement in lib.split(';') {
            let Some(at) = statement.find("pub use ") else {
                continue;
            };
            let chars: Vec<char> = statement[at + 8..].chars().collect();
            for path in use_tree(&chars, &mut 0) {
                if let (Some(first), Some(last)) = (path.first(), path.last())
                    && modules.contains(first)
                {
                    reexports.insert(last.clone(), first.clone());
                }
            }
        }
        Library { modules, reexports }
    }
}

impl Layout for Library {
    fn module_of(&self, file: &Path) -> Option<Vec<String>> {
        let path = module_path(file);
        let binary = file == Path::new("main.rs") || path.first().is_some_and(|p| p == "cli");
        (!binary).then_some(path)
    }

    fn node(&self, path: &[String]) -> Option<String> {
        let first = path.first()?;
        if self.modules.contains(first) {
            Some(first.clone())
        } else {
            self.reexports.get(first).cloned()
        }
    }
}

/// The experiments program: `harness::NAME` and `studies::NAME`.
struct Experiments {
    /// Every module path of the program, as `a::b`.
    modules: BTreeSet<String>,
}

impl Layout for Experiments {
    fn module_of(&self, file: &Path) -> Option<Vec<String>> {
        Some(module_path(file))
    }

    fn node(&self, path: &[String]) -> Option<String> {
        match path {
            [top, sub, ..] if self.modules.contains(&format!("{top}::{sub}")) => {
                Some(format!("{top}::{sub}"))
            }
            [top, ..] if top == "harness" || top == "studies" => Some(top.clone()),
            _ => None,
        }
    }
}

/// The graph of `experiments/`.
fn experiments_graph() -> Graph {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    let mut files = Vec::new();
    rust_files(&dir, Path::new(""), &mut files);
    let modules = files
        .iter()
        .map(|f| module_path(f))
        .filter(|p| p.len() >= 2)
        .map(|p| format!("{}::{}", p[0], p[1]))
        .collect();
    graph(&dir, &Experiments { modules })
}

/// The graph of `src/` (the library).
fn library_graph() -> Graph {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    graph(&src, &Library::read(&src))
}

/// Whether `node` is a study.
fn is_study(node: &str) -> bool {
    node.starts_with("studies::")
}

#[test]
fn experiments_have_no_import_circle() {
    let g = experiments_graph();
    assert!(
        g.keys().any(|n| n.starts_with("harness::")) && g.keys().any(|n| is_study(n)),
        "the experiments' harness and studies were not found: {:?}",
        g.keys()
    );
    assert_eq!(circle(&g), None, "an import circle in experiments/");
}

#[test]
fn no_study_imports_another() {
    for (from, targets) in experiments_graph() {
        let studies: Vec<&String> = targets.iter().filter(|t| is_study(t)).collect();
        assert!(
            !is_study(&from) || studies.is_empty(),
            "{from} imports the studies {studies:?}"
        );
    }
}

#[test]
fn the_harness_imports_no_study() {
    for (from, targets) in experiments_graph() {
        let studies: Vec<&String> = targets.iter().filter(|t| is_study(t)).collect();
        assert!(
            !from.starts_with("harness") || studies.is_empty(),
            "{from} imports the studies {studies:?}"
        );
    }
}

#[test]
fn library_modules_form_no_import_circle() {
    let g = library_graph();
    assert!(
        ["mesh", "laplacian", "solver"]
            .iter()
            .all(|m| g.contains_key(*m)),
        "the library's modules were not found: {:?}",
        g.keys()
    );
    assert_eq!(circle(&g), None, "an import circle among src/'s modules");
}

#[test]
fn the_scanner_reads_use_trees_and_finds_circles() {
    let code = code_only(
        "use crate::a::{b, c::{d, self}};\n// use crate::z;\nlet x = \"crate::y\";\n\
         fn f() { crate::e::g(); $crate::h; super::i::j }",
    );
    let paths = paths_after(&code, "crate::");
    let names: Vec<String> = paths.iter().map(|(_, p)| p.join("::")).collect();
    assert_eq!(names, ["a::b", "a::c::d", "a::c", "e::g"]);
    let supers = paths_after(&code, "super::");
    assert_eq!(supers, [(vec![], ["i", "j"].map(String::from).to_vec())]);
    let in_tests = paths_after(
        "mod tests {\n    use super::*;\n}\nuse super::x;",
        "super::",
    );
    let inside: Vec<&[String]> = in_tests.iter().map(|(m, _)| &m[..]).collect();
    assert_eq!(inside, [&["tests".to_string()][..], &[][..]]);
    let mut g = Graph::new();
    g.entry("a".into()).or_default().insert("b".into());
    g.entry("b".into()).or_default().insert("c".into());
    g.entry("c".into()).or_default();
    assert_eq!(circle(&g), None);
    g.entry("c".into()).or_default().insert("a".into());
    assert_eq!(
        circle(&g),
        Some(["a", "b", "c", "a"].map(String::from).to_vec())
    );
}

#[test]
fn module_paths_follow_rusts_file_rules() {
    assert_eq!(module_path(Path::new("lib.rs")), Vec::<String>::new());
    assert_eq!(module_path(Path::new("mesh/io.rs")), ["mesh", "io"]);
    assert_eq!(
        module_path(Path::new("harness/plot/mod.rs")),
        ["harness", "plot"]
    );
}
