//! The conformance kit (cargo feature `proptest`): one call per seam —
//! [`spd`], [`qr`], [`ldlt`] — runs, against any back end, the properties
//! every back end of this crate passes (docs/backends.md §8 states them and
//! the contract behind them, docs/backends.md §1–§7):
//!
//! | property | SPD | QR | `LDLᵀ` |
//! |---|---|---|---|
//! | [`Property::Named`] | ✓ | ✓ | ✓ |
//! | [`Property::Exactness`] | null-space method | null-space method | KKT |
//! | [`Property::RankSets`] | | ✓ | |
//! | [`Property::Operations`] | | ✓ | |
//! | [`Property::Oracle`] | null-space method, elimination | null-space method | KKT |
//! | [`Property::Refusal`] | a matrix that is not positive definite | | a dependent constraint |
//! | [`Property::SeveralFactors`] | ✓ | ✓ | ✓ |
//! | [`Property::Budget`] | ✓ | ✓ | ✓ |
//! | [`Property::Interruption`] | ✓ | ✓ | ✓ |
//! | [`Property::Columns`] | ✓ | ✓ | ✓ |
//!
//! Every property runs [`KitConfig::cases`] generated cases (proptest,
//! with shrinking; interruption a quarter of them, since each case waits
//! twice for [`crate::interrupt::CONSULT_INTERVAL`]), and every property
//! runs even after another failed: the answer lists each failing property
//! with its minimal case and the seed that reproduces it
//! ([`KitFailure`]). A panic inside the back end is a failure of the
//! property that met it, never of the caller.
//!
//! A researcher's own test (`lse-deform = { version = "0.1", features =
//! ["proptest"] }` in `[dev-dependencies]`), with their back end in place
//! of faer's:
//!
//! ```
//! use std::sync::Arc;
//! use lse_deform::backend::spd::FaerLlt;
//! use lse_deform::testing::conformance::{self, KitConfig};
//!
//! let report = conformance::assert_conforms(conformance::spd(
//!     Arc::new(FaerLlt::auto()),
//!     &KitConfig::with_cases(2),
//! ));
//! assert_eq!(report.backend, "faer-auto");
//! ```

use std::fmt;
use std::hash::BuildHasher;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};

use faer::sparse::{SparseColMat, SparseColMatRef, SparseRowMat, SymbolicSparseColMatRef, Triplet};
use faer::{Mat, MatMut, MatRef};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed, TestError, TestRunner};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::backend::ldlt::{LdltBackend, LdltFactor, LdltSymbolic, PivotFault, PivotRule};
use crate::backend::qr::{
    ConstraintQr, QrBackend, RankTolerance, SparseGivens, particular_solution,
};
use crate::backend::spd::{FaerLlt, SpdBackend, SpdFactor, SpdSymbolic};
use crate::backend::{BackendFacts, BackendName, FactorKind};
use crate::constraints::ConstraintSet;
use crate::deform::Deformer;
use crate::error::{Error, NumericalError, ProblemError};
use crate::formulation::{
    Elimination, Formulation, KKT_PIVOT_TOLERANCE, Kkt, NullSpaceQr, Penalty, Refine,
};
use crate::laplacian::LaplacianKind;
use crate::limits::MemoryBudget;
use crate::problem::LseProblem;
use crate::resources::Resources;
use crate::solver::LseSolver;
use crate::testing::{
    ConstraintMix, ConstructedLse, ConstructedMix, RandomLse, constraint_mixes, constructed_lses,
    constructed_mixes, dense_reference, independent_constraints, laplacian_kinds, meshes,
    random_lses, random_surface, relative_difference, with_soft,
};

// ---------------------------------------------------------------------------
// What the kit checks and what it answers.

/// The seams a back end can fill.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Seam {
    /// [`SpdBackend`]: sparse Cholesky (or anything that solves SPD systems).
    Spd,
    /// [`QrBackend`]: QR of `Bᵀ` with rank detection.
    Qr,
    /// [`LdltBackend`]: static-order `LDLᵀ` of symmetric indefinite matrices.
    Ldlt,
}

impl Seam {
    /// The seam's word in messages.
    pub fn name(self) -> &'static str {
        match self {
            Seam::Spd => "SPD",
            Seam::Qr => "QR",
            Seam::Ldlt => "LDLᵀ",
        }
    }
}

/// A property of the kit (docs/backends.md §8).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Property {
    /// The name is not empty, the same at every call, and the report of a
    /// method that used the back end carries it.
    Named,
    /// (a) Through the method (the null-space method with this SPD or QR
    /// back end, KKT with this `LDLᵀ` back end), every kept hard
    /// constraint holds to `1e-12` of its scale ([`EXACTNESS`]) on
    /// generated meshes and constraint mixes.
    Exactness,
    /// (b) QR: the rank, the kept rows and the skipped rows (redundant and
    /// conflicting, in list order) as constructed, rows a factor of ten
    /// either side of the rank tolerance included; through the method, the
    /// report's rank, redundant and conflicting sets.
    RankSets,
    /// QR: the factor's operations agree with dense arithmetic: `Qᵀ` then
    /// `Q` is the identity and keeps norms, `B_kept Q2 = 0`, `A Q2` equals
    /// `Q` applied to `[0; I]`, `R1ᵀ y = D_kept` makes `B_kept x = D_kept`.
    Operations,
    /// (c) The method's solution agrees with the dense oracle
    /// ([`dense_reference`]) to [`ORACLE`].
    Oracle,
    /// (d) A matrix the back end cannot factor is refused by a typed error
    /// — never a panic, never a non-finite or wrong solution: for SPD a
    /// symmetric matrix with a zero or negative diagonal entry (so not
    /// positive definite), at the factorisation or at the latest at the
    /// first solve; for `LDLᵀ` a KKT matrix with a dependent constraint
    /// (a [`PivotFault`], or a typed error of the factorisation; through
    /// KKT a numerical error).
    Refusal,
    /// (e) Several numeric factorisations of one analysis (SPD, `LDLᵀ`),
    /// or several QR factorisations, alive at once, each solving with its
    /// own matrix in interleaved order.
    SeveralFactors,
    /// (f) A budget of one byte is refused with
    /// [`ProblemError::TooLarge`] (`check_budget` of an analysis, a QR
    /// within the budget, a method's precompute); an unlimited one is not.
    Budget,
    /// (f) A precompute interrupted right after the back end factored, and
    /// a solve interrupted right after it solved ([`crate::interrupt`]),
    /// end in [`Error::Interrupted`]; then the method precomputes and
    /// solves again as if nothing happened.
    Interruption,
    /// (g) Solves of one, three and seven columns at once (a matrix's
    /// solve; through the method, the three columns of a mesh and the
    /// seven of [`LseSolver::solve_columns`], which the null-space method
    /// solves in one pass), each column as it would be alone.
    Columns,
}

