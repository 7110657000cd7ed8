//! The `lse-deform` tool's commands, one module each, and what they share:
//! the method options parsed into the library's types ([`MethodArgs`]),
//! progress spinners, reading inputs and checking outputs. No numerics: the
//! commands call the library and print what it returns.

use std::path::{Path, PathBuf};
use std::time::Duration;

use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use lse_deform::backend::FactorStorage;
use lse_deform::constraints::{ConstraintSet, read_constraints_file};
use lse_deform::error::{ProblemError, SolveOption};
use lse_deform::formulation::Refine;
use lse_deform::limits::{MemoryBudget, parse_bytes};
use lse_deform::mesh;
use lse_deform::options::DeformOptions;
use lse_deform::request::{Given, Inapplicable, Request, RequestOption};
use lse_deform::resources::{FillOrdering, OrderingWord, Resources, Threads};
use lse_deform::{Error, Method, QrKind, SpdKind};

/// `println!` that treats a closed pipe (`lse-deform info m.obj | head`) as
/// the end of the output rather than a panic.
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::cli::emit(format!($($arg)*))
    };
}

pub mod compare;
pub mod deform;
#[cfg(feature = "editor")]
pub mod edit;
pub mod export;
pub mod files;
pub mod generate;
pub mod info;
pub mod panics;
pub mod render;
pub mod scene;
pub mod signals;
pub mod solve;
pub mod summary;

/// How to solve: the formulation and its back ends, the refinement and the
/// memory budget, parsed into [`DeformOptions::solve`]; an option not given
/// keeps [`DeformOptions::default`]'s value (the defaults the help shows
/// are read from there too).
#[derive(Args, Clone, Debug, PartialEq)]
pub struct MethodArgs {
    /// nullspace-qr (the paper), penalty, kkt or eliminate.
    #[arg(long, default_value_t = DeformOptions::default().solve.formulation.method)]
    pub method: Method,
    #[arg(long, help = with_default("QR back end of nullspace-qr: dense-householder, sparse-givens or spqr", lse_deform::formulation::DEFAULT_QR))]
    pub qr: Option<QrKind>,
    #[arg(long, help = factor_help(), default_value_t = lse_deform::formulation::DEFAULT_SPD)]
    pub factor: SpdKind,
    /// The old name of --factor, still accepted (not with --factor).
    #[arg(long, conflicts_with = "factor")]
    pub spd: Option<SpdKind>,
    /// Relative penalty weight of the hard rows (--method penalty only;
    /// required there).
    #[arg(long)]
    pub weight: Option<f64>,
    /// Iterative refinement with the same factor: off, auto or a number of
    /// steps (0 applies none, as off). Default: auto for the exact methods, off for penalty (where
    /// refinement is the method of multipliers and makes it exact).
    #[arg(long)]
    pub refine: Option<Refine>,
    /// Memory budget of the run (bytes, or with one unit: B, K or KiB, M or
    /// MiB, G or GiB, T or TiB, powers of 1024): reading the inputs (decompressed and assembled)
    /// and the precompute; what is estimated beyond it is refused before
    /// it is allocated. Default: LSE_MEMORY_LIMIT when set, else the
    /// smallest of the available memory, the address-space limit and the
    /// cgroup's memory limit.
    #[arg(long, value_parser = memory_budget)]
    pub memory_limit: Option<MemoryBudget>,
    #[command(flatten)]
    pub held: HeldArgs,
    /// Keep the factor in files under this directory (it must exist; each
    /// MPI rank makes its own subdirectory there and removes it, also on
    /// error): --factor mumps only. The memory budget then counts what
    /// stays in memory.
    #[arg(long, value_name = "DIR")]
    pub out_of_core: Option<std::path::PathBuf>,
}

/// The threads and the fill-reducing ordering of the factorisation, held
/// equal across back ends when given (docs/equal-terms.md).
#[derive(Args, Clone, Debug, PartialEq, Default)]
pub struct HeldArgs {
    /// Threads of the factorisation: a count for every back end (faer's
    /// parallelism, OpenBLAS's threads for cholmod and mumps; nalgebra is
    /// sequential), or own: each back end's own choice. The report's
    /// "threads" says what was used. [default: own]
    #[arg(long)]
    pub threads: Option<Threads>,
    /// Fill-reducing ordering: own (each back end's), amd or natural, or
    /// metis (builds with SuiteSparse); amd and metis are computed once on
    /// the matrix factored and given to the back end. The report's
    /// "ordering" says what was used. [default: own]
    #[arg(long)]
    pub ordering: Option<OrderingWord>,
    /// A fill-reducing ordering made elsewhere, given to every back end:
    /// a file of the problem's unknowns (the mesh's vertices; solve: the
    /// columns of A) in elimination order, 0-based, separated by
    /// whitespace or commas, '#' comments, or one JSON array
    /// (docs/equal-terms.md §2). The report's "ordering" is "given".
    #[arg(long, value_name = "FILE", conflicts_with = "ordering")]
    pub ordering_file: Option<PathBuf>,
}

