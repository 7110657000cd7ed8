//! The import graphs of the library (`src/`) and of the experiments
//! program (`experiments/`), read from the sources: every `crate::…`,
//! `super::…` and `self::…` path (in `use` trees, braces included, and
//! inline) outside comments and string literals is an edge from the module
//! of its file to the module it names.
//!
//! - `src/`: the nodes are the library's files (`src/backend/spd/mod.rs` is
//!   `backend::spd`, `src/backend/spd/cholmod.rs` is
//!   `backend::spd::cholmod`; an inline `mod x { … }` belongs to its file).
//!   A path goes to the deepest of its prefixes that is a module; a name a
//!   module only imports or re-exports (`crate::Mesh` through `lib.rs`,
//!   `super::SpdKind` through `spd/mod.rs`) goes on to the module that
//!   defines it, and a name the module defines (or one it cannot see
//!   through, a glob) stops there. Relative paths count too: `pub use
//!   child::X` and `child::f()` in a parent are edges to the child, but the
//!   declaration `mod child;` is not, nor a visibility `pub(in a::b)`, nor
//!   a method call (it names no path). A file's inline
//!   `#[cfg(test)] mod tests` is the file; tests in a file of their own
//!   (`a/tests.rs`) are a node of their own, above `a`, and may import
//!   what imports `a`. `#[cfg]`-gated imports all count:
//!   the graph is the union of every feature combination, so a graph
//!   without a circle holds for each build. The binary's files (`main.rs`,
//!   `cli/`) are another crate and left out, and so is `lib.rs`, the root,
//!   which only declares and re-exports. The layering of the README
//!   (imports point down) needs at least: no circle, the catalogue
//!   of built-in back ends above the seams it names, and the ordering
//!   module calling no back end.
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

/// Whether `c` can be part of an identifier.
fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// `text` without comments (`//`, `/* … */`; doc links name modules
/// without importing them), without the contents of string literals
/// (plain, byte and raw, over several lines too: `""` stays) and with
/// every character literal as `' '` (so that `'{'` and `'"'` unbalance
/// nothing). Lifetimes stay.
fn code_only(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < c.len() {
        let ch = c[i];
        let next = c.get(i + 1).copied();
        let after_ident = i > 0 && is_ident(c[i - 1]);
        if ch == '/' && next == Some('/') {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
            continue;
        }
        if ch == '/' && next == Some('*') {
            let mut depth = 0usize;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    if c[i] == '\n' {
                        out.push('\n');
                    }
                    i += 1;
                }
            }
            out.push(' ');
            continue;
        }
        // Raw strings: `r"…"`, `r#"…"#`, `br"…"` (`r#name` is an identifier).
        if !after_ident && (ch == 'r' || (ch == 'b' && next == Some('r'))) {
            let mut j = i + if ch == 'b' { 2 } else { 1 };
            let mut hashes = 0;
            while c.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if c.get(j) == Some(&'"') {
                let mut k = j + 1;
                while k < c.len() {
                    if c[k] == '"' && (0..hashes).all(|h| c.get(k + 1 + h) == Some(&'#')) {
                        k += 1 + hashes;
                        break;
                    }
                    k += 1;
                }
                out.push_str("\"\"");
                i = k;
                continue;
            }
        }
        if ch == '"' {
            let mut k = i + 1;
            while k < c.len() && c[k] != '"' {
                k += if c[k] == '\\' { 2 } else { 1 };
            }
            out.push_str("\"\"");
            i = k + 1;
            continue;
        }
        if ch == '\'' {
            if next == Some('\\') {
                // An escaped character literal: '\n', '\'', '\u{7f}'.
                let mut k = i + 3;
                while k < c.len() && c[k] != '\'' {
                    k += 1;
                }
                out.push_str("' '");
                i = k + 1;
                continue;
            }
            if c.get(i + 2) == Some(&'\'') {
                out.push_str("' '");
                i += 3;
                continue;
            }
        }
        out.push(ch);
        i += 1;
    }
    out
}

/// Skips whitespace at `pos`.
fn skip_ws(s: &[char], pos: &mut usize) {
    while *pos < s.len() && s[*pos].is_whitespace() {
        *pos += 1;
    }
}