impl Property {
    /// The property's word in messages.
    pub fn name(self) -> &'static str {
        match self {
            Property::Named => "named",
            Property::Exactness => "exactness",
            Property::RankSets => "rank-sets",
            Property::Operations => "operations",
            Property::Oracle => "oracle",
            Property::Refusal => "refusal",
            Property::SeveralFactors => "several-factors",
            Property::Budget => "budget",
            Property::Interruption => "interruption",
            Property::Columns => "columns",
        }
    }
}

/// How much the kit runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KitConfig {
    /// Generated cases per property (interruption: a quarter, at least
    /// one).
    pub cases: u32,
    /// The seed of the generated cases; `None`: a fresh one, which a
    /// failure reports.
    pub seed: Option<u64>,
}

impl Default for KitConfig {
    /// Eight cases per property, a fresh seed.
    fn default() -> Self {
        KitConfig {
            cases: 8,
            seed: None,
        }
    }
}

impl KitConfig {
    /// `cases` cases per property, a fresh seed.
    pub fn with_cases(cases: u32) -> KitConfig {
        KitConfig { cases, seed: None }
    }
}

/// A property that held, and on how many cases.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Passed {
    /// The property.
    pub property: Property,
    /// Cases run (generated ones; 1 for a fixed check).
    pub cases: u32,
}

/// A property that failed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PropertyFailure {
    /// The property.
    pub property: Property,
    /// What went wrong on the minimal case.
    pub message: String,
    /// The minimal failing case (`Debug`, shortened), for generated
    /// properties.
    pub case: Option<String>,
}

/// A back end that passed every property.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KitReport {
    /// The back end's name.
    pub backend: BackendName,
    /// Its seam.
    pub seam: Seam,
    /// The seed the cases were drawn with.
    pub seed: u64,
    /// Every property, in the order run.
    pub passed: Vec<Passed>,
}

/// A back end that failed at least one property.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KitFailure {
    /// The back end's name.
    pub backend: BackendName,
    /// Its seam.
    pub seam: Seam,
    /// The seed the cases were drawn with (`KitConfig { seed: Some(seed),
    /// .. }` draws them again).
    pub seed: u64,
    /// The properties that held.
    pub passed: Vec<Passed>,
    /// The properties that failed, in the order run.
    pub failures: Vec<PropertyFailure>,
}

impl KitFailure {
    /// Whether `property` is among the failures.
    pub fn failed(&self, property: Property) -> bool {
        self.failures.iter().any(|f| f.property == property)
    }
}

impl fmt::Display for KitFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "the {} back end '{}' fails {} of {} properties of the conformance kit (docs/backends.md §8); KitConfig {{ seed: Some({}), .. }} draws the same cases:",
            self.seam.name(),
            self.backend,
            self.failures.len(),
            self.failures.len() + self.passed.len(),
            self.seed
        )?;
        for failure in &self.failures {
            writeln!(f, "- {}: {}", failure.property.name(), failure.message)?;
            if let Some(case) = &failure.case {
                writeln!(f, "  minimal case: {case}")?;
            }
        }
        Ok(())
    }
}

impl std::error::Error for KitFailure {}

/// The report of a back end that passed; panics, at the caller's line, with
/// every failing property and its minimal case otherwise.
#[track_caller]
pub fn assert_conforms(result: Result<KitReport, KitFailure>) -> KitReport {
    match result {
        Ok(report) => report,
        Err(failure) => panic!("{failure}"),
    }
}

/// Runs the properties of one back end and collects their outcomes.
struct Kit<'a> {
    seam: Seam,
    backend: BackendName,
    config: &'a KitConfig,
    seed: u64,
    passed: Vec<Passed>,
    failures: Vec<PropertyFailure>,
}

/// How many simplifications of a failing case are tried at most (or four
/// per case, if more).
const SHRINK_ITERATIONS: u32 = 256;

/// How many characters of a minimal case a failure keeps.
const CASE_CHARS: usize = 4000;