impl HeldArgs {
    /// `budget` with these threads and ordering (the ordering file read
    /// within `budget`).
    pub(crate) fn resources(&self, budget: MemoryBudget) -> Result<Resources, Error> {
        let ordering = match &self.ordering_file {
            Some(path) => lse_deform::resources::read_ordering_file(path, budget)?,
            None => self.ordering.map(FillOrdering::from).unwrap_or_default(),
        };
        Ok(Resources {
            budget,
            threads: self.threads.unwrap_or_default(),
            ordering,
        })
    }

    /// The ordering file as an input of the command (outputs never
    /// replace it).
    pub(crate) fn inputs(&self) -> Vec<files::Role<'_>> {
        self.ordering_file
            .iter()
            .map(|p| ("the ordering file given with --ordering-file", p.as_path()))
            .collect()
    }
}

/// The help of `--factor`: the back ends of this build (and those it
/// lacks), for the Cholesky methods and for kkt.
fn factor_help() -> String {
    let names = |kinds: Vec<SpdKind>| {
        kinds
            .into_iter()
            .map(SpdKind::name)
            .collect::<Vec<_>>()
            .join(", ")
    };
    let here = SpdKind::available();
    let ldlt = here
        .iter()
        .copied()
        .filter(|&k| lse_deform::backend::ldlt::LdltKind::for_spd(k).is_some())
        .collect();
    let missing: Vec<_> = SpdKind::ALL
        .into_iter()
        .filter(|k| !k.in_this_build())
        .collect();
    let mut help = format!(
        "The matrix factorisation: the Cholesky back end of nullspace-qr, penalty and eliminate ({}), and the LDLT back end of kkt ({}).",
        names(here),
        names(ldlt)
    );
    if !missing.is_empty() {
        help += &format!(" Not in this build: {}.", names(missing));
    }
    help + " --spd is its old name, still accepted"
}

/// A help line naming the default, for an option left `None` when not
/// given (so that the command can tell whether it was).
pub(crate) fn with_default(help: &str, default: impl std::fmt::Display) -> String {
    format!("{help} [default: {default}]")
}

/// `--memory-limit`'s value: bytes as [`parse_bytes`] reads them.
pub(crate) fn memory_budget(word: &str) -> Result<MemoryBudget, String> {
    parse_bytes(word).map(MemoryBudget::bytes).ok_or_else(|| {
        format!(
            "'{word}' is not a size (a positive number of bytes, optionally followed by one unit: {})",
            lse_deform::limits::SIZE_UNITS
        )
    })
}

impl MethodArgs {
    /// The options these flags name over [`DeformOptions::default`], the
    /// formulation checked (a penalty without weight, a back end missing
    /// from this build) before anything is read.
    pub(crate) fn options(&self) -> Result<DeformOptions, Error> {
        let options = self.parse_checked()?;
        let request = Request {
            options: options.clone(),
            given: Given {
                qr: self.qr.is_some(),
                ..Given::default()
            },
            ..Request::default()
        };
        for i in request.inapplicable() {
            eprintln!("warning: {}", inapplicable_words(&i));
        }
        Ok(options)
    }

    /// [`MethodArgs::options`] without the warnings (the caller words the
    /// request's own list).
    pub(crate) fn parse_checked(&self) -> Result<DeformOptions, Error> {
        let options = self.parse()?;
        options
            .solve
            .formulation
            .validate(&options.solve.factor_storage)
            .map_err(with_flag)?;
        Ok(options)
    }

    /// [`MethodArgs::options`] unchecked and without the warnings (the
    /// ordering file read).
    fn parse(&self) -> Result<DeformOptions, Error> {
        let mut options = DeformOptions::default();
        let solve = &mut options.solve;
        solve.formulation.method = self.method;
        if let Some(qr) = self.qr {
            solve.formulation.qr = qr.into();
        }
        solve.formulation.spd = self.spd.unwrap_or(self.factor).into();
        solve.formulation.weight = self.weight;
        solve.refine = self.refine.or(solve.refine);
        solve.resources = self
            .held
            .resources(self.memory_limit.unwrap_or(solve.resources.budget))?;
        if let Some(dir) = &self.out_of_core {
            solve.factor_storage = FactorStorage::OutOfCore(dir.clone());
        }
        Ok(options)
    }

