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
//! A pivot that is not positive ends the factorisation with `INFOG(1) =
//! −40` (or −10); MUMPS does not say which unknown, so the error names the
//! code. The breakdown check of the other back ends ([`super::super::spd::BREAKDOWN_RATIO`])
//! needs the factor's diagonal, which MUMPS does not hand out: a factor
//! that lost its digits shows in the solve's forward-error estimate
//! instead (docs/distributed.md §4).

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use faer::MatMut;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

use super::driver::Driver;
use super::instance::Params;
use super::session::{Assembled, Factorisation, Session, Shared, lock};
use super::{MumpsFacts, numerical, too_large};
use crate::backend::spd::{SpdBackend, SpdFactor, SpdKind, SpdSymbolic};
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;

/// MUMPS's Cholesky, in core or out of core under a directory.
#[derive(Debug, Clone, Default)]
pub struct MumpsLlt {
    out_of_core: Option<PathBuf>,
}

impl MumpsLlt {
    /// In core (`None`) or with the factor in files under `out_of_core`.
    pub fn new(out_of_core: Option<PathBuf>) -> MumpsLlt {
        MumpsLlt { out_of_core }
    }
}

/// `ICNTL(7) = 7`: automatic ordering; `ICNTL(28) = 1`: sequential
/// analysis on rank 0.
fn analysis_params() -> Params {
    Params {
        icntl: vec![(7, 7), (28, 1)],
        cntl: Vec::new(),
    }
}

impl SpdBackend for MumpsLlt {
    fn kind(&self) -> SpdKind {
        SpdKind::Mumps
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        let matrix = Assembled::from_lower(lower)?;
        let driver = Driver::create(1, self.out_of_core.as_deref()).map_err(numerical)?;
        let session =
            Session::analyse(driver, matrix, Vec::new(), &analysis_params()).map_err(numerical)?;
        let estimate = super::ffi::count(session.driver.struc().infog(20)) as usize;
        Ok(Box::new(MumpsSymbolic {
            shared: Arc::new(Mutex::new(session)),
            estimate,
        }))
    }
}

/// An analysed pattern.
pub(crate) struct MumpsSymbolic {
    pub shared: Shared,
    /// `INFOG(20)`: estimated entries of the factor over all ranks.
    pub estimate: usize,
}

impl MumpsSymbolic {
    /// Every rank checks MUMPS's estimate of its share against its budget.
    pub fn check_every_rank(&self, budget: MemoryBudget, matrix: &str) -> Result<(), ProblemError> {
        lock(&self.shared)
            .driver
            .check_memory(budget.limit())
            .map_err(|f| too_large(f, matrix))
    }
}

impl SpdSymbolic for MumpsSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn SpdFactor>, NumericalError> {
        let factor = Factorisation::new(&self.shared, lower).map_err(numerical)?;
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
}

/// A numeric factor.
struct MumpsFactor(Factorisation);

impl SpdFactor for MumpsFactor {
    fn dim(&self) -> usize {
        self.0.n
    }

    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) {
        self.0.solve_in_place(rhs);
    }

    fn nnz(&self) -> usize {
        self.0.entries as usize
    }

    fn bytes(&self) -> usize {
        self.0.entries as usize * std::mem::size_of::<f64>()
    }

    fn mumps_facts(&self) -> Option<MumpsFacts> {
        Some(self.0.facts.clone())
    }
}