impl<'a> Kit<'a> {
    fn new(seam: Seam, backend: BackendName, config: &'a KitConfig) -> Kit<'a> {
        let seed = config
            .seed
            .unwrap_or_else(|| std::collections::hash_map::RandomState::new().hash_one(0u8));
        Kit {
            seam,
            backend,
            config,
            seed,
            passed: Vec::new(),
            failures: Vec::new(),
        }
    }

    /// Records that `property` held on `cases` more cases (merged with an
    /// earlier run of the same property) unless it already failed.
    fn pass(&mut self, property: Property, cases: u32) {
        if self.failed(property) {
            return;
        }
        match self.passed.iter_mut().find(|p| p.property == property) {
            Some(p) => p.cases += cases,
            None => self.passed.push(Passed { property, cases }),
        }
    }

    /// Whether `property` failed already.
    fn failed(&self, property: Property) -> bool {
        self.failures.iter().any(|f| f.property == property)
    }

    /// Records the first failure of `property` (dropping what it passed
    /// before).
    fn fail(&mut self, property: Property, message: String, case: Option<String>) {
        if self.failed(property) {
            return;
        }
        self.passed.retain(|p| p.property != property);
        self.failures.push(PropertyFailure {
            property,
            message,
            case,
        });
    }

    /// Runs `check` on `cases` cases of `strategy` (shrinking a failure to
    /// a minimal case); a panic is a failure.
    fn generated<S: Strategy>(
        &mut self,
        property: Property,
        cases: u32,
        strategy: S,
        check: impl Fn(S::Value) -> Result<(), String>,
    ) {
        if self.failed(property) {
            return;
        }
        let config = Config {
            cases,
            max_shrink_iters: SHRINK_ITERATIONS.max(4 * cases),
            failure_persistence: None,
            rng_seed: RngSeed::Fixed(
                self.seed ^ (property as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15),
            ),
            ..Config::default()
        };
        let mut runner = TestRunner::new(config);
        match runner.run(&strategy, |case| check(case).map_err(TestCaseError::fail)) {
            Ok(()) => self.pass(property, cases),
            Err(TestError::Fail(reason, case)) => self.fail(
                property,
                reason.message().to_string(),
                Some(shorten(&format!("{case:?}"))),
            ),
            Err(TestError::Abort(reason)) => {
                self.fail(property, format!("no case could be run: {reason}"), None)
            }
        }
    }

    /// Runs `cases` of the configured count.
    fn cases(&self) -> u32 {
        self.config.cases.max(1)
    }

    /// Runs a check without generated cases; a panic is a failure.
    fn fixed(&mut self, property: Property, check: impl FnOnce() -> Result<(), String>) {
        match catch_unwind(AssertUnwindSafe(check)) {
            Ok(Ok(())) => self.pass(property, 1),
            Ok(Err(message)) => self.fail(property, message, None),
            Err(panic) => self.fail(
                property,
                format!("panicked: {}", panic_message(&*panic)),
                None,
            ),
        }
    }

    fn finish(self) -> Result<KitReport, KitFailure> {
        if self.failures.is_empty() {
            Ok(KitReport {
                backend: self.backend,
                seam: self.seam,
                seed: self.seed,
                passed: self.passed,
            })
        } else {
            Err(KitFailure {
                backend: self.backend,
                seam: self.seam,
                seed: self.seed,
                passed: self.passed,
                failures: self.failures,
            })
        }
    }
}

/// `text`, cut to [`CASE_CHARS`] characters.
fn shorten(text: &str) -> String {
    let count = text.chars().count();
    if count <= CASE_CHARS {
        return text.to_string();
    }
    let head: String = text.chars().take(CASE_CHARS).collect();
    format!("{head}… ({} more characters)", count - CASE_CHARS)
}

/// The message of a caught panic.
fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<String>()
        .cloned()
        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "a panic without a message".into())
}

/// `Ok(())` when `condition` holds, else the message.
fn ensure(condition: bool, message: impl FnOnce() -> String) -> Result<(), String> {
    if condition { Ok(()) } else { Err(message()) }
}

// ---------------------------------------------------------------------------
// Tolerances.

/// How closely a kept hard row must hold through the method: its residual
/// `‖b_k X − d_k‖₂` against its scale `Σ_j |b_kj| ‖X_j‖₂ + ‖d_k‖₂`, after
/// the solver's default refinement (what tests/rank_properties.rs holds
/// every exact method to).
pub const EXACTNESS: f64 = 1e-12;

/// How closely the method's solution must agree with the dense oracle,
/// `max |X − X*| / max |X*|` (the documented example of
/// [`crate::testing`]).
pub const ORACLE: f64 = 1e-8;

/// The largest normwise backward error
/// `‖K x − b‖∞ / (‖K‖∞ ‖x‖∞ + ‖b‖∞)` of a matrix-level solve: a stable
/// direct solve gives a small multiple of `ε`; an iterative one must
/// iterate to this.
pub const BACKWARD_ERROR: f64 = 1e-12;

/// How closely columns solved together must agree with the same columns
/// solved otherwise (relative to the solution's largest entry).
pub const COLUMNS: f64 = 1e-9;

// ---------------------------------------------------------------------------
// The three calls.

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

/// Runs the kit on a QR back end: [`Property::Named`],
/// [`Property::Exactness`], [`Property::RankSets`] and
/// [`Property::Oracle`] through the null-space method (faer's Cholesky),
/// [`Property::Operations`], [`Property::SeveralFactors`],
/// [`Property::Budget`], [`Property::Interruption`], [`Property::Columns`].
///
/// Errors: every failing property with its minimal case ([`KitFailure`]).
pub fn qr(backend: Arc<dyn QrBackend>, config: &KitConfig) -> Result<KitReport, KitFailure> {
    let mut kit = Kit::new(Seam::Qr, backend.name(), config);
    let cases = kit.cases();
    let method = || NullSpaceQr::new(Arc::clone(&backend), Arc::new(FaerLlt::auto()));
    kit.fixed(Property::Named, || {
        let name = backend.name();
        named(&name, &backend.name(), &method(), |r| {
            r.qr_backend.as_ref() == Some(&name)
        })
    });
    kit.generated(Property::Exactness, cases, mixes(), |(mix, kind)| {
        exactness(&method(), &mix, kind)
    });
    kit.generated(Property::RankSets, cases, random_lses(), |lse| {
        qr_random_sets(&*backend, &lse)
    });
    kit.generated(Property::RankSets, cases, constructed_lses(), |lse| {
        qr_constructed_sets(&*backend, &lse)
    });
    kit.generated(Property::RankSets, cases, constructed(), |(mix, kind)| {
        method_sets(&method(), &mix, kind)
    });
    kit.generated(Property::Operations, cases, random_lses(), |lse| {
        qr_operations_of(&*backend, &lse, 3)
    });
    kit.generated(Property::Oracle, cases, mixes(), |(mix, kind)| {
        oracle(&method(), &mix, kind)
    });
    kit.generated(
        Property::SeveralFactors,
        cases,
        (random_lses(), random_lses()),
        |(p, q)| qr_several(&*backend, &p, &q),
    );
    kit.generated(Property::Budget, cases, random_lses(), |lse| {
        qr_budget(&*backend, &lse)
    });
    kit.generated(
        Property::Interruption,
        quarter(cases),
        mixes(),
        |(mix, kind)| {
            let trap = Arc::new(Trap::default());
            let spy: Arc<dyn QrBackend> = Arc::new(SpyQr {
                inner: Arc::clone(&backend),
                trap: Arc::clone(&trap),
            });
            let f = NullSpaceQr::new(spy, Arc::new(FaerLlt::auto()));
            interruption(&f, &trap, &mix, kind, false)
        },
    );
    kit.generated(Property::Columns, cases, random_lses(), |lse| {
        qr_operations_of(&*backend, &lse, 7)
    });
    kit.generated(Property::Columns, cases, mixes(), |(mix, kind)| {
        method_columns(&method(), &mix, kind)
    });
    kit.finish()
}

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

