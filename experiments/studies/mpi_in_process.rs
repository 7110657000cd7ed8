//! `mpi-in-process`: does starting MPI in the timing process change the
//! other back ends' timings? With MUMPS in the build, the experiments
//! program starts MPI (a singleton rank) before its first timing, so that
//! MPI's start-up is not timed as MUMPS's analysis; every faer, nalgebra
//! and CHOLMOD timing of that run then shares its process with an MPI
//! runtime (its progress thread, its pinned memory, its signal handlers).
//!
//! Measured side by side: this program runs itself as a child process
//! ([`probe_if_asked`]) that times the precompute of the paper's scene on
//! the faer and CHOLMOD back ends, once with MPI started first and once
//! without, alternately, for a few rounds. Both children are fresh
//! processes on the same mesh and the same back ends; the only difference
//! is `MPI_Init`. The table gives each back end's median over the rounds
//! and the ratio with / without.

use std::fmt::Write as _;
use std::path::Path;

use lse_deform::mesh::{read_mesh, write_mesh};
use lse_deform::scene::FixedAndHandle;
use serde::{Deserialize, Serialize};

use crate::harness::context::{AnyError, Context};
use crate::harness::environment;
use crate::harness::registry::{Experiment, Input, Summary};
use crate::harness::rows::{fmt_time, markdown_table, median};
use crate::harness::timing::{Terms, null_space_with_spd, setup_and_precompute, start_mpi};

/// The folder and command-line word of this experiment.
pub const NAME: &str = "mpi-in-process";

/// This study's entry in the list of experiments.
pub const EXPERIMENT: Experiment = Experiment {
    name: NAME,
    title: "MPI started in the timing process: the other back ends with and without it",
    inputs: &[Input::Meshes, Input::SuiteSparse, Input::Mumps],
    run,
};

/// The child's instructions: the mesh file to time (the environment
/// variable's value), whether to start MPI first, and how many
/// repetitions.
const PROBE_MESH: &str = "LSE_EXPERIMENTS_PROBE_MESH";
const PROBE_MPI: &str = "LSE_EXPERIMENTS_PROBE_MPI";
const PROBE_REPS: &str = "LSE_EXPERIMENTS_PROBE_REPS";

/// One child's medians, per back end.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Probe {
    mpi: bool,
    /// (back end, median precompute seconds, median numeric seconds).
    medians: Vec<(String, f64, f64)>,
}

/// The back ends timed: those of the build except MUMPS (whose own
/// timings need MPI) and the slow simplicial ones.
fn probed_backends() -> Vec<&'static str> {
    ["faer-auto", "faer-supernodal", "cholmod"]
        .into_iter()
        .filter(|name| {
            name.parse::<lse_deform::SpdKind>()
                .is_ok_and(|k| k.in_this_build())
        })
        .collect()
}

/// In a child started by [`run`]: times the precompute of the paper's
/// scene on `PROBE_MESH` (MPI started first when `PROBE_MPI=1`), prints
/// one JSON line and returns `true`; `false` in any other process.
pub fn probe_if_asked() -> bool {
    let Ok(mesh_path) = std::env::var(PROBE_MESH) else {
        return false;
    };
    let mpi = std::env::var(PROBE_MPI).is_ok_and(|v| v == "1");
    let reps: usize = std::env::var(PROBE_REPS)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    match probe(Path::new(&mesh_path), mpi, reps) {
        Ok(p) => println!("{}", serde_json::to_string(&p).unwrap_or_default()),
        Err(e) => eprintln!("probe failed: {e}"),
    }
    true
}

fn probe(mesh_path: &Path, mpi: bool, reps: usize) -> Result<Probe, AnyError> {
    if mpi {
        start_mpi();
    }
    let mesh = read_mesh(mesh_path, lse_deform::limits::MemoryBudget::default())?.mesh;
    let constraints = FixedAndHandle::paper_default(&mesh).constraints(&mesh)?;
    let mut medians = Vec::new();
    for name in probed_backends() {
        let f = null_space_with_spd(name)?;
        let (mut pre, mut numeric) = (Vec::new(), Vec::new());
        for _ in 0..reps.max(1) {
            let d = setup_and_precompute(&mesh, &constraints, &f, &Terms::Own.resources())?;
            pre.push(d.report().timings_s.precompute());
            numeric.push(d.report().timings_s.numeric);
        }
        medians.push((name.to_string(), median(&pre), median(&numeric)));
    }
    Ok(Probe { mpi, medians })
}

/// One child: this program with the probe's environment.
fn run_child(mesh: &Path, mpi: bool, reps: usize) -> Result<Probe, AnyError> {
    let exe = std::env::current_exe()?;
    let out = environment::child(exe)
        .env(PROBE_MESH, mesh)
        .env(PROBE_MPI, if mpi { "1" } else { "0" })
        .env(PROBE_REPS, reps.to_string())
        .output()?;
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text.lines().last().unwrap_or_default();
    serde_json::from_str(line).map_err(|e| {
        format!(
            "the probe child printed no result ({e}): {}",
            String::from_utf8_lossy(&out.stderr).trim()
        )
        .into()
    })
}

