//! The kit of the `LDLᵀ` seam: [`ldlt`], its KKT cases, its checks
//! through KKT and at the matrix level, and its back end with a trap.

use std::sync::Arc;

use faer::MatMut;
use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMatRef, Triplet};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::backend::ldlt::{LdltBackend, LdltFactor, LdltSymbolic, PivotFault, PivotRule};
use crate::backend::{BackendFacts, BackendName, FactorKind};
use crate::error::{Error, NumericalError, ProblemError};
use crate::formulation::{Formulation, KKT_PIVOT_TOLERANCE, Kkt};
use crate::laplacian::LaplacianKind;
use crate::limits::MemoryBudget;
use crate::testing::ConstraintMix;

use super::common::{budget_answers, check_solve, ensure};
use super::kit::{Kit, KitConfig, KitFailure, KitReport, Property, Seam, quarter};
use super::method::{
    Phase, Trap, exactness, factored, interruption, method_budget, method_columns, named, oracle,
};
use super::strategies::{GridCase, grid_lower, grids, mixes};

// ---------------------------------------------------------------------------
// The call.

/// Runs the kit on an `LDLᵀ` back end: [`Property::Named`],
/// [`Property::Exactness`] and [`Property::Oracle`] through KKT (on
/// independent constraints), [`Property::Refusal`] (a dependent
/// constraint), [`Property::SeveralFactors`], [`Property::Budget`],
/// [`Property::Interruption`], [`Property::Columns`].
///
/// Errors: every failing property with its minimal case ([`KitFailure`]).
pub fn ldlt(backend: Arc<dyn LdltBackend>, config: &KitConfig) -> Result<KitReport, KitFailure> {
    let mut kit = Kit::new(Seam::Ldlt, backend.name(), config);
    let cases = kit.cases();
    let method = || Kkt::with_backend(Arc::clone(&backend));
    kit.fixed(Property::Named, || {
        let expected = FactorKind::Ldlt(backend.name());
        named(&backend.name(), &backend.name(), &method(), |r| {
            r.factor_backend == Some(expected.clone())
        })
    });
    kit.generated(
        Property::Exactness,
        cases,
        independent_mixes(),
        |(mix, kind)| exactness(&method(), &mix, kind),
    );
    kit.generated(
        Property::Oracle,
        cases,
        independent_mixes(),
        |(mix, kind)| oracle(&method(), &mix, kind),
    );
    kit.generated(Property::Refusal, cases, kkt_cases(true), |case| {
        ldlt_refusal(&*backend, &case)
    });
    kit.generated(
        Property::Refusal,
        cases,
        dependent_mixes(),
        |(mix, kind)| kkt_refusal(&method(), &mix, kind),
    );
    kit.generated(Property::SeveralFactors, cases, kkt_cases(false), |case| {
        ldlt_several(&*backend, &case)
    });
    kit.generated(Property::Budget, cases, kkt_cases(false), |case| {
        ldlt_budget(&*backend, &case)
    });
    kit.generated(
        Property::Budget,
        cases,
        independent_mixes(),
        |(mix, kind)| method_budget(&method(), &mix, kind),
    );
    kit.generated(
        Property::Interruption,
        quarter(cases),
        independent_mixes(),
        |(mix, kind)| {
            let trap = Arc::new(Trap::default());
            let spy: Arc<dyn LdltBackend> = Arc::new(SpyLdlt {
                inner: Arc::clone(&backend),
                trap: Arc::clone(&trap),
            });
            interruption(&Kkt::with_backend(spy), &trap, &mix, kind, true)
        },
    );
    kit.generated(Property::Columns, cases, kkt_cases(false), |case| {
        ldlt_columns(&*backend, &case)
    });
    kit.generated(
        Property::Columns,
        cases,
        independent_mixes(),
        |(mix, kind)| method_columns(&method(), &mix, kind),
    );
    kit.finish()
}

// ---------------------------------------------------------------------------
// Cases.

/// [`constraint_mixes`] without their dependent constraints (what KKT
/// accepts).
///
/// [`constraint_mixes`]: crate::testing::constraint_mixes
fn independent_mixes() -> impl Strategy<Value = (ConstraintMix, LaplacianKind)> {
    mixes().prop_map(|(mix, kind)| (without_dependent(mix), kind))
}

