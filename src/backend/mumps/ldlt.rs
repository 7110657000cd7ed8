//! MUMPS's `LDLᵀ` (`SYM = 2`) behind the `LDLᵀ` seam
//! ([`crate::backend::ldlt`]), for the KKT formulation.
//!
//! The KKT formulation's static order goes in as `PERM_IN`
//! (`ICNTL(7) = 1`), with no scaling (`ICNTL(8) = 0`: `K` is already
//! balanced by the formulation's power-of-two multiplier scale, and the
//! thresholds below are relative to `K` as the formulation scaled it), the
//! usual (not compressed) ordering (`ICNTL(12) = 1`) and the root node
//! factored like any other (`ICNTL(13) = 1`).
//!
//! **MUMPS does not keep the static order**, so it pivots. Within its
//! fronts it meets some multipliers before their vertices, where their
//! pivots are zero in exact arithmetic (docs/distributed.md §3 has the
//! counts). With the pivoting threshold `CNTL(1)` at the smallest double,
//! only exactly zero pivots were delayed; the ones rounding left at
//! `1e-16`… of their column were taken, and every digit was lost on trees
//! of hard relative rows (backward error 0.1–0.3, one negative pivot too
//! many, or a sound constraint flagged null). `CNTL(1) =`
//! [`PIVOT_THRESHOLD`] `= 0.01`, MUMPS's default for `SYM = 2`, is
//! threshold pivoting proper: a pivot below 1 % of its column in the front
//! is delayed or paired into a 2×2 block, which bounds the growth.
//!
//! **Null pivots.** MUMPS judges them itself with its null-pivot detection
//! (`ICNTL(24) = 1`), which flags a pivot whose row in the frontal matrix
//! has an infinity norm below `CNTL(3)` times the norm of `K`; `CNTL(3)` is
//! the KKT pivot tolerance `1000 ε`. The flagged unknowns (`PIVNUL_LIST`)
//! and the count of negative pivots (`INFOG(12)`) become the seam's one
//! pivot report ([`LdltFactor::pivot_fault`]): the flagged unknown first
//! in the given order, as a [`PivotFault::Null`]; since MUMPS's sequence
//! is not the static one, the KKT formulation names the dependent
//! constraint from the rows themselves (a rank-revealing QR of `B`), as
//! faer's pivots name it, and blames none when the QR finds the rows
//! independent (docs/distributed.md §3).

use std::path::PathBuf;

use faer::MatMut;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

use super::cholesky::MumpsSymbolic;
use super::instance::Params;
use super::session::DetectedPivots;
use super::session::{Factorisation, lock};
use super::shared::numerical;
use crate::backend::ldlt::{
    LdltBackend, LdltFactor, LdltKind, LdltSymbolic, PivotFault, PivotRule,
};
use crate::backend::openblas::{self, ThreadsFor};
use crate::backend::{BackendFacts, BackendName};
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;
use crate::resources::Threads;

/// The null-pivot threshold relative to the norm of the scaled `K`
/// (`CNTL(3)`): the KKT
/// formulation's pivot tolerance.
const NULL_PIVOT_THRESHOLD: f64 = 1000.0 * f64::EPSILON;

/// The null-pivot threshold of the second look (`CNTL(3)`), when the first
/// flagged pivots: `1e-17` of the norm, below one rounding error of it. On
/// sliver-heavy meshes (camelhead, intrinsic-Delaunay Laplacian) a vertex's
/// row can fall below `1000 ε` of a norm that the slivers' huge entries set
/// while its pivot is sound (faer's test, relative to the pivot's own
/// magnitude, passes it); exact duplicates leave rows of a few rounding
/// errors, which this second look would miss, so it judges vertices only
/// (docs/distributed.md §3).
const ROUNDING_NULL_THRESHOLD: f64 = 1e-17;

/// `CNTL(1)`, the relative threshold of numerical pivoting: MUMPS keeps a
/// pivot in place unless it is below this fraction of the largest entry of
/// its column in the front, and otherwise delays it or pairs it into a 2×2
/// pivot. `0.01` is MUMPS's default for `SYM = 2` (user's guide, `CNTL(1)`):
/// it bounds the growth of the entries by `1 + 1/0.01` per elimination
/// step. Smaller thresholds let MUMPS take pivots that are rounding errors
/// of zero where its sequence meets a multiplier before its vertices:
/// the smallest normal double (the earlier value) and `1000 ε` lost every
/// digit on trees of hard relative rows (Bunny 3k, 100 rows: backward
/// error 0.25), `1e-10` on the 50k-vertex Dragon with 300 rows.
const PIVOT_THRESHOLD: f64 = 0.01;

/// MUMPS's `LDLᵀ`, given the static order.
#[derive(Debug, Clone, Default)]
pub struct MumpsLdlt {
    out_of_core: Option<PathBuf>,
}

impl MumpsLdlt {
    /// In core (`None`) or with the factor in files under `out_of_core`,
    /// which every rank checks it can use (bad input when one cannot:
    /// [`super::shared::check_out_of_core`]). Refused as bad input where
    /// this process cannot drive MUMPS
    /// ([`super::shared::check_driving_rank`]).
    pub fn new(out_of_core: Option<PathBuf>) -> Result<MumpsLdlt, ProblemError> {
        super::shared::check_driving_rank()?;
        super::shared::check_out_of_core(out_of_core.as_deref())?;
        Ok(MumpsLdlt { out_of_core })
    }
}

