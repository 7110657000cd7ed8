//! `compare`: every chosen formulation on every back end that fits, on one
//! mesh problem, each measured against one reference solution (the paper's
//! method with its default back ends, refined to convergence). The CLI's
//! `compare` prints the rows as a table; library and Python callers get
//! them as values.
//!
//! Metrics against the reference `X*` (both in the problem's units):
//! `ΔX = max_i ‖X_i − X*_i‖₂ / length scale` and the relative excess of the
//! energy `E = ‖AX − C‖²`, `ΔE = (E − E*) / E*` (`E` itself when `E* = 0`).

use faer::Mat;
use serde::Serialize;

use crate::backend::BackendName;
use crate::backend::qr::QrKind;
use crate::backend::spd::SpdKind;
use crate::choice::Method;
use crate::constraints::ConstraintSet;
use crate::deform::Deformer;
use crate::error::{Error, ProblemError};
use crate::formulation::{FormulationChoice, Kkt, NullSpaceQr, SpdChoice};
use crate::laplacian::LaplacianKind;
use crate::limits::MemoryBudget;
use crate::mesh::Mesh;
use crate::refinement_types::Refine;
use crate::resources::Resources;

/// What to compare.
#[derive(Debug, Clone, PartialEq)]
pub struct CompareOptions {
    /// Formulations, in table order.
    pub methods: Vec<Method>,
    /// QR back ends for the null-space method (`None`: all of this build).
    pub qrs: Option<Vec<QrKind>>,
    /// SPD back ends, built-in or brought from outside (`None`: every
    /// built-in of this build except `FaerAuto`, which is one of the two
    /// explicit faer variants). An outside back end runs every method but
    /// KKT, which needs an `LDLᵀ` back end (run KKT with an outside one
    /// through [`compare_configurations`]).
    pub spds: Option<Vec<SpdChoice>>,
    /// Penalty weights, one configuration each.
    pub weights: Vec<f64>,
    /// Refinement of every configuration (`None`: each formulation's own).
    pub refine: Option<Refine>,
    /// Solves per configuration (the median time is reported).
    pub repeat: usize,
    /// Estimate the condition number of every factored matrix.
    pub condition: bool,
    /// The memory budget, threads and ordering of every configuration
    /// (held equal across them; the reference is computed within the same
    /// budget, on its back ends' own threads and ordering).
    pub resources: Resources,
}

impl Default for CompareOptions {
    fn default() -> Self {
        CompareOptions {
            methods: Method::ALL.to_vec(),
            qrs: None,
            spds: None,
            weights: vec![1e4, 1e8, 1e12],
            refine: None,
            repeat: 5,
            condition: true,
            resources: Resources::default(),
        }
    }
}

impl CompareOptions {
    /// Every configuration the options allow, in table order: the
    /// null-space method on every QR × SPD pair, the penalty method for
    /// every weight × SPD, KKT on the built-in SPD kinds that select an
    /// `LDLᵀ` variant ([`Kkt::for_spd`]), elimination on every SPD back end.
    ///
    /// Errors: [`ProblemError::InvalidArgument`] when nothing is left.
    pub fn configurations(&self) -> Result<Vec<FormulationChoice>, ProblemError> {
        let qrs = self.qrs.clone().unwrap_or_else(QrKind::available);
        let spds: Vec<SpdChoice> = self.spds.clone().unwrap_or_else(|| {
            SpdKind::available()
                .into_iter()
                .filter(|&k| k != SpdKind::FaerAuto)
                .map(SpdChoice::from)
                .collect()
        });
        let mut configs = Vec::new();
        for &method in &self.methods {
            let with = |spd: &SpdChoice| FormulationChoice {
                spd: spd.clone(),
                ..FormulationChoice::new(method)
            };
            match method {
                Method::NullSpaceQr => {
                    for &qr in &qrs {
                        configs.extend(spds.iter().map(|s| FormulationChoice {
                            qr: qr.into(),
                            ..with(s)
                        }));
                    }
                }
                Method::Penalty => {
                    for &w in &self.weights {
                        configs.extend(spds.iter().map(|s| FormulationChoice {
                            weight: Some(w),
                            ..with(s)
                        }));
                    }
                }
                Method::Kkt => configs.extend(
                    spds.iter()
                        .filter(|s| s.builtin().and_then(Kkt::for_spd).is_some())
                        .map(with),
                ),
                Method::Eliminate => configs.extend(spds.iter().map(with)),
            }
        }
        if configs.is_empty() {
            return Err(ProblemError::InvalidArgument {
                message: "the methods, back ends and weights chosen leave no configuration to run"
                    .into(),
            });
        }
        Ok(configs)
    }
}