/// [`constraint_mixes`] with at least one dependent constraint.
///
/// [`constraint_mixes`]: crate::testing::constraint_mixes
fn dependent_mixes() -> impl Strategy<Value = (ConstraintMix, LaplacianKind)> {
    mixes().prop_filter("a dependent constraint", |(mix, _)| {
        !(mix.redundant.is_empty() && mix.conflicting.is_empty())
    })
}

/// `mix` without its redundant and conflicting constraints.
fn without_dependent(mix: ConstraintMix) -> ConstraintMix {
    let dependent = |i: &usize| mix.redundant.contains(i) || mix.conflicting.contains(i);
    let constraints = (0..mix.constraints.len())
        .filter(|i| !dependent(i))
        .map(|i| mix.constraints[i].clone())
        .collect();
    ConstraintMix {
        constraints,
        redundant: Vec::new(),
        conflicting: Vec::new(),
        ..mix
    }
}

/// A KKT-like matrix `[M sBᵀ; sB 0]`: `M` a grid matrix, `B` rows each
/// with a pivot unknown no earlier row touches (independent), `s` a power
/// of two near `M`'s largest diagonal entry.
#[derive(Clone, Debug)]
pub struct KktCase {
    /// The grid of `M`.
    pub grid: GridCase,
    /// Rows of `B`, before the duplicate.
    pub rows: usize,
    /// The seed of `B`.
    pub b_seed: u64,
    /// Whether twice the first row is appended (dependent).
    pub duplicate: bool,
}

fn kkt_cases(duplicate: bool) -> impl Strategy<Value = KktCase> {
    (grids(), 1usize..6, any::<u64>()).prop_map(move |(grid, rows, b_seed)| KktCase {
        rows: rows.min(grid.side * grid.side - 1).max(1),
        grid,
        b_seed,
        duplicate,
    })
}

/// The rows of `B` of `case`, as `(unknown, coefficient)` lists.
fn kkt_rows(case: &KktCase, n: usize) -> Vec<Vec<(usize, f64)>> {
    let mut rng = ChaCha8Rng::seed_from_u64(case.b_seed);
    let mut touched = vec![false; n];
    let mut rows: Vec<Vec<(usize, f64)>> = Vec::new();
    while rows.len() < case.rows {
        let Some(pivot) = (0..n)
            .map(|_| rng.random_range(0..n))
            .find(|&v| !touched[v])
        else {
            break;
        };
        let other = rng.random_range(0..n);
        let t = rng.random_range(0.2..0.8);
        let row = match (rng.random_range(0..3), other == pivot) {
            (0, _) | (_, true) => vec![(pivot, 1.0)],
            (1, false) => vec![(pivot, t), (other, 1.0 - t)],
            _ => vec![(pivot, 1.0), (other, -1.0)],
        };
        for &(u, _) in &row {
            touched[u] = true;
        }
        rows.push(row);
    }
    if case.duplicate {
        rows.push(rows[0].iter().map(|&(u, v)| (u, 2.0 * v)).collect());
    }
    rows
}

/// The lower triangle of `case`'s KKT matrix with `M` drawn from
/// `values_seed` (the pattern does not depend on it), every diagonal entry
/// stored, and its dimension `n` of the vertex block.
fn kkt_lower(case: &KktCase, values_seed: u64) -> (SparseColMat<usize, f64>, usize) {
    let m = grid_lower(case.grid.side, values_seed);
    let n = m.ncols();
    let rows = kkt_rows(case, n);
    let biggest = (0..n)
        .map(|j| m.val()[m.symbolic().col_ptr()[j]])
        .fold(0.0, f64::max);
    let s = 2f64.powi(biggest.log2().round() as i32);
    let mut triplets: Vec<Triplet<usize, usize, f64>> = Vec::new();
    for j in 0..n {
        let range = m.symbolic().col_ptr()[j]..m.symbolic().col_ptr()[j + 1];
        for p in range {
            triplets.push(Triplet::new(m.symbolic().row_idx()[p], j, m.val()[p]));
        }
    }
    for (k, row) in rows.iter().enumerate() {
        triplets.extend(row.iter().map(|&(u, v)| Triplet::new(n + k, u, s * v)));
        triplets.push(Triplet::new(n + k, n + k, 0.0));
    }
    let dim = n + rows.len();
    let k = SparseColMat::try_new_from_triplets(dim, dim, &triplets).expect("in range");
    (k, n)
}

