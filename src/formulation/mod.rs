//! Formulations of the constrained least-squares problem: the same inputs
//! (`A, C, B, D` of an [`LseProblem`]) and the same [`PrecomputeRecord`]
//! (which the solver turns into the [`crate::report::Report`]), so that the
//! paper's method can be compared with the alternatives on equal terms.
//!
//! | formulation | matrix factored | hard rows |
//! |---|---|---|
//! | [`NullSpaceQr`] (the paper) | `(AQ2)ᵀ(AQ2)`, SPD | exact; dependent rows skipped in list order |
//! | [`Penalty`] | `AᵀA + w²BᵀB`, SPD | approximated (`exact() == false`) |
//! | [`Kkt`] | `[AᵀA sBᵀ; sB 0]`, symmetric indefinite | exact; dependent rows make it singular (an error) |
//! | [`Elimination`] | `A_Uᵀ A_U`, SPD | exact; position constraints only |

use std::sync::Arc;

use crate::backend::ldlt::{LdltBackend, LdltKind};
use crate::backend::qr::{QrBackend, QrKind};
use crate::backend::spd::{SpdBackend, SpdKind};
use crate::backend::{BackendName, FactorStorage};
pub use crate::choice::Method;
use crate::choice::Word;
use crate::error::{ProblemError, SolveOption};

mod elimination;
mod iterative_refinement;
mod kkt;
mod null_space;
mod penalty;
mod precompute;
mod prepared;
mod record;
mod util;

pub use elimination::Elimination;
pub(crate) use iterative_refinement::refine_with_rounding;
pub use iterative_refinement::{
    AUTO_MAX_STEPS, CONVERGED_ULPS, FORWARD_ERROR_WARNING, FactorRounding, REMEASURE_EVERY, Refine,
    RefineStop, Refinement, max_hard_residual, refine,
};
pub use kkt::{KKT_BACKWARD_ERROR_TOLERANCE, KKT_PIVOT_TOLERANCE, Kkt, kkt_ordering};
pub use null_space::NullSpaceQr;
pub use penalty::{
    PENALTY_FORWARD_ERROR_LIMIT, Penalty, PenaltyPoint, PenaltySolution, PenaltySweep,
};
pub use precompute::Formulation;
pub use prepared::Prepared;
pub use record::{FactorSizes, PhaseTimings, PrecomputeRecord, Precomputed};

/// KKT's refusal of an SPD back end that selects no `LDLᵀ` variant.
fn not_an_ldlt(spd: &dyn std::fmt::Display) -> ProblemError {
    ProblemError::InvalidOption {
        option: SolveOption::Spd,
        message: format!(
            "the KKT method factors a symmetric indefinite matrix with an LDLᵀ back end: its SPD back end must select one (faer-auto, faer-simplicial, faer-supernodal or mumps), not '{spd}'; or give the LDLᵀ back end itself"
        ),
    }
}

/// [`FormulationChoice::validate`] of an SPD choice: in this build, and
/// able to keep its factor in `storage`; MUMPS driven from this process.
fn check_spd(spd: &SpdChoice, storage: &FactorStorage) -> Result<(), ProblemError> {
    match spd {
        // Not in the build: the catalogue's refusal (nothing is built).
        Chosen::Builtin(kind) if !kind.in_this_build() => kind.backend_with(storage).map(drop),
        Chosen::Builtin(SpdKind::Mumps) => mumps_drivable(),
        Chosen::Builtin(kind) => storage.refuse_out_of_core(kind.name()),
        Chosen::Own(backend) => storage.refuse_out_of_core(&backend.name()),
    }
}

/// [`check_spd`] for an `LDLᵀ` variant.
fn check_ldlt(kind: LdltKind, storage: &FactorStorage) -> Result<(), ProblemError> {
    match kind {
        LdltKind::Mumps if !kind.in_this_build() => kind.backend_with(storage).map(drop),
        LdltKind::Mumps => mumps_drivable(),
        _ => storage.refuse_out_of_core(kind.name()),
    }
}

/// Whether this process can drive MUMPS (rank 0 of ranks that serve it).
#[cfg(feature = "mumps")]
fn mumps_drivable() -> Result<(), ProblemError> {
    crate::backend::mumps::check_driving_rank()
}