/// The reference of a comparison: `X*` (in the problem's units) and its
/// energy `E* = ‖AX* − C‖²`.
#[derive(Debug, Clone)]
pub struct Reference {
    /// The solution.
    pub x: Mat<f64>,
    /// Its energy.
    pub energy: f64,
    /// Its estimated forward error (relative to the length scale).
    pub forward_error_estimate: Option<f64>,
}

/// The deformer of a comparison, factored for its reference: the
/// null-space method with its default back ends, refined until it
/// converges, within `budget`. [`compare`] and [`compare_configurations`]
/// take it, solve the reference first and then refactor it row by row.
pub fn reference_deformer(
    mesh: Mesh,
    laplacian: LaplacianKind,
    constraints: ConstraintSet,
    budget: MemoryBudget,
) -> Result<Deformer, Error> {
    let resources = Resources::with_budget(budget);
    let formulation = NullSpaceQr::default();
    let mut d = Deformer::with_formulation(mesh, laplacian, constraints, &formulation, &resources)?;
    d.solver_mut().set_refine(Some(Refine::Auto));
    Ok(d)
}

/// Solves the reference with `deformer` as [`reference_deformer`]
/// factored it.
pub fn reference(deformer: &mut Deformer) -> Result<Reference, Error> {
    let x = deformer.solve_matrix()?;
    let r = deformer.report();
    Ok(Reference {
        x,
        energy: r.least_squares_residual.powi(2),
        forward_error_estimate: r.forward_error_estimate,
    })
}

