//! `lse-deform compare MESH -c CONSTRAINTS`: every formulation on every
//! back end against one reference, as a Markdown table (the library's
//! [`lse_deform::compare`] does the work).

use std::path::PathBuf;

use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use lse_deform::compare::{self, CompareOptions, CompareRow};
use lse_deform::error::ProblemError;
use lse_deform::formulation::Refine;
use lse_deform::options::DeformOptions;
use lse_deform::{Error, LaplacianKind, Method, QrKind, SpdKind};

use super::files::{check_distinct, mesh_and_constraints};
use super::{
    check_outputs, constraints_with_warnings, load, show_after_a_second, with_default, write_text,
};

/// Arguments of `compare`.
#[derive(Args)]
pub struct CompareArgs {
    /// Input mesh.
    mesh: PathBuf,
    /// Constraints file (JSON).
    #[arg(long, short = 'c')]
    constraints: PathBuf,
    /// Laplacian weights.
    #[arg(long, default_value_t = DeformOptions::default().laplacian)]
    laplacian: LaplacianKind,
    #[arg(long, value_delimiter = ',', help = with_default("Formulations to run (comma-separated)", listed(&CompareOptions::default().methods)))]
    methods: Option<Vec<Method>>,
    /// QR back ends for nullspace-qr (comma-separated; default all in this
    /// build).
    #[arg(long, value_delimiter = ',')]
    qr: Vec<QrKind>,
    /// Matrix factorisations: Cholesky back ends, for kkt the faer LDLT
    /// variants among them (comma-separated; default all in this build).
    /// `--spd` is the old name, still accepted.
    #[arg(long, visible_alias = "spd", value_delimiter = ',')]
    factor: Vec<SpdKind>,
    #[arg(long, value_delimiter = ',', help = with_default("Penalty weights to try (comma-separated)", listed(&CompareOptions::default().weights)))]
    weights: Option<Vec<f64>>,
    /// Refinement of every configuration (default: each formulation's own;
    /// the reference is always refined).
    #[arg(long)]
    refine: Option<Refine>,
    /// Solves per configuration (the median time is reported).
    #[arg(long, default_value_t = CompareOptions::default().repeat)]
    repeat: usize,
    /// Skip the condition estimates (they cost a few hundred solves each).
    #[arg(long)]
    no_condition: bool,
    /// Also write every report as a JSON array here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Memory budget of the run (reading the inputs and every
    /// precompute), as for `deform` (default: LSE_MEMORY_LIMIT when set,
    /// else the smallest of the system's limits).
    #[arg(long, value_parser = super::memory_budget)]
    memory_limit: Option<lse_deform::limits::MemoryBudget>,
    #[command(flatten)]
    held: super::HeldArgs,
}

impl CompareArgs {
    /// The library's options for these arguments.
    fn options(&self) -> Result<CompareOptions, Error> {
        let d = CompareOptions::default();
        Ok(CompareOptions {
            methods: self.methods.clone().unwrap_or(d.methods),
            qrs: (!self.qr.is_empty()).then(|| self.qr.clone()),
            spds: (!self.factor.is_empty())
                .then(|| self.factor.iter().map(|&k| k.into()).collect()),
            weights: self.weights.clone().unwrap_or(d.weights),
            refine: self.refine,
            repeat: self.repeat,
            condition: !self.no_condition,
            resources: self.held.resources(self.memory_limit.unwrap_or_default())?,
        })
    }
}

/// `a,b,c`: a list as the flag takes it.
fn listed<T: std::fmt::Display>(values: &[T]) -> String {
    values
        .iter()
        .map(T::to_string)
        .collect::<Vec<_>>()
        .join(",")
}

