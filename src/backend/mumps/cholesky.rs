//! MUMPS's `LLᵀ` (`SYM = 1`) behind the SPD seam ([`crate::backend::spd`]).
//!
//! - **analysis** ([`SpdBackend::analyze`]): `JOB = 1`, sequential analysis
//!   (`ICNTL(28) = 1`) with MUMPS's automatic choice of ordering
//!   (`ICNTL(7) = 7`; the report names the one used, from `INFOG(7)`);
//! - **numeric** ([`SpdSymbolic::factorize`]): `JOB = 2` on every rank;
//!   the memory budget was checked on every rank before
//!   ([`SpdSymbolic::check_budget`], MUMPS's own per-rank estimate);
//! - **solve**: `JOB = 3` with every right-hand side in one dense block on
//!   rank 0.
//!
//! MUMPS's `SYM = 1` factorisation stops at an exactly zero pivot (error
//! −10) but not at a negative one: it counts them (`INFOG(12)`), and any
//! count refuses the factor (MUMPS does not say where). The breakdown test
//! of the other back ends (`L_kk²/A_kk` below
//! [`crate::backend::spd::BREAKDOWN_RATIO`]) needs the factor's diagonal,
//! which MUMPS does not hand out, and its null-pivot detection
//! (`ICNTL(24)`) does not act on `SYM = 1`: a pivot that lost its digits
//! without turning negative is seen only by the solve's forward-error
//! estimate (docs/distributed.md §4).

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use faer::MatMut;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

use super::driver::Driver;
use super::instance::Params;
use super::session::DetectedPivots;
use super::session::{Assembled, Factorisation, Session, Shared, lock};
use super::shared::{numerical, too_large};
use crate::backend::openblas::{self, ThreadsFor};
use crate::backend::ordering::{FactorPlan, PlanUsed};
use crate::backend::spd::{SpdBackend, SpdFactor, SpdKind, SpdSymbolic};
use crate::backend::{BackendFacts, BackendName};
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;

/// MUMPS's Cholesky, in core or out of core under a directory.
#[derive(Debug, Clone, Default)]
pub struct MumpsLlt {
    out_of_core: Option<PathBuf>,
}

impl MumpsLlt {
    /// In core (`None`) or with the factor in files under `out_of_core`,
    /// which every rank checks it can use (bad input when one cannot:
    /// [`super::shared::check_out_of_core`]). Refused as bad input where
    /// this process cannot drive MUMPS
    /// ([`super::shared::check_driving_rank`]).
    pub fn new(out_of_core: Option<PathBuf>) -> Result<MumpsLlt, ProblemError> {
        super::shared::check_driving_rank()?;
        super::shared::check_out_of_core(out_of_core.as_deref())?;
        Ok(MumpsLlt { out_of_core })
    }
}

/// `ICNTL(7) = 7`: automatic ordering, or `ICNTL(7) = 1`: the one given
/// in `PERM_IN`; `ICNTL(28) = 1`: sequential analysis on rank 0.
fn analysis_params(given: bool) -> Params {
    Params {
        icntl: vec![(7, if given { 1 } else { 7 }), (28, 1)],
        cntl: Vec::new(),
    }
}

/// MUMPS's `PERM_IN` for `perm[i]` eliminated `i`-th: the 1-based
/// position of each unknown.
pub(crate) fn perm_in(perm: &[usize]) -> Vec<i32> {
    let mut positions = vec![0i32; perm.len()];
    for (position, &unknown) in perm.iter().enumerate() {
        positions[unknown] = position as i32 + 1;
    }
    positions
}

/// A factor with negative pivots (MUMPS's count, `INFOG(12)`) as the
/// seam's error.
fn check_pivots(detected: &DetectedPivots) -> Result<(), NumericalError> {
    match detected.negative {
        0 => Ok(()),
        count => Err(numerical(super::instance::Failure::Rank(format!(
            "the matrix is not positive definite: MUMPS's factorisation met {count} negative pivot{}",
            if count == 1 { "" } else { "s" }
        )))),
    }
}

impl SpdBackend for MumpsLlt {
    fn name(&self) -> BackendName {
        SpdKind::Mumps.name().into()
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        let symbolic = MumpsSymbolic::analyse(
            lower,
            1,
            Vec::new(),
            &analysis_params(false),
            self.out_of_core.as_deref(),
        )?;
        Ok(Box::new(symbolic))
    }

