//! What a precompute computed, as the formulation returns it: the back
//! ends, the factor's facts and sizes, the time of each phase, the
//! warnings, and the facts only this method has ([`MethodFacts`]). The
//! solver ([`crate::solver::LseSolver`]) alone turns it into the
//! [`crate::report::Report`].

use super::{Method, Prepared};
use crate::backend::{BackendFacts, BackendName, FactorKind};
use crate::report::{MethodFacts, Warning};

/// Entry counts of what a precompute built (the report's `nnz`, less the
/// `a` and `b` of the problem itself); `None` where the method builds no
/// such thing.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FactorSizes {
    /// `A Q2` (null-space method only).
    pub aq2: Option<usize>,
    /// The matrix that was factored, counted as a full symmetric matrix
    /// (both triangles).
    pub normal: Option<usize>,
    /// The factor `L` (lower triangle).
    pub factor: Option<usize>,
    /// Bytes of the factor's values and row indices.
    pub factor_bytes: Option<usize>,
    /// Entries of the implicit `Q` and `R` of the constraint QR.
    pub qr: Option<usize>,
}

/// Wall-clock seconds of the precompute's phases (paper §4; the report's
/// `timings_s`), `0` for a phase the method does not have.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PhaseTimings {
    /// QR of `Bᵀ` with rank detection.
    pub qr: f64,
    /// `A Q2`, the KKT ordering, the eliminated columns: what a method
    /// prepares beyond the normal matrix.
    pub preparation: f64,
    /// The normal matrix (pattern and values).
    pub normal_matrix: f64,
    /// Symbolic analysis.
    pub symbolic: f64,
    /// Numeric factorisation.
    pub numeric: f64,
    /// Computing a fill-reducing ordering given to the back end (one held
    /// equal across back ends); 0 when the back end ordered by itself,
    /// inside `symbolic`.
    pub ordering: f64,
}

/// The record of one precompute.
#[derive(Debug, Clone, PartialEq)]
pub struct PrecomputeRecord {
    /// The method.
    pub method: Method,
    /// The QR back end's name (null-space method only).
    pub qr_backend: Option<BackendName>,
    /// The factorisation of the matrix factored (a Cholesky, or KKT's
    /// `LDLᵀ`).
    pub factor_backend: FactorKind,
    /// The numerical rank of `B` (the hard rows kept): the QR's, the
    /// vertices eliminated, all rows for KKT (it fails otherwise); `None`
    /// for penalty, which has no rank detection.
    pub rank: Option<usize>,
    /// Entry counts.
    pub sizes: FactorSizes,
    /// Seconds per phase.
    pub timings: PhaseTimings,
    /// What the user should know about the precompute.
    pub warnings: Vec<Warning>,
    /// What only this method has.
    pub facts: MethodFacts,
    /// What the factor's back end reports beyond this record, as a section
    /// of the report (MUMPS: its ranks under `mumps`); `None` for back
    /// ends that report nothing more.
    pub backend_facts: Option<BackendFacts>,
    /// The fill-reducing ordering the factorisation used
    /// ([`crate::backend::ordering::PlanUsed`]); `None` when nothing was
    /// factored.
    pub ordering: Option<BackendName>,
    /// The threads the factorisation ran on; `None` when nothing was
    /// factored or the back end does not say.
    pub threads: Option<usize>,
}

impl PrecomputeRecord {
    /// An empty record for `method` factoring with `factor_backend`.
    pub fn new(method: Method, factor_backend: FactorKind, facts: MethodFacts) -> Self {
        PrecomputeRecord {
            method,
            qr_backend: None,
            factor_backend,
            rank: None,
            sizes: FactorSizes::default(),
            timings: PhaseTimings::default(),
            warnings: Vec::new(),
            facts,
            backend_facts: None,
            ordering: None,
            threads: None,
        }
    }
}

/// A precomputed system and the record of its precompute.
pub struct Precomputed {
    /// The system, ready to solve.
    pub system: Box<dyn Prepared>,
    /// What the precompute computed.
    pub record: PrecomputeRecord,
}
