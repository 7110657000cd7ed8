//! `lse-deform deform MESH -c CONSTRAINTS -o OUT`: the Laplacian
//! deformation (or ARAP iterations) of a mesh, with its report.

use std::path::PathBuf;

use clap::Args;
use lse_deform::arap::{ArapEnergy, ArapInit};
use lse_deform::choice::Energy;
use lse_deform::options::{ArapOptions, DeformOptions};
use lse_deform::report::{ArapReport, Report};
use lse_deform::request::{self, Given, Outcome, Request};
use lse_deform::{Error, LaplacianKind, mesh};

use super::files::{check_distinct, mesh_and_constraints};
use super::summary::{finish_report, write_report};
use super::{MethodArgs, check_outputs, constraints_with_warnings, load, phase, with_default};

/// Arguments of `deform`.
#[derive(Args)]
pub struct DeformArgs {
    /// Input mesh (.obj, .ply, .off, optionally .gz).
    mesh: PathBuf,
    /// Constraints file (JSON).
    #[arg(long, short = 'c')]
    constraints: PathBuf,
    #[arg(long, help = with_default("Laplacian weights: cotan, uniform, cotan-symmetric or intrinsic-delaunay (--energy laplacian; ARAP always uses cotangent weights)", DeformOptions::default().laplacian))]
    laplacian: Option<LaplacianKind>,
    /// Output mesh (.obj, .ply or .off; .gz after it compresses).
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
    #[arg(long, default_value_t = DeformOptions::default().energy)]
    energy: Energy,
    #[arg(long, help = with_default("ARAP energy: spokes (Sorkine & Alexa 2007) or spokes-and-rims (Chao et al. 2010, libigl's default)", ArapOptions::default().energy))]
    arap_energy: Option<ArapEnergy>,
    #[arg(long, help = with_default("ARAP: the most iterations to run", ArapOptions::default().iterations))]
    iterations: Option<usize>,
    #[arg(long, help = with_default("ARAP: stop when the relative energy decrease of an iteration is at most this (0: run all --iterations)", ArapOptions::default().tolerance))]
    tolerance: Option<f64>,
    #[arg(long, help = with_default("ARAP initial guess: linear (the linear gradient-domain solution; lower energy than rest at every iteration count measured on the Bunny, results/arap/README.md) or rest (rest pose, constrained vertices at their targets, as libigl's tutorials)", ArapOptions::default().init))]
    arap_init: Option<ArapInit>,
}

impl DeformArgs {
    /// The options of the run over [`DeformOptions::default`]
    /// ([`MethodArgs::options`], checked, and the energy, Laplacian and
    /// strictness).
    fn options(&self) -> Result<DeformOptions, Error> {
        let mut options = self.method.parse_checked()?;
        options.energy = self.energy.energy;
        options.laplacian = self.laplacian.unwrap_or(options.laplacian);
        options.strict = self.strict;
        Ok(options)
    }

    /// The library's request for these arguments, with which options were
    /// given.
    fn request(&self) -> Result<Request, Error> {
        let e = &self.energy;
        Ok(Request {
            options: self.options()?,
            arap: e.arap_options(),
            given: Given {
                laplacian: self.laplacian.is_some(),
                arap_energy: e.arap_energy.is_some(),
                iterations: e.iterations.is_some(),
                tolerance: e.tolerance.is_some(),
                arap_init: e.arap_init.is_some(),
                qr: self.method.qr.is_some(),
            },
            condition: self.condition,
        })
    }
}

impl EnergyArgs {
    /// The ARAP options these flags name over [`ArapOptions::default`].
    fn arap_options(&self) -> ArapOptions {
        let d = ArapOptions::default();
        ArapOptions {
            energy: self.arap_energy.unwrap_or(d.energy),
            iterations: self.iterations.unwrap_or(d.iterations),
            tolerance: self.tolerance.unwrap_or(d.tolerance),
            init: self.arap_init.unwrap_or(d.init),
        }
    }
}