/// The identifier at `pos` (possibly empty), moving past it.
fn identifier(s: &[char], pos: &mut usize) -> String {
    let start = *pos;
    while *pos < s.len() && is_ident(s[*pos]) {
        *pos += 1;
    }
    s[start..*pos].iter().collect()
}

/// One leaf of a use tree: its path (segments) and the name it binds
/// (`None` for a glob, whose path is the module globbed).
type Leaf = (Vec<String>, Option<String>);

/// The leaves of a use tree starting at `s[*pos]` (after a `crate::` or
/// `super::`, or a whole tree after `use`): `a::b`, `a::b as c`,
/// `a::{b, c::d}`, `{a, b}`, `a::{self}` (the path `a`, binding `a`),
/// `a::*`. Inline, a path such as `a::f::<T>()` gives `a::f`.
fn use_tree(s: &[char], pos: &mut usize) -> Vec<Leaf> {
    skip_ws(s, pos);
    match s.get(*pos) {
        Some('{') => {
            *pos += 1;
            let mut leaves = Vec::new();
            loop {
                skip_ws(s, pos);
                match s.get(*pos) {
                    None => return leaves,
                    Some('}') => {
                        *pos += 1;
                        return leaves;
                    }
                    Some(',') => *pos += 1,
                    Some(_) => {
                        let before = *pos;
                        leaves.extend(use_tree(s, pos));
                        if *pos == before {
                            *pos += 1;
                        }
                    }
                }
            }
        }
        Some('*') => {
            *pos += 1;
            return vec![(Vec::new(), None)];
        }
        _ => {}
    }
    let ident = identifier(s, pos);
    if ident.is_empty() {
        return Vec::new();
    }
    if s.get(*pos) == Some(&':') && s.get(*pos + 1) == Some(&':') {
        *pos += 2;
        let rest = use_tree(s, pos);
        if rest.is_empty() {
            return vec![(vec![ident.clone()], Some(ident))];
        }
        return rest
            .into_iter()
            .map(|(mut path, binding)| {
                let binding = match binding {
                    Some(name) if name == "self" && path.is_empty() => Some(ident.clone()),
                    other => other,
                };
                path.insert(0, ident.clone());
                (path, binding)
            })
            .collect();
    }
    let mut binding = ident.clone();
    let mut ahead = *pos;
    skip_ws(s, &mut ahead);
    if s.get(ahead..ahead + 2) == Some(&['a', 's'][..])
        && s.get(ahead + 2).is_some_and(|c| c.is_whitespace())
    {
        ahead += 2;
        skip_ws(s, &mut ahead);
        let alias = identifier(s, &mut ahead);
        if !alias.is_empty() {
            binding = alias;
            *pos = ahead;
        }
    }
    if ident == "self" {
        vec![(Vec::new(), Some(binding))]
    } else {
        vec![(vec![ident], Some(binding))]
    }
}

