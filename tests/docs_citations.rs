//! Every citation of the mathematics in the code names a section that
//! exists: `docs/NAME.md §N` (or `§N–§M`) needs a heading `## N.` in
//! `docs/NAME.md`; no citation of a design document outside the
//! repository, and no reference to a tracker's issue numbers (`issue N`,
//! `#N`). Checked in src/, tests/, benches/, docs/, experiments/ and the
//! README. Every relative Markdown link of `README.md` and `docs/*.md`
//! names a file of the repository, and its `#anchor` a heading of that file
//! (the `§N` of the link's text, if any, the anchor's section). The README
//! is a front page: at most 300 lines, the two commands in its first 80.

use std::path::{Path, PathBuf};

/// The project's Rust, Markdown, Python and JavaScript-module files under
/// `dir`, recursively; installed packages (`node_modules`, a browser
/// test's npm install) and build trees are not the project's.
fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name();
        if path.is_dir() {
            if !matches!(
                name.to_str(),
                Some("node_modules" | "target" | "__pycache__")
            ) {
                files(&path, out);
            }
        } else if matches!(
            path.extension().and_then(|e| e.to_str()),
            Some("rs" | "md" | "py" | "mjs")
        ) {
            out.push(path);
        }
    }
}

/// The section numbers cited right after each `docs/NAME.md` in `text`.
fn citations(text: &str) -> Vec<(String, Vec<u32>)> {
    let mut found = Vec::new();
    let mut rest = text;
    while let Some(at) = rest.find("docs/") {
        rest = &rest[at + 5..];
        let Some(end) = rest.find(".md") else { break };
        let name = &rest[..end];
        if name.is_empty()
            || !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        {
            continue;
        }
        let after = &rest[end + 3..];
        let mut sections = Vec::new();
        let mut tail = after.trim_start_matches([' ', ',']);
        while let Some(s) = tail.strip_prefix('§') {
            let digits: String = s.chars().take_while(char::is_ascii_digit).collect();
            let Ok(n) = digits.parse() else { break };
            sections.push(n);
            tail = s[digits.len()..].trim_start_matches(['–', '-', ',', ' ']);
        }
        found.push((name.to_string(), sections));
    }
    found
}

#[test]
fn every_docs_citation_names_an_existing_section() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut paths = vec![root.join("README.md")];
    for dir in ["src", "tests", "benches", "docs", "experiments"] {
        files(&root.join(dir), &mut paths);
    }
    let mut checked = 0;
    for path in paths.iter().filter(|p| !p.ends_with("docs_citations.rs")) {
        let text = std::fs::read_to_string(path).unwrap();
        let lower = text.to_lowercase();
        assert!(
            !lower
                .match_indices("issue ")
                .any(|(i, m)| lower[i + m.len()..].starts_with(|c: char| c.is_ascii_digit())),
            "{} refers to a tracker issue number",
            path.display()
        );
        assert!(
            !text.match_indices('#').any(|(i, _)| {
                text[..i].ends_with([' ', '(', '\n'])
                    && text[i + 1..].starts_with(|c: char| c.is_ascii_digit())
            }),
            "{} refers to a tracker issue as #N",
            path.display()
        );
        assert!(
            !text.contains("DESIGN §") && !text.contains("DESIGN.md §"),
            "{} cites a design document outside the repository",
            path.display()
        );
        for (name, sections) in citations(&text) {
            let doc = root.join("docs").join(format!("{name}.md"));
            let body = std::fs::read_to_string(&doc).unwrap_or_else(|_| {
                panic!(
                    "{} cites docs/{name}.md, which does not exist",
                    path.display()
                )
            });
            for n in sections {
                assert!(
                    body.contains(&format!("\n## {n}. ")),
                    "{} cites docs/{name}.md §{n}, which has no such section",
                    path.display()
                );
                checked += 1;
            }
        }
    }
    assert!(checked >= 10, "only {checked} section citations found");
}

#[test]
fn the_citation_scanner_reads_ranges_and_lists() {
    assert_eq!(
        citations("see docs/units.md §1–§3 and docs/arap.md §2, §4."),
        vec![
            ("units".to_string(), vec![1, 3]),
            ("arap".to_string(), vec![2, 4])
        ]
    );
    assert_eq!(
        citations("docs/units.md)"),
        vec![("units".to_string(), vec![])]
    );
}

/// A Markdown link: the text between its brackets (the part on the line
/// of `](`) and its target.
#[derive(Debug, PartialEq)]
struct Link {
    text: String,
    target: String,
}

/// The links `[text](target)` and images `![alt](target)` of a Markdown
/// `text`, outside fenced code blocks.
fn links(text: &str) -> Vec<Link> {
    let mut found = Vec::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        let mut from = 0;
        while let Some(at) = line[from..].find("](").map(|i| from + i) {
            let open = line[..at].rfind('[').map_or(0, |i| i + 1);
            let rest = &line[at + 2..];
            let Some(end) = rest.find(')') else { break };
            found.push(Link {
                text: line[open..at].to_string(),
                target: rest[..end].to_string(),
            });
            from = at + 2 + end;
        }
    }
    found
}

