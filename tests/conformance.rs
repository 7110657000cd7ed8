//! Every built-in back end of this build runs the conformance kit
//! (`lse_deform::testing::conformance`, docs/backends.md §8): the SPD back
//! ends of `SpdKind::available()`, the QR back ends of
//! `QrKind::available()` and the `LDLᵀ` back ends of the catalogue that
//! this build has (CHOLMOD, SPQR with `--features suitesparse`; MUMPS's
//! Cholesky and `LDLᵀ` with `--features mumps`). And the kit is not true
//! by construction: back ends each broken in one way fail the property
//! that says so, and only it.

use std::sync::Arc;

use faer::MatMut;
use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use lse_deform::QrKind;
use lse_deform::backend::BackendName;
use lse_deform::backend::ldlt::LdltKind;
use lse_deform::backend::spd::{FaerLlt, SpdBackend, SpdFactor, SpdKind, SpdSymbolic};
use lse_deform::error::{NumericalError, ProblemError};
use lse_deform::limits::MemoryBudget;
use lse_deform::testing::conformance::{self, KitConfig, KitFailure, KitReport, Property};

/// The cases per property: 32, or `PROPTEST_CASES` when set (as for this
/// crate's other property tests).
fn config() -> KitConfig {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(32);
    KitConfig::with_cases(cases)
}

