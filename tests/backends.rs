//! The linear-algebra back ends, on fixed cases computed by hand: QR of
//! empty, zero and fully fixing constraint rows; SPD back ends naming the
//! failing pivot of an arrowhead in the original ordering and detecting its
//! breakdown; every catalogue word naming its back end; a relative chain
//! factored in a fill-reducing order. What every back end must do on
//! generated cases (rank and skipped sets, the factor's operations,
//! agreement with the dense oracle through the method, several factors of
//! one analysis, budgets, interruption, many columns) is the conformance
//! kit's, which tests/conformance.rs runs on every built-in back end
//! (docs/backends.md §8).

use std::sync::Arc;

use faer::Mat;
use faer::sparse::{SparseColMat, SparseRowMat, Triplet};
use lse_deform::backend::qr::{self, ConstraintQr, QrBackend, QrKind, RankTolerance};
use lse_deform::backend::spd::{self, SpdBackend, SpdKind};
use lse_deform::error::{NumericalError, ProblemError};
use lse_deform::testing::conformance;
use lse_deform::testing::relative_difference;
use lse_deform::{Deformer, LaplacianKind, formulation::NullSpaceQr};

/// Every QR back end in this build.
fn qr_backends() -> Vec<Arc<dyn QrBackend>> {
    QrKind::available()
        .into_iter()
        .map(|k| k.backend().unwrap())
        .collect()
}

/// Every SPD back end in this build.
fn spd_backends() -> Vec<Arc<dyn SpdBackend>> {
    SpdKind::available()
        .into_iter()
        .map(|k| k.backend().unwrap())
        .collect()
}

/// The kit's checks of a factor's operations on `b`
/// ([`conformance::qr_operations`]), three columns.
fn check_qr_operations(name: &str, qr: &dyn ConstraintQr, b: &SparseRowMat<usize, f64>, seed: u64) {
    if let Err(e) = conformance::qr_operations(qr, b, 3, seed) {
        panic!("{name}: {e}");
    }
}

#[test]
fn qr_edge_cases() {
    // No constraint rows, an empty row, a zero row, all unknowns fixed.
    let tol = RankTolerance::default();
    let empty = SparseRowMat::<usize, f64>::try_new_from_triplets(0, 5, &[]).unwrap();
    let with_zero = SparseRowMat::<usize, f64>::try_new_from_triplets(
        3,
        4,
        &[
            Triplet::new(0, 1, 1.0),
            Triplet::new(2, 1, 2.0),
            Triplet::new(2, 3, 1e-3),
        ],
    )
    .unwrap();
    let all = SparseRowMat::<usize, f64>::try_new_from_triplets(
        3,
        3,
        &[
            Triplet::new(0, 2, 1.0),
            Triplet::new(1, 0, 1.0),
            Triplet::new(2, 1, 1.0),
            Triplet::new(2, 0, 0.5),
        ],
    )
    .unwrap();
    for backend in qr_backends() {
        let name = &*backend.name();
        let f = backend.factor(empty.as_ref(), tol).unwrap();
        assert_eq!((f.rank(), f.skipped().len()), (0, 0), "{name}");
        check_qr_operations(name, &*f, &empty, 1);
        let f = backend.factor(with_zero.as_ref(), tol).unwrap();
        assert_eq!(f.rank(), 2, "{name}");
        assert_eq!(f.skipped(), &[1], "{name}");
        check_qr_operations(name, &*f, &with_zero, 2);
        let f = backend.factor(all.as_ref(), tol).unwrap();
        assert_eq!(f.rank(), 3, "{name}");
        check_qr_operations(name, &*f, &all, 3);
    }
}

/// Lower triangle of a symmetric matrix given by its full triplets.
fn lower(n: usize, full: &[(usize, usize, f64)]) -> SparseColMat<usize, f64> {
    let trip: Vec<Triplet<usize, usize, f64>> = full
        .iter()
        .filter(|&&(i, j, _)| i >= j)
        .map(|&(i, j, v)| Triplet::new(i, j, v))
        .collect();
    SparseColMat::try_new_from_triplets(n, n, &trip).unwrap()
}

/// An arrowhead: hub `h` coupled (−0.5) to 11 leaves with diagonal 1. The
/// Schur complement of the hub is `hub_diag − 11/4`. AMD eliminates the
/// leaves (degree 1) before the hub (degree 11), so the hub is the last
/// pivot: a nontrivial permutation that puts the failing pivot at permuted
/// position 11 while its original index is `h` (in the natural order the
/// hub's own pivot would be positive and a leaf would fail instead).
fn arrowhead(h: usize, hub_diag: f64) -> SparseColMat<usize, f64> {
    let n = 12;
    let mut full = vec![(h, h, hub_diag)];
    for v in (0..n).filter(|&v| v != h) {
        full.push((v, v, 1.0));
        full.push((v, h, -0.5));
        full.push((h, v, -0.5));
    }
    lower(n, &full)
}

