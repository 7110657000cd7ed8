//! The `lse-deform` command-line tool.
//!
//! Exit codes: 0 success, 2 bad input (mesh, constraints, arguments),
//! 3 numerical failure. Errors are one line on stderr; `--verbose` adds the
//! chain of causes.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use lse_deform::arap::{ArapDeformer, ArapEnergy, ArapInit};
use lse_deform::constraints::{ConstraintSet, read_constraints_file};
use lse_deform::error::ProblemError;
use lse_deform::export::{META_FILE, export_meta, export_problem, read_meta};
use lse_deform::mesh::{self, Quality, Topology, generate};
use lse_deform::problem::LseProblem;
use lse_deform::scene::{FixedAndHandle, MixedScene};
use lse_deform::{
    Deformer, Error, Formulation, FormulationChoice, LaplacianKind, LseSolver, Method, QrKind,
    Report, SpdKind, formulation, mtx,
};

mod cli;

#[derive(Parser)]
#[command(
    name = "lse-deform",
    version,
    about = "Laplacian mesh deformation with exact (hard) and soft constraints (Masuda et al., SMI 2006)"
)]
struct Cli {
    /// Print the full chain of causes of an error.
    #[arg(long, global = true)]
    verbose: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Deform a mesh under the constraints of a JSON file.
    Deform(DeformArgs),
    /// Write a generated mesh (no input file needed).
    Generate(GenerateArgs),
    /// Print counts, topology and triangle quality of a mesh.
    Info(InfoArgs),
    /// Write a constraints file that fixes the bottom of a mesh and drags a
    /// handle at its top.
    Scene(SceneArgs),
    /// Write A, C, B, D, the factored matrix (Matrix Market) and meta.json.
    ExportSystem(ExportArgs),
    /// Solve min ‖AX − C‖ s.t. BX = D for matrices in Matrix Market files
    /// (a directory as export-system writes it, or --a/--c/--b/--d).
    Solve(SolveArgs),
    /// Run every formulation on every back end on one problem and print a
    /// table (precompute, solve, constraint residual, condition).
    Compare(CompareArgs),
    /// Render a mesh, or a deformation of it over the original as a ghost,
    /// to PNG (displacement or difference colour maps, constraint groups).
    Render(cli::render::RenderArgs),
    /// Interactive editor in the browser: serves a local page to select
    /// fixed and handle regions and drag them (see README, "Interactive
    /// editing").
    #[cfg(feature = "editor")]
    Edit(EditArgs),
}

#[cfg(feature = "editor")]
#[derive(Args)]
struct EditArgs {
    /// Input mesh.
    mesh: PathBuf,
    /// Constraints file (JSON) to start with.
    #[arg(long, short = 'c')]
    constraints: Option<PathBuf>,
    /// Address to bind (anything but a loopback address prints a warning:
    /// plain HTTP carries the token unencrypted).
    #[arg(long, default_value = "127.0.0.1")]
    host: String,
    /// Port (0: any free port; the first line on stdout says which).
    #[arg(long, default_value_t = 0)]
    port: u16,
    /// Cap on request bodies in bytes (413 beyond).
    #[arg(long, default_value_t = lse_deform::editor::DEFAULT_MAX_BODY_BYTES)]
    max_body_bytes: usize,
    /// The session token that every API request must carry (16 to 256
    /// characters of A-Z a-z 0-9 - . _ ~); by default 32 random bytes in
    /// hex. Prefer the environment variable: a command line is visible to
    /// other users.
    #[arg(long, env = lse_deform::editor::TOKEN_ENV, hide_env_values = true)]
    token: Option<String>,
    /// Seconds a request body has to arrive after its head (408 beyond).
    #[arg(long, default_value_t = lse_deform::editor::DEFAULT_BODY_TIMEOUT.as_secs_f64())]
    body_timeout: f64,
    /// Seconds a connection may stay idle, or take to send a request head,
    /// before it is closed.
    #[arg(long, default_value_t = lse_deform::editor::DEFAULT_IDLE_TIMEOUT.as_secs_f64())]
    idle_timeout: f64,
}

/// How to solve: the formulation and its back ends.
#[derive(Args, Clone)]
struct MethodArgs {
    /// nullspace-qr (the paper), penalty, kkt or eliminate.
    #[arg(long, default_value = "nullspace-qr")]
    method: String,
    /// QR back end: dense-householder, sparse-givens or spqr.
    #[arg(long, default_value = "sparse-givens")]
    qr: String,
    /// SPD back end: faer-auto, faer-supernodal, faer-simplicial, nalgebra or
    /// cholmod (for kkt: the faer LDLT variant).
    #[arg(long, default_value = "faer-auto")]
    spd: String,
    /// Penalty weight of the hard rows (--method penalty).
    #[arg(long)]
    weight: Option<f64>,
    /// Iterative refinement with the same factor: off, auto or a number of
    /// steps. Default: auto for the exact methods, off for penalty (where
    /// refinement is the method of multipliers and makes it exact).
    #[arg(long, value_parser = parse_refine)]
    refine: Option<formulation::Refine>,
}

impl MethodArgs {
    /// The formulation these options name.
    fn formulation(&self) -> Result<Box<dyn Formulation>, Error> {
        let choice = FormulationChoice {
            method: self.method.parse()?,
            qr: self.qr.parse()?,
            spd: self.spd.parse()?,
            weight: self.weight,
        };
        Ok(choice.build()?)
    }
}

fn parse_refine(s: &str) -> Result<formulation::Refine, String> {
    formulation::Refine::parse(s).map_err(|e| e.to_string())
}