/// A quarter of `cases`, at least one.
fn quarter(cases: u32) -> u32 {
    cases.div_ceil(4)
}

// ---------------------------------------------------------------------------
// Cases: meshes with constraints, and matrices.

/// [`constraint_mixes`] with a Laplacian kind.
fn mixes() -> impl Strategy<Value = (ConstraintMix, LaplacianKind)> {
    (constraint_mixes(), laplacian_kinds())
}

/// [`constructed_mixes`] with a Laplacian kind.
fn constructed() -> impl Strategy<Value = (ConstructedMix, LaplacianKind)> {
    (constructed_mixes(), laplacian_kinds())
}

/// [`constraint_mixes`] without their dependent constraints (what KKT
/// accepts).
fn independent_mixes() -> impl Strategy<Value = (ConstraintMix, LaplacianKind)> {
    mixes().prop_map(|(mix, kind)| (without_dependent(mix), kind))
}

/// [`constraint_mixes`] with at least one dependent constraint.
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

/// A grid matrix: `side × side` unknowns, values drawn from `seed`.
#[derive(Clone, Debug)]
pub struct GridCase {
    /// Unknowns per side.
    pub side: usize,
    /// The seed of the values.
    pub seed: u64,
}

/// Grids of 2–8 unknowns a side.
fn grids() -> impl Strategy<Value = GridCase> {
    (2usize..9, any::<u64>()).prop_map(|(side, seed)| GridCase { side, seed })
}

/// The lower triangle of `L + s I`, `L` the Laplacian of a `side × side`
/// grid with edge weights in `[0.5, 1.5)` and `s` in `[0.01, 1)`, both
/// drawn from `seed`: symmetric positive definite, its pattern fixed by
/// `side` alone. Public so that a back end's own tests can use the kit's
/// matrices.
pub fn grid_lower(side: usize, seed: u64) -> SparseColMat<usize, f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = side * side;
    let shift = rng.random_range(0.01..1.0);
    let mut diagonal = vec![shift; n];
    let mut triplets = Vec::new();
    for a in 0..n {
        let (i, j) = (a / side, a % side);
        let right = (j + 1 < side).then_some(a + 1);
        let below = (i + 1 < side).then_some(a + side);
        for b in [right, below].into_iter().flatten() {
            let w = rng.random_range(0.5..1.5);
            triplets.push(Triplet::new(b, a, -w));
            diagonal[a] += w;
            diagonal[b] += w;
        }
    }
    triplets.extend(
        diagonal
            .iter()
            .enumerate()
            .map(|(a, &d)| Triplet::new(a, a, d)),
    );
    SparseColMat::try_new_from_triplets(n, n, &triplets).expect("a grid's triplets are in range")
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
// Dense arithmetic on the lower triangle.

/// `K X` for the symmetric `K` given by its lower triangle.
fn lower_times(lower: SparseColMatRef<'_, usize, f64>, x: MatRef<'_, f64>) -> Mat<f64> {
    let (ptr, rows, val) = (
        lower.symbolic().col_ptr(),
        lower.symbolic().row_idx(),
        lower.val(),
    );
    let mut y = Mat::<f64>::zeros(x.nrows(), x.ncols());
    for c in 0..x.ncols() {
        for j in 0..lower.ncols() {
            for p in ptr[j]..ptr[j + 1] {
                let i = rows[p];
                y[(i, c)] += val[p] * x[(j, c)];
                if i != j {
                    y[(j, c)] += val[p] * x[(i, c)];
                }
            }
        }
    }
    y
}

/// `‖K‖∞` for the symmetric `K` given by its lower triangle.
fn lower_norm_inf(lower: SparseColMatRef<'_, usize, f64>) -> f64 {
    let (ptr, rows, val) = (
        lower.symbolic().col_ptr(),
        lower.symbolic().row_idx(),
        lower.val(),
    );
    let mut sums = vec![0.0f64; lower.ncols()];
    for j in 0..lower.ncols() {
        for p in ptr[j]..ptr[j + 1] {
            sums[rows[p]] += val[p].abs();
            if rows[p] != j {
                sums[j] += val[p].abs();
            }
        }
    }
    sums.into_iter().fold(0.0, f64::max)
}

/// The largest normwise backward error over the columns of `x` as a
/// solution of `K x = b`; infinite for a non-finite `x`.
fn backward_error(lower: SparseColMatRef<'_, usize, f64>, x: &Mat<f64>, b: &Mat<f64>) -> f64 {
    let kx = lower_times(lower, x.as_ref());
    let norm = lower_norm_inf(lower);
    let mut worst = 0.0f64;
    for c in 0..x.ncols() {
        let column = |m: &Mat<f64>| (0..m.nrows()).map(|i| m[(i, c)].abs()).fold(0.0, f64::max);
        let residual = (0..x.nrows())
            .map(|i| (kx[(i, c)] - b[(i, c)]).abs())
            .fold(0.0, f64::max);
        let eta = residual / (norm * column(x) + column(b));
        worst = worst.max(if eta.is_nan() { f64::INFINITY } else { eta });
    }
    worst
}

