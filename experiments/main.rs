//! The `experiments` program: regenerates `results/` — the paper's
//! evaluation (Table 1, Fig. 6–9) and the comparisons this crate's users come
//! for (weight sweeps, scaling, interactive drag, performance against
//! CHOLMOD), each as CSV/JSON data, PNG and SVG plots and a section of
//! `results/README.md`.
//!
//! ```sh
//! cargo run --release --bin experiments -- all                       # generated meshes, into target/experiments/
//! cargo run --release --bin experiments -- all --mesh-dir ../shared/meshes --out results
//! cargo run --release --bin experiments -- table1 --mesh-dir ../shared/meshes
//! cargo run --release --bin experiments -- weight-sweep --mesh my.obj -c my.json
//! ```
//!
//! The experiments are listed once, in [`EXPERIMENTS`]; the infrastructure
//! is in [`harness`], the experiments in [`studies`]. Without
//! `--out` a run writes to a fresh directory under `target/experiments/`;
//! the committed `results/` is written only with `--out results`.

mod harness;
mod studies;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use clap::builder::{PossibleValue, PossibleValuesParser};

use harness::context::{self, AnyError, Context};
use harness::demo;
use harness::environment;
use harness::registry::{self, Experiment, Summary, assemble_readme};
use harness::rows::markdown_table;
use studies::{
    accuracy, arap, breakdown, conflicts, distributed, drag, editor, mpi_in_process, performance,
    python, relative, renders, scaling, table1, weight_sweep,
};

/// Every experiment, in the order of `all` and of `results/README.md`: the
/// single list, from which the command line takes its choices and
/// `results/README.md` its sections.
const EXPERIMENTS: &[Experiment] = &[
    table1::EXPERIMENT,
    weight_sweep::EXPERIMENT,
    accuracy::EXPERIMENT,
    breakdown::EXPERIMENT,
    relative::EXPERIMENT,
    conflicts::EXPERIMENT,
    scaling::EXPERIMENT,
    drag::EXPERIMENT,
    renders::EXPERIMENT,
    performance::EXPERIMENT,
    distributed::EXPERIMENT,
    mpi_in_process::EXPERIMENT,
    arap::EXPERIMENT,
    python::EXPERIMENT,
    editor::EXPERIMENT,
];

/// Every experiment first (in the order of `all`), then `all` and
/// `viz-demo`: the words the command line accepts.
fn experiment_words() -> PossibleValuesParser {
    let mut words: Vec<PossibleValue> = EXPERIMENTS
        .iter()
        .map(|e| {
            let inputs: Vec<&str> = e.inputs.iter().map(|i| i.describe()).collect();
            PossibleValue::new(e.name).help(format!("{} ({})", e.title, inputs.join(", ")))
        })
        .collect();
    words.push(PossibleValue::new("all").help("Every experiment above, in order, then README.md"));
    words.push(
        PossibleValue::new("viz-demo").help("Development aid: one plot of each kind and a render"),
    );
    PossibleValuesParser::new(words)
}