/// Vertices first, then multipliers: every multiplier after its vertices.
fn natural_order(dim: usize) -> Vec<usize> {
    (0..dim).collect()
}

/// The rule KKT holds pivots to, for `n` vertices.
fn kkt_rule(n: usize) -> PivotRule {
    PivotRule {
        positive: n,
        tolerance: KKT_PIVOT_TOLERANCE,
    }
}

// ---------------------------------------------------------------------------
// Through KKT.

/// (d) through KKT: dependent constraints are refused with a numerical
/// error.
fn kkt_refusal(
    f: &dyn Formulation,
    mix: &ConstraintMix,
    kind: LaplacianKind,
) -> Result<(), String> {
    match factored(f, mix, kind)?.and_then(|mut d| d.solve_matrix()) {
        Err(Error::Numerical(e)) => ensure(!e.to_string().is_empty(), || "an empty message".into()),
        Err(e) => Err(format!(
            "dependent constraints {:?} refused, but not as a numerical error: {e}",
            [&mix.redundant[..], &mix.conflicting[..]].concat()
        )),
        Ok(_) => Err(format!(
            "dependent constraints {:?} were accepted",
            [&mix.redundant[..], &mix.conflicting[..]].concat()
        )),
    }
}

// ---------------------------------------------------------------------------
// LDLᵀ at the matrix level.

/// A KKT matrix (lower triangle) and its factor.
type FactoredKkt = (SparseColMat<usize, f64>, Box<dyn LdltFactor>);

/// `case` analysed in the natural order (vertices, then multipliers) and
/// factored with `M` from `values_seed`, all pivots keeping KKT's rule.
fn ldlt_factor(
    symbolic: &dyn LdltSymbolic,
    case: &KktCase,
    values_seed: u64,
) -> Result<FactoredKkt, String> {
    let (k, n) = kkt_lower(case, values_seed);
    let factor = symbolic
        .factorize(k.as_ref())
        .map_err(|e| format!("factorisation: {e}"))?;
    match factor.pivot_fault(k.as_ref(), kkt_rule(n)) {
        None => Ok((k, factor)),
        Some(fault) => Err(format!(
            "independent constraints, yet a pivot fault: {fault:?}"
        )),
    }
}

/// The analysis of `case`'s pattern in the natural order.
fn ldlt_analysis(
    backend: &dyn LdltBackend,
    case: &KktCase,
) -> Result<Box<dyn LdltSymbolic>, String> {
    let (k, _) = kkt_lower(case, case.grid.seed);
    backend
        .analyze(k.symbolic(), &natural_order(k.ncols()))
        .map_err(|e| format!("analysis: {e}"))
}

/// (d) `LDLᵀ`: a dependent constraint is a pivot fault (or a typed error
/// of the factorisation).
fn ldlt_refusal(backend: &dyn LdltBackend, case: &KktCase) -> Result<(), String> {
    let (k, n) = kkt_lower(case, case.grid.seed);
    let symbolic = backend
        .analyze(k.symbolic(), &natural_order(k.ncols()))
        .map_err(|e| format!("analysis: {e}"))?;
    let factor = match symbolic.factorize(k.as_ref()) {
        Err(e) => return ensure(!e.to_string().is_empty(), || "an empty message".into()),
        Ok(factor) => factor,
    };
    match factor.pivot_fault(k.as_ref(), kkt_rule(n)) {
        Some(PivotFault::Reported { message } | PivotFault::Null { test: message, .. }) => {
            ensure(!message.is_empty(), || "a pivot fault without words".into())
        }
        Some(PivotFault::Computed { .. }) => Ok(()),
        None => Err(format!(
            "multiplier {} repeats multiplier {n} (twice its row), yet no pivot fault",
            k.ncols() - 1
        )),
    }
}

