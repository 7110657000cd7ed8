//! The kit of the SPD seam: [`spd`], its cases, its checks at the
//! matrix level, and its back end with a trap.

use std::sync::Arc;

use faer::MatMut;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::backend::qr::SparseGivens;
use crate::backend::spd::{SpdBackend, SpdFactor, SpdSymbolic};
use crate::backend::{BackendFacts, BackendName, FactorKind};
use crate::error::{NumericalError, ProblemError};
use crate::formulation::{Elimination, NullSpaceQr, Penalty};
use crate::laplacian::LaplacianKind;
use crate::limits::MemoryBudget;
use crate::testing::{ConstraintMix, independent_constraints, laplacian_kinds, meshes, with_soft};

use super::common::{budget_answers, check_solve, ensure, random_mat};
use super::kit::{Kit, KitConfig, KitFailure, KitReport, Property, Seam, quarter};
use super::method::{
    Phase, Trap, exactness, interruption, method_budget, method_columns, named, oracle,
};
use super::strategies::{GridCase, grid_lower, grids, mixes};

// ---------------------------------------------------------------------------
// The call.

/// Runs the kit on an SPD back end: [`Property::Named`],
/// [`Property::Exactness`] and [`Property::Oracle`] through the null-space
/// method (sparse Givens QR) and elimination, [`Property::Refusal`],
/// [`Property::SeveralFactors`], [`Property::Budget`],
/// [`Property::Interruption`], [`Property::Columns`].
///
/// Errors: every failing property with its minimal case ([`KitFailure`]).
pub fn spd(backend: Arc<dyn SpdBackend>, config: &KitConfig) -> Result<KitReport, KitFailure> {
    let mut kit = Kit::new(Seam::Spd, backend.name(), config);
    let cases = kit.cases();
    let method = || NullSpaceQr::new(Arc::new(SparseGivens::default()), Arc::clone(&backend));
    kit.fixed(Property::Named, || {
        let expected = FactorKind::Cholesky(backend.name());
        named(&backend.name(), &backend.name(), &method(), |r| {
            r.factor_backend == Some(expected.clone())
        })
    });
    kit.generated(Property::Exactness, cases, mixes(), |(mix, kind)| {
        exactness(&method(), &mix, kind)
    });
    kit.generated(Property::Oracle, cases, mixes(), |(mix, kind)| {
        oracle(&method(), &mix, kind)
    });
    kit.generated(Property::Oracle, cases, position_mixes(), |(mix, kind)| {
        oracle(&Elimination::new(Arc::clone(&backend)), &mix, kind)
    });
    kit.generated(Property::Refusal, cases, refusal_cases(), |case| {
        spd_refusal(&*backend, &case)
    });
    kit.generated(Property::SeveralFactors, cases, grids(), |case| {
        spd_several(&*backend, &case)
    });
    kit.generated(Property::Budget, cases, grids(), |case| {
        spd_budget(&*backend, &case)
    });
    kit.generated(Property::Budget, cases, mixes(), |(mix, kind)| {
        method_budget(
            &Penalty::with_backend(1.0, Arc::clone(&backend)),
            &mix,
            kind,
        )
    });
    kit.generated(
        Property::Interruption,
        quarter(cases),
        mixes(),
        |(mix, kind)| {
            let trap = Arc::new(Trap::default());
            let spy: Arc<dyn SpdBackend> = Arc::new(SpySpd {
                inner: Arc::clone(&backend),
                trap: Arc::clone(&trap),
            });
            let f = NullSpaceQr::new(Arc::new(SparseGivens::default()), spy);
            interruption(&f, &trap, &mix, kind, true)
        },
    );
    kit.generated(Property::Columns, cases, grids(), |case| {
        spd_columns(&*backend, &case)
    });
    kit.generated(Property::Columns, cases, mixes(), |(mix, kind)| {
        method_columns(&method(), &mix, kind)
    });
    kit.finish()
}

// ---------------------------------------------------------------------------
// Cases.

/// Meshes with 3–11 independent position constraints and 0–3 soft ones
/// (what elimination accepts), with a Laplacian kind.
fn position_mixes() -> impl Strategy<Value = (ConstraintMix, LaplacianKind)> {
    (
        meshes(),
        any::<u64>(),
        3usize..12,
        0usize..4,
        laplacian_kinds(),
    )
        .prop_map(|(mesh, seed, count, n_soft, kind)| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let hard = independent_constraints(&mesh, &mut rng, count, true);
            let rank = hard.len();
            let constraints = with_soft(&mesh, &mut rng, hard, n_soft);
            let mix = ConstraintMix {
                mesh,
                constraints,
                rank,
                redundant: Vec::new(),
                conflicting: Vec::new(),
            };
            (mix, kind)
        })
}

/// A grid matrix whose diagonal entry at `unknown` is multiplied by
/// `factor ≤ 0`: not positive definite.
#[derive(Clone, Debug)]
pub struct RefusalCase {
    /// The grid.
    pub grid: GridCase,
    /// The unknown whose diagonal is spoiled (modulo the dimension).
    pub unknown: usize,
    /// What the diagonal entry is multiplied by: 0, −½ or −1.
    pub factor: f64,
}

fn refusal_cases() -> impl Strategy<Value = RefusalCase> {
    (
        grids(),
        any::<usize>(),
        prop::sample::select(vec![0.0, -0.5, -1.0]),
    )
        .prop_map(|(grid, unknown, factor)| RefusalCase {
            unknown: unknown % (grid.side * grid.side),
            grid,
            factor,
        })
}

// ---------------------------------------------------------------------------
// SPD at the matrix level.