#[cfg(not(feature = "mumps"))]
fn mumps_drivable() -> Result<(), ProblemError> {
    Ok(())
}

/// The QR back end of a default formulation: sparse Givens rotations.
pub const DEFAULT_QR: QrKind = QrKind::SparseGivens;

/// The SPD back end of a default formulation: faer's Cholesky, simplicial
/// or supernodal by its own choice (and for KKT its `LDLᵀ`).
pub const DEFAULT_SPD: SpdKind = SpdKind::FaerAuto;

/// A back end as chosen: a word of the catalogue
/// ([`crate::backend::catalogue`]), or a back end brought from outside
/// the crate ([`Chosen::Own`]), which then appears under its own name in
/// every record, report and `compare` row.
pub enum Chosen<K, B: ?Sized> {
    /// One of the crate's own back ends.
    Builtin(K),
    /// A back end from outside the catalogue.
    Own(Arc<B>),
}

/// The SPD back end of a formulation.
pub type SpdChoice = Chosen<SpdKind, dyn SpdBackend>;
/// The QR back end of the null-space method.
pub type QrChoice = Chosen<QrKind, dyn QrBackend>;
/// The `LDLᵀ` back end of the KKT method.
pub type LdltChoice = Chosen<LdltKind, dyn LdltBackend>;

/// What a chosen back end is called: its name ([`BackendName`]).
pub trait NamedBackend {
    /// The back end's name.
    fn backend_name(&self) -> BackendName;
}

impl NamedBackend for dyn SpdBackend {
    fn backend_name(&self) -> BackendName {
        self.name()
    }
}

impl NamedBackend for dyn QrBackend {
    fn backend_name(&self) -> BackendName {
        self.name()
    }
}

impl NamedBackend for dyn LdltBackend {
    fn backend_name(&self) -> BackendName {
        self.name()
    }
}

impl<K: Word, B: ?Sized + NamedBackend> Chosen<K, B> {
    /// The back end's name: the catalogue's word, or the outside back
    /// end's own.
    pub fn name(&self) -> BackendName {
        match self {
            Chosen::Builtin(kind) => kind.name().into(),
            Chosen::Own(backend) => backend.backend_name(),
        }
    }

    /// The catalogue's word, for a built-in.
    pub(crate) fn builtin(&self) -> Option<K> {
        match self {
            Chosen::Builtin(kind) => Some(*kind),
            Chosen::Own(_) => None,
        }
    }
}

impl<K: Clone, B: ?Sized> Clone for Chosen<K, B> {
    fn clone(&self) -> Self {
        match self {
            Chosen::Builtin(kind) => Chosen::Builtin(kind.clone()),
            Chosen::Own(backend) => Chosen::Own(Arc::clone(backend)),
        }
    }
}

impl<K, B: ?Sized> From<K> for Chosen<K, B> {
    fn from(kind: K) -> Self {
        Chosen::Builtin(kind)
    }
}

/// Built-ins are equal by their word, outside back ends by identity (the
/// same object).
impl<K: PartialEq, B: ?Sized> PartialEq for Chosen<K, B> {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Chosen::Builtin(a), Chosen::Builtin(b)) => a == b,
            (Chosen::Own(a), Chosen::Own(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }
}

impl<K: PartialEq, B: ?Sized> PartialEq<K> for Chosen<K, B> {
    fn eq(&self, other: &K) -> bool {
        matches!(self, Chosen::Builtin(kind) if kind == other)
    }
}

impl<K: Word + std::fmt::Debug, B: ?Sized + NamedBackend> std::fmt::Debug for Chosen<K, B> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Chosen::Builtin(kind) => write!(f, "{kind:?}"),
            Chosen::Own(backend) => write!(f, "Own({:?})", backend.backend_name()),
        }
    }
}

impl<K: Word, B: ?Sized + NamedBackend> std::fmt::Display for Chosen<K, B> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name())
    }
}

