//! MUMPS's `LDLᵀ` (`SYM = 2`) behind the `LDLᵀ` seam
//! ([`crate::backend::ldlt`]), for the KKT formulation.
//!
//! The seam's contract is a **static** order given by the caller. MUMPS
//! gets it as `PERM_IN` (`ICNTL(7) = 1`) with numerical pivoting all but
//! off (`CNTL(1)` = the smallest normal double, [`PIVOT_THRESHOLD`]), no
//! scaling (`ICNTL(8) = 0`), the usual (not
//! compressed) ordering (`ICNTL(12) = 1`) and the root node factored like
//! any other (`ICNTL(13) = 1`), so that it eliminates in the caller's
//! order as faer does, up to MUMPS's own order inside a front. MUMPS does not hand out the pivots: it judges them
//! itself with its null-pivot detection (`ICNTL(24) = 1`), which flags a
//! pivot whose row in the frontal matrix has an infinity norm below
//! `CNTL(3)·‖K‖∞`; `CNTL(3)` is the KKT pivot tolerance
//! ([`crate::formulation::KKT_PIVOT_TOLERANCE`]) and `K` is already scaled
//! so that its constraint block matches `AᵀA`. The flagged unknowns
//! (`PIVNUL_LIST`) and the count of negative pivots (`INFOG(12)`) are what
//! [`LdltFactor::detected_pivots`] returns; the KKT formulation maps them to
//! the same errors as faer's pivots (docs/distributed.md §3).

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use faer::MatMut;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

use super::cholesky::MumpsSymbolic;
use super::driver::Driver;
use super::instance::Params;
use super::session::{Assembled, Factorisation, Session, lock};
use super::{MumpsFacts, numerical};
use crate::backend::ldlt::{
    DetectedPivots, LdltBackend, LdltFactor, LdltKind, LdltSymbolic, Pivot,
};
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;

/// The null-pivot threshold relative to `‖K‖∞` (`CNTL(3)`): the KKT
/// formulation's pivot tolerance.
const NULL_PIVOT_THRESHOLD: f64 = 1000.0 * f64::EPSILON;

/// The relative pivoting threshold `CNTL(1)`: the smallest positive normal
/// double, so that only a pivot that is (nearly) exactly zero is passed
/// over. Not 0: with `CNTL(1) = 0` MUMPS 5.5 takes only the first candidate
/// of a front (`DMUMPS_FAC_I_LDLT`) and delays it when it is exactly zero;
/// MUMPS's order of the fully summed variables inside a front is not
/// exactly `PERM_IN`'s (of two duplicated constraints it finds the earlier
/// one null), so a multiplier can meet a zero pivot, and independent
/// constraints (a grid with relative constraints) ended in `INFOG(1) = −10`.
const PIVOT_THRESHOLD: f64 = f64::MIN_POSITIVE;

/// MUMPS's `LDLᵀ` in a static order.
#[derive(Debug, Clone, Default)]
pub struct MumpsLdlt {
    out_of_core: Option<PathBuf>,
}

impl MumpsLdlt {
    /// In core (`None`) or with the factor in files under `out_of_core`.
    pub fn new(out_of_core: Option<PathBuf>) -> MumpsLdlt {
        MumpsLdlt { out_of_core }
    }
}

fn analysis_params() -> Params {
    Params {
        icntl: vec![(6, 0), (7, 1), (8, 0), (12, 1), (13, 1), (24, 1), (28, 1)],
        cntl: vec![(1, PIVOT_THRESHOLD), (3, NULL_PIVOT_THRESHOLD)],
    }
}

impl LdltBackend for MumpsLdlt {
    fn kind(&self) -> LdltKind {
        LdltKind::Mumps
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
    ) -> Result<Box<dyn LdltSymbolic>, NumericalError> {
        let matrix = Assembled::from_lower(lower)?;
        // PERM_IN(i): the (1-based) position of unknown i in the order.
        let mut perm_in = vec![0i32; order.len()];
        for (position, &unknown) in order.iter().enumerate() {
            perm_in[unknown] = position as i32 + 1;
        }
        let driver = Driver::create(2, self.out_of_core.as_deref()).map_err(numerical)?;
        let session =
            Session::analyse(driver, matrix, perm_in, &analysis_params()).map_err(numerical)?;
        let estimate = super::ffi::count(session.driver.struc().infog(20)) as usize;
        Ok(Box::new(MumpsLdltSymbolic(MumpsSymbolic {
            shared: Arc::new(Mutex::new(session)),
            estimate,
        })))
    }
}

struct MumpsLdltSymbolic(MumpsSymbolic);

impl LdltSymbolic for MumpsLdltSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn LdltFactor>, NumericalError> {
        let factor = Factorisation::new(&self.0.shared, lower).map_err(numerical)?;
        let detected = {
            let session = lock(&self.0.shared);
            let struc = session.driver.struc();
            let count = struc.infog(28).max(0) as usize;
            let list = struc.0.pivnul_list;
            let null = if list.is_null() {
                Vec::new()
            } else {
                // SAFETY: with ICNTL(24) = 1, MUMPS allocates PIVNUL_LIST on
                // the host with at least INFOG(28) entries (user's guide,
                // §5.13).
                unsafe { std::slice::from_raw_parts(list, count) }
                    .iter()
                    .map(|&i| (i - 1).max(0) as usize)
                    .collect()
            };
            DetectedPivots {
                null,
                negative: struc.infog(12).max(0) as usize,
            }
        };
        Ok(Box::new(MumpsLdltFactor { factor, detected }))
    }

    fn factor_values(&self) -> usize {
        self.0.estimate
    }

    fn check_budget(
        &self,
        budget: MemoryBudget,
        _dim: usize,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        self.0.check_every_rank(budget, matrix)
    }
}

struct MumpsLdltFactor {
    factor: Factorisation,
    detected: DetectedPivots,
}

impl LdltFactor for MumpsLdltFactor {
    fn dim(&self) -> usize {
        self.factor.n
    }

    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) {
        self.factor.solve_in_place(rhs);
    }

    fn nnz(&self) -> usize {
        self.factor.entries as usize
    }

    fn bytes(&self) -> usize {
        self.factor.entries as usize * std::mem::size_of::<f64>()
    }

    fn pivots(&self, _lower: SparseColMatRef<'_, usize, f64>) -> Vec<Pivot> {
        Vec::new()
    }

    fn reported_failure(&self) -> Option<&str> {
        None
    }

    fn detected_pivots(&self) -> Option<DetectedPivots> {
        Some(self.detected.clone())
    }

    fn mumps_facts(&self) -> Option<MumpsFacts> {
        Some(self.factor.facts.clone())
    }
}