/// (d) SPD: a matrix with a non-positive diagonal entry is refused by the
/// factorisation or the first solve, with a typed error.
fn spd_refusal(backend: &dyn SpdBackend, case: &RefusalCase) -> Result<(), String> {
    let mut lower = grid_lower(case.grid.side, case.grid.seed);
    let at = lower.symbolic().col_ptr()[case.unknown];
    lower.val_mut()[at] *= case.factor;
    let symbolic = match backend.analyze(lower.symbolic()) {
        Ok(symbolic) => symbolic,
        Err(e) => return ensure(!e.to_string().is_empty(), || "an empty message".into()),
    };
    let mut factor = match symbolic.factorize(lower.as_ref()) {
        Ok(factor) => factor,
        Err(e) => return ensure(!e.to_string().is_empty(), || "an empty message".into()),
    };
    let mut x = random_mat(lower.ncols(), 3, case.grid.seed);
    match factor.solve_in_place(x.as_mut()) {
        Err(e) => ensure(!e.to_string().is_empty(), || "an empty message".into()),
        Ok(()) => Err(format!(
            "a matrix with diagonal entry {:e} at unknown {} (not positive definite) was factored and solved",
            lower.val()[at],
            case.unknown
        )),
    }
}

/// (e) SPD: three factors of one analysis, solved in interleaved order.
fn spd_several(backend: &dyn SpdBackend, case: &GridCase) -> Result<(), String> {
    let matrices: Vec<_> = (0..3)
        .map(|i| grid_lower(case.side, case.seed.wrapping_add(i)))
        .collect();
    let symbolic = backend
        .analyze(matrices[0].symbolic())
        .map_err(|e| format!("analysis: {e}"))?;
    ensure(symbolic.factor_nnz() > 0, || {
        "the analysis reports no stored entries".into()
    })?;
    let mut factors = Vec::new();
    for m in &matrices {
        factors.push(
            symbolic
                .factorize(m.as_ref())
                .map_err(|e| format!("factorisation: {e}"))?,
        );
    }
    for f in &factors {
        ensure(f.dim() == matrices[0].ncols(), || {
            format!("dimension {} of {}", f.dim(), matrices[0].ncols())
        })?;
        ensure(f.nnz() > 0 && f.bytes() > 0, || {
            format!("a factor of {} entries in {} bytes", f.nnz(), f.bytes())
        })?;
    }
    for (step, i) in [0usize, 1, 2, 2, 0, 1].into_iter().enumerate() {
        check_solve(matrices[i].as_ref(), 3, case.seed ^ step as u64, |x| {
            factors[i].solve_in_place(x)
        })
        .map_err(|e| format!("factor {i} of three (solve {step}): {e}"))?;
    }
    Ok(())
}

/// (f) SPD: the analysis refuses a budget of one byte, accepts an
/// unlimited one.
fn spd_budget(backend: &dyn SpdBackend, case: &GridCase) -> Result<(), String> {
    let lower = grid_lower(case.side, case.seed);
    let symbolic = backend
        .analyze(lower.symbolic())
        .map_err(|e| format!("analysis: {e}"))?;
    budget_answers(|budget| symbolic.check_budget(budget, lower.ncols(), "the kit's matrix"))
}

/// (g) SPD: one, three and seven columns at once.
fn spd_columns(backend: &dyn SpdBackend, case: &GridCase) -> Result<(), String> {
    let lower = grid_lower(case.side, case.seed);
    let symbolic = backend
        .analyze(lower.symbolic())
        .map_err(|e| format!("analysis: {e}"))?;
    let mut factor = symbolic
        .factorize(lower.as_ref())
        .map_err(|e| format!("factorisation: {e}"))?;
    for cols in [1, 3, 7] {
        check_solve(lower.as_ref(), cols, case.seed ^ cols as u64, |x| {
            factor.solve_in_place(x)
        })?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------
// Interruption: the back end with a trap.

/// An SPD back end with a [`Trap`].
struct SpySpd {
    inner: Arc<dyn SpdBackend>,
    trap: Arc<Trap>,
}

struct SpySpdSymbolic {
    inner: Box<dyn SpdSymbolic>,
    trap: Arc<Trap>,
}

struct SpySpdFactor {
    inner: Box<dyn SpdFactor>,
    trap: Arc<Trap>,
}

impl SpdBackend for SpySpd {
    fn name(&self) -> BackendName {
        self.inner.name()
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        let inner = self.inner.analyze(lower)?;
        Ok(Box::new(SpySpdSymbolic {
            inner,
            trap: Arc::clone(&self.trap),
        }))
    }

    fn analyze_planned(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        plan: &crate::backend::ordering::FactorPlan,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        let inner = self.inner.analyze_planned(lower, plan)?;
        Ok(Box::new(SpySpdSymbolic {
            inner,
            trap: Arc::clone(&self.trap),
        }))
    }
}

impl SpdSymbolic for SpySpdSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn SpdFactor>, NumericalError> {
        let inner = self.inner.factorize(lower)?;
        self.trap.at(Phase::Factorize);
        Ok(Box::new(SpySpdFactor {
            inner,
            trap: Arc::clone(&self.trap),
        }))
    }

    fn factor_nnz(&self) -> usize {
        self.inner.factor_nnz()
    }

    fn check_budget(
        &self,
        budget: MemoryBudget,
        dim: usize,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        self.inner.check_budget(budget, dim, matrix)
    }

    fn plan_used(&self) -> crate::backend::ordering::PlanUsed {
        self.inner.plan_used()
    }
}

impl SpdFactor for SpySpdFactor {
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

    fn facts(&self) -> Option<BackendFacts> {
        self.inner.facts()
    }

    fn refactorizations(&self) -> usize {
        self.inner.refactorizations()
    }
}