/// A formulation with its back ends (the CLI's `--method`, `--qr`,
/// `--spd`, `--weight`); [`FormulationChoice::build`] makes it.
///
/// - `NullSpaceQr`: any QR back end × any SPD back end;
/// - `Penalty`: any SPD back end, `weight` required (there is no weight that
///   is right for every mesh: it competes with the scale of `L`);
/// - `Kkt`: the `LDLᵀ` back end `ldlt`, or when `None` the catalogue's
///   variant that `spd` selects ([`LdltKind::for_spd`]: faer's or
///   MUMPS's); other SPD kinds are refused;
/// - `Eliminate`: any SPD back end (position constraints only).
///
/// `qr` is used by `NullSpaceQr` only; `weight` by `Penalty` only; `ldlt`
/// by `Kkt` only. Each back end is a catalogue word or an outside back
/// end ([`Chosen`]).
///
/// The catalogue (every word, with the build that has it):
/// - SPD (`spd`): `faer-auto` (the default), `faer-supernodal`,
///   `faer-simplicial`, `nalgebra`, `cholmod` (feature `suitesparse`),
///   `mumps` (feature `mumps`); [`SpdKind::available`] lists this build's;
/// - QR (`qr`): `sparse-givens` (the default), `dense-householder`, `spqr`
///   (feature `suitesparse`); [`QrKind::available`];
/// - `LDLᵀ` (`ldlt`): `faer-ldlt-auto`, `faer-ldlt-supernodal`,
///   `faer-ldlt-simplicial`, `mumps-ldlt` (feature `mumps`).
#[derive(Clone, Debug, PartialEq)]
pub struct FormulationChoice {
    /// The formulation.
    pub method: Method,
    /// The QR back end of `NullSpaceQr`.
    pub qr: QrChoice,
    /// The SPD back end (for `Kkt` without `ldlt`: the catalogue's `LDLᵀ`
    /// variant it selects).
    pub spd: SpdChoice,
    /// The `LDLᵀ` back end of `Kkt`; `None`: the one `spd` selects.
    pub ldlt: Option<LdltChoice>,
    /// The relative weight of the hard rows under `Penalty`.
    pub weight: Option<f64>,
}

impl FormulationChoice {
    /// `method` with the default back ends: sparse Givens QR, faer's
    /// automatic Cholesky (and `LDLᵀ`), no weight.
    pub fn new(method: Method) -> FormulationChoice {
        FormulationChoice {
            method,
            qr: DEFAULT_QR.into(),
            spd: DEFAULT_SPD.into(),
            ldlt: None,
            weight: None,
        }
    }

    /// The name of the back end that factors: the SPD back end's, or for
    /// `Kkt` the `LDLᵀ` back end's (the report's `factor_backend`).
    pub(crate) fn factor_name(&self) -> BackendName {
        match (&self.method, &self.ldlt, &self.spd) {
            (Method::Kkt, Some(ldlt), _) => ldlt.name(),
            (Method::Kkt, None, Chosen::Builtin(spd)) => {
                LdltKind::for_spd(*spd).map_or_else(|| spd.name().into(), |k| k.name().into())
            }
            _ => self.spd.name(),
        }
    }

    /// A label for tables: the method and its back ends' names
    /// (`nullspace-qr sparse-givens/faer-auto`, `penalty faer-auto w=1e8`,
    /// `kkt faer-ldlt-auto`, `eliminate my-cg`).
    pub fn label(&self) -> String {
        match self.method {
            Method::NullSpaceQr => format!("{} {}/{}", self.method, self.qr, self.spd),
            Method::Penalty => match self.weight {
                Some(w) => format!("{} {} w={w:e}", self.method, self.spd),
                None => format!("{} {}", self.method, self.spd),
            },
            Method::Kkt => format!("{} {}", self.method, self.factor_name()),
            Method::Eliminate => format!("{} {}", self.method, self.spd),
        }
    }

    /// The formulation.
    ///
    /// Errors: [`ProblemError::InvalidOption`] for a penalty without a
    /// finite positive weight or an SPD kind that KKT cannot use;
    /// [`ProblemError::InvalidArgument`] for a back end missing from this
    /// build.
    pub fn build(&self) -> Result<Box<dyn Formulation>, ProblemError> {
        self.build_with(&FactorStorage::InCore)
    }

