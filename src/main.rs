//! The `lse-deform` command-line tool.
//!
//! Exit codes: 0 success, 2 bad input (mesh, constraints, arguments),
//! 3 numerical failure. Errors are one line on stderr; `--verbose` adds the
//! chain of causes.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use lse_deform::arap::{ArapDeformer, ArapEnergy, ArapInit};
use lse_deform::constraints::read_constraints;
use lse_deform::export::export_problem;
use lse_deform::mesh::{self, Quality, Topology, generate};
use lse_deform::scene::{FixedAndHandle, MixedScene};
use lse_deform::{Deformer, Error, LaplacianKind, backend, formulation};

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
    /// Write A, C, B, D and the factored matrix in Matrix Market format.
    ExportSystem(ExportArgs),
    /// Run every formulation on every back end on one problem and print a
    /// table (precompute, solve, constraint residual, condition).
    Compare(CompareArgs),
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
struct CompareArgs {
    /// Input mesh.
    mesh: PathBuf,
    /// Constraints file (JSON).
    #[arg(long, short = 'c')]
    constraints: PathBuf,
    /// Laplacian weights.
    #[arg(long, default_value = "cotan")]
    laplacian: LaplacianKind,
    /// Penalty weights to try (comma-separated).
    #[arg(long, default_value = "1e4,1e8,1e12", value_delimiter = ',')]
    weights: Vec<f64>,
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
        Command::Compare(a) => compare(a),
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

/// A spinner on stderr for one phase (drawn only on a terminal).
fn phase(message: &str) -> ProgressBar {
    let bar = ProgressBar::new_spinner();
    if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} ({elapsed})") {
        bar.set_style(style);
    }
    bar.set_message(message.to_string());
    bar.enable_steady_tick(Duration::from_millis(100));
    bar
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

