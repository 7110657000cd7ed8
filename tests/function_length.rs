//! Functions short enough to read at once: no function in `src/` or
//! `experiments/` is longer than [`LIMIT`] lines, counted from the line of
//! its `fn` to the line of its closing brace (doc comments and attributes
//! not counted). `cargo test --test function_length -- --nocapture` prints
//! the five longest of each tree.
//!
//! The count is lexical: braces inside string and character literals and
//! after `//` are skipped; a `fn` with no body (a trait method's
//! declaration) ends at its `;`.

use std::path::{Path, PathBuf};

/// The most lines a function may have.
const LIMIT: usize = 120;

/// The Rust files under `dir`, recursively.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().and_then(|e| e.to_str()) == Some("rs") {
            out.push(path);
        }
    }
}

/// `line` without its `//` comment and with the contents of its string and
/// character literals removed (a literal's braces are not the code's).
fn code_of(line: &str) -> String {
    let mut out = String::new();
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '/' if chars.peek() == Some(&'/') => break,
            '"' => {
                while let Some(d) = chars.next() {
                    match d {
                        '\\' => {
                            chars.next();
                        }
                        '"' => break,
                        _ => {}
                    }
                }
            }
            '\'' => {
                // A character literal ('{', '\n') or a lifetime ('a).
                let rest: String = chars.clone().take(3).collect();
                let mut it = rest.chars();
                match (it.next(), it.next(), it.next()) {
                    (Some('\\'), _, _) => {
                        for d in chars.by_ref() {
                            if d == '\'' {
                                break;
                            }
                        }
                    }
                    (Some(_), Some('\''), _) => {
                        chars.next();
                        chars.next();
                    }
                    _ => {}
                }
            }
            _ => out.push(c),
        }
    }
    out
}

/// The name of the function declared on `line`, if it declares one.
fn declared_fn(line: &str) -> Option<&str> {
    let trimmed = line.trim_start();
    let at = trimmed.find("fn ")?;
    let before = &trimmed[..at];
    let qualifiers = [
        "pub(crate)",
        "pub(super)",
        "pub",
        "const",
        "unsafe",
        "async",
        "extern \"C\"",
    ];
    let mut rest = before.trim();
    while !rest.is_empty() {
        let q = qualifiers.iter().find(|q| rest.starts_with(**q))?;
        rest = rest[q.len()..].trim_start();
    }
    let name = &trimmed[at + 3..];
    let end = name.find(|c: char| !(c.is_alphanumeric() || c == '_'))?;
    (end > 0).then(|| &name[..end])
}

/// `(lines, name, first line)` of every function with a body in `text`.
fn functions(text: &str) -> Vec<(usize, String, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut found = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let Some(name) = declared_fn(&code_of(line)).map(str::to_string) else {
            continue;
        };
        let (mut depth, mut opened) = (0i64, false);
        for (j, l) in lines.iter().enumerate().skip(i) {
            let code = code_of(l);
            for c in code.chars() {
                match c {
                    '{' => {
                        depth += 1;
                        opened = true;
                    }
                    '}' => depth -= 1,
                    _ => {}
                }
            }
            if opened && depth == 0 {
                found.push((j - i + 1, name.clone(), i + 1));
                break;
            }
            if !opened && code.trim_end().ends_with(';') {
                break;
            }
        }
    }
    found
}

/// Every function of the Rust files under `root/dir`, longest first.
fn longest(dir: &str) -> Vec<(usize, String)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut paths = Vec::new();
    rust_files(&root.join(dir), &mut paths);
    let mut all = Vec::new();
    for path in paths {
        let text = std::fs::read_to_string(&path).unwrap();
        let shown = path.strip_prefix(root).unwrap().display().to_string();
        for (n, name, line) in functions(&text) {
            all.push((n, format!("{shown}:{line} {name}")));
        }
    }
    all.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
    all
}

#[test]
fn the_counter_counts_bodies_and_skips_literals_and_comments() {
    let text = "pub(crate) fn a() {\n    let s = \"}}}\";\n    let c = '}';\n    // }\n}\n\
                fn b<'a>(x: &'a str) -> &'a str {\n    x\n}\n\
                trait T {\n    fn c(&self);\n}\n";
    let got = functions(text);
    assert_eq!(
        got,
        vec![(5, "a".to_string(), 1), (3, "b".to_string(), 6)],
        "a spans lines 1–5 despite the braces in its literals and comment; b lines 6–8; c has no body"
    );
}

#[test]
fn no_function_is_longer_than_the_limit() {
    let mut too_long = Vec::new();
    for dir in ["src", "experiments"] {
        let all = longest(dir);
        assert!(
            all.len() > 100,
            "{dir}: too few functions found ({})",
            all.len()
        );
        println!("the five longest functions in {dir}/:");
        for (n, at) in all.iter().take(5) {
            println!("  {n:4} lines  {at}");
        }
        too_long.extend(all.into_iter().filter(|(n, _)| *n > LIMIT));
    }
    assert!(
        too_long.is_empty(),
        "functions longer than {LIMIT} lines: {too_long:?}"
    );
}