    /// The plan's permutation as `PERM_IN` (`ICNTL(7) = 1`), and its
    /// threads as OpenBLAS's count on the driving rank for the analysis
    /// and each factorisation (other ranks keep their environment's:
    /// `mpirun -x OPENBLAS_NUM_THREADS=…` sets theirs).
    fn analyze_planned(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        plan: &FactorPlan,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        let given = plan.permutation.as_deref().map(perm_in);
        let threads = ThreadsFor::new(plan.threads.requested());
        let mut symbolic = MumpsSymbolic::analyse(
            lower,
            1,
            given.clone().unwrap_or_default(),
            &analysis_params(given.is_some()),
            self.out_of_core.as_deref(),
        )?;
        symbolic.threads = plan.threads.requested();
        if given.is_some() {
            symbolic.ordering = plan.ordering.into();
        }
        drop(threads);
        Ok(Box::new(symbolic))
    }
}

/// An analysed pattern.
pub(crate) struct MumpsSymbolic {
    pub shared: Shared,
    /// `INFOG(20)`: estimated entries of the factor over all ranks.
    pub estimate: usize,
    /// OpenBLAS's threads on this rank for each factorisation; `None`:
    /// its own.
    pub threads: Option<usize>,
    /// The report's word for the ordering used.
    pub ordering: std::borrow::Cow<'static, str>,
}

impl MumpsSymbolic {
    /// A new instance with `SYM = sym` (out of core under `out_of_core`)
    /// that analyses `lower` with `params` (and `perm_in` when not empty).
    pub(crate) fn analyse(
        lower: SymbolicSparseColMatRef<'_, usize>,
        sym: i32,
        perm_in: Vec<i32>,
        params: &Params,
        out_of_core: Option<&std::path::Path>,
    ) -> Result<MumpsSymbolic, NumericalError> {
        let matrix = Assembled::from_lower(lower)?;
        let driver = Driver::create(sym, out_of_core).map_err(numerical)?;
        let session = Session::analyse(driver, matrix, perm_in, params).map_err(numerical)?;
        let estimate = super::ffi::count(session.driver.struc().infog(20)) as usize;
        let own = super::session::ordering_name(session.driver.struc().infog(7));
        Ok(MumpsSymbolic {
            shared: Arc::new(Mutex::new(session)),
            estimate,
            threads: None,
            ordering: format!("own ({own})").into(),
        })
    }

    /// Every rank checks MUMPS's estimate of its share against its budget.
    pub(crate) fn check_every_rank(
        &self,
        budget: MemoryBudget,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        lock(&self.shared)
            .driver
            .check_memory(budget)
            .map_err(|f| too_large(f, matrix))
    }
}

impl SpdSymbolic for MumpsSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn SpdFactor>, NumericalError> {
        let threads = ThreadsFor::new(self.threads);
        let factor = Factorisation::new(&self.shared, lower).map_err(numerical)?;
        drop(threads);
        check_pivots(&lock(&self.shared).detected_pivots())?;
        Ok(Box::new(MumpsFactor(factor)))
    }

    fn factor_nnz(&self) -> usize {
        self.estimate
    }

    fn check_budget(
        &self,
        budget: MemoryBudget,
        _dim: usize,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        self.check_every_rank(budget, matrix)
    }

    /// The threads on the driving rank: those asked for when OpenBLAS is
    /// loaded, otherwise its count in effect (the report's `mumps` block
    /// has the ranks).
    fn plan_used(&self) -> PlanUsed {
        PlanUsed {
            ordering: self.ordering.clone(),
            threads: openblas::threads_used(self.threads),
        }
    }
}

/// A numeric factor.
struct MumpsFactor(Factorisation);

impl SpdFactor for MumpsFactor {
    fn dim(&self) -> usize {
        self.0.n
    }

    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) -> Result<(), NumericalError> {
        self.0.solve_in_place(rhs)
    }

    fn nnz(&self) -> usize {
        self.0.entries as usize
    }

    fn bytes(&self) -> usize {
        self.0.entries as usize * std::mem::size_of::<f64>()
    }

    fn facts(&self) -> Option<BackendFacts> {
        Some(self.0.facts.to_backend_facts())
    }

    fn refactorizations(&self) -> usize {
        self.0.refactorizations
    }
}
