//! The programs some experiments run besides this one, found or created
//! the documented way, or the reason why not (for the section, which then
//! says what was not measured):
//!
//! - a Python with numpy, scipy and libigl (`arap`, `python`): `$LSE_PYTHON`
//!   if set, else the virtual environment `target/experiments/venv`,
//!   created if missing as docs/python.md §1 and `.ci/run` do
//!   (`python3 -m venv`, `pip install numpy scipy libigl`); `python` also
//!   installs this checkout's package into it (`pip install .`, built by
//!   maturin), so that it measures this revision;
//! - Node with playwright-core and Chromium (`editor`), as `.ci/run`'s
//!   browser test: `node`, `chromium` (or `$CHROMIUM`), and
//!   `npm ci` in `tests/browser` when its `node_modules` is missing;
//! - the `lse-deform` command-line tool (`editor`, `distributed`): `cargo
//!   build --release --bin lse-deform`, with this build's `suitesparse` and
//!   `mumps` features;
//! - `mpirun` (`distributed`), on `PATH`.
//!
//! Paths in the reasons are relative to the repository, never a machine's.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The repository's top level (the workspace root).
pub fn workspace_root() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest.parent().unwrap_or(manifest).to_path_buf()
}

/// The virtual environment the experiments create, relative to the root.
pub const VENV: &str = "target/experiments/venv";

/// A Python interpreter and where it came from.
#[derive(Debug, Clone)]
pub struct Python {
    /// The interpreter.
    pub exe: PathBuf,
    /// Where it came from, for the sections ("$LSE_PYTHON", the venv).
    pub origin: String,
}

impl Python {
    /// Runs the script `experiments/SCRIPT` with `args`; its standard
    /// output, or `Err` with the last line of its standard error.
    pub fn script(&self, script: &str, args: &[&OsStr]) -> Result<Vec<u8>, String> {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(script);
        let out = child(&self.exe)
            .arg(path)
            .args(args)
            .output()
            .map_err(|e| format!("{script}: {e}"))?;
        if out.status.success() {
            Ok(out.stdout)
        } else {
            Err(format!("{script} failed: {}", last_line(&out.stderr)))
        }
    }
}

/// The prefixes of the variables Open MPI and PMIx put into a process's
/// own environment when it initialises MPI as a singleton (which this
/// program does once a section has used MUMPS in the process): the
/// address of its PMIx server, its job and its rank.
const INHERITED_MPI_PREFIXES: [&str; 5] = ["OMPI_", "PMIX_", "ORTE_", "OPAL_", "PRTE_"];

/// The MPI variables this program was started with (the user's own, such
/// as `OMPI_MCA_btl`), recorded by [`record_startup_environment`] before
/// any MPI initialisation.
static STARTUP_MPI_VARIABLES: std::sync::OnceLock<Vec<std::ffi::OsString>> =
    std::sync::OnceLock::new();

/// Records which MPI variables the environment holds now; call first in
/// `main`, before any section can initialise MPI.
pub fn record_startup_environment() {
    let _ = STARTUP_MPI_VARIABLES.get_or_init(|| {
        std::env::vars_os()
            .map(|(k, _)| k)
            .filter(|k| is_mpi_variable(k))
            .collect()
    });
}

/// A command for `program` that does not inherit this process's MPI
/// singleton: without it, an `mpirun` started after a section used MUMPS
/// in the process takes itself for a rank of that singleton and fails, and
/// a child that initialises MPI joins the parent's job instead of starting
/// its own. The MPI variables the program was started with are passed on.
pub fn child(program: impl AsRef<OsStr>) -> Command {
    let mut command = Command::new(program);
    let startup = STARTUP_MPI_VARIABLES
        .get()
        .map(Vec::as_slice)
        .unwrap_or(&[]);
    for (key, _) in std::env::vars_os() {
        if is_mpi_variable(&key) && !startup.contains(&key) {
            command.env_remove(key);
        }
    }
    command
}

/// Whether `key` starts with one of [`INHERITED_MPI_PREFIXES`].
fn is_mpi_variable(key: &OsStr) -> bool {
    key.to_str()
        .is_some_and(|k| INHERITED_MPI_PREFIXES.iter().any(|p| k.starts_with(p)))
}

/// Why a child failed: the last line of its error output, else of its
/// standard output, and its exit status.
pub fn failure(out: &std::process::Output) -> String {
    let line = [&out.stderr, &out.stdout]
        .into_iter()
        .map(|b| last_line(b))
        .find(|l| l != "no output")
        .unwrap_or_else(|| "no output".into());
    format!("{line} ({})", out.status)
}

