//! A back end from outside the crate, written against the public API only
//! (as another crate would): an iterative SPD back end, Jacobi-
//! preconditioned conjugate gradients under the name `jacobi-pcg`. It
//! passes the conformance kit, appears under its own name in a report and
//! in `compare`'s rows beside the built-ins, and runs the precompute
//! breakdown and a penalty weight sweep. docs/backends.md §9 walks through
//! it, docs/backends.md §10 through the calls.

use std::sync::Arc;

use faer::MatMut;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use lse_deform::backend::spd::{FaerLlt, SpdBackend, SpdFactor, SpdSymbolic};
use lse_deform::backend::{BackendFacts, BackendName};
use lse_deform::compare::{CompareOptions, Configuration, compare_configurations};
use lse_deform::error::{Error, NumericalError};
use lse_deform::formulation::{Chosen, FormulationChoice, PenaltySweep};
use lse_deform::scene::FixedAndHandle;
use lse_deform::testing::conformance::{self, KitConfig};
use lse_deform::testing::{random_surface, relative_difference};
use lse_deform::{Deformer, LaplacianKind, Method, QrKind, formulation::NullSpaceQr};

// ---------------------------------------------------------------------------
// The back end.

/// Jacobi-preconditioned conjugate gradients as an SPD back end.
///
/// - Analysis: nothing to order; the pattern is kept, to refuse a matrix
///   of another pattern.
/// - "Factorisation": the matrix is copied with the inverse of its
///   diagonal (the preconditioner). A diagonal entry that is not positive
///   (or not finite) is refused: the matrix is then not positive definite.
/// - Solve, column by column: conjugate gradients from `x = 0`, stopped
///   when the normwise backward error `‖b − A x‖∞ / (‖A‖∞ ‖x‖∞ + ‖b‖∞)`
///   of the true residual is at most `tolerance`; refused with a typed
///   error when `pᵀ A p ≤ 0` (not positive definite) or after
///   `max_iterations(n)` iterations without convergence. Never a
///   non-finite result.
#[derive(Clone, Copy, Debug)]
struct JacobiPcg {
    /// The largest normwise backward error accepted.
    tolerance: f64,
}

impl Default for JacobiPcg {
    /// `1e-14`: a few units of rounding on these sizes.
    fn default() -> Self {
        JacobiPcg { tolerance: 1e-14 }
    }
}

/// The name of the back end in every report and table.
const NAME: &str = "jacobi-pcg";

impl JacobiPcg {
    /// At most `10 n + 100` iterations per column: conjugate gradients
    /// ends in `n` steps in exact arithmetic; rounding may need more, and a
    /// matrix whose conditioning needs far more is refused.
    fn max_iterations(n: usize) -> usize {
        10 * n + 100
    }
}

impl SpdBackend for JacobiPcg {
    fn name(&self) -> BackendName {
        NAME.into()
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        Ok(Box::new(PcgSymbolic {
            settings: *self,
            col_ptr: lower.col_ptr().to_vec(),
            row_idx: lower.row_idx().to_vec(),
        }))
    }
}

/// The analysed pattern (lower triangle, CSC, sorted rows).
struct PcgSymbolic {
    settings: JacobiPcg,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
}

/// A typed error of this back end.
fn refusal(message: String) -> NumericalError {
    NumericalError::Backend {
        backend: NAME.into(),
        message,
    }
}

impl SpdSymbolic for PcgSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn SpdFactor>, NumericalError> {
        let pattern = lower.symbolic();
        if pattern.col_ptr() != self.col_ptr || pattern.row_idx() != self.row_idx {
            return Err(refusal(
                "the matrix does not have the analysed pattern".into(),
            ));
        }
        let mut inverse_diagonal = vec![0.0; lower.ncols()];
        for (j, inverse) in inverse_diagonal.iter_mut().enumerate() {
            // Sorted rows of the lower triangle: the diagonal comes first.
            let p = self.col_ptr[j];
            let d = if p < self.col_ptr[j + 1] && self.row_idx[p] == j {
                lower.val()[p]
            } else {
                0.0
            };
            if !(d > 0.0 && d.is_finite()) {
                return Err(NumericalError::NotPositiveDefinite {
                    matrix: String::new(),
                    unknown: j,
                    vertex: None,
                    pivot: Some(d),
                });
            }
            *inverse = 1.0 / d;
        }
        Ok(Box::new(PcgFactor {
            settings: self.settings,
            col_ptr: self.col_ptr.clone(),
            row_idx: self.row_idx.clone(),
            values: lower.val().to_vec(),
            inverse_diagonal,
        }))
    }

    /// What a factor stores in `f64` values: the matrix and the inverse
    /// diagonal.
    fn factor_nnz(&self) -> usize {
        self.row_idx.len() + self.col_ptr.len() - 1
    }
}