/// Runs `compare` and prints its table (and writes the rows as JSON).
pub(crate) fn compare(a: CompareArgs) -> Result<(), Error> {
    if let Some(json) = &a.json {
        let mut inputs = mesh_and_constraints(&a.mesh, &a.constraints).to_vec();
        inputs.extend(a.held.inputs());
        check_distinct(&inputs, &[("--json", json.as_path())])?;
    }
    check_outputs(None, a.json.as_deref())?;
    let options = a.options()?;
    // Fail before any work when the filters leave nothing to run.
    let configs = options
        .configurations()
        .map_err(|e| ProblemError::InvalidArgument {
            message: format!("--methods/--qr/--factor/--weights: {e}"),
        })?;
    let budget = options.resources.budget;
    let mesh = load(&a.mesh, budget)?;
    let (constraints, warnings) = constraints_with_warnings(&a.constraints, &mesh, false, budget)?;
    let mut deformer = compare::reference_deformer(mesh, a.laplacian, constraints, budget)?;
    let bar =
        ProgressBar::with_draw_target(Some(configs.len() as u64 + 1), ProgressDrawTarget::hidden());
    if let Ok(style) = ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} ({elapsed})") {
        bar.set_style(style);
    }
    show_after_a_second(&bar);
    bar.set_message("reference (nullspace-qr, refined)");
    let configs: Vec<compare::Configuration> = configs
        .into_iter()
        .map(compare::Configuration::new)
        .collect();
    // The bar moves on as each configuration starts (the reference, then
    // each row before it, is done) and once more at the end.
    let (reference, mut rows) =
        compare::compare_configurations(&mut deformer, &configs, &options, &mut |config| {
            bar.inc(1);
            bar.set_message(config.label.clone());
        })?;
    bar.inc(1);
    if let Some(e) = reference.forward_error_estimate.filter(|&e| e > 1e-12) {
        eprintln!(
            "warning: the reference solution (nullspace-qr, refined) has an estimated forward error of {e:.1e}: differences below it are not resolved"
        );
    }
    bar.finish_and_clear();
    print_compare_table(&rows);
    // The warnings of reading the inputs belong to every report.
    for report in rows.iter_mut().filter_map(|r| r.report.as_mut()) {
        report.warnings.splice(
            0..0,
            warnings.iter().map(|w| super::summary::mismatch_warning(w)),
        );
    }
    if let Some(path) = &a.json {
        let json = serde_json::to_string_pretty(&rows).map_err(|e| Error::io(path, e.into()))?;
        write_text(path, json)?;
    }
    Ok(())
}

/// The threads of a row, with the ranks of a back end on several
/// (`1 × 2 ranks`).
fn threads_cell(r: &CompareRow) -> String {
    let threads = r.threads.map_or("—".to_string(), |t| t.to_string());
    match r.ranks {
        Some(ranks) if ranks > 1 => format!("{threads} × {ranks} ranks"),
        _ => threads,
    }
}

/// The Markdown table of `compare` on stdout (status text in full).
fn print_compare_table(rows: &[CompareRow]) {
    out!(
        "| method | QR | SPD | weight | ordering | threads | precompute (s) | solve, median (ms) | refine (ms) | max ‖BX − D‖ (mesh units) | ΔX (× diagonal) | ΔE (relative) | forward error est. (× diagonal) | κ₂ est. of the factored matrix | status |"
    );
    out!("|---|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|");
    let opt = |v: Option<f64>, f: &dyn Fn(f64) -> String| v.map(f).unwrap_or_else(|| "—".into());
    for r in rows {
        out!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.method,
            r.qr.as_deref().unwrap_or("—"),
            r.spd,
            opt(r.weight, &|w| format!("{w:.0e}")),
            r.ordering.as_deref().unwrap_or("—"),
            threads_cell(r),
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
    if rows.iter().any(|r| r.condition.is_some()) {
        // Each method factors a different matrix: the estimates say how
        // hard each factorisation is, not which result is more accurate.
        out!(
            "\nκ₂ est.: nullspace-qr factors (AQ₂)ᵀ(AQ₂), penalty AᵀA + w²BᵀB, kkt the scaled KKT matrix, eliminate the normal matrix of the free columns; compare accuracy by ΔX and the forward error."
        );
    }
}