/// `rows × cols` entries in `[−1, 1)` from `seed`.
fn random_mat(rows: usize, cols: usize, seed: u64) -> Mat<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Mat::from_fn(rows, cols, |_, _| rng.random_range(-1.0..1.0))
}

/// Solves `K x = b` for `cols` random columns with `solve` and checks the
/// backward error against `lower`.
fn check_solve(
    lower: SparseColMatRef<'_, usize, f64>,
    cols: usize,
    seed: u64,
    solve: impl FnOnce(MatMut<'_, f64>) -> Result<(), NumericalError>,
) -> Result<(), String> {
    let b = random_mat(lower.ncols(), cols, seed);
    let mut x = b.clone();
    solve(x.as_mut()).map_err(|e| format!("a solve of {cols} columns failed: {e}"))?;
    let eta = backward_error(lower, &x, &b);
    ensure(eta <= BACKWARD_ERROR, || {
        format!(
            "a solve of {cols} columns has a backward error of {eta:e} (at most {BACKWARD_ERROR:e})"
        )
    })
}

// ---------------------------------------------------------------------------
// Through the method.

/// The constraints of `mix` as a set.
fn constraint_set(mix: &ConstraintMix) -> Result<ConstraintSet, String> {
    ConstraintSet::from_vec(mix.constraints.clone()).map_err(|e| e.to_string())
}

/// The assembled problem of `mix` (in its units), not factored.
fn problem(mix: &ConstraintMix, kind: LaplacianKind) -> Result<LseProblem, String> {
    Deformer::assemble(&mix.mesh, kind, &constraint_set(mix)?)
        .map_err(|e| format!("the case is not a problem: {e}"))
}

/// `mix` precomputed with `f` (the outer error: the case is not a
/// problem; the inner: the precompute's).
fn factored(
    f: &dyn Formulation,
    mix: &ConstraintMix,
    kind: LaplacianKind,
) -> Result<Result<Deformer, Error>, String> {
    problem(mix, kind)?;
    let set = constraint_set(mix)?;
    Ok(Deformer::with_formulation(
        mix.mesh.clone(),
        kind,
        set,
        f,
        &Resources::default(),
    ))
}

/// `mix` precomputed with `f` and solved: `X` in the problem's units.
fn solved(
    f: &dyn Formulation,
    mix: &ConstraintMix,
    kind: LaplacianKind,
) -> Result<(Deformer, Mat<f64>), String> {
    let mut d = factored(f, mix, kind)?.map_err(|e| format!("precompute: {e}"))?;
    let x = d.solve_matrix().map_err(|e| format!("solve: {e}"))?;
    Ok((d, x))
}

/// `Σ_j |b_kj| ‖X_j‖₂ + ‖d_k‖₂`: the scale of hard row `k`'s residual.
fn row_scale(problem: &LseProblem, k: usize, x: &Mat<f64>) -> f64 {
    let b = problem.b();
    let range = b.symbolic().row_range(k);
    let cols = &b.symbolic().col_idx()[range.clone()];
    let norm = |j: usize| {
        (0..x.ncols())
            .map(|c| x[(j, c)].powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let d = (0..x.ncols())
        .map(|c| problem.d()[(k, c)].powi(2))
        .sum::<f64>()
        .sqrt();
    cols.iter()
        .zip(&b.val()[range])
        .map(|(&j, &v)| v.abs() * norm(j))
        .sum::<f64>()
        + d
}

/// (a): every kept hard row (the first `rank`) holds to [`EXACTNESS`].
fn exactness(f: &dyn Formulation, mix: &ConstraintMix, kind: LaplacianKind) -> Result<(), String> {
    let (d, x) = solved(f, mix, kind)?;
    let problem = d.problem();
    for k in 0..mix.rank {
        let (r, size) = (problem.hard_residual(k, &x), row_scale(problem, k, &x));
        ensure(r <= EXACTNESS * size, || {
            format!(
                "kept constraint {k} misses by {r:e}, {:e} of its scale {size:e}",
                r / size
            )
        })?;
    }
    Ok(())
}

/// (c): the solution agrees with the dense oracle on the kept rows.
fn oracle(f: &dyn Formulation, mix: &ConstraintMix, kind: LaplacianKind) -> Result<(), String> {
    let (d, x) = solved(f, mix, kind)?;
    let kept: Vec<usize> = (0..mix.rank).collect();
    let reference = dense_reference(d.problem(), &kept);
    let diff = relative_difference(&x, &reference);
    ensure(diff <= ORACLE, || {
        format!("{diff:e} from the dense oracle (at most {ORACLE:e})")
    })
}

/// The name is not empty and stable, and the report of `f` on a fixed
/// problem satisfies `carries`.
fn named(
    name: &BackendName,
    again: &BackendName,
    f: &dyn Formulation,
    carries: impl Fn(&crate::Report) -> bool,
) -> Result<(), String> {
    ensure(!name.trim().is_empty(), || "the name is empty".into())?;
    ensure(name == again, || {
        format!("the name changes between calls: '{name}', then '{again}'")
    })?;
    let mesh = random_surface(4, 4, 1);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let constraints = independent_constraints(&mesh, &mut rng, 5, false);
    let mix = ConstraintMix {
        rank: constraints.len(),
        mesh,
        constraints,
        redundant: Vec::new(),
        conflicting: Vec::new(),
    };
    let (d, _) = solved(f, &mix, LaplacianKind::Cotangent)?;
    let report = d.report();
    ensure(carries(report), || {
        format!(
            "the report does not carry the name '{name}': factor_backend {:?}, qr_backend {:?}",
            report.factor_backend, report.qr_backend
        )
    })
}

/// (b) through the method: the report's rank, redundant and conflicting
/// sets are the constructed ones.
fn method_sets(
    f: &dyn Formulation,
    mix: &ConstructedMix,
    kind: LaplacianKind,
) -> Result<(), String> {
    let as_mix = ConstraintMix {
        mesh: mix.mesh.clone(),
        constraints: mix.constraints.clone(),
        rank: mix.kept.len(),
        redundant: mix.redundant.clone(),
        conflicting: mix.conflicting.clone(),
    };
    let (d, _) = solved(f, &as_mix, kind)?;
    let r = d.report();
    let conflicting: Vec<usize> = r.conflicting.iter().map(|c| c.index).collect();
    ensure(r.rank == Some(mix.kept.len()), || {
        format!("rank {:?}, constructed {}", r.rank, mix.kept.len())
    })?;
    ensure(r.redundant == mix.redundant, || {
        format!(
            "redundant {:?}, constructed {:?}",
            r.redundant, mix.redundant
        )
    })?;
    ensure(conflicting == mix.conflicting, || {
        format!(
            "conflicting {conflicting:?}, constructed {:?}",
            mix.conflicting
        )
    })
}

/// (f): a precompute within one byte is refused as too large.
fn method_budget(
    f: &dyn Formulation,
    mix: &ConstraintMix,
    kind: LaplacianKind,
) -> Result<(), String> {
    let p = problem(mix, kind)?;
    match f.precompute_with(&p, &Resources::with_budget(MemoryBudget::bytes(1))) {
        Err(Error::Problem(ProblemError::TooLarge { .. })) => Ok(()),
        Err(e) => Err(format!(
            "a precompute within one byte failed otherwise: {e}"
        )),
        Ok(_) => Err("a precompute within one byte was not refused".into()),
    }
}

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

/// (g) through the method: seven columns `[C, 2C, C₀ + C₁]` (and `D`
/// alike) solved together give `[X, 2X, X₀ + X₁]` for the three-column
/// solution `X`.
fn method_columns(
    f: &dyn Formulation,
    mix: &ConstraintMix,
    kind: LaplacianKind,
) -> Result<(), String> {
    let p = problem(mix, kind)?;
    let mut solver = LseSolver::with_formulation(p.clone(), f, &Resources::default())
        .map_err(|e| format!("precompute: {e}"))?;
    let x = solver.solve().map_err(|e| format!("solve: {e}"))?;
    let widen = |m: &Mat<f64>| {
        Mat::from_fn(m.nrows(), 7, |i, c| match c {
            0..3 => m[(i, c)],
            3..6 => 2.0 * m[(i, c - 3)],
            _ => m[(i, 0)] + m[(i, 1)],
        })
    };
    let (c, dd) = (widen(p.c()), widen(p.d()));
    let (wide, _) = solver
        .solve_columns(c.as_ref(), dd.as_ref(), Refine::Auto)
        .map_err(|e| format!("a solve of seven columns failed: {e}"))?;
    let diff = relative_difference(&wide, &widen(&x));
    ensure(diff <= COLUMNS, || {
        format!(
            "seven columns solved together differ from the three-column solution by {diff:e} (at most {COLUMNS:e})"
        )
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

/// `check` refuses one byte as too large and accepts an unlimited budget.
fn budget_answers(check: impl Fn(MemoryBudget) -> Result<(), ProblemError>) -> Result<(), String> {
    match check(MemoryBudget::bytes(1)) {
        Err(ProblemError::TooLarge { detail }) => {
            ensure(!detail.is_empty(), || "an empty message".into())?
        }
        Err(e) => return Err(format!("a budget of one byte refused otherwise: {e}")),
        Ok(()) => return Err("a budget of one byte was accepted".into()),
    }
    check(MemoryBudget::unlimited()).map_err(|e| format!("an unlimited budget was refused: {e}"))
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
// QR at the matrix level.

/// `rows` sorted.
fn sorted(rows: &[usize]) -> Vec<usize> {
    let mut rows = rows.to_vec();
    rows.sort_unstable();
    rows
}

/// The factor's rank, kept and skipped rows are `kept` and `skipped`.
fn sets_are(qr: &dyn ConstraintQr, kept: &[usize], skipped: &[usize]) -> Result<(), String> {
    ensure(qr.rank() == kept.len(), || {
        format!("rank {}, constructed {}", qr.rank(), kept.len())
    })?;
    ensure(sorted(qr.kept()) == sorted(kept), || {
        format!("kept {:?}, constructed {kept:?}", sorted(qr.kept()))
    })?;
    ensure(qr.skipped() == skipped, || {
        format!(
            "skipped {:?} (increasing), constructed {skipped:?}",
            qr.skipped()
        )
    })
}

/// (b) on [`random_lses`]: independent, redundant and conflicting rows.
fn qr_random_sets(backend: &dyn QrBackend, lse: &RandomLse) -> Result<(), String> {
    let b = lse.problem.b();
    let qr = backend
        .factor(b.as_ref(), RankTolerance::default())
        .map_err(|e| format!("QR: {e}"))?;
    let skipped = sorted(&[&lse.redundant[..], &lse.conflicting[..]].concat());
    sets_are(&*qr, &lse.independent_rows, &skipped)
}

/// (b) on [`constructed_lses`]: rows either side of the tolerance, scaled
/// by `10^±8`.
fn qr_constructed_sets(backend: &dyn QrBackend, lse: &ConstructedLse) -> Result<(), String> {
    let b = lse.problem.b();
    let qr = backend
        .factor(b.as_ref(), RankTolerance::default())
        .map_err(|e| format!("QR: {e}"))?;
    let skipped = sorted(&[&lse.redundant[..], &lse.conflicting[..]].concat());
    sets_are(&*qr, &lse.kept, &skipped)
}

/// [`Property::Operations`] (and with `cols = 7`, [`Property::Columns`])
/// on the factor of `lse`'s `B`.
fn qr_operations_of(backend: &dyn QrBackend, lse: &RandomLse, cols: usize) -> Result<(), String> {
    let b = lse.problem.b();
    let qr = backend
        .factor(b.as_ref(), RankTolerance::default())
        .map_err(|e| format!("QR: {e}"))?;
    qr_operations(&*qr, b, cols, lse.problem.n() as u64)
}

/// `max |m|`.
fn max_abs(m: MatRef<'_, f64>) -> f64 {
    let mut x = 0.0f64;
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            x = x.max(m[(i, j)].abs());
        }
    }
    x
}

/// The rows `rows` of `b` as a CSC matrix.
fn rows_as_csc(b: &SparseRowMat<usize, f64>, rows: &[usize]) -> SparseColMat<usize, f64> {
    let mut triplets = Vec::new();
    for (k, &i) in rows.iter().enumerate() {
        let range = b.symbolic().row_range(i);
        let cols = &b.symbolic().col_idx()[range.clone()];
        triplets.extend(
            cols.iter()
                .zip(&b.val()[range])
                .map(|(&j, &v)| Triplet::new(k, j, v)),
        );
    }
    SparseColMat::try_new_from_triplets(rows.len(), b.ncols(), &triplets).expect("in range")
}

/// The checks of [`Property::Operations`] on a factor `qr` of `b`, with
/// operands of `cols ≥ 3` columns drawn from `seed`: `Q` applied after `Qᵀ`
/// is the identity and `Qᵀ` keeps norms (to `1e-12`), `B_kept Q2 = 0`,
/// `A Q2` equals `A` times `Q [0; I]` (for a random sparse `A`), and
/// `x = Q [R1⁻ᵀ D_kept; 0]` satisfies `B_kept x = D_kept`. Public so that
/// a QR back end's own fixed cases can use it.
///
/// Errors: the first check that fails, in words.
pub fn qr_operations(
    qr: &dyn ConstraintQr,
    b: &SparseRowMat<usize, f64>,
    cols: usize,
    seed: u64,
) -> Result<(), String> {
    let (n, r) = (qr.n(), qr.rank());
    ensure(n == b.ncols() && r <= n, || {
        format!("n = {n}, rank {r} for B of {} columns", b.ncols())
    })?;
    ensure((0..n - r).all(|k| qr.free_unknown(k) < n), || {
        "free_unknown names no unknown".into()
    })?;
    round_trip(qr, cols, seed)?;
    let bq2 = qr.mul_a_q2(rows_as_csc(b, qr.kept()).as_ref()).to_dense();
    let scale = max_abs(b.to_dense().as_ref()).max(1.0);
    let err = max_abs(bq2.as_ref());
    ensure(
        bq2.ncols() == n - r && err < 1e-13 * scale * (n as f64).sqrt(),
        || {
            format!(
                "B_kept Q2 has {} columns and entries up to {err:e}",
                bq2.ncols()
            )
        },
    )?;
    a_q2_agrees(qr, seed)?;
    particular_solves(qr, b, cols, seed)
}

/// `Q Qᵀ x = x` and `‖Qᵀ x‖ = ‖x‖` for `cols` random columns.
fn round_trip(qr: &dyn ConstraintQr, cols: usize, seed: u64) -> Result<(), String> {
    let (n, r) = (qr.n(), qr.rank());
    let x = random_mat(n, cols, seed);
    let (mut y, mut z) = (Mat::zeros(r, cols), Mat::zeros(n - r, cols));
    qr.apply_qt(x.as_ref(), y.as_mut(), z.as_mut());
    let mut back = Mat::zeros(n, cols);
    qr.apply_q(y.as_ref(), z.as_ref(), back.as_mut());
    let err = max_abs((&back - &x).as_ref());
    ensure(err < 1e-12, || {
        format!("Q Qᵀ x differs from x by {err:e} ({cols} columns)")
    })?;
    let (nx, nyz) = (
        x.norm_l2(),
        (y.norm_l2().powi(2) + z.norm_l2().powi(2)).sqrt(),
    );
    ensure((nx - nyz).abs() < 1e-12 * nx.max(1.0), || {
        format!("‖Qᵀx‖ = {nyz}, ‖x‖ = {nx}")
    })
}

/// `A Q2` by [`ConstraintQr::mul_a_q2`] equals `A` times `Q [0; I]` for a
/// random sparse `A` of seven rows.
fn a_q2_agrees(qr: &dyn ConstraintQr, seed: u64) -> Result<(), String> {
    let (n, r) = (qr.n(), qr.rank());
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5a);
    let mut triplets = Vec::new();
    for i in 0..7 {
        for j in 0..n {
            if rng.random_bool(0.3) {
                triplets.push(Triplet::new(i, j, rng.random_range(-1.0..1.0)));
            }
        }
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(7, n, &triplets).expect("in range");
    let aq2 = qr.mul_a_q2(a.as_ref()).to_dense();
    let mut q2 = Mat::<f64>::zeros(n, n - r);
    let identity = Mat::<f64>::identity(n - r, n - r);
    qr.apply_q(
        Mat::<f64>::zeros(r, n - r).as_ref(),
        identity.as_ref(),
        q2.as_mut(),
    );
    let err = max_abs((&aq2 - a.to_dense() * &q2).as_ref());
    ensure(err < 1e-12, || {
        format!("mul_a_q2 differs from A Q2 by {err:e}")
    })
}

/// `x = Q [R1⁻ᵀ D_kept; 0]` satisfies every kept row, for `cols` columns.
fn particular_solves(
    qr: &dyn ConstraintQr,
    b: &SparseRowMat<usize, f64>,
    cols: usize,
    seed: u64,
) -> Result<(), String> {
    let d = random_mat(b.nrows(), cols, seed ^ 0xd);
    let (_, x) = particular_solution(qr, d.as_ref());
    let bx = b.to_dense() * &x;
    let size = max_abs(x.as_ref()).max(1.0) * max_abs(b.to_dense().as_ref()).max(1.0);
    for &i in qr.kept() {
        for c in 0..cols {
            let e = (bx[(i, c)] - d[(i, c)]).abs();
            ensure(e < 1e-10 * size, || {
                format!("kept row {i}, column {c}: B x − D = {e:e}")
            })?;
        }
    }
    Ok(())
}

/// (e) QR: two factorisations alive at once, each solving for its own
/// `B`.
fn qr_several(backend: &dyn QrBackend, p: &RandomLse, q: &RandomLse) -> Result<(), String> {
    let tol = RankTolerance::default();
    let fp = backend
        .factor(p.problem.b().as_ref(), tol)
        .map_err(|e| format!("QR: {e}"))?;
    let fq = backend
        .factor(q.problem.b().as_ref(), tol)
        .map_err(|e| format!("QR: {e}"))?;
    for (i, (f, b)) in [
        (&fp, p.problem.b()),
        (&fq, q.problem.b()),
        (&fp, p.problem.b()),
    ]
    .into_iter()
    .enumerate()
    {
        particular_solves(&**f, b, 3, i as u64)
            .map_err(|e| format!("factor {} of two: {e}", i % 2))?;
    }
    Ok(())
}

/// (f) QR: a factorisation within one byte is refused as too large, an
/// unlimited one is not.
fn qr_budget(backend: &dyn QrBackend, lse: &RandomLse) -> Result<(), String> {
    let b = lse.problem.b();
    let within = |budget| match backend.factor_with(
        b.as_ref(),
        RankTolerance::default(),
        &Resources::with_budget(budget),
    ) {
        Ok(_) => Ok(()),
        Err(Error::Problem(e)) => Err(e),
        Err(e) => Err(ProblemError::InvalidArgument {
            message: format!("(not a problem error) {e}"),
        }),
    };
    budget_answers(within)
}

// ---------------------------------------------------------------------------
// Interruption: a back end wrapped to spring a trap at one phase.

/// Where the trap springs.
#[derive(Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
enum Phase {
    None = 0,
    Factorize = 1,
    Solve = 2,
}

/// A trap armed for one phase: when the wrapped back end has done that
/// phase, the trap springs (once) and waits one consult interval, so that
/// the library's next check asks the hook, which then says stop.
#[derive(Default)]
struct Trap {
    armed: AtomicU8,
    sprung: Arc<AtomicBool>,
}

impl Trap {
    fn arm(&self, phase: Phase) {
        self.sprung.store(false, Ordering::SeqCst);
        self.armed.store(phase as u8, Ordering::SeqCst);
    }

    fn at(&self, phase: Phase) {
        let armed = self.armed.compare_exchange(
            phase as u8,
            Phase::None as u8,
            Ordering::SeqCst,
            Ordering::SeqCst,
        );
        if armed.is_ok() {
            self.sprung.store(true, Ordering::SeqCst);
            std::thread::sleep(crate::interrupt::CONSULT_INTERVAL);
        }
    }

    fn sprung(&self) -> bool {
        self.sprung.load(Ordering::SeqCst)
    }

    /// Runs `f` with a hook that says stop once the trap has sprung.
    fn run<T>(&self, f: impl FnOnce() -> T) -> T {
        let sprung = Arc::clone(&self.sprung);
        crate::interrupt::with_hook(move || sprung.load(Ordering::SeqCst), f)
    }
}

/// (f): interrupted after the back end factored (and, when `solves`,
/// after it solved), the method ends in [`Error::Interrupted`], then
/// precomputes and solves as before.
fn interruption(
    f: &dyn Formulation,
    trap: &Trap,
    mix: &ConstraintMix,
    kind: LaplacianKind,
    solves: bool,
) -> Result<(), String> {
    trap.arm(Phase::Factorize);
    let outcome = trap.run(|| factored(f, mix, kind))?.map(|_| ());
    ensure(trap.sprung(), || {
        "the back end was never asked to factor".into()
    })?;
    ensure(matches!(outcome, Err(Error::Interrupted)), || {
        format!("a precompute interrupted after the factorisation ended in {outcome:?}")
    })?;
    trap.arm(Phase::None);
    let mut d =
        factored(f, mix, kind)?.map_err(|e| format!("precompute after an interruption: {e}"))?;
    let x = d
        .solve_matrix()
        .map_err(|e| format!("solve after an interrupted precompute: {e}"))?;
    if solves {
        trap.arm(Phase::Solve);
        let outcome = trap.run(|| d.solve_matrix());
        ensure(matches!(outcome, Err(Error::Interrupted)), || {
            format!("a solve interrupted after the back end solved ended in {outcome:?}")
        })?;
        trap.arm(Phase::None);
        let again = d
            .solve_matrix()
            .map_err(|e| format!("solve after an interrupted solve: {e}"))?;
        let diff = relative_difference(&again, &x);
        ensure(diff <= COLUMNS, || {
            format!("after an interrupted solve, the solution moved by {diff:e}")
        })?;
    }
    Ok(())
}

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

/// A QR back end with a [`Trap`] (its factorisation is its one phase).
struct SpyQr {
    inner: Arc<dyn QrBackend>,
    trap: Arc<Trap>,
}

impl QrBackend for SpyQr {
    fn name(&self) -> BackendName {
        self.inner.name()
    }

    fn factor_with(
        &self,
        b: faer::sparse::SparseRowMatRef<'_, usize, f64>,
        tolerance: RankTolerance,
        resources: &Resources,
    ) -> Result<Box<dyn ConstraintQr>, Error> {
        let qr = self.inner.factor_with(b, tolerance, resources)?;
        self.trap.at(Phase::Factorize);
        Ok(qr)
    }
}