/// Runs `deform`: Laplacian editing, or ARAP with `--energy arap`
/// ([`lse_deform::request::deform`] decides and runs).
pub(crate) fn deform(a: DeformArgs) -> Result<(), Error> {
    let mut outputs = vec![("-o", a.output.as_path())];
    outputs.extend(a.report.as_deref().map(|r| ("--report", r)));
    let mut inputs = mesh_and_constraints(&a.mesh, &a.constraints).to_vec();
    inputs.extend(a.method.held.inputs());
    check_distinct(&inputs, &outputs)?;
    check_outputs(Some(&a.output), a.report.as_deref())?;
    let budget = a.method.budget();
    let mesh = load(&a.mesh, budget)?;
    let (constraints, warnings) =
        constraints_with_warnings(&a.constraints, &mesh, a.strict, budget)?;
    let request = a.request()?;
    for i in request.inapplicable() {
        eprintln!("warning: {}", super::inapplicable_words(&i));
    }
    let bar = phase(&format!(
        "set-up, precompute ({}) and {}",
        request.options.solve.formulation.method,
        match request.options.energy {
            Energy::Arap => "ARAP iterations",
            Energy::Laplacian => "solve",
        }
    ));
    let outcome = request::deform(mesh, constraints, &request)?;
    bar.finish_and_clear();
    match &outcome.arap {
        Some(history) => finish_arap(&a, &outcome, history, &warnings),
        None => finish_linear(&a, &outcome, &warnings),
    }
}

/// What the summary line of a mesh calls the unknowns and the rows of `B`.
const NAMES: (&str, &str) = ("vertices", "constraints");

/// The Laplacian energy's outputs: a strict refusal (after the warnings and
/// the summary when a constraint conflicts), or the mesh and the report.
fn finish_linear(a: &DeformArgs, outcome: &Outcome, warnings: &[String]) -> Result<(), Error> {
    let report = &outcome.report;
    if let Err(e) = outcome.verdict() {
        if !report.conflicting.is_empty() {
            // The warnings and the summary line with its counts still go
            // to stderr; nothing is written.
            finish_report(report, warnings, None, NAMES, || Ok(()))?;
        }
        return Err(e);
    }
    let out = outcome.mesh.with_positions(outcome.positions.clone())?;
    finish_report(report, warnings, a.report.as_deref(), NAMES, || {
        let bar = phase(&format!("writing {}", a.output.display()));
        mesh::write_mesh(&out, &a.output)?;
        bar.finish_and_clear();
        Ok(())
    })
}

/// ARAP's outputs: its warnings and summary, a strict refusal, or the mesh
/// and the report.
fn finish_arap(
    a: &DeformArgs,
    outcome: &Outcome,
    history: &ArapReport,
    warnings: &[String],
) -> Result<(), Error> {
    let report = &outcome.report;
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    let summary = arap_summary(report, history);
    if let Err(e) = outcome.verdict() {
        eprintln!("{summary}");
        return Err(e);
    }
    let out = outcome.mesh.with_positions(outcome.positions.clone())?;
    // Staged together: a report that cannot be written leaves no mesh.
    super::staged(|| {
        mesh::write_mesh(&out, &a.output)?;
        match &a.report {
            Some(path) => write_report(report, warnings, path),
            None => Ok(()),
        }
    })?;
    eprintln!("{summary}");
    Ok(())
}

/// ARAP's one-line summary.
fn arap_summary(report: &Report, history: &ArapReport) -> String {
    format!(
        "{} + ARAP ({}, init {}): {} vertices, {} hard constraints ({} redundant, {} conflicting), max |BX - D| = {:.2e} mesh units ({:.1e} × diagonal); {} iterations ({}), energy {:.6e} -> {:.6e} mesh units²; precompute {:.3} s, {:.4} s per iteration (local {:.3} s, global {:.3} s in all)",
        report.method,
        history.energy,
        history.init,
        report.vertices,
        report.hard_constraints,
        report.redundant.len(),
        report.conflicting.len(),
        report.max_constraint_residual,
        report.max_constraint_residual_relative,
        history.iterations,
        history
            .stop_reason
            .map_or_else(|| "not run".to_string(), |s| s.to_string()),
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
    )
}

#[cfg(test)]
mod tests {
    use clap::Parser;
    use lse_deform::options::{ArapOptions, DeformOptions};

    use super::DeformArgs;

    #[derive(Parser)]
    struct Command {
        #[command(flatten)]
        deform: DeformArgs,
    }

    #[test]
    fn no_options_are_the_library_defaults() {
        let argv = ["deform", "m.obj", "-c", "c.json", "-o", "out.obj"];
        let a = Command::try_parse_from(argv).unwrap().deform;
        assert_eq!(a.options().unwrap(), DeformOptions::default());
        assert_eq!(a.energy.arap_options(), ArapOptions::default());
    }
}