    /// The run's memory budget: `--memory-limit`, else the default.
    pub(crate) fn budget(&self) -> MemoryBudget {
        self.memory_limit.unwrap_or_default()
    }
}

/// A request's option that does not apply, in the command line's words:
/// `--weight applies to --method penalty only; ignored with --method kkt`.
pub(crate) fn inapplicable_words(i: &Inapplicable) -> String {
    let flag = match i.option {
        RequestOption::Laplacian => "--laplacian",
        RequestOption::ArapEnergy => "--arap-energy",
        RequestOption::Iterations => "--iterations",
        RequestOption::Tolerance => "--tolerance",
        RequestOption::ArapInit => "--arap-init",
        RequestOption::Weight => "--weight",
        RequestOption::Qr => "--qr",
        RequestOption::Condition => "--condition",
    };
    let note = i.note.map(|n| format!(" ({n})")).unwrap_or_default();
    format!(
        "{flag} applies to --{} {} only; ignored with --{} {}{note}",
        i.applies_to.0, i.applies_to.1, i.chosen.0, i.chosen.1
    )
}

/// A library error about an option, with the option's flag in front.
fn with_flag(e: ProblemError) -> Error {
    match e {
        ProblemError::InvalidOption { option, message } => {
            let flag = match option {
                SolveOption::Method => "--method",
                SolveOption::Qr => "--qr",
                SolveOption::Spd => "--factor",
                SolveOption::Weight => "--weight",
                SolveOption::Refine => "--refine",
            };
            ProblemError::InvalidArgument {
                message: format!("{flag}: {message}"),
            }
            .into()
        }
        other => other.into(),
    }
}

/// Writes one line to stdout; a closed pipe ends the process quietly.
pub(crate) fn emit(line: String) {
    use std::io::Write;
    let mut stdout = std::io::stdout().lock();
    if let Err(e) = writeln!(stdout, "{line}") {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("error: writing to standard output failed: {e}");
        std::process::exit(2);
    }
}

/// A spinner on stderr for one phase. It is drawn only on a terminal
/// (indicatif's stderr target hides itself otherwise) and only once the
/// phase has lasted a second, so quick runs and pipes print nothing extra.
/// Several phases can share it through `set_message`.
pub(crate) fn phase(message: &str) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} ({elapsed})") {
        bar.set_style(style);
    }
    bar.set_message(message.to_string());
    show_after_a_second(&bar);
    bar
}

/// Points `bar` at stderr one second from now unless it has finished.
/// The spinner is a convenience: when its thread cannot start (its stack
/// is mapped, and under a tight address-space limit the spawn fails), the
/// phase runs without it.
pub(crate) fn show_after_a_second(bar: &ProgressBar) {
    let weak = bar.downgrade();
    let _ = std::thread::Builder::new().spawn(move || {
        std::thread::sleep(Duration::from_secs(1));
        if let Some(bar) = weak.upgrade()
            && !bar.is_finished()
        {
            bar.set_draw_target(ProgressDrawTarget::stderr());
            bar.enable_steady_tick(Duration::from_millis(100));
        }
    });
}

/// Reads a mesh within the run's memory budget with a spinner, printing
/// its notes and warnings.
pub(crate) fn load(path: &Path, budget: MemoryBudget) -> Result<mesh::Mesh, Error> {
    let bar = phase(&format!("reading {}", path.display()));
    let loaded = mesh::read_mesh(path, budget)?;
    bar.finish_and_clear();
    for note in &loaded.notes {
        eprintln!("note: {note}");
    }
    for w in loaded.mesh.warnings() {
        eprintln!("warning: {w}");
    }
    Ok(loaded.mesh)
}

/// Writes `text` and a newline to `path` atomically: a failed write (a
/// full disk) leaves a previous file as it was.
pub(crate) fn write_text(path: &Path, text: String) -> Result<(), Error> {
    lse_deform::atomic::write_bytes(path, (text + "\n").as_bytes()).map_err(|e| Error::io(path, e))
}

/// Runs `write` with its outputs staged ([`lse_deform::atomic::staged`]):
/// they replace their files together when it succeeds, and none does when
/// it fails.
pub(crate) fn staged<T>(write: impl FnOnce() -> Result<T, Error>) -> Result<T, Error> {
    lse_deform::atomic::staged(write, |path, e| Error::io(path, e))
}