    /// The formulation, a built-in factor kept in `storage` (out of core:
    /// the catalogue's `mumps` only; a setting of that back end, which the
    /// catalogue passes to it).
    ///
    /// Errors: as [`FormulationChoice::build`], and
    /// [`ProblemError::InvalidArgument`] for out-of-core storage with
    /// another back end.
    pub(crate) fn build_with(
        &self,
        storage: &FactorStorage,
    ) -> Result<Box<dyn Formulation>, ProblemError> {
        storage.check()?;
        match self.method {
            Method::NullSpaceQr => Ok(Box::new(NullSpaceQr::new(
                self.qr_backend()?,
                self.spd_backend(storage)?,
            ))),
            Method::Penalty => Ok(Box::new(Penalty::with_backend(
                self.penalty_weight()?,
                self.spd_backend(storage)?,
            ))),
            Method::Kkt => Ok(Box::new(Kkt::with_backend(self.ldlt_backend(storage)?))),
            Method::Eliminate => Ok(Box::new(Elimination::new(self.spd_backend(storage)?))),
        }
    }

    /// Checks what [`FormulationChoice::build_with`] would refuse, without
    /// building a back end: the storage, the penalty weight, and each back
    /// end in this build and able to keep its factor in `storage` (MUMPS:
    /// driven from this process; its out-of-core directory is checked on
    /// every rank when it is built).
    pub fn validate(&self, storage: &FactorStorage) -> Result<(), ProblemError> {
        storage.check()?;
        match self.method {
            Method::NullSpaceQr => {
                if let Chosen::Builtin(kind) = self.qr
                    && !kind.in_this_build()
                {
                    kind.backend()?;
                }
                check_spd(&self.spd, storage)
            }
            Method::Penalty => {
                self.penalty_weight()?;
                check_spd(&self.spd, storage)
            }
            Method::Kkt => match (&self.ldlt, &self.spd) {
                (Some(Chosen::Builtin(kind)), _) => check_ldlt(*kind, storage),
                (Some(Chosen::Own(backend)), _) => storage.refuse_out_of_core(&backend.name()),
                (None, Chosen::Builtin(spd)) => check_ldlt(
                    LdltKind::for_spd(*spd).ok_or_else(|| not_an_ldlt(spd))?,
                    storage,
                ),
                (None, spd @ Chosen::Own(_)) => Err(not_an_ldlt(spd)),
            },
            Method::Eliminate => check_spd(&self.spd, storage),
        }
    }

    /// The SPD back end, a built-in made with `storage`.
    fn spd_backend(&self, storage: &FactorStorage) -> Result<Arc<dyn SpdBackend>, ProblemError> {
        match &self.spd {
            Chosen::Builtin(kind) => kind.backend_with(storage),
            Chosen::Own(backend) => {
                storage.refuse_out_of_core(&backend.name())?;
                Ok(Arc::clone(backend))
            }
        }
    }

    /// The QR back end.
    fn qr_backend(&self) -> Result<Arc<dyn QrBackend>, ProblemError> {
        match &self.qr {
            Chosen::Builtin(kind) => kind.backend(),
            Chosen::Own(backend) => Ok(Arc::clone(backend)),
        }
    }

    /// The penalty weight, required finite and positive.
    fn penalty_weight(&self) -> Result<f64, ProblemError> {
        let invalid = |message: String| ProblemError::InvalidOption {
            option: SolveOption::Weight,
            message,
        };
        let w = self.weight.ok_or_else(|| {
            invalid(
                "the penalty method needs a weight (the relative weight of the former hard rows)"
                    .into(),
            )
        })?;
        if !(w.is_finite() && w > 0.0) {
            return Err(invalid(format!("weight {w} must be finite and > 0")));
        }
        Ok(w)
    }

    /// KKT's `LDLᵀ` back end: `ldlt`, or the catalogue's variant that a
    /// built-in `spd` selects, made with `storage`.
    fn ldlt_backend(&self, storage: &FactorStorage) -> Result<Arc<dyn LdltBackend>, ProblemError> {
        let refuse = |spd: &dyn std::fmt::Display| not_an_ldlt(spd);
        match (&self.ldlt, &self.spd) {
            (Some(Chosen::Builtin(kind)), _) => kind.backend_with(storage),
            (Some(Chosen::Own(backend)), _) => {
                storage.refuse_out_of_core(&backend.name())?;
                Ok(Arc::clone(backend))
            }
            (None, Chosen::Builtin(spd)) => LdltKind::for_spd(*spd)
                .ok_or_else(|| refuse(spd))?
                .backend_with(storage),
            (None, spd @ Chosen::Own(_)) => Err(refuse(spd)),
        }
    }
}