/// The first column whose pivot is not positive in a dense Cholesky in the
/// natural order (an independent computation), or `None`.
fn natural_order_failing_pivot(a: &Mat<f64>) -> Option<usize> {
    let n = a.nrows();
    let mut l = Mat::<f64>::zeros(n, n);
    for j in 0..n {
        let d = a[(j, j)] - (0..j).map(|k| l[(j, k)] * l[(j, k)]).sum::<f64>();
        if d <= 0.0 {
            return Some(j);
        }
        l[(j, j)] = d.sqrt();
        for i in j + 1..n {
            let s = a[(i, j)] - (0..j).map(|k| l[(i, k)] * l[(j, k)]).sum::<f64>();
            l[(i, j)] = s / l[(j, j)];
        }
    }
    None
}

#[test]
fn spd_backends_name_the_failing_pivot_in_the_original_order() {
    let h = 4;
    let not_pd = arrowhead(h, 2.0);
    // Without the fill-reducing permutation the failure would be elsewhere:
    // the answer below is the hub only if the back end permuted and mapped
    // the pivot back.
    let dense_full = {
        let lo = not_pd.to_dense();
        Mat::from_fn(12, 12, |i, j| if i >= j { lo[(i, j)] } else { lo[(j, i)] })
    };
    let natural = natural_order_failing_pivot(&dense_full);
    assert!(matches!(natural, Some(k) if k != h), "{natural:?}");
    for backend in spd_backends() {
        let name = backend.name();
        let symbolic = backend.analyze(not_pd.symbolic()).unwrap();
        let err = symbolic
            .factorize(not_pd.as_ref())
            .err()
            .unwrap_or_else(|| panic!("{name}: no error"));
        match err {
            NumericalError::NotPositiveDefinite { unknown, .. } => {
                assert_eq!(unknown, h, "{name}")
            }
            // MUMPS counts negative pivots but does not say where
            // (docs/distributed.md §4).
            NumericalError::Backend { message, .. } if backend.name() == SpdKind::Mumps.name() => {
                assert!(message.contains("1 negative pivot"), "{message}")
            }
            other => panic!("{name}: {other}"),
        }
    }
}

#[test]
fn spd_backends_detect_breakdown() {
    // Hub pivot 2.75 + 1e-14 − 11/4 ≈ 1e-14: ratio ≈ 4e-15 < BREAKDOWN_RATIO.
    let h = 7;
    let nearly_singular = arrowhead(h, 2.75 + 1e-14);
    // MUMPS's SYM = 1 has no breakdown test (docs/distributed.md §4): the
    // forward-error estimate speaks for it (the catalogue checks that).
    let with_breakdown_test = spd_backends()
        .into_iter()
        .filter(|b| b.name() != SpdKind::Mumps.name());
    for backend in with_breakdown_test {
        let name = backend.name();
        let symbolic = backend.analyze(nearly_singular.symbolic()).unwrap();
        let err = symbolic
            .factorize(nearly_singular.as_ref())
            .err()
            .unwrap_or_else(|| panic!("{name}: no error"));
        match err {
            NumericalError::Breakdown {
                unknown,
                ratio,
                threshold,
                ..
            } => {
                assert_eq!(unknown, h, "{name}");
                assert!(ratio < threshold && ratio > 0.0, "{name}: ratio {ratio:e}");
                assert_eq!(threshold, spd::BREAKDOWN_RATIO);
            }
            other => panic!("{name}: {other}"),
        }
        // Well away from singular, the same pattern factors.
        let fine = arrowhead(h, 3.5);
        assert!(symbolic.factorize(fine.as_ref()).is_ok(), "{name}");
    }
}

#[test]
fn kinds_know_every_name() {
    // Every kind's name parses back to it; its back end, when in this
    // build, carries the same name.
    for kind in QrKind::ALL {
        assert_eq!(kind.name().parse::<QrKind>().unwrap(), kind);
        assert_eq!(kind.to_string(), kind.name());
        if kind.in_this_build() {
            assert_eq!(kind.backend().unwrap().name(), kind.name());
        }
    }
    for kind in SpdKind::ALL {
        assert_eq!(kind.name().parse::<SpdKind>().unwrap(), kind);
        assert_eq!(kind.to_string(), kind.name());
        if kind.in_this_build() {
            assert_eq!(kind.backend().unwrap().name(), kind.name());
        }
    }
    // The SuiteSparse ones: in this build with the feature, else a message
    // saying how to get them.
    let suitesparse = cfg!(feature = "suitesparse");
    assert_eq!(QrKind::Spqr.in_this_build(), suitesparse);
    assert_eq!(SpdKind::Cholmod.in_this_build(), suitesparse);
    if let Err(ProblemError::InvalidArgument { message }) = QrKind::Spqr.backend() {
        assert!(
            !suitesparse && message.contains("--features suitesparse"),
            "{message}"
        );
    }
    if let Err(ProblemError::InvalidArgument { message }) = SpdKind::Cholmod.backend() {
        assert!(
            !suitesparse && message.contains("--features suitesparse"),
            "{message}"
        );
    }
    assert_eq!(qr_backends().len(), if suitesparse { 3 } else { 2 });
    let mumps = usize::from(cfg!(feature = "mumps"));
    assert_eq!(
        spd_backends().len(),
        if suitesparse { 5 } else { 4 } + mumps
    );
    // An unknown name: the message lists the names of this build.
    let Err(message) = "householder".parse::<QrKind>().map_err(|e| e.to_string()) else {
        panic!("unknown QR name accepted");
    };
    assert!(
        QrKind::available()
            .iter()
            .all(|k| message.contains(k.name())),
        "{message}"
    );
    let Err(message) = "cholesky".parse::<SpdKind>().map_err(|e| e.to_string()) else {
        panic!("unknown SPD name accepted");
    };
    assert!(
        SpdKind::available()
            .iter()
            .all(|k| message.contains(k.name())),
        "{message}"
    );
}

