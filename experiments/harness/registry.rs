//! What an experiment is to the harness: its name (the command-line word
//! and the folder under `--out`), its section title in `results/README.md`,
//! the inputs it needs and its `run` function. Each study exports its
//! [`Experiment`]; the single list of them is `EXPERIMENTS` in `main.rs`,
//! from which the command line takes its choices and `results/README.md`
//! its sections (see [`assemble_readme`]).

use std::fmt::Write as _;
use std::path::Path;

use crate::harness::context::{AnyError, Context, Machine};

/// What an experiment reports for the summary table.
pub struct Summary {
    /// One line: the main finding, or why nothing was measured.
    pub headline: String,
    /// Whether the section measured nothing (an input this build or
    /// machine lacks): its status is then `skipped`, never `ok`.
    pub skipped: bool,
}

impl Summary {
    /// A section that measured: its main finding.
    pub fn measured(headline: String) -> Summary {
        Summary {
            headline,
            skipped: false,
        }
    }

    /// A section that could not run here: `why` says what is missing.
    pub fn skipped(why: String) -> Summary {
        Summary {
            headline: why,
            skipped: true,
        }
    }
}

/// What an experiment reads besides the library.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// Every mesh of the evaluation (`--mesh`, `--mesh-dir`, else generated
    /// stand-ins).
    Meshes,
    /// One mesh: the Bunny of `--mesh-dir` if present, else a generated
    /// bumpy sphere (see [`Context::fallback_mesh`]).
    OneMesh,
    /// Optionally the user's constraint file (`-c`).
    Constraints,
    /// Optionally the SuiteSparse feature (its columns are left out
    /// without it).
    SuiteSparse,
    /// Optionally the MUMPS feature (its columns are left out without it;
    /// `distributed` then says what it could not measure).
    Mumps,
    /// A Python environment with libigl (found or created as the section
    /// says; the comparison is left out without it).
    Python,
    /// Node with playwright-core and Chromium (found or installed as
    /// `.ci/run` does; the section says what was not measured without).
    Browser,
}

impl Input {
    /// A few words for `--help`.
    pub fn describe(self) -> &'static str {
        match self {
            Input::Meshes => "meshes",
            Input::OneMesh => "one mesh",
            Input::Constraints => "optional -c constraints",
            Input::SuiteSparse => "optional suitesparse feature",
            Input::Mumps => "optional mumps feature",
            Input::Python => "optional Python with libigl",
            Input::Browser => "optional Node and Chromium",
        }
    }
}

/// An experiment's entry point: measures, writes its rows, figures and
/// `section.md` under `ctx.out/<name>/`, and returns its headline.
pub type Runner = fn(&Context) -> Result<Summary, AnyError>;

/// One experiment of the list.
pub struct Experiment {
    /// Command-line word and folder name.
    pub name: &'static str,
    /// Section title in `results/README.md`.
    pub title: &'static str,
    /// What it reads.
    pub inputs: &'static [Input],
    /// Runs it.
    pub run: Runner,
}

/// What an experiment could not measure because this build lacks an
/// optional input it names (the SuiteSparse and MUMPS features), as lines
/// for the end of its section.
pub fn missing_build_inputs(e: &Experiment) -> Option<String> {
    let mut notes = Vec::new();
    if e.inputs.contains(&Input::SuiteSparse) && !cfg!(feature = "suitesparse") {
        notes.push(
            "**Not measured:** the CHOLMOD and SPQR back ends (the reference rows and columns above are missing): \
             this build has no `--features suitesparse` (it needs libsuitesparse-dev, libclang-dev and libopenblas0-pthread; see the README).",
        );
    }
    if e.inputs.contains(&Input::Mumps) && !cfg!(feature = "mumps") {
        notes.push(
            "**Not measured:** the MUMPS back end (its rows and columns above are missing; MUMPS is not in this build): \
             this build has no `--features mumps` (it needs libmumps-ptscotch-dev, libmumps-headers-dev, libopenmpi-dev, openmpi-bin and libclang-dev).",
        );
    }
    (!notes.is_empty()).then(|| notes.join("\n\n"))
}

/// The git revision in a section's machine line (`… (git REV, …`), if any.
fn section_revision(section: &str) -> Option<String> {
    let start = section.find("(git ")? + 5;
    let rest = &section[start..];
    let end = rest.find([',', ')'])?;
    Some(rest[..end].to_string())
}

/// The anchor GitHub gives a heading.
fn anchor(title: &str) -> String {
    title
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-')
        .collect::<String>()
        .replace(' ', "-")
}

/// The header line naming the revisions the sections were written at.
fn revisions_line(revisions: &[(String, Vec<&str>)], machine: &Machine) -> String {
    let dirty = if revisions.iter().any(|(rev, _)| rev.ends_with("-dirty")) {
        " A revision marked `-dirty` had uncommitted changes: its sections are not reproducible from it."
    } else {
        ""
    };
    match revisions {
        [(rev, _)] => format!(
            "Every section below was written at git {rev}; this assembly: {}.{dirty}\n",
            machine.one_line()
        ),
        _ => {
            let list: Vec<String> = revisions
                .iter()
                .map(|(rev, names)| format!("git {rev}: {}", names.join(", ")))
                .collect();
            format!(
                "The sections were written at different git revisions ({}); this assembly: {}.{dirty}\n",
                list.join("; "),
                machine.one_line()
            )
        }
    }
}

/// Joins the sections present under `out` into `out/README.md`, in the
/// order of `experiments`.
pub fn assemble_readme(
    out: &Path,
    machine: &Machine,
    experiments: &[Experiment],
) -> Result<(), AnyError> {
    let mut s = String::from("# Results\n\n");
    let _ = writeln!(
        s,
        "Everything in this directory is written by the `experiments` program; nothing is edited by hand. \
         Regenerate all of it with\n\n```sh\ncargo run --release --features suitesparse,mumps --bin experiments -- all --mesh-dir ../shared/meshes --out results\n```\n\n\
         (without `--mesh-dir` it runs on generated meshes; without `--features suitesparse` the CHOLMOD and SPQR columns are left out, without `--features mumps` the MUMPS columns and the `distributed` section's measurements; \
         without a Python with libigl, Node or Chromium, found or created as docs/development.md §2 says, the sections of `arap`, `python` and `editor` say what was not measured; \
         without `--out results` it writes to a fresh directory under `target/experiments/`). \
         Each section names the command that regenerates it alone. CSV files start with a `#` line describing the machine and build.\n"
    );
    let mut toc = String::new();
    let mut body = String::new();
    // The git revision each section was written at (from its machine
    // line), so that the header states the sections' revisions, not this
    // run's.
    let mut revisions: Vec<(String, Vec<&str>)> = Vec::new();
    for e in experiments {
        let Ok(section) = std::fs::read_to_string(out.join(e.name).join("section.md")) else {
            continue;
        };
        let rev = section_revision(&section).unwrap_or_else(|| "not recorded".into());
        match revisions.iter_mut().find(|(r, _)| *r == rev) {
            Some((_, names)) => names.push(e.name),
            None => revisions.push((rev, vec![e.name])),
        }
        let _ = writeln!(toc, "- [{}](#{})", e.title, anchor(e.title));
        let _ = writeln!(body, "## {}\n\n{}\n", e.title, section.trim_end());
    }
    let _ = writeln!(s, "{}", revisions_line(&revisions, machine));
    s.push_str(&toc);
    s.push('\n');
    s.push_str(&body);
    std::fs::write(out.join("README.md"), s)?;
    Ok(())
}