/// Command line of the experiments program.
#[derive(Parser)]
#[command(
    name = "experiments",
    about = "Regenerates results/ of lse-deform: data, plots, renders and results/README.md"
)]
struct Cli {
    /// Which experiment(s) to run.
    #[arg(value_parser = experiment_words())]
    experiment: String,
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
    /// A constraint file (JSON, as `lse-deform scene` writes) for the
    /// --mesh files: weight-sweep sweeps it besides its built-in scenes.
    #[arg(short = 'c', long = "constraints", value_name = "FILE")]
    constraints: Option<PathBuf>,
    /// Output directory. Default: a fresh directory
    /// target/experiments/NAME-YYYYMMDD-HHMMSS; the committed results are
    /// written only with `--out results`.
    #[arg(long)]
    out: Option<PathBuf>,
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

/// Exit code 1 with the error on stderr, or success.
fn exit(outcome: Result<(), AnyError>) -> ExitCode {
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// The context of the run, from the command line.
fn context(cli: &Cli) -> Result<Context, AnyError> {
    if let Some(dir) = &cli.mesh_dir
        && !dir.is_dir()
    {
        return Err(format!("--mesh-dir {} is not a directory", dir.display()).into());
    }
    let out = cli
        .out
        .clone()
        .unwrap_or_else(|| context::fresh_out_dir(&cli.experiment));
    let ctx = Context::new(
        out,
        cli.meshes.clone(),
        cli.mesh_dir.clone(),
        cli.constraints.clone(),
        cli.quick,
        cli.seed,
    )?;
    std::fs::create_dir_all(&ctx.out)
        .map_err(|e| format!("cannot create {}: {e}", ctx.out.display()))?;
    Ok(ctx)
}

/// Adds to an experiment's section what the harness knows and the section
/// may lack: what this build could not measure, and the machine line with
/// the revision (which `results/README.md`'s header reads).
fn complete_section(ctx: &Context, e: &Experiment, path: &Path) -> Result<(), AnyError> {
    let mut section = std::fs::read_to_string(path)?.trim_end().to_string();
    if let Some(note) = registry::missing_build_inputs(e) {
        section = format!("{section}\n\n{note}");
    }
    let machine = ctx.machine.one_line();
    if !section.contains(&machine) {
        section = format!("{section}\n\n_{machine}_");
    }
    std::fs::write(path, section + "\n")?;
    Ok(())
}

/// Runs `e` into an empty folder `out/<name>/` (what an earlier run left
/// there is removed first, so that nothing older stays beside the new
/// section); if it fails, its section says so and nothing else is left.
fn run_fresh(ctx: &Context, e: &Experiment) -> Result<Summary, AnyError> {
    let dir = ctx.out.join(e.name);
    if dir.exists() {
        std::fs::remove_dir_all(&dir)
            .map_err(|err| format!("cannot empty {}: {err}", dir.display()))?;
    }
    let outcome = (e.run)(ctx);
    if outcome.is_ok() {
        complete_section(ctx, e, &dir.join("section.md"))?;
    }
    outcome.inspect_err(|err| {
        let _ = std::fs::remove_dir_all(&dir);
        let section = format!(
            "{}**Failed at this revision**, nothing of this experiment was measured: {err}\n\n_{}_\n",
            ctx.regenerate(e.name),
            ctx.machine.one_line()
        );
        if let Err(write) = ctx.write_section(e.name, &section) {
            eprintln!("error: writing the section of {}: {write}", e.name);
        }
    })
}

fn main() -> ExitCode {
    environment::record_startup_environment();
    // A child of `mpi-in-process` times and exits before any parsing.
    if mpi_in_process::probe_if_asked() {
        return ExitCode::SUCCESS;
    }
    let cli = Cli::parse();
    if let (performance::NAME, Some(mesh)) = (cli.experiment.as_str(), &cli.memory_probe) {
        return exit(performance::memory_probe(mesh));
    }
    if cli.experiment == "viz-demo" {
        return exit(demo::viz_demo(&cli.demo_out));
    }
    let ctx = match context(&cli) {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    eprintln!("{}", ctx.machine.one_line());
    eprintln!("writing to {}", ctx.out.display());
    let started = Instant::now();
    let mut rows = Vec::new();
    let mut failed = false;
    for e in EXPERIMENTS {
        if cli.experiment != "all" && cli.experiment != e.name {
            continue;
        }
        let t = Instant::now();
        let (status, headline) = match run_fresh(&ctx, e) {
            Ok(s) if s.skipped => ("skipped".to_string(), s.headline),
            Ok(s) => ("ok".to_string(), s.headline),
            Err(err) => {
                failed = true;
                ("FAILED".to_string(), err.to_string())
            }
        };
        let seconds = t.elapsed().as_secs_f64();
        eprintln!("{}: {status} in {seconds:.1} s — {headline}", e.name);
        rows.push(vec![
            e.name.to_string(),
            status,
            format!("{seconds:.1}"),
            headline,
        ]);
    }
    if let Err(e) = assemble_readme(&ctx.out, &ctx.machine, EXPERIMENTS) {
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
