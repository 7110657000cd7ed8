//! MUMPS's `LDLᵀ` (`SYM = 2`) behind the `LDLᵀ` seam
//! ([`crate::backend::ldlt`]), for the KKT formulation.
//!
//! The seam's contract is a **static** order given by the caller. MUMPS
//! gets it as `PERM_IN` (`ICNTL(7) = 1`) with numerical pivoting only for
//! a pivot that is exactly zero (`CNTL(1)`, [`PIVOT_THRESHOLD`]), MUMPS's
//! automatic symmetric scaling (`ICNTL(8) = 77`: a diagonal scaling, which
//! changes no pivot's zero-ness and makes the null-pivot test below
//! relative to rows of comparable size), the usual (not compressed) ordering
//! (`ICNTL(12) = 1`) and the root node factored like any other
//! (`ICNTL(13) = 1`). MUMPS still orders within its own tree: unknowns with
//! one pattern (duplicate constraints) are merged into one node and may be
//! eliminated in another order than the given one. MUMPS does not hand
//! out the pivots: it judges them itself with its null-pivot detection
//! (`ICNTL(24) = 1`), which flags a pivot whose row in the frontal matrix
//! has an infinity norm below `CNTL(3)` times the norm of the scaled `K`;
//! `CNTL(3)` is the KKT pivot
//! tolerance `1000 ε` and `K` is already scaled so that its constraint
//! block matches `AᵀA`. The flagged unknowns (`PIVNUL_LIST`) and the count
//! of negative pivots (`INFOG(12)`) are what [`LdltFactor::detected_pivots`]
//! returns; the KKT formulation maps them to the same errors as faer's
//! pivots (docs/distributed.md §3).

use std::path::PathBuf;

use faer::MatMut;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

use super::cholesky::MumpsSymbolic;
use super::instance::Params;
use super::session::{Factorisation, lock};
use super::{MumpsFacts, numerical};
use crate::backend::ldlt::{
    DetectedPivots, LdltBackend, LdltFactor, LdltKind, LdltSymbolic, Pivot,
};
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;

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
/// pivot in place unless it is below this fraction of the largest entry
/// of its column in the front. Zero would turn pivoting off, but MUMPS's
/// null-pivot detection lives in its pivot search and stops with it (a
/// zero pivot is then error −10), so the threshold is the smallest normal
/// double rather than zero: only an exactly zero pivot leaves its place.
/// (With `1e-10`, small but sound pivots of sliver-heavy meshes were
/// delayed out of the static order and met as null ones later.)
const PIVOT_THRESHOLD: f64 = f64::MIN_POSITIVE;

/// MUMPS's `LDLᵀ` in a static order.
#[derive(Debug, Clone, Default)]
pub struct MumpsLdlt {
    out_of_core: Option<PathBuf>,
}

impl MumpsLdlt {
    /// In core (`None`) or with the factor in files under `out_of_core`,
    /// which every rank checks it can use (bad input when one cannot:
    /// [`super::check_out_of_core`]).
    pub fn new(out_of_core: Option<PathBuf>) -> Result<MumpsLdlt, ProblemError> {
        super::check_out_of_core(out_of_core.as_deref())?;
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
    fn kind(&self) -> LdltKind {
        LdltKind::Mumps
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
    ) -> Result<Box<dyn LdltSymbolic>, NumericalError> {
        // PERM_IN(i): the (1-based) position of unknown i in the order.
        let mut perm_in = vec![0i32; order.len()];
        for (position, &unknown) in order.iter().enumerate() {
            perm_in[unknown] = position as i32 + 1;
        }
        let symbolic = MumpsSymbolic::analyse(
            lower,
            2,
            perm_in,
            &analysis_params(),
            self.out_of_core.as_deref(),
        )?;
        Ok(Box::new(MumpsLdltSymbolic(symbolic)))
    }
}

struct MumpsLdltSymbolic(MumpsSymbolic);

impl LdltSymbolic for MumpsLdltSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn LdltFactor>, NumericalError> {
        let shared = &self.0.shared;
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