fn deform(a: DeformArgs) -> Result<(), Error> {
    let mesh = load(&a.mesh)?;
    let constraints = read_constraints(&a.constraints, mesh.n_vertices())?;
    let m = &a.method;
    let formulation = formulation::build(&m.method, &m.qr, &m.spd, m.weight)?;
    if a.energy.energy == "arap" {
        return deform_arap(&a, mesh, constraints, formulation.as_ref());
    }
    let bar = phase("set-up");
    let mut deformer = Deformer::new(mesh, a.laplacian, constraints)?;
    bar.set_message(format!("precompute ({})", formulation.name()));
    deformer.precompute(formulation.as_ref())?;
    if a.condition {
        bar.set_message("condition estimate (Lanczos)");
        deformer.estimate_condition()?;
    }
    bar.set_message("solve");
    let solution = deformer.solve()?;
    bar.finish_and_clear();
    let report = &solution.report;
    for c in &report.conflicting {
        eprintln!(
            "warning: constraint {} conflicts with earlier constraints and was dropped (residual {:.3e})",
            c.index, c.residual
        );
    }
    let out = deformer.mesh().with_positions(solution.positions)?;
    mesh::write_mesh(&out, &a.output)?;
    if let Some(path) = &a.report {
        let json = serde_json::to_string_pretty(report).map_err(|e| Error::io(path, e.into()))?;
        std::fs::write(path, json + "\n").map_err(|e| Error::io(path, e))?;
    }
    let t = &report.timings_s;
    let rank = report
        .rank
        .map(|r| format!("rank {r} of "))
        .unwrap_or_default();
    eprintln!(
        "{}: {} vertices, {rank}{} hard constraints ({} redundant, {} conflicting), max |BX - D| = {:.2e}; set-up {:.3} s, precompute {:.3} s, solve {:.4} s{}",
        report.method,
        report.vertices,
        report.hard_constraints,
        report.redundant.len(),
        report.conflicting.len(),
        report.max_constraint_residual,
        t.setup,
        t.precompute(),
        t.solve,
        report
            .condition_estimate
            .as_ref()
            .map(|c| format!(", condition ~{:.2e}", c.value))
            .unwrap_or_default()
    );
    Ok(())
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
    bar.set_message(format!("precompute ({})", formulation.name()));
    arap.precompute(formulation)?;
    bar.set_message("ARAP iterations");
    arap.initialize(e.arap_init)?;
    let history = arap.run(e.iterations, e.tolerance)?;
    bar.finish_and_clear();
    let report = arap.report().clone();
    for c in &report.conflicting {
        eprintln!(
            "warning: constraint {} conflicts with earlier constraints and was dropped (residual {:.3e})",
            c.index, c.residual
        );
    }
    let out = arap.mesh().with_positions(arap.positions())?;
    mesh::write_mesh(&out, &a.output)?;
    if let Some(path) = &a.report {
        let json = serde_json::to_string_pretty(&report).map_err(|e| Error::io(path, e.into()))?;
        std::fs::write(path, json + "\n").map_err(|e| Error::io(path, e))?;
    }
    eprintln!(
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
    Ok(())
}

fn export_system(a: ExportArgs) -> Result<(), Error> {
    let mesh = load(&a.mesh)?;
    let constraints = read_constraints(&a.constraints, mesh.n_vertices())?;
    let m = &a.method;
    let formulation = formulation::build(&m.method, &m.qr, &m.spd, m.weight)?;
    let mut deformer = Deformer::new(mesh, a.laplacian, constraints)?;
    deformer.precompute(formulation.as_ref())?;
    let files = export_problem(&a.output, deformer.problem(), deformer.prepared())?;
    eprintln!(
        "wrote {}, {}, {}, {}{}",
        files.a.display(),
        files.c.display(),
        files.b.display(),
        files.d.display(),
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
    max_constraint_residual: Option<f64>,
    condition: Option<f64>,
    report: Option<lse_deform::Report>,
}

fn compare(a: CompareArgs) -> Result<(), Error> {
    let mesh = load(&a.mesh)?;
    let constraints = read_constraints(&a.constraints, mesh.n_vertices())?;
    let mut deformer = Deformer::new(mesh, a.laplacian, constraints)?;
    let available = |names: &[&'static str]| -> Vec<&'static str> {
        names
            .iter()
            .copied()
            .filter(|n| cfg!(feature = "suitesparse") || !matches!(*n, "spqr" | "cholmod"))
            .collect()
    };
    let qrs = available(backend::qr::NAMES);
    let spds: Vec<&str> = available(backend::spd::NAMES)
        .into_iter()
        .filter(|n| *n != "faer-auto")
        .collect();
    let mut configs: Vec<(&str, Option<&str>, &str, Option<f64>)> = Vec::new();
    for &q in &qrs {
        for &s in &spds {
            configs.push(("nullspace-qr", Some(q), s, None));
        }
    }
    for &w in &a.weights {
        for &s in &spds {
            configs.push(("penalty", None, s, Some(w)));
        }
    }
    for s in ["faer-simplicial", "faer-supernodal"] {
        configs.push(("kkt", None, s, None));
    }
    for &s in &spds {
        configs.push(("eliminate", None, s, None));
    }
    let bar = ProgressBar::new(configs.len() as u64);
    if let Ok(style) = ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} ({elapsed})") {
        bar.set_style(style);
    }
    let mut rows = Vec::new();
    for (method, qr, spd, weight) in configs {
        bar.set_message(format!("{method} {} {spd}", qr.unwrap_or("")));
        let mut row = CompareRow {
            method: method.into(),
            qr: qr.map(Into::into),
            spd: spd.into(),
            weight,
            status: "ok".into(),
            precompute_s: None,
            solve_median_s: None,
            max_constraint_residual: None,
            condition: None,
            report: None,
        };
        let outcome = (|| -> Result<(), Error> {
            let f = formulation::build(method, qr.unwrap_or("sparse-givens"), spd, weight)?;
            deformer.precompute(f.as_ref())?;
            let mut times = Vec::new();
            for _ in 0..a.repeat.max(1) {
                deformer.solve_matrix()?;
                times.push(deformer.report().timings_s.solve);
            }
            times.sort_by(f64::total_cmp);
            row.solve_median_s = Some(times[times.len() / 2]);
            if !a.no_condition {
                row.condition = Some(deformer.estimate_condition()?.value);
            }
            let r = deformer.report().clone();
            row.precompute_s = Some(r.timings_s.precompute());
            row.max_constraint_residual = Some(r.max_constraint_residual);
            row.report = Some(r);
            Ok(())
        })();
        if let Err(e) = outcome {
            row.status = format!(
                "error ({}): {e}",
                if e.is_input_error() {
                    "input"
                } else {
                    "numerical"
                }
            );
        }
        rows.push(row);
        bar.inc(1);
    }
    bar.finish_and_clear();
    out!(
        "| method | QR | SPD | weight | precompute (s) | solve, median (ms) | max ‖BX − D‖ | condition est. | status |"
    );
    out!("|---|---|---|---|---:|---:|---:|---:|---|");
    let opt = |v: Option<f64>, f: &dyn Fn(f64) -> String| v.map(f).unwrap_or_else(|| "—".into());
    for r in &rows {
        out!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.method,
            r.qr.as_deref().unwrap_or("—"),
            r.spd,
            opt(r.weight, &|w| format!("{w:.0e}")),
            opt(r.precompute_s, &|t| format!("{t:.3}")),
            opt(r.solve_median_s, &|t| format!("{:.2}", t * 1e3)),
            opt(r.max_constraint_residual, &|v| format!("{v:.1e}")),
            opt(r.condition, &|v| format!("{v:.2e}")),
            if r.status.len() > 90 {
                format!(
                    "{}…",
                    &r.status[..r
                        .status
                        .char_indices()
                        .nth(90)
                        .map(|c| c.0)
                        .unwrap_or(r.status.len())]
                )
            } else {
                r.status.clone()
            }
        );
    }
    if let Some(path) = &a.json {
        let json = serde_json::to_string_pretty(&rows).map_err(|e| Error::io(path, e.into()))?;
        std::fs::write(path, json + "\n").map_err(|e| Error::io(path, e))?;
    }
    Ok(())
}

fn generate_cmd(a: GenerateArgs) -> Result<(), Error> {
    let kind: generate::GeneratedKind = a
        .kind
        .parse()
        .map_err(|e: lse_deform::error::MeshError| Error::Mesh(e))?;
    let mesh = generate::with_about_vertices(kind, a.vertices, a.seed)?;
    mesh::write_mesh(&mesh, &a.output)?;
    eprintln!(
        "{kind}: {} vertices, {} faces -> {}",
        mesh.n_vertices(),
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
    std::fs::write(&a.output, set.to_json()).map_err(|e| Error::io(&a.output, e))?;
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