#[derive(Args)]
struct ExportArgs {
    /// Input mesh.
    mesh: PathBuf,
    /// Constraints file (JSON).
    #[arg(long, short = 'c')]
    constraints: PathBuf,
    /// Laplacian weights.
    #[arg(long, default_value = "cotan")]
    laplacian: LaplacianKind,
    #[command(flatten)]
    method: MethodArgs,
    /// Output directory.
    #[arg(long, short = 'o')]
    output: PathBuf,
}

#[derive(Args)]
struct SolveArgs {
    /// Directory holding A.mtx, C.mtx, B.mtx, D.mtx (and meta.json), as
    /// export-system writes it.
    dir: Option<PathBuf>,
    /// A (l × n, sparse); default DIR/A.mtx.
    #[arg(long)]
    a: Option<PathBuf>,
    /// C (l × k, dense); default DIR/C.mtx.
    #[arg(long)]
    c: Option<PathBuf>,
    /// B (m × n, sparse, one hard constraint per row in priority order);
    /// default DIR/B.mtx.
    #[arg(long)]
    b: Option<PathBuf>,
    /// D (m × k, dense); default DIR/D.mtx.
    #[arg(long)]
    d: Option<PathBuf>,
    /// meta.json of export-system (Laplacian rows, length scale); default
    /// DIR/meta.json when it exists.
    #[arg(long)]
    meta: Option<PathBuf>,
    #[command(flatten)]
    method: MethodArgs,
    /// Output: X (n × k) as a dense Matrix Market file.
    #[arg(long, short = 'o')]
    output: PathBuf,
    /// Write the report as JSON here.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Estimate the condition number of the factored matrix.
    #[arg(long)]
    condition: bool,
}

#[derive(Args)]
struct CompareArgs {
    /// Input mesh.
    mesh: PathBuf,
    /// Constraints file (JSON).
    #[arg(long, short = 'c')]
    constraints: PathBuf,
    /// Laplacian weights.
    #[arg(long, default_value = "cotan")]
    laplacian: LaplacianKind,
    /// Formulations to run (comma-separated; default all four).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "nullspace-qr,penalty,kkt,eliminate"
    )]
    methods: Vec<String>,
    /// QR back ends for nullspace-qr (comma-separated; default all in this
    /// build).
    #[arg(long, value_delimiter = ',')]
    qr: Vec<String>,
    /// SPD back ends (comma-separated; default all in this build; kkt runs
    /// the faer LDLT variants among them).
    #[arg(long, value_delimiter = ',')]
    spd: Vec<String>,
    /// Penalty weights to try (comma-separated).
    #[arg(long, default_value = "1e4,1e8,1e12", value_delimiter = ',')]
    weights: Vec<f64>,
    /// Refinement of every configuration (default: each formulation's own;
    /// the reference is always refined).
    #[arg(long, value_parser = parse_refine)]
    refine: Option<formulation::Refine>,
    /// Solves per configuration (the median time is reported).
    #[arg(long, default_value_t = 5)]
    repeat: usize,
    /// Skip the condition estimates (they cost a few hundred solves each).
    #[arg(long)]
    no_condition: bool,
    /// Also write every report as a JSON array here.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(Args)]
struct DeformArgs {
    /// Input mesh (.obj, .ply, .off, optionally .gz).
    mesh: PathBuf,
    /// Constraints file (JSON).
    #[arg(long, short = 'c')]
    constraints: PathBuf,
    /// Laplacian weights.
    #[arg(long, default_value = "cotan")]
    laplacian: LaplacianKind,
    /// Output mesh (.obj or .ply).
    #[arg(long, short = 'o')]
    output: PathBuf,
    /// Write the report as JSON here.
    #[arg(long)]
    report: Option<PathBuf>,
    #[command(flatten)]
    method: MethodArgs,
    /// Estimate the condition number of the factored matrix (Lanczos; costs
    /// up to a few hundred extra solves).
    #[arg(long)]
    condition: bool,
    /// Turn warnings that have a strict form into errors, writing nothing:
    /// an estimated forward error above 1e-8 of the bounding-box diagonal
    /// (exit 3), a constraints file made for another mesh (exit 2) and a
    /// conflicting hard constraint (exit 2; the warnings and the summary
    /// line are still printed).
    #[arg(long)]
    strict: bool,
    #[command(flatten)]
    energy: EnergyArgs,
}

/// The deformation energy of `deform`.
#[derive(Args)]
struct EnergyArgs {
    /// Deformation energy: the linear Laplacian (the paper; --laplacian
    /// chooses its weights) or as-rigid-as-possible (cotangent weights).
    #[arg(long, default_value = "laplacian", value_parser = ["laplacian", "arap"])]
    energy: String,
    /// ARAP energy: spokes (Sorkine & Alexa 2007) or spokes-and-rims (Chao
    /// et al. 2010, libigl's default).
    #[arg(long, default_value = "spokes-and-rims")]
    arap_energy: ArapEnergy,
    /// ARAP: the most iterations to run.
    #[arg(long, default_value_t = 10)]
    iterations: usize,
    /// ARAP: stop when the relative energy decrease of an iteration is at
    /// most this (0 runs all --iterations).
    #[arg(long, default_value_t = 0.0)]
    tolerance: f64,
    /// ARAP initial guess: linear (the linear gradient-domain solution;
    /// lower energy than rest at every iteration count measured on the
    /// Bunny, results/arap/README.md) or rest (rest pose, constrained
    /// vertices at their targets, as libigl's tutorials).
    #[arg(long, default_value = "linear")]
    arap_init: ArapInit,
}