/// (e) `LDLᵀ`: three factors of one analysis, solved in interleaved order.
fn ldlt_several(backend: &dyn LdltBackend, case: &KktCase) -> Result<(), String> {
    let symbolic = ldlt_analysis(backend, case)?;
    let mut factors = Vec::new();
    for i in 0..3 {
        factors.push(ldlt_factor(
            &*symbolic,
            case,
            case.grid.seed.wrapping_add(i),
        )?);
    }
    for (step, i) in [0usize, 1, 2, 2, 0, 1].into_iter().enumerate() {
        let (k, factor) = &mut factors[i];
        ensure(factor.dim() == k.ncols(), || {
            format!("dimension {} of {}", factor.dim(), k.ncols())
        })?;
        check_solve(k.as_ref(), 3, case.b_seed ^ step as u64, |x| {
            factor.solve_in_place(x)
        })
        .map_err(|e| format!("factor {i} of three (solve {step}): {e}"))?;
    }
    Ok(())
}

/// (f) `LDLᵀ`: the analysis refuses a budget of one byte, accepts an
/// unlimited one.
fn ldlt_budget(backend: &dyn LdltBackend, case: &KktCase) -> Result<(), String> {
    let symbolic = ldlt_analysis(backend, case)?;
    let (k, _) = kkt_lower(case, case.grid.seed);
    budget_answers(|budget| symbolic.check_budget(budget, k.ncols(), "the kit's KKT matrix"))
}

/// (g) `LDLᵀ`: one, three and seven columns at once.
fn ldlt_columns(backend: &dyn LdltBackend, case: &KktCase) -> Result<(), String> {
    let symbolic = ldlt_analysis(backend, case)?;
    let (k, mut factor) = ldlt_factor(&*symbolic, case, case.grid.seed)?;
    for cols in [1, 3, 7] {
        check_solve(k.as_ref(), cols, case.b_seed ^ cols as u64, |x| {
            factor.solve_in_place(x)
        })?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------
// Interruption: the back end with a trap.

/// An `LDLᵀ` back end with a [`Trap`].
struct SpyLdlt {
    inner: Arc<dyn LdltBackend>,
    trap: Arc<Trap>,
}

struct SpyLdltSymbolic {
    inner: Box<dyn LdltSymbolic>,
    trap: Arc<Trap>,
}

struct SpyLdltFactor {
    inner: Box<dyn LdltFactor>,
    trap: Arc<Trap>,
}

impl LdltBackend for SpyLdlt {
    fn name(&self) -> BackendName {
        self.inner.name()
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
    ) -> Result<Box<dyn LdltSymbolic>, NumericalError> {
        let inner = self.inner.analyze(lower, order)?;
        Ok(Box::new(SpyLdltSymbolic {
            inner,
            trap: Arc::clone(&self.trap),
        }))
    }
}

impl LdltSymbolic for SpyLdltSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn LdltFactor>, NumericalError> {
        let inner = self.inner.factorize(lower)?;
        self.trap.at(Phase::Factorize);
        Ok(Box::new(SpyLdltFactor {
            inner,
            trap: Arc::clone(&self.trap),
        }))
    }

    fn factor_values(&self) -> usize {
        self.inner.factor_values()
    }

    fn check_budget(
        &self,
        budget: MemoryBudget,
        dim: usize,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        self.inner.check_budget(budget, dim, matrix)
    }
}

impl LdltFactor for SpyLdltFactor {
    fn dim(&self) -> usize {
        self.inner.dim()
    }

    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) -> Result<(), NumericalError> {
        self.inner.solve_in_place(rhs)?;
        self.trap.at(Phase::Solve);
        Ok(())
    }

    fn nnz(&self) -> usize {
        self.inner.nnz()
    }

    fn bytes(&self) -> usize {
        self.inner.bytes()
    }

    fn pivot_fault(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
        rule: PivotRule,
    ) -> Option<PivotFault> {
        self.inner.pivot_fault(lower, rule)
    }

    fn facts(&self) -> Option<BackendFacts> {
        self.inner.facts()
    }

    fn refactorizations(&self) -> usize {
        self.inner.refactorizations()
    }
}