/// `ΔX = max_i ‖X_i − X*_i‖₂ / scale` over the rows (scale: the length
/// scale; a non-positive scale counts as the smallest positive double).
pub(crate) fn delta_x(x: &Mat<f64>, reference: &Mat<f64>, scale: f64) -> f64 {
    let worst = (0..x.nrows())
        .map(|i| {
            (0..x.ncols())
                .map(|c| (x[(i, c)] - reference[(i, c)]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max);
    worst / scale.max(f64::MIN_POSITIVE)
}

/// `ΔE = (E − E*) / E*`, or `E` when `E* = 0`.
pub(crate) fn delta_e(energy: f64, reference: f64) -> f64 {
    if reference > 0.0 {
        (energy - reference) / reference
    } else {
        energy
    }
}

/// A configuration to compare, with the label its row carries: any
/// [`FormulationChoice`], built-in back ends or a researcher's own
/// ([`crate::formulation::Chosen::Own`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Configuration {
    /// The row's label (by default [`FormulationChoice::label`]).
    pub label: String,
    /// What to run.
    pub choice: FormulationChoice,
}

impl Configuration {
    /// `choice` under its default label.
    pub fn new(choice: FormulationChoice) -> Configuration {
        Configuration {
            label: choice.label(),
            choice,
        }
    }

    /// `choice` under `label`.
    pub fn labelled(label: impl Into<String>, choice: FormulationChoice) -> Configuration {
        Configuration {
            label: label.into(),
            choice,
        }
    }
}

/// One configuration's result.
#[derive(Debug, Clone, Serialize)]
pub struct CompareRow {
    /// The configuration's label.
    pub label: String,
    /// The formulation.
    pub method: Method,
    /// The QR back end's name (null-space method only).
    pub qr: Option<BackendName>,
    /// The SPD back end's name (KKT: the SPD kind that selects its `LDLᵀ`
    /// variant, or the `LDLᵀ` back end's name when one was given).
    pub spd: BackendName,
    /// The penalty weight.
    pub weight: Option<f64>,
    /// The fill-reducing ordering the factorisation used (the report's
    /// `ordering`).
    pub ordering: Option<String>,
    /// The threads it ran on (the report's `threads`).
    pub threads: Option<usize>,
    /// MPI ranks, for a back end that runs on several (MUMPS: its report
    /// section's `ranks`).
    pub ranks: Option<usize>,
    /// `ok`, `ok, warning: …` or `error (input|numerical): …`.
    pub status: String,
    /// Seconds of precompute.
    pub precompute_s: Option<f64>,
    /// Median seconds of one solve.
    pub solve_median_s: Option<f64>,
    /// Seconds of refinement of the last solve.
    pub refine_s: Option<f64>,
    /// `max ‖b_k X − d_k‖₂` over the kept hard constraints.
    pub max_constraint_residual: Option<f64>,
    /// `max_i ‖X_i − X*_i‖ / bbox diagonal` against the reference.
    pub delta_x: Option<f64>,
    /// `(E − E*) / E*` with `E = ‖AX − C‖²`, against the reference.
    pub delta_e: Option<f64>,
    /// The estimated forward error of the solution.
    pub forward_error_estimate: Option<f64>,
    /// The estimated condition number of the factored matrix.
    pub condition: Option<f64>,
    /// The full report.
    pub report: Option<crate::Report>,
}

impl CompareRow {
    /// An empty row for `config`.
    fn new(config: &Configuration) -> CompareRow {
        let choice = &config.choice;
        let spd = match (&choice.method, &choice.ldlt) {
            (Method::Kkt, Some(ldlt)) => ldlt.name(),
            _ => choice.spd.name(),
        };
        CompareRow {
            label: config.label.clone(),
            method: choice.method,
            qr: (choice.method == Method::NullSpaceQr).then(|| choice.qr.name()),
            spd,
            weight: choice.weight,
            ordering: None,
            threads: None,
            ranks: None,
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
        }
    }
}

/// Runs `config` on `deformer`'s problem and measures it against
/// `reference`. An error of the configuration (a breakdown, a refused
/// constraint kind) is its row's status, not an error of the comparison.
pub(crate) fn run_one(
    deformer: &mut Deformer,
    config: &Configuration,
    options: &CompareOptions,
    reference: &Reference,
) -> CompareRow {
    let mut row = CompareRow::new(config);
    match measure(deformer, config, options, reference, &mut row) {
        Err(e) => {
            let class = if e.is_input_error() {
                "input"
            } else {
                "numerical"
            };
            row.status = format!("error ({class}): {e}");
        }
        Ok(()) => {
            if let Some(r) = &row.report
                && !r.warnings.is_empty()
            {
                row.status = format!(
                    "ok, warning: {}",
                    r.warnings
                        .iter()
                        .map(|w| w.message.as_str())
                        .collect::<Vec<_>>()
                        .join("; ")
                );
            }
        }
    }
    row
}

/// The measurements of [`run_one`].
fn measure(
    deformer: &mut Deformer,
    config: &Configuration,
    options: &CompareOptions,
    reference: &Reference,
    row: &mut CompareRow,
) -> Result<(), Error> {
    let f = config.choice.build()?;
    deformer.solver_mut().set_refine(options.refine);
    deformer.refactor_with(f.as_ref(), &options.resources)?;
    let mut times = Vec::new();
    let mut x = Mat::<f64>::zeros(0, 0);
    for _ in 0..options.repeat.max(1) {
        crate::interrupt::check()?;
        x = deformer.solve_matrix()?;
        times.push(deformer.report().timings_s.solve);
    }
    times.sort_by(f64::total_cmp);
    row.solve_median_s = Some(times[times.len() / 2]);
    if options.condition {
        row.condition = Some(deformer.solver_mut().estimate_condition()?.value);
    }
    let r = deformer.report().clone();
    // X and the reference are in the problem's units (solve_matrix).
    row.delta_x = Some(delta_x(&x, &reference.x, deformer.problem().length_scale()));
    row.delta_e = Some(delta_e(r.least_squares_residual.powi(2), reference.energy));
    row.precompute_s = Some(r.timings_s.precompute());
    row.refine_s = Some(r.timings_s.refine);
    row.max_constraint_residual = Some(r.max_constraint_residual);
    row.forward_error_estimate = r.forward_error_estimate;
    row.ordering = r.ordering.clone();
    row.threads = r.threads;
    row.ranks = r
        .backend_facts
        .as_ref()
        .and_then(|f| f.get("ranks"))
        .and_then(|v| v.as_u64())
        .map(|v| v as usize);
    row.report = Some(r);
    Ok(())
}

/// Every configuration of `options` on `deformer`'s problem (a
/// [`reference_deformer`]), after the reference; `progress` is told each configuration before it runs.
pub fn compare(
    deformer: &mut Deformer,
    options: &CompareOptions,
    progress: &mut dyn FnMut(&Configuration),
) -> Result<(Reference, Vec<CompareRow>), Error> {
    let configs: Vec<Configuration> = options
        .configurations()?
        .into_iter()
        .map(Configuration::new)
        .collect();
    compare_configurations(deformer, &configs, options, progress)
}

/// `configs`, built-in or not, on `deformer`'s problem (a
/// [`reference_deformer`]) after the reference, each measured as [`compare`] measures the built-ins (the
/// same reference, ΔX, ΔE, phase timings, condition estimate, weights and
/// refinement from `options`; `options`' lists of methods, back ends and
/// weights are not used). `progress` is told each configuration before it
/// runs.
///
/// Errors: [`ProblemError::InvalidArgument`] for an empty list or a given
/// ordering that is not a permutation of the problem's unknowns; the
/// reference's errors; an interruption. A configuration's own failure is
/// its row's status.
pub fn compare_configurations(
    deformer: &mut Deformer,
    configs: &[Configuration],
    options: &CompareOptions,
    progress: &mut dyn FnMut(&Configuration),
) -> Result<(Reference, Vec<CompareRow>), Error> {
    if configs.is_empty() {
        return Err(ProblemError::InvalidArgument {
            message: "no configuration to compare".into(),
        }
        .into());
    }
    // An ordering of the wrong unknowns is the comparison's input error
    // (as for deform), not every row's.
    options
        .resources
        .ordering
        .check_unknowns(deformer.problem().n())?;
    let reference = reference(deformer)?;
    let mut rows = Vec::with_capacity(configs.len());
    for config in configs {
        // An interruption is no configuration's failure: it ends the
        // comparison (a row that recorded one is not kept).
        crate::interrupt::check()?;
        progress(config);
        let row = run_one(deformer, config, options, &reference);
        crate::interrupt::check()?;
        rows.push(row);
    }
    Ok((reference, rows))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kkt_runs_only_on_the_faer_variants_and_empty_choices_are_refused() {
        let options = CompareOptions {
            methods: vec![Method::Kkt],
            spds: Some(vec![
                SpdKind::Nalgebra.into(),
                SpdKind::FaerSimplicial.into(),
            ]),
            ..CompareOptions::default()
        };
        let configs = options.configurations().unwrap();
        assert_eq!(configs.len(), 1);
        assert_eq!(configs[0].spd, SpdKind::FaerSimplicial);
        let none = CompareOptions {
            methods: vec![Method::Kkt],
            spds: Some(vec![SpdKind::Nalgebra.into()]),
            ..CompareOptions::default()
        };
        assert!(none.configurations().is_err());
    }

    #[test]
    fn metrics_measure_the_worst_vertex_and_the_relative_energy() {
        let r = Mat::<f64>::zeros(2, 3);
        let mut x = Mat::<f64>::zeros(2, 3);
        x[(1, 0)] = 3.0;
        x[(1, 1)] = 4.0;
        x[(0, 2)] = 1.0;
        assert_eq!(delta_x(&x, &r, 10.0), 0.5);
        assert_eq!(delta_e(3.0, 2.0), 0.5);
        assert_eq!(delta_e(3.0, 0.0), 3.0);
    }
}