/// The matrix, ready to be solved with.
struct PcgFactor {
    settings: JacobiPcg,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
    inverse_diagonal: Vec<f64>,
}

/// `Σ aᵢ bᵢ`.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `max |aᵢ|`.
fn norm_inf(a: &[f64]) -> f64 {
    a.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// The state of conjugate gradients between iterations.
struct Cg {
    x: Vec<f64>,
    r: Vec<f64>,
    p: Vec<f64>,
    rz: f64,
}

impl PcgFactor {
    fn n(&self) -> usize {
        self.inverse_diagonal.len()
    }

    /// `A v` from the lower triangle.
    fn times(&self, v: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; v.len()];
        for j in 0..self.n() {
            for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                let (i, a) = (self.row_idx[p], self.values[p]);
                y[i] += a * v[j];
                if i != j {
                    y[j] += a * v[i];
                }
            }
        }
        y
    }

    /// `‖A‖∞`.
    fn norm(&self) -> f64 {
        let mut sums = vec![0.0f64; self.n()];
        for j in 0..self.n() {
            for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                let (i, a) = (self.row_idx[p], self.values[p].abs());
                sums[i] += a;
                if i != j {
                    sums[j] += a;
                }
            }
        }
        norm_inf(&sums)
    }

    /// Conjugate gradients started (or restarted) at `x`: `r = b − A x`,
    /// `p = M⁻¹ r`.
    fn start(&self, b: &[f64], x: Vec<f64>) -> Cg {
        let ax = self.times(&x);
        let r: Vec<f64> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
        let p: Vec<f64> = r
            .iter()
            .zip(&self.inverse_diagonal)
            .map(|(r, d)| r * d)
            .collect();
        let rz = dot(&r, &p);
        Cg { x, r, p, rz }
    }

    /// The normwise backward error of `x` with its true residual.
    fn backward_error(&self, b: &[f64], x: &[f64], norm: f64) -> f64 {
        let ax = self.times(x);
        let r: Vec<f64> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
        norm_inf(&r) / (norm * norm_inf(x) + norm_inf(b))
    }

    /// One iteration; `Err` on non-positive curvature.
    fn step(&self, cg: &mut Cg, iteration: usize) -> Result<(), NumericalError> {
        let q = self.times(&cg.p);
        let curvature = dot(&cg.p, &q);
        if !(curvature > 0.0 && curvature.is_finite()) {
            return Err(refusal(format!(
                "non-positive curvature pᵀAp = {curvature:e} at iteration {iteration}: the matrix is not positive definite"
            )));
        }
        let alpha = cg.rz / curvature;
        for ((x, r), (p, q)) in cg.x.iter_mut().zip(&mut cg.r).zip(cg.p.iter().zip(&q)) {
            *x += alpha * p;
            *r -= alpha * q;
        }
        let z: Vec<f64> =
            cg.r.iter()
                .zip(&self.inverse_diagonal)
                .map(|(r, d)| r * d)
                .collect();
        let rz = dot(&cg.r, &z);
        let beta = rz / cg.rz;
        for (p, z) in cg.p.iter_mut().zip(&z) {
            *p = z + beta * *p;
        }
        cg.rz = rz;
        Ok(())
    }

    /// Solves `A x = b` to the tolerance: the recurrence's residual says
    /// when to look, the true residual decides (and restarts the
    /// recurrence when it disagrees).
    fn solve_column(&self, b: &[f64], norm: f64) -> Result<Vec<f64>, NumericalError> {
        let tolerance = self.settings.tolerance;
        let mut cg = self.start(b, vec![0.0; b.len()]);
        let cap = JacobiPcg::max_iterations(self.n());
        let mut eta = self.backward_error(b, &cg.x, norm);
        for iteration in 0..cap {
            if eta <= tolerance || norm_inf(b) == 0.0 {
                return Ok(cg.x);
            }
            self.step(&mut cg, iteration)?;
            if norm_inf(&cg.r) <= tolerance * (norm * norm_inf(&cg.x) + norm_inf(b)) {
                eta = self.backward_error(b, &cg.x, norm);
                if eta > tolerance {
                    cg = self.start(b, cg.x);
                }
            }
        }
        Err(refusal(format!(
            "no convergence in {cap} iterations: the normwise backward error is {eta:e}, above {tolerance:e}"
        )))
    }
}

impl SpdFactor for PcgFactor {
    fn dim(&self) -> usize {
        self.n()
    }