/// One table row: back end, median without, median with, ratio.
#[derive(Debug, Clone, Serialize)]
struct Row {
    backend: String,
    without_mpi_s: f64,
    with_mpi_s: f64,
    ratio: f64,
    numeric_without_s: f64,
    numeric_with_s: f64,
    rounds: usize,
}

/// The rows from the children's probes (alternating without, with).
fn rows_of(probes: &[Probe]) -> Vec<Row> {
    let column = |backend: &str, mpi: bool, pick: fn(&(String, f64, f64)) -> f64| -> Vec<f64> {
        probes
            .iter()
            .filter(|p| p.mpi == mpi)
            .filter_map(|p| p.medians.iter().find(|m| m.0 == backend).map(pick))
            .collect()
    };
    probed_backends()
        .into_iter()
        .filter_map(|b| {
            let without = column(b, false, |m| m.1);
            let with = column(b, true, |m| m.1);
            if without.is_empty() || with.is_empty() {
                return None;
            }
            let (a, c) = (median(&without), median(&with));
            Some(Row {
                backend: b.to_string(),
                without_mpi_s: a,
                with_mpi_s: c,
                ratio: c / a,
                numeric_without_s: median(&column(b, false, |m| m.2)),
                numeric_with_s: median(&column(b, true, |m| m.2)),
                rounds: without.len().min(with.len()),
            })
        })
        .collect()
}

fn section(ctx: &Context, mesh: &str, reps: usize, rows: &[Row]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Whether an MPI runtime started in the timing process (as the experiments program does when MUMPS is in the build, docs/distributed.md) \
         changes the other back ends' timings. This program runs itself as two kinds of child process on {mesh} (the paper's scene, null-space method, \
         each back end's own ordering and threads): one starts MPI (a singleton rank) before timing, the other does not. They run alternately, \
         {} rounds of {reps} precomputes each; each cell is the median over the rounds of each child's median.\n",
        rows.first().map_or(0, |r| r.rounds)
    );
    s.push_str(&ctx.regenerate(NAME));
    let header = [
        "SPD back end",
        "precompute without MPI",
        "precompute with MPI",
        "with / without",
        "numeric without",
        "numeric with",
    ];
    let table: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.backend.clone(),
                fmt_time(r.without_mpi_s),
                fmt_time(r.with_mpi_s),
                format!("{:.2}", r.ratio),
                fmt_time(r.numeric_without_s),
                fmt_time(r.numeric_with_s),
            ]
        })
        .collect();
    s.push_str(&markdown_table(&header, &table));
    s.push_str(&ctx.closing(&[], &format!("Data: [`{NAME}/mpi.json`]({NAME}/mpi.json).")));
    s
}

/// The mesh of the probe: the largest evaluation mesh of at most 60k
/// vertices (the paper's sizes, where a run takes seconds).
fn probe_mesh(ctx: &Context) -> Result<(String, lse_deform::Mesh), AnyError> {
    let meshes = ctx.evaluation_meshes()?;
    let case = meshes
        .iter()
        .filter(|c| c.mesh.n_vertices() <= 60_000)
        .max_by_key(|c| c.mesh.n_vertices())
        .or(meshes.first())
        .ok_or("no evaluation mesh")?;
    Ok((
        format!("{} ({} vertices)", case.name, case.mesh.n_vertices()),
        case.mesh.clone(),
    ))
}

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    if !cfg!(feature = "mumps") {
        return Ok(Summary::skipped(
            "MUMPS is not in this build: no MPI is started in the timing process, so there is nothing to compare".into(),
        ));
    }
    let dir = ctx.dir(NAME)?;
    let (label, mesh) = probe_mesh(ctx)?;
    let file = std::env::temp_dir().join(format!("lse-{NAME}-{}.obj", std::process::id()));
    write_mesh(&mesh, &file)?;
    let (rounds, reps) = if ctx.quick { (1, 1) } else { (4, 3) };
    let bar = ctx.bar(2 * rounds, NAME);
    let mut probes = Vec::new();
    let mut failure = None;
    for _ in 0..rounds {
        for mpi in [false, true] {
            match run_child(&file, mpi, reps) {
                Ok(p) => probes.push(p),
                Err(e) => failure = Some(e.to_string()),
            }
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    let _ = std::fs::remove_file(&file);
    let rows = rows_of(&probes);
    if rows.is_empty() {
        return Err(failure
            .unwrap_or_else(|| "no probe gave a result".into())
            .into());
    }
    ctx.write_json(&dir.join("mpi.json"), &rows)?;
    ctx.write_section(NAME, &section(ctx, &label, reps, &rows))?;
    let worst = rows.iter().map(|r| r.ratio).fold(f64::NAN, f64::max);
    Ok(Summary::measured(format!(
        "precompute with MPI in the process / without: {} (worst {worst:.2})",
        rows.iter()
            .map(|r| format!("{} {:.2}", r.backend, r.ratio))
            .collect::<Vec<_>>()
            .join(", ")
    )))
}