/// Every failure of `results`, one message.
fn all_pass(results: Vec<Result<KitReport, KitFailure>>) {
    let failures: Vec<String> = results
        .into_iter()
        .filter_map(|r| r.err().map(|f| f.to_string()))
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn every_spd_backend_of_this_build_passes_the_kit() {
    let kinds = SpdKind::available();
    assert_eq!(
        kinds.len(),
        4 + usize::from(cfg!(feature = "suitesparse")) + usize::from(cfg!(feature = "mumps"))
    );
    all_pass(
        kinds
            .into_iter()
            .map(|kind| conformance::spd(kind.backend().unwrap(), &config()))
            .collect(),
    );
}

#[test]
fn every_qr_backend_of_this_build_passes_the_kit() {
    let kinds = QrKind::available();
    assert_eq!(kinds.len(), 2 + usize::from(cfg!(feature = "suitesparse")));
    all_pass(
        kinds
            .into_iter()
            .map(|kind| conformance::qr(kind.backend().unwrap(), &config()))
            .collect(),
    );
}

#[test]
fn every_ldlt_backend_of_this_build_passes_the_kit() {
    let kinds: Vec<LdltKind> = LdltKind::ALL
        .into_iter()
        .filter(|&k| k != LdltKind::Mumps || cfg!(feature = "mumps"))
        .collect();
    all_pass(
        kinds
            .into_iter()
            .map(|kind| conformance::ldlt(kind.backend().unwrap(), &config()))
            .collect(),
    );
}

/// A few cases: what the broken back ends below need to be caught.
fn few() -> KitConfig {
    KitConfig {
        cases: 4,
        seed: Some(36),
    }
}

/// What a broken back end does wrong.
#[derive(Clone, Copy, PartialEq)]
enum Fault {
    /// Every factor of an analysis solves with the first matrix factored.
    KeepsTheFirstFactor,
    /// A matrix that is not positive definite is solved by the identity.
    AcceptsAnything,
    /// Any budget is accepted.
    IgnoresTheBudget,
    /// Solves of more than three columns leave the columns past the third
    /// as they were.
    SolvesThreeColumnsOnly,
}

/// faer's Cholesky with one [`Fault`].
struct Broken {
    fault: Fault,
}

struct BrokenSymbolic {
    inner: Box<dyn SpdSymbolic>,
    fault: Fault,
    lower: std::sync::Mutex<Option<SparseColMat<usize, f64>>>,
}

struct BrokenFactor {
    inner: Option<Box<dyn SpdFactor>>,
    dim: usize,
    fault: Fault,
}

/// A copy of `lower`.
fn owned(lower: SparseColMatRef<'_, usize, f64>) -> SparseColMat<usize, f64> {
    let pattern = SymbolicSparseColMat::new_checked(
        lower.nrows(),
        lower.ncols(),
        lower.symbolic().col_ptr().to_vec(),
        None,
        lower.symbolic().row_idx().to_vec(),
    );
    SparseColMat::new(pattern, lower.val().to_vec())
}

impl SpdBackend for Broken {
    fn name(&self) -> BackendName {
        "broken".into()
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        Ok(Box::new(BrokenSymbolic {
            inner: FaerLlt::auto().analyze(lower)?,
            fault: self.fault,
            lower: std::sync::Mutex::new(None),
        }))
    }
}

impl SpdSymbolic for BrokenSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn SpdFactor>, NumericalError> {
        let dim = lower.ncols();
        let lower = match self.fault {
            Fault::KeepsTheFirstFactor => {
                let mut first = self.lower.lock().unwrap();
                first.get_or_insert_with(|| owned(lower)).clone()
            }
            _ => owned(lower),
        };
        let inner = match self.inner.factorize(lower.as_ref()) {
            Ok(f) => Some(f),
            Err(_) if self.fault == Fault::AcceptsAnything => None,
            Err(e) => return Err(e),
        };
        Ok(Box::new(BrokenFactor {
            inner,
            dim,
            fault: self.fault,
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
        match self.fault {
            Fault::IgnoresTheBudget => Ok(()),
            _ => self.inner.check_budget(budget, dim, matrix),
        }
    }
}

impl SpdFactor for BrokenFactor {
    fn dim(&self) -> usize {
        self.dim
    }

    fn solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) -> Result<(), NumericalError> {
        let Some(inner) = self.inner.as_mut() else {
            return Ok(());
        };
        if self.fault == Fault::SolvesThreeColumnsOnly && rhs.ncols() > 3 {
            return inner.solve_in_place(rhs.as_mut().subcols_mut(0, 3));
        }
        inner.solve_in_place(rhs)
    }

    fn nnz(&self) -> usize {
        self.inner.as_ref().map_or(self.dim, |f| f.nnz())
    }

    fn bytes(&self) -> usize {
        self.inner.as_ref().map_or(8 * self.dim, |f| f.bytes())
    }
}

/// The failure of the kit on faer's Cholesky with `fault`.
fn failure_of(fault: Fault) -> KitFailure {
    match conformance::spd(Arc::new(Broken { fault }), &few()) {
        Ok(report) => panic!("a back end that breaks the contract passed: {report:?}"),
        Err(failure) => failure,
    }
}

/// The property that says so catches each broken back end, and no other
/// property fails (so each property checks what it claims).
#[test]
fn the_kit_catches_each_broken_contract_by_its_property() {
    let cases = [
        (Fault::KeepsTheFirstFactor, Property::SeveralFactors),
        (Fault::AcceptsAnything, Property::Refusal),
        (Fault::IgnoresTheBudget, Property::Budget),
        (Fault::SolvesThreeColumnsOnly, Property::Columns),
    ];
    for (fault, property) in cases {
        let failure = failure_of(fault);
        let failed: Vec<Property> = failure.failures.iter().map(|f| f.property).collect();
        assert_eq!(failed, [property], "{failure}");
        let text = failure.to_string();
        assert!(
            text.contains("'broken'")
                && text.contains(property.name())
                && text.contains("seed: Some(36)"),
            "{text}"
        );
    }
}

/// A failure names the minimal case, and `assert_conforms` panics with it.
#[test]
#[should_panic(expected = "the SPD back end 'broken' fails 1 of")]
fn assert_conforms_panics_with_the_failure() {
    conformance::assert_conforms(conformance::spd(
        Arc::new(Broken {
            fault: Fault::IgnoresTheBudget,
        }),
        &few(),
    ));
}