/// A breadth-first chain of relative constraints (the paper's Fig. 9
/// feature region) is factored in a fill-reducing constraint order: far
/// fewer rotations than in priority order, the same solution as the paper's
/// per-block Householder QR, and the hard constraints still exact.
#[test]
fn relative_chain_uses_fill_reducing_order() {
    use lse_deform::backend::qr::{GivensQr, GivensRowOrder};
    use lse_deform::scene::{FixedAndHandle, MixedScene};
    let mesh = lse_deform::mesh::generate::grid(40, 40).unwrap();
    let scene = MixedScene {
        base: FixedAndHandle::paper_default(&mesh),
        relative: 600,
        edges: 0,
        faces: 0,
        duplicate: false,
        conflict: false,
    };
    let cs = scene.constraints(&mesh).unwrap();
    let mut d = Deformer::new(
        mesh.clone(),
        LaplacianKind::Cotangent,
        cs,
        &lse_deform::SolveOptions::default(),
    )
    .unwrap();
    let b = d.problem().b().clone();
    let nnz_b = b.val().len();
    let tol = RankTolerance::default();
    let reordered = GivensQr::new(b.as_ref(), tol, GivensRowOrder::default()).unwrap();
    assert_eq!(reordered.rank(), b.nrows());
    assert_eq!(
        reordered.kept(),
        (0..b.nrows()).collect::<Vec<_>>().as_slice()
    );
    // A relative constraint rotates its second vertex into the first one's
    // R row at most once when the chain is eliminated leaves first.
    assert!(
        reordered.n_rotations() <= nnz_b,
        "{} rotations for nnz(B) = {nnz_b}",
        reordered.n_rotations()
    );
    d.refactor_with(
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    let x = d.solve_matrix().unwrap();
    assert!(d.report().max_constraint_residual <= 1e-12 * mesh.bbox_diagonal());
    let paper = NullSpaceQr::new(
        Arc::new(qr::DenseHouseholder),
        Arc::new(spd::FaerLlt::auto()),
    );
    d.refactor_with(&paper, &lse_deform::resources::Resources::default())
        .unwrap();
    let reference = d.solve_matrix().unwrap();
    let diff = relative_difference(&x, &reference);
    assert!(diff < 1e-9, "differs from DenseHouseholder by {diff:e}");
}

/// A finding of the latest round of faults: faer's factorisations checked only their
/// factor's estimate (12 bytes an entry) against the budget, not what the
/// process already holds nor their workspace: with a budget of exactly
/// that estimate and a process holding more than it already, they went
/// ahead. Now what the process holds (its resident set) is counted on
/// top, and the refusal says so.
#[test]
fn faer_counts_what_the_process_holds_against_the_budget() {
    use lse_deform::backend::ldlt::LdltKind;
    use lse_deform::limits::{FACTOR_BYTES_PER_ENTRY, MemoryBudget};
    let m = lse_deform::testing::conformance::grid_lower(60, 3);
    let n = m.ncols();
    let order: Vec<usize> = (0..n).collect();
    for kind in [SpdKind::FaerSupernodal, SpdKind::FaerSimplicial] {
        let symbolic = kind.backend().unwrap().analyze(m.symbolic()).unwrap();
        let estimate = symbolic.factor_nnz() as u64 * FACTOR_BYTES_PER_ENTRY;
        // Held and touched: the resident set is at least this.
        let ballast = vec![1u8; 2 * estimate as usize];
        let budget = MemoryBudget::bytes(estimate);
        let e = symbolic.check_budget(budget, n, "A").unwrap_err();
        assert!(e.to_string().contains("this process holds"), "{e}");
        let roomy = MemoryBudget::bytes(1 << 40);
        symbolic.check_budget(roomy, n, "A").unwrap();
        drop(ballast);
    }
    let backend = LdltKind::FaerSupernodal.backend().unwrap();
    let symbolic = backend.analyze(m.symbolic(), &order).unwrap();
    let estimate = symbolic.factor_values() as u64 * FACTOR_BYTES_PER_ENTRY;
    let ballast = vec![1u8; 2 * estimate as usize];
    let e = symbolic
        .check_budget(MemoryBudget::bytes(estimate), n, "K")
        .unwrap_err();
    assert!(e.to_string().contains("this process holds"), "{e}");
    drop(ballast);
}