/// The brace blocks of `code`: the byte offsets of each `{` and its `}`,
/// and the module's name for a `mod NAME {`; outer blocks before the
/// blocks inside them.
fn braces(code: &str) -> Vec<(usize, usize, Option<String>)> {
    let mut blocks: Vec<(usize, usize, Option<String>)> = Vec::new();
    let mut open: Vec<usize> = Vec::new();
    for (i, c) in code.char_indices() {
        match c {
            '{' => {
                let head = code[..i].trim_end();
                let name: String = head
                    .chars()
                    .rev()
                    .take_while(|c| is_ident(*c))
                    .collect::<Vec<_>>()
                    .into_iter()
                    .rev()
                    .collect();
                let rest = head[..head.len() - name.len()].trim_end();
                let is_mod = !name.is_empty()
                    && rest.ends_with("mod")
                    && !rest[..rest.len() - 3].ends_with(is_ident);
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
    blocks
}

/// The inline modules (`mod NAME { … }`) of `code`: the offsets of their
/// `{` and `}`, and their names, outer ones before the modules inside them.
fn inline_modules(code: &str) -> Vec<(usize, usize, String)> {
    braces(code)
        .into_iter()
        .filter_map(|(a, b, name)| Some((a, b, name?)))
        .collect()
}

/// The innermost block of `blocks` enclosing byte `at` if it is not a
/// module's (a function body, say: what a `use` there binds is seen only
/// inside it), as its span.
fn local_block(blocks: &[(usize, usize, Option<String>)], at: usize) -> Option<(usize, usize)> {
    blocks
        .iter()
        .rev()
        .find(|(a, b, _)| *a < at && at < *b)
        .filter(|(_, _, name)| name.is_none())
        .map(|(a, b, _)| (*a, *b))
}

/// The names of the inline modules of `blocks` enclosing byte `at`,
/// outermost first.
fn enclosing(blocks: &[(usize, usize, String)], at: usize) -> Vec<String> {
    blocks
        .iter()
        .filter(|(a, b, _)| *a < at && at < *b)
        .map(|(_, _, name)| name.clone())
        .collect()
}

/// Every path named after `prefix` (`crate::` or `super::`) in `code`,
/// where the prefix starts a path (not `$crate::` or `a::super::`), with
/// the inline modules it stands in.
fn paths_after(code: &str, prefix: &str) -> Vec<(Vec<String>, Vec<String>)> {
    let chars: Vec<char> = code.chars().collect();
    let blocks = inline_modules(code);
    let mut found = Vec::new();
    let mut from = 0;
    while let Some(at) = code[from..].find(prefix) {
        let at = from + at;
        from = at + prefix.len();
        let before = code[..at].chars().next_back();
        if before.is_some_and(|c| is_ident(c) || c == '$' || c == ':') {
            continue;
        }
        let mut pos = code[..from].chars().count();
        let inside = enclosing(&blocks, at);
        found.extend(
            use_tree(&chars, &mut pos)
                .into_iter()
                .map(|(p, _)| (inside.clone(), p)),
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

/// The graph of the crate in `dir` (by `crate::` and `super::` paths).
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

/// The strongly connected components of `g` with more than one node: the
/// sets of modules that import each other round a circle.
fn tangles(g: &Graph) -> Vec<BTreeSet<String>> {
    // Kosaraju: finishing order on `g`, then components on its reverse.
    fn finish<'a>(
        g: &'a Graph,
        n: &'a str,
        seen: &mut BTreeSet<&'a str>,
        order: &mut Vec<&'a str>,
    ) {
        if !seen.insert(n) {
            return;
        }
        for m in g.get(n).into_iter().flatten() {
            finish(g, m, seen, order);
        }
        order.push(n);
    }
    let mut reverse = Graph::new();
    for (from, targets) in g {
        reverse.entry(from.clone()).or_default();
        for to in targets {
            reverse.entry(to.clone()).or_default().insert(from.clone());
        }
    }
    let (mut seen, mut order) = (BTreeSet::new(), Vec::new());
    for n in reverse.keys() {
        finish(g, n, &mut seen, &mut order);
    }
    let mut assigned = BTreeSet::new();
    let mut out = Vec::new();
    for n in order.into_iter().rev() {
        if assigned.contains(n) {
            continue;
        }
        let mut component = BTreeSet::new();
        let mut todo = vec![n.to_string()];
        while let Some(m) = todo.pop() {
            if !assigned.insert(m.clone()) {
                continue;
            }
            todo.extend(reverse[&m].iter().cloned());
            component.insert(m);
        }
        if component.len() > 1 {
            out.push(component);
        }
    }
    out.sort();
    out
}

/// The circles of `g`: for every edge that lies on one, the shortest
/// circle through it (each circle once, starting at its least node, first
/// repeated last), shortest first. Every edge that closes a circle is in
/// one of them, so breaking them all breaks every circle.
fn circles(g: &Graph) -> Vec<Vec<String>> {
    /// The shortest path from `from` to `to` in `g` (breadth first), both
    /// ends included.
    fn shortest(g: &Graph, from: &str, to: &str) -> Option<Vec<String>> {
        let mut previous: BTreeMap<&str, &str> = BTreeMap::new();
        let mut queue = std::collections::VecDeque::from([from]);
        let mut seen = BTreeSet::from([from]);
        while let Some(n) = queue.pop_front() {
            if n == to {
                let mut path = vec![to.to_string()];
                let mut at = to;
                while at != from {
                    at = previous[at];
                    path.push(at.to_string());
                }
                path.reverse();
                return Some(path);
            }
            for m in g.get(n).into_iter().flatten() {
                if seen.insert(m) {
                    previous.insert(m, n);
                    queue.push_back(m);
                }
            }
        }
        None
    }
    let mut found = BTreeSet::new();
    for component in tangles(g) {
        for from in &component {
            for to in g[from].iter().filter(|t| component.contains(*t)) {
                // The edge `from → to`, then back from `to` to `from`.
                let Some(back) = shortest(g, to, from) else {
                    continue;
                };
                let mut c = vec![from.clone()];
                c.extend(back);
                c.pop();
                let least = (0..c.len()).min_by_key(|&k| &c[k]).unwrap();
                c.rotate_left(least);
                c.push(c[0].clone());
                found.insert((c.len(), c));
            }
        }
    }
    found.into_iter().map(|(_, c)| c).collect()
}

/// What a failed circle check prints: every circle [`circles`] finds, each
/// as its whole path, and the tangles they make up.
fn describe_circles(g: &Graph) -> Option<String> {
    let tangles = tangles(g);
    if tangles.is_empty() {
        return None;
    }
    let found = circles(g);
    let mut text = format!(
        "{} import circle(s) among src/'s files (the shortest through each edge on one):\n",
        found.len()
    );
    for c in &found {
        text += &format!("  {}\n", c.join(" -> "));
    }
    text += "in the tangles (files that import each other round a circle):\n";
    for t in &tangles {
        text += &format!(
            "  {{{}}}\n",
            t.iter().cloned().collect::<Vec<_>>().join(", ")
        );
    }
    Some(text)
}

/// One `use` declaration's leaf: the module it stands in (inline modules
/// included), its path as written and the name it binds (`None`: a glob).
struct Use {
    scope: Vec<String>,
    path: Vec<String>,
    binding: Option<String>,
    /// Where it is (a byte offset in its file's code).
    at: usize,
    /// The block it binds in, if not its module (a function body).
    block: Option<(usize, usize)>,
}

/// The library, file by file: its modules, its `use` declarations and the
/// paths its code names outside them.
struct Library {
    /// The module path of every file (`lib.rs` is the empty path).
    files: BTreeSet<Vec<String>>,
    /// Every module: the files' and the inline ones.
    modules: BTreeSet<Vec<String>>,
    /// Every `use` leaf of every file.
    uses: Vec<Use>,
    /// (module, name) → the `use` leaves binding that name there (more
    /// than one under different `#[cfg]`s).
    bindings: BTreeMap<(Vec<String>, String), Vec<usize>>,
    /// Paths outside `use` declarations: (the module they stand in, the
    /// path as written, from an identifier followed by `::`, where it is).
    inline: Vec<(Vec<String>, Vec<String>, usize)>,
}

/// How deep aliases are followed (a circle of re-exports is an error for
/// rustc; here it only stops).
const ALIAS_DEPTH: usize = 16;

impl Library {
    /// Reads `src/` (without the binary's `main.rs` and `cli/`).
    fn read(src: &Path) -> Library {
        let mut files = Vec::new();
        rust_files(src, Path::new(""), &mut files);
        let sources = files
            .into_iter()
            .filter(|f| f != Path::new("main.rs") && !f.starts_with("cli"))
            .map(|f| {
                let text = std::fs::read_to_string(src.join(&f)).unwrap();
                (module_path(&f), text)
            })
            .collect();
        Library::from_sources(sources)
    }

    /// The library of these files (module path, text).
    fn from_sources(sources: Vec<(Vec<String>, String)>) -> Library {
        let mut lib = Library {
            files: sources.iter().map(|(m, _)| m.clone()).collect(),
            modules: sources.iter().map(|(m, _)| m.clone()).collect(),
            uses: Vec::new(),
            bindings: BTreeMap::new(),
            inline: Vec::new(),
        };
        for (module, text) in sources {
            lib.scan(&module, &code_only(&text));
        }
        for (k, u) in lib.uses.iter().enumerate() {
            if let Some(name) = &u.binding {
                lib.bindings
                    .entry((u.scope.clone(), name.clone()))
                    .or_default()
                    .push(k);
            }
        }
        lib
    }

    /// Reads one file's inline modules, `use` declarations and other
    /// paths.
    fn scan(&mut self, module: &[String], code: &str) {
        let chars: Vec<char> = code.chars().collect();
        // Byte offsets of the characters, for the inline-module blocks.
        let offsets: Vec<usize> = code.char_indices().map(|(b, _)| b).collect();
        let all = braces(code);
        let blocks = inline_modules(code);
        let scope_at = |i: usize| {
            let mut scope = module.to_vec();
            scope.extend(enclosing(&blocks, offsets[i]));
            scope
        };
        for (a, _, name) in &blocks {
            let mut m = module.to_vec();
            m.extend(enclosing(&blocks, *a));
            m.push(name.clone());
            self.modules.insert(m);
        }
        let starts_path = |i: usize| {
            i == 0 || !(is_ident(chars[i - 1]) || chars[i - 1] == '$' || chars[i - 1] == ':')
        };
        let mut i = 0;
        while i < chars.len() {
            if !(is_ident(chars[i]) && starts_path(i)) {
                i += 1;
                continue;
            }
            let mut pos = i;
            let word = identifier(&chars, &mut pos);
            let before: String = chars[i.saturating_sub(8)..i].iter().collect();
            if word == "in" && before.trim_end().ends_with("pub(") {
                // `pub(in crate::a)`: a visibility, not an import.
                use_tree(&chars, &mut pos);
                i = pos;
                continue;
            }
            if word == "use" && chars.get(pos).is_some_and(|c| c.is_whitespace()) {
                let scope = scope_at(i);
                skip_ws(&chars, &mut pos);
                if chars.get(pos) == Some(&':') {
                    // `use ::name`: an outside crate.
                    i = pos + 2;
                    continue;
                }
                for (path, binding) in use_tree(&chars, &mut pos) {
                    self.uses.push(Use {
                        scope: scope.clone(),
                        path,
                        binding,
                        at: offsets[i],
                        block: local_block(&all, offsets[i]),
                    });
                }
                i = pos.max(i + 1);
                continue;
            }
            if chars.get(pos) == Some(&':') && chars.get(pos + 1) == Some(&':') {
                let scope = scope_at(i);
                let mut at = i;
                for (path, _) in use_tree(&chars, &mut at) {
                    self.inline.push((scope.clone(), path, offsets[i]));
                }
                i = at.max(pos);
                continue;
            }
            i = pos;
        }
    }

    /// The file a module belongs to: the deepest of its prefixes that is a
    /// file.
    fn file_of(&self, module: &[String]) -> Vec<String> {
        (0..=module.len())
            .rev()
            .map(|n| module[..n].to_vec())
            .find(|m| self.files.contains(m))
            .unwrap_or_default()
    }

    /// The `use` leaves binding `name` in `scope` that are seen at byte
    /// `at` of its file (`None`: from outside, only the module's own).
    fn bound(&self, scope: &[String], name: &str, at: Option<usize>) -> Vec<&Use> {
        let key = (scope.to_vec(), name.to_string());
        let uses = self.bindings.get(&key).into_iter().flatten();
        let seen = |u: &&Use| match (u.block, at) {
            (None, _) => true,
            (Some((a, b)), Some(x)) => a < x && x < b,
            (Some(_), None) => false,
        };
        let all: Vec<&Use> = uses.map(|&k| &self.uses[k]).filter(seen).collect();
        // A name a block binds hides the module's.
        if all.iter().any(|u| u.block.is_some()) {
            all.into_iter().filter(|u| u.block.is_some()).collect()
        } else {
            all
        }
    }

    /// The full paths (from the crate root) a path written in `scope` at
    /// byte `at` of its file stands for: none for an outside crate's, more
    /// than one for a name bound differently under different `#[cfg]`s.
    fn absolute(
        &self,
        scope: &[String],
        path: &[String],
        at: usize,
        depth: usize,
    ) -> Vec<Vec<String>> {
        let Some((first, rest)) = path.split_first() else {
            return vec![scope.to_vec()];
        };
        if depth > ALIAS_DEPTH {
            return Vec::new();
        }
        let mut base = scope.to_vec();
        let mut rest = rest;
        match first.as_str() {
            "crate" => base.clear(),
            "self" => {}
            "super" => {
                if base.pop().is_none() {
                    return Vec::new();
                }
                while rest.first().is_some_and(|s| s == "super") {
                    if base.pop().is_none() {
                        return Vec::new();
                    }
                    rest = &rest[1..];
                }
            }
            name => {
                let mut child = scope.to_vec();
                child.push(name.to_string());
                if self.modules.contains(&child) {
                    base = child;
                } else {
                    // A name the scope imports (`use a::b; b::c`), or an
                    // outside crate's (`std::`, `faer::`): nothing.
                    let mut out = Vec::new();
                    for u in self.bound(scope, name, Some(at)) {
                        for mut p in self.absolute(&u.scope, &u.path, u.at, depth + 1) {
                            p.extend(rest.iter().cloned());
                            out.push(p);
                        }
                    }
                    return out;
                }
            }
        }
        base.extend(rest.iter().cloned());
        vec![base]
    }

    /// The modules defining what the full path `path` names: the deepest
    /// module among its prefixes, or, where the next segment is a name that
    /// module imports, where that import leads.
    fn targets(&self, path: &[String], depth: usize) -> Vec<Vec<String>> {
        let mut module = Vec::new();
        for (k, segment) in path.iter().enumerate() {
            let mut child = module.clone();
            child.push(segment.clone());
            if self.modules.contains(&child) {
                module = child;
                continue;
            }
            let uses = self.bound(&module, segment, None);
            if uses.is_empty() {
                break;
            }
            if depth > ALIAS_DEPTH {
                return Vec::new();
            }
            let mut out = Vec::new();
            for u in uses {
                for mut p in self.absolute(&u.scope, &u.path, u.at, depth + 1) {
                    p.extend(path[k + 1..].iter().cloned());
                    out.extend(self.targets(&p, depth + 1));
                }
            }
            // An outside crate's name, re-exported: no edge.
            return out;
        }
        vec![module]
    }

    /// Every path written in the library: (the module it stands in, the
    /// path, where it is).
    fn written(&self) -> impl Iterator<Item = (&Vec<String>, &Vec<String>, usize)> {
        let uses = self.uses.iter().map(|u| (&u.scope, &u.path, u.at));
        uses.chain(self.inline.iter().map(|(s, p, at)| (s, p, *at)))
    }

    /// The files a path written in `scope` at `at` imports from.
    fn imported(&self, scope: &[String], path: &[String], at: usize) -> BTreeSet<Vec<String>> {
        let mut out = BTreeSet::new();
        for full in self.absolute(scope, path, at, 0) {
            for target in self.targets(&full, 0) {
                out.insert(self.file_of(&target));
            }
        }
        out
    }

    /// The graph of the files: each file (module path as `a::b`) → the
    /// files it imports; the root (`lib.rs`) left out.
    fn graph(&self) -> Graph {
        let mut g = Graph::new();
        for file in &self.files {
            if !file.is_empty() {
                g.entry(file.join("::")).or_default();
            }
        }
        for (scope, path, at) in self.written() {
            let from = self.file_of(scope);
            if from.is_empty() {
                continue;
            }
            for to in self.imported(scope, path, at) {
                if !to.is_empty() && to != from {
                    g.get_mut(&from.join("::")).unwrap().insert(to.join("::"));
                }
            }
        }
        g
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

/// The graph of `src/` (the library), file by file.
fn library_graph() -> Graph {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    Library::read(&src).graph()
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
fn library_files_form_no_import_circle() {
    let g = library_graph();
    assert!(
        [
            "mesh",
            "laplacian",
            "solver",
            "backend::spd",
            "backend::spd::cholmod",
            "backend::mumps::session",
        ]
        .iter()
        .all(|m| g.contains_key(*m)),
        "the library's files were not found: {:?}",
        g.keys()
    );
    if let Some(text) = describe_circles(&g) {
        panic!("{text}");
    }
}

#[test]
fn the_catalogue_sits_above_the_seams() {
    let seams = [
        "backend::spd",
        "backend::ldlt",
        "backend::qr",
        "backend::mumps",
        "backend::ordering",
    ];
    let under = |m: &str| {
        seams
            .iter()
            .any(|s| m == *s || m.starts_with(&format!("{s}::")))
    };
    let offenders: Vec<String> = library_graph()
        .into_iter()
        .filter(|(from, targets)| under(from) && targets.contains("backend::catalogue"))
        .map(|(from, _)| from)
        .collect();
    assert!(
        offenders.is_empty(),
        "these files under the seams import backend::catalogue: {offenders:?}"
    );
}

#[test]
fn the_ordering_calls_no_back_end() {
    let g = library_graph();
    let back_ends: Vec<&String> = g["backend::ordering"]
        .iter()
        .filter(|t| {
            ["spd", "ldlt", "qr", "mumps", "catalogue"]
                .iter()
                .any(|s| t.starts_with(&format!("backend::{s}")))
        })
        .collect();
    assert!(
        back_ends.is_empty(),
        "backend::ordering imports {back_ends:?}"
    );
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
    assert_eq!(describe_circles(&g), None);
    g.entry("c".into()).or_default().insert("a".into());
    assert_eq!(
        circle(&g),
        Some(["a", "b", "c", "a"].map(String::from).to_vec())
    );
    g.entry("b".into()).or_default().insert("a".into());
    let found: Vec<String> = circles(&g).iter().map(|c| c.join(" ")).collect();
    assert_eq!(found, ["a b a", "a b c a"]);
}

#[test]
fn the_scanner_skips_comments_and_every_kind_of_literal() {
    let code = code_only(
        "let a = r#\"{\"crate::x\": 1}\"#; /* use crate::y; /* nested */ */\n\
         let b = \"two\n lines { crate::z\"; let c = '{'; let d = '\"'; let e = '\\'';\n\
         fn f<'a>(x: &'a str) {} let g = br\"}\"; use crate::w;",
    );
    for gone in ["crate::x", "crate::y", "crate::z", "nested"] {
        assert!(!code.contains(gone), "{gone} left in {code:?}");
    }
    assert!(code.contains("fn f<'a>(x: &'a str) {}"), "{code:?}");
    assert_eq!(code.matches('{').count(), code.matches('}').count());
    let paths = paths_after(&code, "crate::");
    assert_eq!(paths, [(vec![], vec!["w".to_string()])]);
}

#[test]
fn use_trees_give_paths_and_the_names_they_bind() {
    let shown = |text: &str| -> Vec<String> {
        let chars: Vec<char> = text.chars().collect();
        use_tree(&chars, &mut 0)
            .iter()
            .map(|(p, b)| format!("{}={}", p.join("::"), b.as_deref().unwrap_or("*")))
            .collect()
    };
    assert_eq!(
        shown("a::{b as c, d::{self, e}, f::*, self as g}"),
        ["a::b=c", "a::d=d", "a::d::e=e", "a::f=*", "a=g"]
    );
    assert_eq!(shown("g::h::<T>()"), ["g::h=h"]);
}

#[test]
fn files_are_nodes_and_names_resolve_to_their_definitions() {
    let file = |m: &str, text: &str| {
        let path = m.split("::").filter(|s| !s.is_empty()).map(String::from);
        (path.collect(), text.to_string())
    };
    let lib = Library::from_sources(vec![
        file("", "pub mod a; pub mod x; pub mod y; pub use a::b::Thing;"),
        // The parent re-exports its child's type and defines `Z`.
        file(
            "a",
            "mod b; mod c; pub use b::Thing; use crate::y::Private; pub struct Z;",
        ),
        // Child → parent for what the parent defines: an edge.
        file("a::b", "use super::Z; pub struct Thing;"),
        // Through the parent's re-export and import: to their definitions.
        file(
            "a::c",
            "use super::{Thing, Private};\nfn f() { super::b::g(); }",
        ),
        // Through lib.rs's re-export, and an inline module's paths.
        file(
            "x",
            "use crate::Thing;\nmod tests { use super::*; use crate::y; fn t() { y::q(); } }",
        ),
        file(
            "y",
            "pub struct Private; pub fn q() {}\npub(in crate::a) fn r() {}",
        ),
    ]);
    let g = lib.graph();
    let edges: Vec<String> = g
        .iter()
        .flat_map(|(from, to)| to.iter().map(move |t| format!("{from}>{t}")))
        .collect();
    assert_eq!(
        edges,
        [
            "a>a::b",
            "a>y",
            "a::b>a",
            "a::c>a::b",
            "a::c>y",
            "x>a::b",
            "x>y"
        ]
    );
    assert_eq!(circles(&g), [["a", "a::b", "a"].map(String::from).to_vec()]);
    let text = describe_circles(&g).unwrap();
    assert!(text.contains("a -> a::b -> a"), "{text}");
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
