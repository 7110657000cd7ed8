//! Every citation of the mathematics in the code names a section that
//! exists: `docs/NAME.md §N` (or `§N–§M`) needs a heading `## N.` in
//! `docs/NAME.md`; no citation of a design document outside the
//! repository, and no reference to a tracker's issue numbers (`issue N`,
//! `#N`). Checked in src/, tests/, benches/, docs/, experiments/ and the
//! README.

use std::path::{Path, PathBuf};

/// The Rust and Markdown files under `dir`, recursively.
fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            files(&path, out);
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