/// The last non-empty line of a program's output (its error, usually).
pub fn last_line(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes)
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("no output")
        .trim()
        .to_string()
}

/// Runs `cmd`; `Err` names `what` and the last line it printed.
fn run(cmd: &mut Command, what: &str) -> Result<(), String> {
    let out = cmd.output().map_err(|e| format!("{what}: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!("{what} failed: {}", last_line(&out.stderr)))
    }
}

/// `true` if `python -c "import MODULES"` succeeds.
fn imports(python: &Path, modules: &str) -> bool {
    child(python)
        .args(["-c", &format!("import {modules}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// A Python with numpy, scipy and libigl (see the module documentation).
pub fn python_with_libigl() -> Result<Python, String> {
    const MODULES: &str = "numpy, scipy, igl";
    if let Some(p) = std::env::var_os("LSE_PYTHON") {
        let exe = PathBuf::from(p);
        return if imports(&exe, MODULES) {
            Ok(Python {
                exe,
                origin: "`$LSE_PYTHON`".into(),
            })
        } else {
            Err("the Python of `$LSE_PYTHON` does not import numpy, scipy and igl".into())
        };
    }
    let root = workspace_root();
    let venv = root.join(VENV);
    let exe = venv.join("bin").join("python");
    if !exe.exists() {
        run(
            child("python3").args(["-m", "venv"]).arg(&venv),
            &format!("`python3 -m venv {VENV}`"),
        )?;
    }
    if !imports(&exe, MODULES) {
        run(
            child(&exe).args(["-m", "pip", "install", "-q", "numpy", "scipy", "libigl"]),
            &format!("`pip install numpy scipy libigl` in {VENV}"),
        )?;
    }
    Ok(Python {
        exe,
        origin: format!("the virtual environment `{VENV}`"),
    })
}

/// [`python_with_libigl`] with this checkout's `lse_deform` package
/// installed into it (`pip install --force-reinstall --no-deps .`: rebuilt
/// by maturin from the working tree, so the module is this revision's).
pub fn python_with_package() -> Result<Python, String> {
    let python = python_with_libigl()?;
    run(
        child(&python.exe)
            .args([
                "-m",
                "pip",
                "install",
                "-q",
                "--force-reinstall",
                "--no-deps",
                ".",
            ])
            .current_dir(workspace_root()),
        "`pip install .` (the lse_deform package, built by maturin)",
    )?;
    if !imports(&python.exe, "lse_deform") {
        return Err("`import lse_deform` fails after `pip install .`".into());
    }
    Ok(python)
}

/// `true` if `program` is an executable file on `PATH` (or a path to one).
fn on_path(program: &str) -> bool {
    let p = Path::new(program);
    if p.components().count() > 1 {
        return p.is_file();
    }
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|d| d.join(program).is_file()))
}

/// Node with playwright-core, and Chromium.
#[derive(Debug, Clone)]
pub struct Browser {
    /// Chromium's executable (`$CHROMIUM`, else the first `chromium` on
    /// `PATH`).
    pub chromium: PathBuf,
}

/// Node, playwright-core (`npm ci` in `tests/browser` if missing) and
/// Chromium, or the reason why not.
pub fn browser() -> Result<Browser, String> {
    if !on_path("node") || !on_path("npm") {
        return Err("no `node` and `npm` on PATH".into());
    }
    let chromium = match std::env::var_os("CHROMIUM") {
        Some(c) => PathBuf::from(c),
        None => {
            let paths = std::env::var_os("PATH").unwrap_or_default();
            std::env::split_paths(&paths)
                .map(|d| d.join("chromium"))
                .find(|p| p.is_file())
                .ok_or("no `chromium` on PATH (`.ci/run` installs Debian's with apt-get)")?
        }
    };
    if !chromium.is_file() {
        return Err("`$CHROMIUM` is not a file".into());
    }
    let tests = workspace_root().join("tests").join("browser");
    if !tests.join("node_modules").join("playwright-core").is_dir() {
        run(
            child("npm")
                .args(["ci", "--no-audit", "--no-fund"])
                .current_dir(&tests),
            "`npm ci` in tests/browser (playwright-core)",
        )?;
    }
    Ok(Browser { chromium })
}

/// The optional features of this experiments build that the
/// `lse-deform` command-line tool is built with too (`suitesparse`,
/// `mumps`), so that every study that runs the tool runs the same binary.
fn mirrored_features() -> Vec<&'static str> {
    let mut features = Vec::new();
    if cfg!(feature = "suitesparse") {
        features.push("suitesparse");
    }
    if cfg!(feature = "mumps") {
        features.push("mumps");
    }
    features
}

/// Builds the `lse-deform` command-line tool (release, default features
/// plus this build's `suitesparse` and `mumps`) and returns its path, as
/// cargo reports it (`--message-format json`: the `executable` of the
/// binary's `compiler-artifact` message), so that it is found wherever
/// cargo's target directory is (`CARGO_TARGET_DIR`, `build.target-dir`).
pub fn cli_binary() -> Result<PathBuf, String> {
    let root = workspace_root();
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let features = mirrored_features();
    let mut command = child(cargo);
    command.args([
        "build",
        "--release",
        "--bin",
        "lse-deform",
        "--message-format",
        "json-render-diagnostics",
    ]);
    if !features.is_empty() {
        command.args(["--features", &features.join(",")]);
    }
    let what = "`cargo build --release --bin lse-deform`";
    let out = command
        .current_dir(&root)
        .output()
        .map_err(|e| format!("{what}: {e}"))?;
    if !out.status.success() {
        return Err(format!("{what} failed: {}", last_line(&out.stderr)));
    }
    match built_executable(&out.stdout, "lse-deform") {
        Some(exe) if exe.is_file() => Ok(exe),
        Some(exe) => Err(format!(
            "{what} named {} but left no file there",
            exe.display()
        )),
        None => Err(format!(
            "{what} reported no executable of the binary lse-deform"
        )),
    }
}

/// The `executable` of the `compiler-artifact` message of the binary
/// target `name` among cargo's JSON messages `stdout` (one per line).
fn built_executable(stdout: &[u8], name: &str) -> Option<PathBuf> {
    String::from_utf8_lossy(stdout).lines().find_map(|line| {
        let message: serde_json::Value = serde_json::from_str(line).ok()?;
        let is_binary = message["reason"] == "compiler-artifact"
            && message["target"]["name"] == name
            && message["target"]["kind"]
                .as_array()
                .is_some_and(|kinds| kinds.iter().any(|k| k == "bin"));
        is_binary
            .then(|| message["executable"].as_str().map(PathBuf::from))
            .flatten()
    })
}

/// `mpirun` on `PATH`, or why not.
pub fn mpirun() -> Result<PathBuf, String> {
    if on_path("mpirun") {
        Ok(PathBuf::from("mpirun"))
    } else {
        Err("no `mpirun` on PATH (Debian: openmpi-bin)".into())
    }
}

/// GNU time (`/usr/bin/time`, which reports a process's peak resident set
/// with `-f %M`), if present.
pub fn gnu_time() -> Option<PathBuf> {
    let p = PathBuf::from("/usr/bin/time");
    p.is_file().then_some(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_singletons_variables_are_dropped_and_the_rest_kept() {
        for key in ["PMIX_SERVER_URI2", "OMPI_MCA_ess", "ORTE_SCHIZO_DETECTION"] {
            assert!(is_mpi_variable(OsStr::new(key)), "{key}");
        }
        for key in ["PATH", "LSE_MESH_DIR", "OPENBLAS_NUM_THREADS", "XOMPI_"] {
            assert!(!is_mpi_variable(OsStr::new(key)), "{key}");
        }
    }

    #[test]
    fn a_failure_names_standard_output_when_the_error_output_is_empty() {
        let out = std::process::Command::new("sh")
            .args(["-c", "echo first; echo 'the reason'; exit 3"])
            .output()
            .expect("sh runs");
        let why = failure(&out);
        assert!(why.starts_with("the reason ("), "{why}");
        assert!(why.contains('3'), "{why}");
    }

    /// The binary's path is what cargo says, wherever its target directory
    /// is: the executable of the `bin` artifact named `lse-deform`, not of
    /// the library of that name, and nothing from other messages.
    #[test]
    fn the_binary_is_where_cargo_says_it_built_it() {
        let stdout = concat!(
            r#"{"reason":"compiler-artifact","target":{"name":"lse-deform","kind":["lib"]},"executable":null}"#,
            "\n",
            r#"{"reason":"compiler-artifact","target":{"name":"lse-deform","kind":["bin"]},"executable":"elsewhere/cargo-target/release/lse-deform"}"#,
            "\n",
            r#"{"reason":"build-finished","success":true}"#,
            "\n",
        );
        assert_eq!(
            built_executable(stdout.as_bytes(), "lse-deform"),
            Some(PathBuf::from("elsewhere/cargo-target/release/lse-deform"))
        );
        assert_eq!(built_executable(b"not json\n", "lse-deform"), None);
        let lib_only = r#"{"reason":"compiler-artifact","target":{"name":"lse-deform","kind":["lib"]},"executable":null}"#;
        assert_eq!(built_executable(lib_only.as_bytes(), "lse-deform"), None);
    }
}
