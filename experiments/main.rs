//! The `experiments` program: regenerates `results/` — the paper's
//! evaluation (Table 1, Fig. 6–9) and the comparisons this crate's users come
//! for (weight sweeps, scaling, interactive drag, performance against
//! CHOLMOD), each as CSV/JSON data, PNG and SVG plots and a section of
//! `results/README.md`.
//!
//! ```sh
//! cargo run --release --bin experiments -- all                       # generated meshes
//! cargo run --release --bin experiments -- all --mesh-dir ../shared/meshes
//! cargo run --release --bin experiments -- table1 --mesh-dir ../shared/meshes
//! ```

mod accuracy;
mod arap;
mod breakdown;
mod conflicts;
mod context;
mod demo;
mod drag;
mod performance;
mod plot;
mod relative;
mod render;
mod renders;
mod scaling;
mod table1;
mod text;
mod weight_sweep;

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, ValueEnum};

use context::{Context, assemble_readme, markdown_table};

/// Any failure of an experiment, as one line.
pub type AnyError = Box<dyn std::error::Error>;

/// What an experiment reports for the summary table.
pub struct Summary {
    /// One line: the main finding.
    pub headline: String,
}

/// Command line of the experiments program.
#[derive(Parser)]
#[command(
    name = "experiments",
    about = "Regenerates results/ of lse-deform: data, plots, renders and results/README.md"
)]
struct Cli {
    /// Which experiment(s) to run.
    #[arg(value_enum)]
    experiment: Experiment,
    /// A directory of meshes (e.g. ../shared/meshes): every .obj, .ply and
    /// .off file in it (optionally .gz) is used, named by its file stem; a
    /// directory without any is an error. Without --mesh-dir and --mesh the
    /// experiments use generated meshes. Also read from LSE_MESH_DIR.
    #[arg(long, env = "LSE_MESH_DIR")]
    mesh_dir: Option<PathBuf>,
    /// A mesh file to run on (repeatable; with --mesh-dir, in addition to
    /// its meshes and first).
    #[arg(long = "mesh", value_name = "PATH")]
    meshes: Vec<PathBuf>,
    /// Output directory.
    #[arg(long, default_value = "results")]
    out: PathBuf,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Smaller meshes and fewer repetitions (a smoke test, not for results/).
    #[arg(long)]
    quick: bool,
    /// Internal: the child process of the performance experiment's peak
    /// memory measurement (runs the paper's scene on this mesh and prints
    /// JSON).
    #[arg(long, hide = true)]
    memory_probe: Option<PathBuf>,
    /// For viz-demo: its output directory.
    #[arg(long, default_value = "target/viz-demo")]
    demo_out: PathBuf,
}

/// The experiments.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Experiment {
    /// Every experiment below, in order, then results/README.md.
    All,
    /// The paper's Table 1.
    Table1,
    /// Penalty relative weight 10⁻⁴ … 10¹² against the null-space method.
    WeightSweep,
    /// Digits lost without and with refinement against the condition
    /// number; penalty with and without multiplier updates.
    Accuracy,
    /// The paper's Fig. 7 and 8: precompute time by phase.
    PrecomputeBreakdown,
    /// The paper's Fig. 9 and 11: many relative constraints.
    RelativeConstraints,
    /// The paper's Fig. 6: conflicting constraints.
    Conflicts,
    /// Precompute and solve time against vertex count.
    Scaling,
    /// 300 frames of an interactive drag.
    Drag,
    /// Renders of the table1, conflicts and relative-constraint scenes.
    Renders,
    /// Ours against CHOLMOD and the memory-bandwidth floor.
    Performance,
    /// ARAP: bend and twist, ours against libigl, exact general constraints.
    Arap,
    /// Development aid: one plot of each kind and a render.
    VizDemo,
}

type Runner = fn(&Context) -> Result<Summary, AnyError>;

const ORDER: &[(Experiment, &str, Runner)] = &[
    (Experiment::Table1, "table1", table1::run),
    (Experiment::WeightSweep, "weight-sweep", weight_sweep::run),
    (Experiment::Accuracy, "accuracy", accuracy::run),
    (
        Experiment::PrecomputeBreakdown,
        "precompute-breakdown",
        breakdown::run,
    ),
    (
        Experiment::RelativeConstraints,
        "relative-constraints",
        relative::run,
    ),
    (Experiment::Conflicts, "conflicts", conflicts::run),
    (Experiment::Scaling, "scaling", scaling::run),
    (Experiment::Drag, "drag", drag::run),
    (Experiment::Renders, "renders", renders::run),
    (Experiment::Performance, "performance", performance::run),
    (Experiment::Arap, "arap", arap::run),
];

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let (Experiment::Performance, Some(mesh)) = (cli.experiment, &cli.memory_probe) {
        return match performance::memory_probe(mesh) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::FAILURE
            }
        };
    }
    if cli.experiment == Experiment::VizDemo {
        return match demo::viz_demo(&cli.demo_out) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::FAILURE
            }
        };
    }
    if let Some(dir) = &cli.mesh_dir
        && !dir.is_dir()
    {
        eprintln!("error: --mesh-dir {} is not a directory", dir.display());
        return ExitCode::from(2);
    }
    let ctx = match Context::new(
        cli.out.clone(),
        cli.meshes.clone(),
        cli.mesh_dir.clone(),
        cli.quick,
        cli.seed,
    ) {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    if let Err(e) = std::fs::create_dir_all(&ctx.out) {
        eprintln!("error: cannot create {}: {e}", ctx.out.display());
        return ExitCode::from(2);
    }
    eprintln!("{}", ctx.machine.one_line());
    let started = Instant::now();
    let mut rows = Vec::new();
    let mut failed = false;
    for &(which, name, run) in ORDER {
        if cli.experiment != Experiment::All && cli.experiment != which {
            continue;
        }
        let t = Instant::now();
        let outcome = run(&ctx);
        let seconds = t.elapsed().as_secs_f64();
        let (status, headline) = match outcome {
            Ok(s) => ("ok".to_string(), s.headline),
            Err(e) => {
                failed = true;
                ("FAILED".to_string(), e.to_string())
            }
        };
        eprintln!("{name}: {status} in {seconds:.1} s — {headline}");
        rows.push(vec![
            name.to_string(),
            status,
            format!("{seconds:.1}"),
            headline,
        ]);
    }
    if let Err(e) = assemble_readme(&ctx.out, &ctx.machine) {
        eprintln!("error: writing {}/README.md: {e}", ctx.out.display());
        failed = true;
    }
    println!(
        "\n{}",
        markdown_table(&["experiment", "status", "seconds", "main finding"], &rows)
    );
    println!("total: {:.1} s", started.elapsed().as_secs_f64());
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
