//! What the kit checks and what it answers ([`Seam`], [`Property`],
//! [`KitConfig`], [`KitReport`], [`KitFailure`]), and the runner every
//! seam's call drives.

use std::fmt;
use std::hash::BuildHasher;
use std::panic::{AssertUnwindSafe, catch_unwind};

use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed, TestError, TestRunner};

use crate::backend::BackendName;

// ---------------------------------------------------------------------------
// What the kit checks and what it answers.

/// The seams a back end can fill.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Seam {
    /// [`SpdBackend`]: sparse Cholesky (or anything that solves SPD systems).
    ///
    /// [`SpdBackend`]: crate::backend::spd::SpdBackend
    Spd,
    /// [`QrBackend`]: QR of `Bᵀ` with rank detection.
    ///
    /// [`QrBackend`]: crate::backend::qr::QrBackend
    Qr,
    /// [`LdltBackend`]: static-order `LDLᵀ` of symmetric indefinite matrices.
    ///
    /// [`LdltBackend`]: crate::backend::ldlt::LdltBackend
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
    ///
    /// [`EXACTNESS`]: crate::testing::conformance::EXACTNESS
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
    ///
    /// [`ORACLE`]: crate::testing::conformance::ORACLE
    /// [`dense_reference`]: crate::testing::dense_reference
    Oracle,
    /// (d) A matrix the back end cannot factor is refused by a typed error
    /// — never a panic, never a non-finite or wrong solution: for SPD a
    /// symmetric matrix with a zero or negative diagonal entry (so not
    /// positive definite), at the factorisation or at the latest at the
    /// first solve; for `LDLᵀ` a KKT matrix with a dependent constraint
    /// (a [`PivotFault`], or a typed error of the factorisation; through
    /// KKT a numerical error).
    ///
    /// [`PivotFault`]: crate::backend::ldlt::PivotFault
    Refusal,
    /// (e) Several numeric factorisations of one analysis (SPD, `LDLᵀ`),
    /// or several QR factorisations, alive at once, each solving with its
    /// own matrix in interleaved order.
    SeveralFactors,
    /// (f) A budget of one byte is refused with
    /// [`ProblemError::TooLarge`] (`check_budget` of an analysis, a QR
    /// within the budget, a method's precompute); an unlimited one is not.
    ///
    /// [`ProblemError::TooLarge`]: crate::error::ProblemError::TooLarge
    Budget,
    /// (f) A precompute interrupted right after the back end factored, and
    /// a solve interrupted right after it solved ([`crate::interrupt`]),
    /// end in [`Error::Interrupted`]; then the method precomputes and
    /// solves again as if nothing happened.
    ///
    /// [`Error::Interrupted`]: crate::error::Error::Interrupted
    Interruption,
    /// (g) Solves of one, three and seven columns at once (a matrix's
    /// solve; through the method, the three columns of a mesh and the
    /// seven of [`LseSolver::solve_columns`], which the null-space method
    /// solves in one pass), each column as it would be alone.
    ///
    /// [`LseSolver::solve_columns`]: crate::solver::LseSolver::solve_columns
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
pub(super) struct Kit<'a> {
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
    pub(super) fn new(seam: Seam, backend: BackendName, config: &'a KitConfig) -> Kit<'a> {
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
    pub(super) fn generated<S: Strategy>(
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
    pub(super) fn cases(&self) -> u32 {
        self.config.cases.max(1)
    }

    /// Runs a check without generated cases; a panic is a failure.
    pub(super) fn fixed(&mut self, property: Property, check: impl FnOnce() -> Result<(), String>) {
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

    pub(super) fn finish(self) -> Result<KitReport, KitFailure> {
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

/// A quarter of `cases`, at least one.
pub(super) fn quarter(cases: u32) -> u32 {
    cases.div_ceil(4)
}