    fn solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) -> Result<(), NumericalError> {
        let norm = self.norm();
        for c in 0..rhs.ncols() {
            let b: Vec<f64> = (0..self.n()).map(|i| rhs[(i, c)]).collect();
            if !b.iter().all(|v| v.is_finite()) {
                return Err(refusal(format!(
                    "column {c} of the right-hand side is not finite"
                )));
            }
            let x = self.solve_column(&b, norm)?;
            for (i, v) in x.into_iter().enumerate() {
                rhs[(i, c)] = v;
            }
        }
        Ok(())
    }

    /// The stored entries: the matrix's lower triangle.
    fn nnz(&self) -> usize {
        self.values.len()
    }

    fn bytes(&self) -> usize {
        8 * (self.values.len() + self.row_idx.len() + self.col_ptr.len() + self.n())
    }

    fn facts(&self) -> Option<BackendFacts> {
        Some(
            BackendFacts::new(NAME)
                .with("tolerance", self.settings.tolerance)
                .with("max_iterations", JacobiPcg::max_iterations(self.n())),
        )
    }
}

// ---------------------------------------------------------------------------
// It passes the kit.

/// 32 cases per property (`PROPTEST_CASES` overrides it), as
/// tests/conformance.rs runs the built-ins.
#[test]
fn the_pcg_back_end_passes_the_kit() {
    let report = conformance::assert_conforms(conformance::spd(
        Arc::new(JacobiPcg::default()),
        &KitConfig::with_cases(
            std::env::var("PROPTEST_CASES")
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(32),
        ),
    ));
    assert_eq!(report.backend, NAME);
}

// ---------------------------------------------------------------------------
// Under its own name, beside the built-ins.

/// A generated surface of 13 × 13 vertices with the paper's scene: the
/// bottom fifth fixed, a handle at the top moved.
fn scene() -> Deformer {
    let mesh = random_surface(12, 12, 36);
    let constraints = FixedAndHandle::paper_default(&mesh)
        .constraints(&mesh)
        .unwrap();
    Deformer::new(
        mesh,
        LaplacianKind::Cotangent,
        constraints,
        &lse_deform::SolveOptions::default(),
    )
    .unwrap()
}