/// Fail fast: the output mesh (its format and its directory) and any other
/// output file are checked before the input is read or anything is solved.
pub(crate) fn check_outputs(mesh_out: Option<&Path>, file_out: Option<&Path>) -> Result<(), Error> {
    if let Some(path) = mesh_out {
        notes(mesh::check_mesh_output(path)?);
    }
    if let Some(path) = file_out {
        notes(mesh::check_writable(path)?);
    }
    Ok(())
}

/// Prints the notes of an output check ([`mesh::check_writable`]: an
/// interrupted earlier run's outputs put in order).
pub(crate) fn notes(notes: Vec<String>) {
    for note in notes {
        eprintln!("note: {note}");
    }
}

/// Reads a constraints file for `mesh` within the run's memory budget: a
/// `"mesh"` object in it that names another mesh is a warning, or with
/// `strict` an error (exit code 2); then the vertex ranges are checked.
pub(crate) fn constraints_for(
    path: &Path,
    mesh: &mesh::Mesh,
    strict: bool,
    budget: MemoryBudget,
) -> Result<ConstraintSet, Error> {
    constraints_with_warnings(path, mesh, strict, budget).map(|(set, _)| set)
}

/// [`constraints_for`], also returning the warning it printed (a file made
/// for another mesh), for the command's report.
pub(crate) fn constraints_with_warnings(
    path: &Path,
    mesh: &mesh::Mesh,
    strict: bool,
    budget: MemoryBudget,
) -> Result<(ConstraintSet, Vec<String>), Error> {
    let bar = phase(&format!("reading {}", path.display()));
    let set = read_constraints_file(path, budget)?;
    bar.finish_and_clear();
    let mut warnings = Vec::new();
    if let Some(detail) = set.mesh_mismatch(mesh) {
        if strict {
            return Err(lse_deform::error::ConstraintError::MeshMismatch { detail }.into());
        }
        let warning = format!(
            "{} was {detail} (--strict makes this an error)",
            path.display()
        );
        eprintln!("warning: {warning}");
        warnings.push(warning);
    }
    set.check_vertices(mesh.n_vertices())?;
    Ok((set, warnings))
}

#[cfg(test)]
mod tests {
    use clap::Parser;
    use lse_deform::options::DeformOptions;
    use lse_deform::{Method, SpdKind};

    use super::MethodArgs;

    #[derive(Parser)]
    struct Flags {
        #[command(flatten)]
        method: MethodArgs,
    }

    fn parse(args: &[&str]) -> MethodArgs {
        let argv = std::iter::once("test").chain(args.iter().copied());
        Flags::try_parse_from(argv).unwrap().method
    }

    #[test]
    fn no_flags_are_the_library_defaults() {
        assert_eq!(parse(&[]).options().unwrap(), DeformOptions::default());
    }

    #[test]
    fn spd_is_an_alias_of_factor() {
        let old = parse(&["--method", "kkt", "--spd", "faer-simplicial"]);
        let new = parse(&["--method", "kkt", "--factor", "faer-simplicial"]);
        assert_eq!(old.options().unwrap(), new.options().unwrap());
        let options = new.options().unwrap();
        assert_eq!(options.solve.formulation.spd, SpdKind::FaerSimplicial);
        assert_eq!(options.solve.formulation.method, Method::Kkt);
        assert_ne!(
            DeformOptions::default().solve.formulation.spd,
            SpdKind::FaerSimplicial
        );
    }

    /// `--spd a --factor b` is refused naming both flags. (Before: `--spd`
    /// was an alias, and the message named `--factor` twice.)
    #[test]
    fn spd_and_factor_together_are_refused_naming_both() {
        let argv = ["test", "--spd", "faer-simplicial", "--factor", "nalgebra"];
        let e = Flags::try_parse_from(argv).err().unwrap().to_string();
        assert!(e.contains("--spd") && e.contains("--factor"), "{e}");
    }

    /// The help of `--factor` lists every back end of this build (`mumps`
    /// in a build with it) and says which are missing. (Before: a fixed
    /// list, without `mumps`.)
    #[test]
    fn the_factor_help_lists_this_builds_back_ends() {
        use clap::CommandFactory;
        let help = Flags::command().render_long_help().to_string();
        for kind in SpdKind::ALL {
            assert!(help.contains(kind.name()), "{kind}: {help}");
        }
        let missing = help.contains("Not in this build");
        assert_eq!(
            missing,
            SpdKind::available().len() < SpdKind::ALL.len(),
            "{help}"
        );
        if cfg!(feature = "mumps") {
            let list = help.split("Not in this build").next().unwrap();
            assert!(list.contains("mumps"), "{help}");
        }
    }
}