#[derive(Args)]
struct GenerateArgs {
    /// icosphere, bumpy-sphere, grid, unsymmetric-grid or sliver.
    kind: String,
    /// Approximate number of vertices.
    #[arg(long, default_value_t = 10_000)]
    vertices: usize,
    /// Seed of the random parts (bumps, slivers).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output mesh (.obj, .ply or .off).
    #[arg(long, short = 'o')]
    output: PathBuf,
}

#[derive(Args)]
struct InfoArgs {
    /// Input mesh.
    mesh: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct SceneArgs {
    /// Input mesh.
    mesh: PathBuf,
    /// Fraction of vertices fixed at the bottom.
    #[arg(long, default_value_t = 0.2)]
    fixed: f64,
    /// Fraction of vertices in the handle at the top.
    #[arg(long, default_value_t = 0.02)]
    handle: f64,
    /// Axis from bottom to top: x, y or z (default: the longest extent).
    #[arg(long)]
    axis: Option<char>,
    /// Handle displacement "dx,dy,dz" (default: 15% of the bounding-box
    /// diagonal, perpendicular to the axis).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    offset: Option<[f64; 3]>,
    /// Make the handle soft with this weight (default: hard).
    #[arg(long)]
    handle_weight: Option<f64>,
    /// Add this many relative constraints (a spanning tree of a patch in the
    /// middle, keeping its shape).
    #[arg(long, default_value_t = 0)]
    relative: usize,
    /// Add this many on-edge constraints (edge midpoints moved).
    #[arg(long, default_value_t = 0)]
    edges: usize,
    /// Add this many on-face constraints (face centroids moved).
    #[arg(long, default_value_t = 0)]
    faces: usize,
    /// Append a duplicate of the first fixed constraint (redundant).
    #[arg(long)]
    duplicate: bool,
    /// Append a constraint contradicting the second fixed one (conflicting).
    #[arg(long)]
    conflict: bool,
    /// Output constraints file.
    #[arg(long, short = 'o')]
    output: PathBuf,
}

/// `println!` that treats a closed pipe (`lse-deform info m.obj | head`) as
/// the end of the output rather than a panic.
macro_rules! out {
    ($($arg:tt)*) => {
        emit(format!($($arg)*))
    };
}

fn emit(line: String) {
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

fn parse_vec3(s: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("expected three comma-separated numbers, got '{s}'"));
    }
    let mut v = [0.0; 3];
    for (o, p) in v.iter_mut().zip(parts) {
        *o = p.trim().parse::<f64>().map_err(|e| format!("'{p}': {e}"))?;
        if !o.is_finite() {
            return Err(format!("'{p}' is not finite"));
        }
    }
    Ok(v)
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Deform(a) => deform(a),
        Command::Generate(a) => generate_cmd(a),
        Command::Info(a) => info(a),
        Command::Scene(a) => scene(a),
        Command::ExportSystem(a) => export_system(a),
        Command::Solve(a) => solve(a),
        Command::Compare(a) => compare(a),
        Command::Render(a) => return cli::render::main(a, cli.verbose),
        #[cfg(feature = "editor")]
        Command::Edit(a) => edit(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            if cli.verbose {
                let mut source = std::error::Error::source(&e);
                while let Some(s) = source {
                    eprintln!("  caused by: {s}");
                    source = s.source();
                }
            }
            ExitCode::from(e.exit_code() as u8)
        }
    }
}

#[cfg(feature = "editor")]
fn edit(a: EditArgs) -> Result<(), Error> {
    let seconds = |name: &str, s: f64| {
        if s.is_finite() && s > 0.0 && s <= 1e6 {
            Ok(Duration::from_secs_f64(s))
        } else {
            Err(Error::from(ProblemError::InvalidArgument {
                message: format!("{name} {s} must be a positive number of seconds (at most 1e6)"),
            }))
        }
    };
    lse_deform::editor::run(lse_deform::editor::EditOptions {
        mesh: a.mesh,
        constraints: a.constraints,
        host: a.host,
        port: a.port,
        max_body_bytes: a.max_body_bytes,
        token: a.token,
        body_timeout: seconds("--body-timeout", a.body_timeout)?,
        idle_timeout: seconds("--idle-timeout", a.idle_timeout)?,
    })
}

/// A spinner on stderr for one phase. It is drawn only on a terminal
/// (indicatif's stderr target hides itself otherwise) and only once the
/// phase has lasted a second, so quick runs and pipes print nothing extra.
/// Several phases can share it through `set_message`.
fn phase(message: &str) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} ({elapsed})") {
        bar.set_style(style);
    }
    bar.set_message(message.to_string());
    show_after_a_second(&bar);
    bar
}

/// Points `bar` at stderr one second from now unless it has finished.
fn show_after_a_second(bar: &ProgressBar) {
    let weak = bar.downgrade();
    std::thread::spawn(move || {
        std::thread::sleep(Duration::from_secs(1));
        if let Some(bar) = weak.upgrade()
            && !bar.is_finished()
        {
            bar.set_draw_target(ProgressDrawTarget::stderr());
            bar.enable_steady_tick(Duration::from_millis(100));
        }
    });
}