/// GitHub's anchor of a heading: lower case, spaces to `-`, every other
/// character that is not alphanumeric, `-` or `_` dropped.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// The anchors of the headings of a Markdown `text` (outside code blocks).
fn anchors(text: &str) -> Vec<String> {
    let mut found = Vec::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        } else if !fenced && line.starts_with('#') {
            found.push(slug(line.trim_start_matches('#')));
        }
    }
    found
}

/// What is wrong with the relative links of the Markdown file `file`
/// (under the repository `root`) whose text is `text`: a target that is
/// not a file or directory of the repository, an anchor that is no
/// heading of its Markdown target, a `§N` in a link's text whose anchor is
/// not section N.
fn broken_links(root: &Path, file: &Path, text: &str) -> Vec<String> {
    let root = root.canonicalize().unwrap();
    let dir = file.parent().unwrap();
    let mut broken = Vec::new();
    for Link {
        text: label,
        target,
    } in links(text)
    {
        if target.contains("://") || target.starts_with("mailto:") {
            continue;
        }
        let (path, anchor) = match target.split_once('#') {
            Some((p, a)) => (p, Some(a)),
            None => (target.as_str(), None),
        };
        let resolved = if path.is_empty() {
            file.to_path_buf()
        } else {
            dir.join(path)
        };
        match resolved.canonicalize() {
            Ok(real) if real.starts_with(&root) => {}
            _ => {
                broken.push(format!("{target}: no such file in the repository"));
                continue;
            }
        }
        let Some(anchor) = anchor else { continue };
        if resolved.extension().and_then(|e| e.to_str()) == Some("md") {
            let body = std::fs::read_to_string(&resolved).unwrap_or_default();
            if !anchors(&body).iter().any(|a| a == anchor) {
                broken.push(format!("{target}: no heading with the anchor #{anchor}"));
            }
        }
        if let Some(s) = label.split('§').nth(1) {
            let n: String = s.chars().take_while(char::is_ascii_digit).collect();
            if !n.is_empty() && !anchor.starts_with(&format!("{n}-")) {
                broken.push(format!(
                    "[{label}]({target}): the anchor is not section {n}"
                ));
            }
        }
    }
    broken
}

#[test]
fn every_relative_link_of_the_readme_and_docs_names_an_existing_file_and_section() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut paths = vec![root.join("README.md")];
    for entry in std::fs::read_dir(root.join("docs")).unwrap().flatten() {
        if entry.path().extension().and_then(|e| e.to_str()) == Some("md") {
            paths.push(entry.path());
        }
    }
    let mut checked = 0;
    for path in &paths {
        let text = std::fs::read_to_string(path).unwrap();
        let broken = broken_links(root, path, &text);
        assert!(broken.is_empty(), "{}: {broken:#?}", path.display());
        checked += links(&text).len();
    }
    assert!(checked >= 50, "only {checked} links found");
}

#[test]
fn the_link_checker_finds_missing_files_anchors_and_sections() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let doc = root.join("docs").join("cli.md");
    let text = "[ok](units.md#7-the-penalty-weight-is-another-quantity), \
        [units.md §7](units.md#7-the-penalty-weight-is-another-quantity), \
        ![a picture](../results/renders/conflicts.png)\n\
        [gone](nowhere.md) [outside](../../etc/passwd) [anchor](units.md#99-none)\n\
        [units.md §3](units.md#7-the-penalty-weight-is-another-quantity)\n\
        ```\n[in code](nowhere.md)\n```\n";
    assert_eq!(
        broken_links(root, &doc, text),
        vec![
            "nowhere.md: no such file in the repository".to_string(),
            "../../etc/passwd: no such file in the repository".to_string(),
            "units.md#99-none: no heading with the anchor #99-none".to_string(),
            "[units.md §3](units.md#7-the-penalty-weight-is-another-quantity): \
             the anchor is not section 3"
                .to_string(),
        ]
    );
    assert_eq!(
        slug("5. `--refine` and the forward-error estimate"),
        "5---refine-and-the-forward-error-estimate"
    );
}

#[test]
fn the_readme_is_a_front_page_with_both_commands_first() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let lines: Vec<&str> = readme.lines().collect();
    assert!(lines.len() <= 300, "README.md has {} lines", lines.len());
    // The main job (every experiment, on generated meshes without
    // --mesh-dir) and the test command that .ci/run runs.
    let ci = std::fs::read_to_string(root.join(".ci/run")).unwrap();
    assert!(ci.lines().any(|l| l.trim() == "cargo test --workspace"));
    for command in [
        "cargo run --release --bin experiments -- all",
        "cargo test --workspace",
    ] {
        assert!(
            lines.iter().take(80).any(|l| l.trim() == command),
            "README.md does not give `{command}` in its first 80 lines"
        );
    }
}
