//! The `lse-deform` command-line tool: parses the command line and
//! dispatches to the command modules of `cli/`.
//!
//! Exit codes: 0 success, 2 bad input (mesh, constraints, arguments) or
//! a problem refused as too large for the memory budget, 3 numerical
//! failure. Errors are one line on stderr; `--verbose` adds the
//! chain of causes.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

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
    Deform(cli::deform::DeformArgs),
    /// Write a generated mesh (no input file needed).
    Generate(cli::generate::GenerateArgs),
    /// Print counts, topology and triangle quality of a mesh.
    Info(cli::info::InfoArgs),
    /// Write a constraints file that fixes the bottom of a mesh and drags a
    /// handle at its top.
    Scene(cli::scene::SceneArgs),
    /// Write A, C, B, D, the factored matrix (Matrix Market) and meta.json.
    ExportSystem(cli::export::ExportArgs),
    /// Solve min ‖AX − C‖ s.t. BX = D for matrices in Matrix Market files
    /// (a directory as export-system writes it, or --a/--c/--b/--d).
    Solve(cli::solve::SolveArgs),
    /// Run every formulation on every back end on one problem and print a
    /// table (precompute, solve, constraint residual, condition).
    Compare(cli::compare::CompareArgs),
    /// Render a mesh, or a deformation of it over the original as a ghost,
    /// to PNG (displacement or difference colour maps, constraint groups).
    Render(cli::render::RenderArgs),
    /// Interactive editor in the browser: serves a local page to select
    /// fixed and handle regions and drag them (docs/editor.md §1).
    #[cfg(feature = "editor")]
    Edit(cli::edit::EditArgs),
}

fn main() -> ExitCode {
    // Before any thread allocates: under an address-space limit, one
    // malloc arena, so that the mapped size the memory budget checks is
    // what the process really holds (`limits::cap_allocator_arenas`).
    lse_deform::limits::cap_allocator_arenas();
    // A panic under memory pressure prints its message and skips the
    // backtrace it could not allocate, instead of waiting forever for the
    // backtrace lock (`cli::panics`); hooks installed later (MUMPS's
    // abort of every rank) chain to it.
    cli::panics::install();
    // A limit too tight for a thread's stack is a refusal, not the panic
    // of the first `thread::spawn` (the signal thread's, just below).
    if let Err(message) = cli::panics::can_start_a_thread() {
        eprintln!("error: {message}");
        return ExitCode::from(2);
    }
    // First, before any other thread starts: an interrupted run removes
    // its temporary files and out-of-core scratch directories.
    cli::signals::install();
    // rayon's pool, started now so that a limit too tight for its threads
    // is a refusal before any work, not a panic in the middle of it.
    if let Err(e) = lse_deform::resources::start_thread_pool() {
        eprintln!("error: {e}");
        return ExitCode::from(2);
    }
    // A malformed LSE_MEMORY_LIMIT is bad input, before anything is read
    // (the default budget of every command comes from it); under `mpirun`
    // every rank checks its own and all agree (a rank-1 mistake fails the
    // run on every rank), then every rank but 0 serves rank 0's MUMPS
    // commands until rank 0 ends the run, and exits with rank 0's code.
    let start = lse_deform::limits::MemoryBudget::from_environment()
        .map(|_| ())
        .map_err(|e| e.to_string());
    #[cfg(feature = "mumps")]
    let start = match lse_deform::backend::mumps::serve_if_worker(start) {
        lse_deform::backend::mumps::RankRole::Served(code) => return ExitCode::from(code),
        lse_deform::backend::mumps::RankRole::Lead(start) => start,
    };
    let code = run(start);
    // Every MUMPS object is dropped by now: the other ranks may go.
    #[cfg(feature = "mumps")]
    lse_deform::backend::mumps::end_ranks(code);
    ExitCode::from(code)
}

/// Parses the command line and runs the command (`start`: the start-up
/// check of the environment, every rank's under `mpirun`); the exit code.
fn run(start: Result<(), String>) -> u8 {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // Help and version print to stdout with code 0; errors to
            // stderr with code 2.
            let _ = e.print();
            return e.exit_code() as u8;
        }
    };
    if let Err(message) = start {
        eprintln!("error: {message}");
        return 2;
    }
    let result = match cli.command {
        Command::Deform(a) => cli::deform::deform(a),
        Command::Generate(a) => cli::generate::generate(a),
        Command::Info(a) => cli::info::info(a),
        Command::Scene(a) => cli::scene::scene(a),
        Command::ExportSystem(a) => cli::export::export_system(a),
        Command::Solve(a) => cli::solve::solve(a),
        Command::Compare(a) => cli::compare::compare(a),
        Command::Render(a) => return cli::render::main(a, cli.verbose),
        #[cfg(feature = "editor")]
        Command::Edit(a) => cli::edit::edit(a),
    };
    match result {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            if cli.verbose {
                let mut source = std::error::Error::source(&e);
                while let Some(s) = source {
                    eprintln!("  caused by: {s}");
                    source = s.source();
                }
            }
            e.exit_code() as u8
        }
    }
}