fn load(path: &Path) -> Result<mesh::Mesh, Error> {
    let bar = phase(&format!("reading {}", path.display()));
    let loaded = mesh::read_mesh(path)?;
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
fn write_text(path: &Path, text: String) -> Result<(), Error> {
    lse_deform::atomic::write_bytes(path, (text + "\n").as_bytes()).map_err(|e| Error::io(path, e))
}

/// Fail fast: the output mesh (its format and its directory) and any other
/// output file are checked before the input is read or anything is solved.
fn check_outputs(mesh_out: Option<&Path>, file_out: Option<&Path>) -> Result<(), Error> {
    if let Some(path) = mesh_out {
        mesh::check_mesh_output(path)?;
    }
    if let Some(path) = file_out {
        mesh::check_writable(path)?;
    }
    Ok(())
}

/// Reads a constraints file for `mesh`: a `"mesh"` object in it that names
/// another mesh is a warning, or with `strict` an error (exit code 2); then
/// the vertex ranges are checked.
fn constraints_for(path: &Path, mesh: &mesh::Mesh, strict: bool) -> Result<ConstraintSet, Error> {
    let bar = phase(&format!("reading {}", path.display()));
    let set = read_constraints_file(path)?;
    bar.finish_and_clear();
    if let Some(detail) = set.mesh_mismatch(mesh) {
        if strict {
            return Err(lse_deform::error::ConstraintError::MeshMismatch { detail }.into());
        }
        eprintln!(
            "warning: {} was {detail} (--strict makes this an error)",
            path.display()
        );
    }
    set.check_vertices(mesh.n_vertices())?;
    Ok(set)
}

fn deform(a: DeformArgs) -> Result<(), Error> {
    check_outputs(Some(&a.output), a.report.as_deref())?;
    let mesh = load(&a.mesh)?;
    let constraints = constraints_for(&a.constraints, &mesh, a.strict)?;
    let m = &a.method;
    let formulation = m.formulation()?;
    if a.energy.energy == "arap" {
        return deform_arap(&a, mesh, constraints, formulation.as_ref());
    }
    let bar = phase("set-up");
    let mut deformer = Deformer::new(mesh, a.laplacian, constraints)?;
    deformer.set_refine(m.refine);
    bar.set_message(format!("precompute ({})", formulation.name()));
    deformer.precompute(formulation.as_ref())?;
    if a.condition {
        bar.set_message("condition estimate (Lanczos)");
        deformer.estimate_condition()?;
    }
    bar.set_message("solve");
    let solution = deformer.solve()?;
    bar.finish_and_clear();
    if a.strict && !solution.report.conflicting.is_empty() {
        // The warnings and the summary line with its counts still go to
        // stderr; nothing is written.
        finish_report(&solution.report, None, "vertices", "constraints")?;
        check_strict_conflicts(&solution.report, a.strict)?;
    }
    check_strict(&solution.report, a.strict)?;
    let out = deformer.mesh().with_positions(solution.positions)?;
    let bar = phase(&format!("writing {}", a.output.display()));
    mesh::write_mesh(&out, &a.output)?;
    bar.finish_and_clear();
    finish_report(
        &solution.report,
        a.report.as_deref(),
        "vertices",
        "constraints",
    )
}

fn deform_arap(
    a: &DeformArgs,
    mesh: mesh::Mesh,
    constraints: lse_deform::ConstraintSet,
    formulation: &dyn formulation::Formulation,
) -> Result<(), Error> {
    let e = &a.energy;
    let bar = phase("set-up");
    let mut arap = ArapDeformer::new(mesh, constraints, e.arap_energy)?;
    arap.set_refine(a.method.refine);
    bar.set_message(format!("precompute ({})", formulation.name()));
    arap.precompute(formulation)?;
    bar.set_message("ARAP iterations");
    arap.initialize(e.arap_init)?;
    let history = arap.run(e.iterations, e.tolerance)?;
    bar.finish_and_clear();
    let report = arap.report().clone();
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    let summary = format!(
        "{} + ARAP ({}, init {}): {} vertices, {} hard constraints ({} redundant, {} conflicting), max |BX - D| = {:.2e}; {} iterations ({}), energy {:.6e} -> {:.6e}; precompute {:.3} s, {:.4} s per iteration (local {:.3} s, global {:.3} s in all)",
        report.method,
        history.energy,
        history.init,
        report.vertices,
        report.hard_constraints,
        report.redundant.len(),
        report.conflicting.len(),
        report.max_constraint_residual,
        history.iterations,
        history.stop_reason,
        history.initial_energy,
        history
            .energies
            .last()
            .copied()
            .unwrap_or(history.initial_energy),
        report.timings_s.precompute(),
        history.time_per_iteration_s,
        history.local_time_s,
        history.global_time_s,
    );
    if a.strict && !report.conflicting.is_empty() {
        eprintln!("{summary}");
        return check_strict_conflicts(&report, a.strict);
    }
    let out = arap.mesh().with_positions(arap.positions())?;
    mesh::write_mesh(&out, &a.output)?;
    if let Some(path) = &a.report {
        let json = serde_json::to_string_pretty(&report).map_err(|e| Error::io(path, e.into()))?;
        write_text(path, json)?;
    }
    eprintln!("{summary}");
    Ok(())
}

fn export_system(a: ExportArgs) -> Result<(), Error> {
    // Fail fast: the directory (created now, as the export would) must take
    // files before the mesh is read and the system factored.
    std::fs::create_dir_all(&a.output).map_err(|e| Error::io(&a.output, e))?;
    mesh::check_writable(&a.output.join("A.mtx"))?;
    let mesh = load(&a.mesh)?;
    let constraints = constraints_for(&a.constraints, &mesh, false)?;
    let m = &a.method;
    let formulation = m.formulation()?;
    let mut deformer = Deformer::new(mesh, a.laplacian, constraints)?;
    deformer.precompute(formulation.as_ref())?;
    let files = export_problem(&a.output, deformer.problem(), deformer.prepared())?;
    let meta = export_meta(&a.output, deformer.problem(), deformer.report())?;
    eprintln!(
        "wrote {}, {}, {}, {}, {}{}",
        files.a.display(),
        files.c.display(),
        files.b.display(),
        files.d.display(),
        meta.display(),
        files
            .factored
            .map(|f| format!(
                " and {} (the matrix {} factors)",
                f.display(),
                formulation.name()
            ))
            .unwrap_or_default()
    );
    Ok(())
}

/// The path of one of `solve`'s matrices: the flag, else `DIR/NAME`.
fn matrix_path(
    flag: &Option<PathBuf>,
    dir: &Option<PathBuf>,
    name: &str,
) -> Result<PathBuf, Error> {
    match (flag, dir) {
        (Some(p), _) => Ok(p.clone()),
        (None, Some(d)) => Ok(d.join(name)),
        (None, None) => Err(lse_deform::error::ProblemError::InvalidArgument {
            message: format!(
                "no {name}: give a directory or --{}",
                name.trim_end_matches(".mtx").to_lowercase()
            ),
        }
        .into()),
    }
}

fn solve(a: SolveArgs) -> Result<(), Error> {
    // Fail fast, as `deform` does: both outputs must be writable before
    // the matrices are read and factored.
    check_outputs(None, Some(&a.output))?;
    check_outputs(None, a.report.as_deref())?;
    let path = |flag: &Option<PathBuf>, name: &str| matrix_path(flag, &a.dir, name);
    let (pa, pc, pb, pd) = (
        path(&a.a, "A.mtx")?,
        path(&a.c, "C.mtx")?,
        path(&a.b, "B.mtx")?,
        path(&a.d, "D.mtx")?,
    );
    let m = &a.method;
    let formulation = m.formulation()?;
    let meta_path = a.meta.clone().or_else(|| {
        a.dir
            .as_ref()
            .map(|d| d.join(META_FILE))
            .filter(|p| p.exists())
    });
    let meta = meta_path
        .as_deref()
        .map(read_meta)
        .transpose()?
        .unwrap_or_default();
    let bar = phase("reading the matrices");
    let t = std::time::Instant::now();
    let (ma, mc, mb, md) = mtx::read_system(&pa, &pc, &pb, &pd)?;
    let mut problem = LseProblem::from_parts(ma.as_ref(), mc.as_ref(), mb.as_ref(), md.as_ref())?;
    if let Some(rows) = meta.laplacian_rows {
        problem = problem.with_laplacian_rows(rows);
    }
    if let Some(scale) = meta.length_scale {
        problem = problem.with_length_scale(scale);
    }
    let mut base = Report {
        length_unit: meta.length_unit.unwrap_or(1.0),
        ..Report::default()
    };
    base.timings_s.setup = t.elapsed().as_secs_f64();
    let mut solver = LseSolver::with_report(problem, base);
    solver.set_refine(m.refine);
    bar.set_message(format!("precompute ({})", formulation.name()));
    solver.precompute(formulation.as_ref())?;
    if a.condition {
        bar.set_message("condition estimate (Lanczos)");
        solver.estimate_condition()?;
    }
    bar.set_message("solve");
    let x = solver.solve()?;
    bar.finish_and_clear();
    mtx::write_dense(&a.output, x.as_ref())?;
    finish_report(
        solver.report(),
        a.report.as_deref(),
        "unknowns",
        "rows of B",
    )
}

/// Conflict warnings, the `--report` file and the summary line of
/// `deform` and `solve`.
fn finish_report(
    report: &Report,
    path: Option<&Path>,
    unknowns: &str,
    constraints: &str,
) -> Result<(), Error> {
    // The conflicting constraints are among the warnings (the first few one
    // by one, the rest counted: a file can hold 10⁵ of them).
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(path) = path {
        let json = serde_json::to_string_pretty(report).map_err(|e| Error::io(path, e.into()))?;
        write_text(path, json)?;
    }
    eprintln!("{}", summary_line(report, unknowns, constraints));
    Ok(())
}

/// `--strict`: a conflicting hard constraint is an error (exit 2) before
/// anything is written; the message names the first (every one is among
/// the warnings).
fn check_strict_conflicts(report: &Report, strict: bool) -> Result<(), Error> {
    let count = report.conflicting.len();
    if !strict || count == 0 {
        return Ok(());
    }
    let first = report
        .warnings
        .iter()
        .find(|w| {
            w.starts_with(&format!(
                "constraint {} conflicts",
                report.conflicting[0].index
            ))
        })
        .cloned()
        .unwrap_or_else(|| {
            format!(
                "constraint {} conflicts with earlier constraints (residual {:.3e})",
                report.conflicting[0].index, report.conflicting[0].residual
            )
        });
    let detail = if count > 1 {
        format!("{first}; and {} more", count - 1)
    } else {
        first
    };
    Err(lse_deform::error::ConstraintError::Conflicting { count, detail }.into())
}

/// `--strict`: an estimated forward error above the warning threshold is
/// an error (exit 3) before anything is written.
fn check_strict(report: &Report, strict: bool) -> Result<(), Error> {
    let estimate = report.forward_error_estimate.unwrap_or(0.0);
    if strict && (estimate.is_nan() || estimate > formulation::FORWARD_ERROR_WARNING) {
        return Err(lse_deform::error::NumericalError::LostAccuracy {
            matrix: format!("{} (--strict)", report.method),
            estimate,
            tolerance: formulation::FORWARD_ERROR_WARNING,
        }
        .into());
    }
    Ok(())
}

/// The one-line summary of a deformation or solve on stderr.
fn summary_line(report: &Report, unknowns: &str, constraints: &str) -> String {
    let t = &report.timings_s;
    let rank = report
        .rank
        .map(|r| format!("rank {r} of "))
        .unwrap_or_default();
    let dependence = if report.redundant.is_detected() {
        format!(
            "{} redundant, {} conflicting",
            report.redundant.len(),
            report.conflicting.len()
        )
    } else {
        "redundancy and conflicts not detected".into()
    };
    let refinement = report
        .refinement
        .as_ref()
        .map(|r| {
            format!(
                ", refine {} ({} steps, {:.4} s), forward error ~{:.1e}",
                r.mode, r.steps, t.refine, r.forward_error_estimate
            )
        })
        .unwrap_or_default();
    format!(
        "{}: {} {unknowns}, {rank}{} hard {constraints} ({dependence}), max |BX - D| = {:.2e}; set-up {:.3} s, precompute {:.3} s, solve {:.4} s{refinement}{}",
        report.method,
        report.vertices,
        report.hard_constraints,
        report.max_constraint_residual,
        t.setup,
        t.precompute(),
        t.solve,
        report
            .condition_estimate
            .as_ref()
            .map(|c| format!(", condition ~{:.2e}", c.value))
            .unwrap_or_default()
    )
}

/// One row of `compare`.
#[derive(serde::Serialize)]
struct CompareRow {
    method: String,
    qr: Option<String>,
    spd: String,
    weight: Option<f64>,
    status: String,
    precompute_s: Option<f64>,
    solve_median_s: Option<f64>,
    refine_s: Option<f64>,
    max_constraint_residual: Option<f64>,
    /// `max_i ‖X_i − X*_i‖ / bbox diagonal` against the reference.
    delta_x: Option<f64>,
    /// `(E − E*) / E*` with `E = ‖AX − C‖²`, against the reference.
    delta_e: Option<f64>,
    forward_error_estimate: Option<f64>,
    condition: Option<f64>,
    report: Option<lse_deform::Report>,
}

/// Every name of `names` parsed.
fn parse_all<T: std::str::FromStr<Err = ProblemError>>(names: &[String]) -> Result<Vec<T>, Error> {
    Ok(names.iter().map(|n| n.parse()).collect::<Result<_, _>>()?)
}

/// Every configuration the filters of `a` allow, in table order (the
/// names parsed here, so a misspelt one stops `compare` before any work).
fn compare_configs(a: &CompareArgs) -> Result<Vec<FormulationChoice>, Error> {
    let invalid = |message: String| -> Error { ProblemError::InvalidArgument { message }.into() };
    let qrs: Vec<QrKind> = if a.qr.is_empty() {
        QrKind::available()
    } else {
        parse_all(&a.qr)?
    };
    let spds: Vec<SpdKind> = if a.spd.is_empty() {
        SpdKind::available()
            .into_iter()
            .filter(|&k| k != SpdKind::FaerAuto)
            .collect()
    } else {
        parse_all(&a.spd)?
    };
    let methods = a
        .methods
        .iter()
        .map(|m| {
            m.parse::<Method>().map_err(|_| {
                invalid(format!(
                    "unknown method '{m}' in --methods (expected some of: {})",
                    Method::ALL.map(Method::name).join(", ")
                ))
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut configs = Vec::new();
    for method in methods {
        let with = |spd: SpdKind| FormulationChoice {
            spd,
            ..FormulationChoice::new(method)
        };
        match method {
            Method::NullSpaceQr => {
                for &qr in &qrs {
                    configs.extend(spds.iter().map(|&s| FormulationChoice { qr, ..with(s) }));
                }
            }
            Method::Penalty => {
                for &w in &a.weights {
                    configs.extend(spds.iter().map(|&s| FormulationChoice {
                        weight: Some(w),
                        ..with(s)
                    }));
                }
            }
            Method::Kkt => {
                let faer = [
                    SpdKind::FaerSupernodal,
                    SpdKind::FaerSimplicial,
                    SpdKind::FaerAuto,
                ];
                configs.extend(spds.iter().filter(|s| faer.contains(s)).map(|&s| with(s)));
            }
            Method::Eliminate => configs.extend(spds.iter().map(|&s| with(s))),
        }
    }
    if configs.is_empty() {
        return Err(invalid(
            "--methods/--qr/--spd/--weights leave no configuration to run".into(),
        ));
    }
    Ok(configs)
}

/// The reference solution of `compare`: the paper's method with the default
/// back ends, refined until it converges, and its energy `‖AX − C‖²`.
fn compare_reference(deformer: &mut Deformer) -> Result<(faer::Mat<f64>, f64), Error> {
    deformer.set_refine(Some(formulation::Refine::Auto));
    deformer.precompute(&lse_deform::NullSpaceQr::default())?;
    let x = deformer.solve_matrix()?;
    let r = deformer.report();
    if let Some(e) = r.forward_error_estimate.filter(|&e| e > 1e-12) {
        eprintln!(
            "warning: the reference solution (nullspace-qr, refined) has an estimated forward error of {e:.1e}: differences below it are not resolved"
        );
    }
    let energy = r.least_squares_residual.powi(2);
    Ok((x, energy))
}

/// Runs one configuration and fills its row.
fn compare_one(
    deformer: &mut Deformer,
    config: &FormulationChoice,
    a: &CompareArgs,
    reference: &(faer::Mat<f64>, f64),
    row: &mut CompareRow,
) -> Result<(), Error> {
    let f = config.build()?;
    deformer.set_refine(a.refine);
    deformer.precompute(f.as_ref())?;
    let mut times = Vec::new();
    let mut x = faer::Mat::<f64>::zeros(0, 0);
    for _ in 0..a.repeat.max(1) {
        x = deformer.solve_matrix()?;
        times.push(deformer.report().timings_s.solve);
    }
    times.sort_by(f64::total_cmp);
    row.solve_median_s = Some(times[times.len() / 2]);
    if !a.no_condition {
        row.condition = Some(deformer.estimate_condition()?.value);
    }
    let r = deformer.report().clone();
    let (x_ref, e_ref) = reference;
    // X and the reference are in the problem's units (solve_matrix).
    let diagonal = deformer.problem().length_scale().max(f64::MIN_POSITIVE);
    row.delta_x = Some(
        (0..x.nrows())
            .map(|i| {
                (0..3)
                    .map(|c| (x[(i, c)] - x_ref[(i, c)]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(0.0, f64::max)
            / diagonal,
    );
    let energy = r.least_squares_residual.powi(2);
    row.delta_e = Some(if *e_ref > 0.0 {
        (energy - e_ref) / e_ref
    } else {
        energy
    });
    row.precompute_s = Some(r.timings_s.precompute());
    row.refine_s = Some(r.timings_s.refine);
    row.max_constraint_residual = Some(r.max_constraint_residual);
    row.forward_error_estimate = r.forward_error_estimate;
    row.report = Some(r);
    Ok(())
}

fn compare(a: CompareArgs) -> Result<(), Error> {
    check_outputs(None, a.json.as_deref())?;
    let configs = compare_configs(&a)?;
    let mesh = load(&a.mesh)?;
    let constraints = constraints_for(&a.constraints, &mesh, false)?;
    let mut deformer = Deformer::new(mesh, a.laplacian, constraints)?;
    let bar =
        ProgressBar::with_draw_target(Some(configs.len() as u64 + 1), ProgressDrawTarget::hidden());
    if let Ok(style) = ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} ({elapsed})") {
        bar.set_style(style);
    }
    show_after_a_second(&bar);
    bar.set_message("reference (nullspace-qr, refined)");
    let reference = compare_reference(&mut deformer)?;
    bar.inc(1);
    let mut rows = Vec::new();
    for config in &configs {
        // The QR back end is named for the null-space method only.
        let qr = (config.method == Method::NullSpaceQr).then(|| config.qr.name().to_string());
        bar.set_message(format!(
            "{} {} {}",
            config.method,
            qr.as_deref().unwrap_or(""),
            config.spd
        ));
        let mut row = CompareRow {
            method: config.method.name().into(),
            qr,
            spd: config.spd.name().into(),
            weight: config.weight,
            status: "ok".into(),
            precompute_s: None,
            solve_median_s: None,
            refine_s: None,
            max_constraint_residual: None,
            delta_x: None,
            delta_e: None,
            forward_error_estimate: None,
            condition: None,
            report: None,
        };
        if let Err(e) = compare_one(&mut deformer, config, &a, &reference, &mut row) {
            let class = if e.is_input_error() {
                "input"
            } else {
                "numerical"
            };
            row.status = format!("error ({class}): {e}");
        } else if let Some(r) = &row.report
            && !r.warnings.is_empty()
        {
            row.status = format!("ok, warning: {}", r.warnings.join("; "));
        }
        rows.push(row);
        bar.inc(1);
    }
    bar.finish_and_clear();
    print_compare_table(&rows);
    if let Some(path) = &a.json {
        let json = serde_json::to_string_pretty(&rows).map_err(|e| Error::io(path, e.into()))?;
        write_text(path, json)?;
    }
    Ok(())
}

/// The Markdown table of `compare` on stdout (status text in full).
fn print_compare_table(rows: &[CompareRow]) {
    out!(
        "| method | QR | SPD | weight | precompute (s) | solve, median (ms) | refine (ms) | max ‖BX − D‖ | ΔX | ΔE | forward error est. | condition est. | status |"
    );
    out!("|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|");
    let opt = |v: Option<f64>, f: &dyn Fn(f64) -> String| v.map(f).unwrap_or_else(|| "—".into());
    for r in rows {
        out!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.method,
            r.qr.as_deref().unwrap_or("—"),
            r.spd,
            opt(r.weight, &|w| format!("{w:.0e}")),
            opt(r.precompute_s, &|t| format!("{t:.3}")),
            opt(r.solve_median_s, &|t| format!("{:.2}", t * 1e3)),
            opt(r.refine_s, &|t| format!("{:.2}", t * 1e3)),
            opt(r.max_constraint_residual, &|v| format!("{v:.1e}")),
            opt(r.delta_x, &|v| format!("{v:.1e}")),
            opt(r.delta_e, &|v| format!("{v:.1e}")),
            opt(r.forward_error_estimate, &|v| format!("{v:.1e}")),
            opt(r.condition, &|v| format!("{v:.2e}")),
            r.status.replace('|', "\\|")
        );
    }
}

fn generate_cmd(a: GenerateArgs) -> Result<(), Error> {
    let kind: generate::GeneratedKind = a
        .kind
        .parse()
        .map_err(|e: lse_deform::error::MeshError| Error::Mesh(e))?;
    mesh::check_mesh_output(&a.output)?;
    let size = generate::size_for_vertices(kind, a.vertices)?;
    let mesh = generate::generate(kind, size, a.seed)?;
    mesh::write_mesh(&mesh, &a.output)?;
    let n = mesh.n_vertices();
    let nearest = if n == a.vertices {
        String::new()
    } else {
        // The family's sizes next to the one chosen, so the user sees why N
        // was not hit exactly.
        let neighbours: Vec<String> = [size.checked_sub(1), size.checked_add(1)]
            .into_iter()
            .flatten()
            .filter(|&s| s >= kind.min_size())
            .filter_map(|s| kind.vertex_count(s))
            .map(|c| c.to_string())
            .collect();
        format!(
            " (the nearest {kind} to the {} vertices asked for; the neighbouring sizes have {})",
            a.vertices,
            neighbours.join(" and ")
        )
    };
    eprintln!(
        "{kind}: {n} vertices, {} faces{nearest} -> {}",
        mesh.n_faces(),
        a.output.display()
    );
    Ok(())
}

fn info(a: InfoArgs) -> Result<(), Error> {
    let mesh = load(&a.mesh)?;
    let topo = Topology::of(&mesh);
    let q = Quality::of(&mesh);
    let (lo, hi) = mesh.bounding_box();
    if a.json {
        let v = serde_json::json!({
            "vertices": mesh.n_vertices(),
            "faces": mesh.n_faces(),
            "edges": topo.n_edges,
            "boundary_edges": topo.n_boundary_edges,
            "boundary_loops": topo.n_boundary_loops,
            "non_manifold_edges": topo.n_non_manifold_edges,
            "components": topo.n_components,
            "consistently_oriented": topo.consistently_oriented,
            "euler_characteristic": topo.euler_characteristic,
            "genus": topo.genus,
            "bbox_min": lo,
            "bbox_max": hi,
            "bbox_diagonal": mesh.bbox_diagonal(),
            "min_angle_deg": q.min_angle_deg,
            "max_angle_deg": q.max_angle_deg,
            "max_aspect_ratio": q.max_aspect_ratio,
            "percent_min_angle_below_10deg": q.percent_below_10_deg,
            "faces_min_angle_below_1deg": q.count_below_1_deg,
            "edge_length_ratio": q.edge_length_ratio,
        });
        out!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return Ok(());
    }
    out!("vertices            {}", mesh.n_vertices());
    out!("faces               {}", mesh.n_faces());
    out!("edges               {}", topo.n_edges);
    out!(
        "boundary            {} edges in {} loops{}",
        topo.n_boundary_edges,
        topo.n_boundary_loops,
        if topo.n_boundary_edges == 0 {
            " (closed)"
        } else {
            ""
        }
    );
    out!("non-manifold edges  {}", topo.n_non_manifold_edges);
    out!("components          {}", topo.n_components);
    out!(
        "orientation         {}",
        if topo.consistently_oriented {
            "consistent"
        } else {
            "inconsistent"
        }
    );
    out!("Euler char.         {}", topo.euler_characteristic);
    out!(
        "genus               {}",
        topo.genus
            .map(|g| g.to_string())
            .unwrap_or_else(|| "undefined (non-manifold)".into())
    );
    out!(
        "bounding box        {lo:?} .. {hi:?} (diagonal {:.6})",
        mesh.bbox_diagonal()
    );
    out!(
        "angles              min {:.4} deg, max {:.4} deg",
        q.min_angle_deg,
        q.max_angle_deg
    );
    out!("worst aspect ratio  {:.2}", q.max_aspect_ratio);
    out!(
        "slivers             {:.2}% of faces with min angle < 10 deg, {} below 1 deg",
        q.percent_below_10_deg,
        q.count_below_1_deg
    );
    out!("edge length ratio   {:.1}", q.edge_length_ratio);
    Ok(())
}

fn scene(a: SceneArgs) -> Result<(), Error> {
    check_outputs(None, Some(&a.output))?;
    let mesh = load(&a.mesh)?;
    let mut s = FixedAndHandle::paper_default(&mesh);
    if let Some(axis) = a.axis {
        s.axis = match axis {
            'x' => 0,
            'y' => 1,
            'z' => 2,
            other => {
                return Err(lse_deform::error::ProblemError::InvalidArgument {
                    message: format!("--axis {other}: expected x, y or z"),
                }
                .into());
            }
        };
        let mut offset = [0.0; 3];
        offset[(s.axis + 1) % 3] = 0.15 * mesh.bbox_diagonal();
        s.offset = offset;
    }
    if let Some(o) = a.offset {
        s.offset = o;
    }
    s.fixed_fraction = a.fixed;
    s.handle_fraction = a.handle;
    s.handle_weight = a.handle_weight;
    let mixed = MixedScene {
        base: s.clone(),
        relative: a.relative,
        edges: a.edges,
        faces: a.faces,
        duplicate: a.duplicate,
        conflict: a.conflict,
    };
    let set = mixed.constraints(&mesh)?;
    lse_deform::atomic::write_bytes(&a.output, set.to_json().as_bytes())
        .map_err(|e| Error::io(&a.output, e))?;
    let (fixed, handle) = s.regions(&mesh)?;
    let mut extra = String::new();
    for (count, what) in [
        (a.relative, "relative"),
        (a.edges, "on-edge"),
        (a.faces, "on-face"),
        (usize::from(a.duplicate), "duplicate"),
        (usize::from(a.conflict), "conflicting"),
    ] {
        if count > 0 {
            extra.push_str(&format!(" + {count} {what}"));
        }
    }
    eprintln!(
        "{} constraints: {} fixed + {} handle vertices{extra} (axis {}, offset {:?}) -> {}",
        set.len(),
        fixed.len(),
        handle.len(),
        ["x", "y", "z"][s.axis],
        s.offset,
        a.output.display()
    );
    Ok(())
}