#[test]
fn the_report_names_the_pcg_back_end_and_its_solution_is_the_defaults() {
    let mut d = scene();
    let pcg: Arc<dyn SpdBackend> = Arc::new(JacobiPcg::default());
    let qr = QrKind::SparseGivens.backend().unwrap();
    d.refactor_with(
        &NullSpaceQr::new(qr, pcg),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    let x = d.solve_matrix().unwrap();
    let report = serde_json::to_value(d.report()).unwrap();
    assert_eq!(report["factor_backend"], NAME);
    assert_eq!(report["qr_backend"], "sparse-givens");
    // Its own facts, in a section under its name.
    assert_eq!(report[NAME]["tolerance"], 1e-14);
    // The factor's size is what it stores: the lower triangle of the
    // reduced normal matrix (n − r unknowns, `normal` entries in full).
    let r = d.report();
    let dim = r.vertices - r.rank.unwrap();
    let normal = r.nnz.normal.unwrap();
    assert_eq!(r.nnz.factor, Some((normal + dim) / 2));
    d.refactor_with(
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    let reference = d.solve_matrix().unwrap();
    let diff = relative_difference(&x, &reference);
    assert!(diff < 1e-10, "{diff:e} from faer's Cholesky");
}

/// A configuration with the PCG back end.
fn own(method: Method, weight: Option<f64>, pcg: &Arc<dyn SpdBackend>) -> Configuration {
    Configuration::new(FormulationChoice {
        spd: Chosen::Own(Arc::clone(pcg)),
        weight,
        ..FormulationChoice::new(method)
    })
}

/// A configuration with the built-in back ends.
fn builtin(method: Method, weight: Option<f64>) -> Configuration {
    Configuration::new(FormulationChoice {
        weight,
        ..FormulationChoice::new(method)
    })
}

#[test]
fn compare_lists_the_pcg_back_end_beside_the_builtins() {
    let mut d = scene();
    let pcg: Arc<dyn SpdBackend> = Arc::new(JacobiPcg::default());
    let configs = [
        builtin(Method::NullSpaceQr, None),
        own(Method::NullSpaceQr, None, &pcg),
        builtin(Method::Penalty, Some(1e4)),
        own(Method::Penalty, Some(1e4), &pcg),
        builtin(Method::Eliminate, None),
        own(Method::Eliminate, None, &pcg),
    ];
    let options = CompareOptions {
        repeat: 1,
        ..CompareOptions::default()
    };
    let (_, rows) = compare_configurations(&mut d, &configs, &options, &mut |_| {}).unwrap();
    for row in &rows {
        println!(
            "{:40} {:12} ΔX {:9.2e} (estimate {:9.2e}) ΔE {:9.2e} κ {:9.2e} {}",
            row.label,
            row.spd,
            row.delta_x.unwrap_or(f64::NAN),
            row.forward_error_estimate.unwrap_or(f64::NAN),
            row.delta_e.unwrap_or(f64::NAN),
            row.condition.unwrap_or(f64::NAN),
            row.status
        );
    }
    assert_eq!(rows[1].label, "nullspace-qr sparse-givens/jacobi-pcg");
    for (builtin, own) in [
        (&rows[0], &rows[1]),
        (&rows[2], &rows[3]),
        (&rows[4], &rows[5]),
    ] {
        assert_eq!(builtin.spd, "faer-auto");
        assert_eq!(own.spd, NAME, "{}", own.label);
        assert!(own.label.contains(NAME), "{}", own.label);
        assert!(
            own.status.starts_with("ok"),
            "{}: {}",
            own.label,
            own.status
        );
        let report = own.report.as_ref().unwrap();
        assert_eq!(report.factor_backend.as_ref().unwrap().name(), NAME);
        // The same measurements as the built-in's, and the same answer
        // within the errors the two estimate for themselves.
        let (a, b) = (builtin.delta_x.unwrap(), own.delta_x.unwrap());
        let estimates =
            builtin.forward_error_estimate.unwrap() + own.forward_error_estimate.unwrap();
        assert!(
            (a - b).abs() <= 10.0 * estimates + 1e-13,
            "{}: ΔX {b:e} against {a:e}, estimates {estimates:e}",
            own.label
        );
        assert!(own.condition.is_some() && own.precompute_s.is_some());
    }
    assert!(rows[1].delta_x.unwrap() < 1e-10);
}

// ---------------------------------------------------------------------------
// The precompute breakdown and the weight sweep, from Rust.

#[test]
fn the_precompute_breakdown_with_the_pcg_back_end() {
    let mut d = scene();
    let pcg: Arc<dyn SpdBackend> = Arc::new(JacobiPcg::default());
    d.refactor_with(
        &NullSpaceQr::new(QrKind::SparseGivens.backend().unwrap(), pcg),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    d.solve_matrix().unwrap();
    let t = &d.report().timings_s;
    let phases = [
        ("qr", t.qr),
        ("preparation", t.preparation),
        ("normal matrix", t.normal_matrix),
        ("symbolic", t.symbolic),
        ("numeric", t.numeric),
    ];
    for (phase, seconds) in phases {
        println!("{phase:14} {:9.3} ms", seconds * 1e3);
        assert!(seconds.is_finite() && seconds >= 0.0, "{phase}: {seconds}");
    }
    let total: f64 = phases.iter().map(|(_, s)| s).sum();
    assert_eq!(t.precompute(), total);
    println!("{:14} {:9.3} ms (solve)", "", t.solve * 1e3);
}

#[test]
fn a_penalty_weight_sweep_with_the_pcg_back_end() {
    let d = scene();
    let problem = d.problem();
    let pcg = JacobiPcg::default();
    let sweep = PenaltySweep::new(problem, &pcg).unwrap();
    assert_eq!(sweep.backend(), NAME);
    let faer = PenaltySweep::new(problem, &FaerLlt::auto()).unwrap();
    let weights = [1e-2, 1.0, 1e2, 1e4, 1e8, 1e12];
    let (ours, theirs) = (sweep.run(problem, &weights), faer.run(problem, &weights));
    let mut residuals = Vec::new();
    for (p, q) in ours.iter().zip(&theirs) {
        match (&p.result, &q.result) {
            (Ok(a), Ok(b)) => {
                // Each within its estimated error of the penalty solution.
                let diff = relative_difference(&a.x, &b.x);
                let bound = 10.0 * (a.forward_error_estimate + b.forward_error_estimate) + 1e-13;
                println!(
                    "w = {:6.0e}: hard residual {:9.2e}, {diff:9.2e} from faer's (bound {bound:9.2e})",
                    p.weight, a.max_constraint_residual
                );
                assert!(diff <= bound, "w = {:e}: {diff:e} > {bound:e}", p.weight);
                residuals.push(a.max_constraint_residual);
            }
            // A weight it cannot solve is a typed refusal, never NaN.
            (Err(e), _) => {
                println!("w = {:6.0e}: {e}", p.weight);
                assert!(matches!(e, Error::Numerical(_)), "w = {:e}: {e}", p.weight);
            }
            (Ok(_), Err(e)) => println!("w = {:6.0e}: faer refuses: {e}", p.weight),
        }
    }
    // The moderate weights all solve, and there a larger weight holds the
    // hard rows more tightly (beyond, the residual is rounding).
    assert!(ours[..4].iter().all(|p| p.result.is_ok()));
    assert!(
        residuals[..4].windows(2).all(|w| w[1] < w[0]),
        "{residuals:?}"
    );
}