fn analysis_params() -> Params {
    Params {
        icntl: vec![(6, 0), (7, 1), (8, 0), (12, 1), (13, 1), (24, 1), (28, 1)],
        cntl: vec![(1, PIVOT_THRESHOLD), (3, NULL_PIVOT_THRESHOLD)],
    }
}

impl LdltBackend for MumpsLdlt {
    fn name(&self) -> BackendName {
        LdltKind::Mumps.name().into()
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
    ) -> Result<Box<dyn LdltSymbolic>, NumericalError> {
        // PERM_IN(i): the (1-based) position of unknown i in the order.
        let perm_in = super::cholesky::perm_in(order);
        let position = perm_in.iter().map(|&p| p as usize - 1).collect();
        let symbolic = MumpsSymbolic::analyse(
            lower,
            2,
            perm_in,
            &analysis_params(),
            self.out_of_core.as_deref(),
        )?;
        Ok(Box::new(MumpsLdltSymbolic { symbolic, position }))
    }

    /// OpenBLAS's count on the driving rank for each factorisation.
    fn analyze_on_threads(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
        threads: Threads,
    ) -> Result<Box<dyn LdltSymbolic>, NumericalError> {
        let _threads = ThreadsFor::new(threads.requested());
        let perm_in = super::cholesky::perm_in(order);
        let position = perm_in.iter().map(|&p| p as usize - 1).collect();
        let mut symbolic = MumpsSymbolic::analyse(
            lower,
            2,
            perm_in,
            &analysis_params(),
            self.out_of_core.as_deref(),
        )?;
        symbolic.threads = threads.requested();
        Ok(Box::new(MumpsLdltSymbolic { symbolic, position }))
    }
}

struct MumpsLdltSymbolic {
    symbolic: MumpsSymbolic,
    /// `position[j]`: where unknown `j` stands in the given order.
    position: Vec<usize>,
}

impl LdltSymbolic for MumpsLdltSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn LdltFactor>, NumericalError> {
        let shared = &self.symbolic.shared;
        let _threads = ThreadsFor::new(self.symbolic.threads);
        let mut factor = Factorisation::new(shared, lower).map_err(numerical)?;
        let mut detected = lock(shared).detected_pivots();
        if !detected.null.is_empty() {
            // A second look at rounding level: what is still null there is
            // null; what is not was a small sound pivot, and this factor is
            // the one to keep.
            lock(shared).set_factorisation_cntl(vec![(3, ROUNDING_NULL_THRESHOLD)]);
            let second = Factorisation::new(shared, lower);
            let mut session = lock(shared);
            session.set_factorisation_cntl(vec![(3, NULL_PIVOT_THRESHOLD)]);
            factor = second.map_err(numerical)?;
            detected.null_at_rounding = session.detected_pivots().null;
        }
        Ok(Box::new(MumpsLdltFactor {
            factor,
            detected,
            position: self.position.clone(),
        }))
    }

    fn factor_values(&self) -> usize {
        self.symbolic.estimate
    }

    fn check_budget(
        &self,
        budget: MemoryBudget,
        _dim: usize,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        self.symbolic.check_every_rank(budget, matrix)
    }

    /// On the driving rank: those asked for when OpenBLAS is loaded,
    /// otherwise its count in effect.
    fn threads_used(&self) -> Option<usize> {
        openblas::threads_used(self.symbolic.threads)
    }
}

struct MumpsLdltFactor {
    factor: Factorisation,
    detected: DetectedPivots,
    position: Vec<usize>,
}

impl LdltFactor for MumpsLdltFactor {
    fn dim(&self) -> usize {
        self.factor.n
    }

    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) -> Result<(), NumericalError> {
        self.factor.solve_in_place(rhs)
    }

    fn nnz(&self) -> usize {
        self.factor.entries as usize
    }

    fn bytes(&self) -> usize {
        self.factor.entries as usize * std::mem::size_of::<f64>()
    }

    /// The null pivot first in the given order. A flagged unknown of the
    /// negative block (a multiplier of KKT) is a dependence; flagged
    /// unknowns of the positive block alone may be small sound pivots of
    /// a norm set by slivers: those still null at rounding level are null.
    /// The count of negative pivots is not used: with no null pivot a
    /// nonsingular `K` has exactly the expected inertia, and MUMPS's count
    /// is not always it when it takes 2×2 pivots around an exact zero.
    fn pivot_fault(
        &self,
        _lower: SparseColMatRef<'_, usize, f64>,
        rule: PivotRule,
    ) -> Option<PivotFault> {
        let detected = &self.detected;
        let negative_flagged = detected.null.iter().any(|&u| u >= rule.positive);
        let suspects = if negative_flagged {
            &detected.null
        } else {
            &detected.null_at_rounding
        };
        let unknown = suspects
            .iter()
            .copied()
            .filter(|&u| u < self.position.len())
            .min_by_key(|&u| self.position[u])?;
        Some(PivotFault::Null {
            unknown,
            test: format!(
                "MUMPS found its pivot null (the norm of its row below {NULL_PIVOT_THRESHOLD:e} of the scaled matrix's)"
            ),
        })
    }

    fn facts(&self) -> Option<BackendFacts> {
        Some(self.factor.facts.to_backend_facts())
    }

    fn refactorizations(&self) -> usize {
        self.factor.refactorizations
    }
}
