//! MUMPS in this process (MPI started as one rank; the tests take turns
//! through the process-wide lock). Expected values are worked out by hand.

use faer::Mat;
use faer::sparse::{SparseColMat, Triplet};

use super::{MumpsLdlt, MumpsLlt};
use crate::backend::ldlt::{LdltBackend, PivotFault, PivotRule};
use crate::backend::spd::{SpdBackend, solve};
use crate::limits::MemoryBudget;

/// The lower triangle of a symmetric matrix from its `(row ≥ col)` entries.
fn lower(n: usize, entries: &[(usize, usize, f64)]) -> SparseColMat<usize, f64> {
    let t: Vec<_> = entries
        .iter()
        .map(|&(i, j, v)| Triplet::new(i, j, v))
        .collect();
    SparseColMat::try_new_from_triplets(n, n, &t).unwrap()
}

/// `[4 1; 1 3] x = [1; 2]`: `x = [1/11; 7/11]`.
#[test]
fn cholesky_solves_a_two_by_two_system() {
    let a = lower(2, &[(0, 0, 4.0), (1, 0, 1.0), (1, 1, 3.0)]);
    let symbolic = MumpsLlt::default().analyze(a.symbolic()).unwrap();
    assert_eq!(symbolic.factor_nnz(), 3);
    let mut factor = symbolic.factorize(a.as_ref()).unwrap();
    let x = solve(
        factor.as_mut(),
        Mat::from_fn(2, 1, |i, _| (i + 1) as f64).as_ref(),
    )
    .unwrap();
    assert!((x[(0, 0)] - 1.0 / 11.0).abs() < 1e-15);
    assert!((x[(1, 0)] - 7.0 / 11.0).abs() < 1e-15);
    let facts = factor.facts().unwrap();
    assert_eq!(facts.section, "mumps");
    assert_eq!(facts.get("ranks"), Some(&serde_json::json!(1)));
    assert_eq!(
        facts.get("factor_entries_per_rank"),
        Some(&serde_json::json!([3]))
    );
    assert_eq!(facts.get("out_of_core"), Some(&serde_json::json!(false)));
}

/// Two factors of one analysis, solved in turn: each solves with its own
/// matrix (`diag(2, 4)` and `diag(8, 16)`), although MUMPS holds one factor.
#[test]
fn factors_of_one_analysis_keep_their_own_matrices() {
    let a = lower(2, &[(0, 0, 2.0), (1, 0, 0.0), (1, 1, 4.0)]);
    let b = lower(2, &[(0, 0, 8.0), (1, 0, 0.0), (1, 1, 16.0)]);
    let symbolic = MumpsLlt::default().analyze(a.symbolic()).unwrap();
    let mut fa = symbolic.factorize(a.as_ref()).unwrap();
    let mut fb = symbolic.factorize(b.as_ref()).unwrap();
    let ones = Mat::from_fn(2, 3, |_, _| 1.0);
    for _ in 0..2 {
        let xa = solve(fa.as_mut(), ones.as_ref()).unwrap();
        let xb = solve(fb.as_mut(), ones.as_ref()).unwrap();
        for c in 0..3 {
            assert_eq!((xa[(0, c)], xa[(1, c)]), (0.5, 0.25));
            assert_eq!((xb[(0, c)], xb[(1, c)]), (0.125, 0.0625));
        }
    }
}

/// A matrix that is not positive definite (`[1 2; 2 1]`, eigenvalues 3 and
/// −1: pivots 1 and 1 − 4 = −3) is refused, naming the negative pivot.
#[test]
fn an_indefinite_matrix_is_refused_by_the_cholesky() {
    let a = lower(2, &[(0, 0, 1.0), (1, 0, 2.0), (1, 1, 1.0)]);
    let symbolic = MumpsLlt::default().analyze(a.symbolic()).unwrap();
    let e = symbolic.factorize(a.as_ref()).err().unwrap().to_string();
    assert!(e.contains("mumps") && e.contains("1 negative pivot"), "{e}");
}

/// A singular matrix (`[1 1; 1 1]`: pivots 1 and exactly 0) is refused
/// with MUMPS's code −10.
#[test]
fn a_singular_matrix_is_refused_by_the_cholesky() {
    let a = lower(2, &[(0, 0, 1.0), (1, 0, 1.0), (1, 1, 1.0)]);
    let symbolic = MumpsLlt::default().analyze(a.symbolic()).unwrap();
    let e = symbolic.factorize(a.as_ref()).err().unwrap().to_string();
    assert!(e.contains("numerically singular [INFOG(1) = -10]"), "{e}");
}

/// The tridiagonal `[-1 4 -1]` of order `n`.
fn tridiagonal(n: usize) -> SparseColMat<usize, f64> {
    let mut entries = vec![(0, 0, 4.0)];
    for i in 1..n {
        entries.push((i, i, 4.0));
        entries.push((i, i - 1, -1.0));
    }
    lower(n, &entries)
}

/// A budget of one byte is refused before the factorisation, naming
/// MUMPS's estimate (of a matrix large enough that MUMPS, which counts in
/// millions of bytes, estimates more than zero).
#[test]
fn a_tiny_budget_is_refused_after_the_analysis() {
    let a = tridiagonal(200_000);
    let symbolic = MumpsLlt::default().analyze(a.symbolic()).unwrap();
    let e = symbolic
        .check_budget(MemoryBudget::bytes(1), 200_000, "A")
        .unwrap_err()
        .to_string();
    assert!(e.contains("INFO(15)"), "{e}");
    assert!(e.contains("more than the memory budget"), "{e}");
    symbolic
        .check_budget(MemoryBudget::bytes(1 << 40), 200_000, "A")
        .unwrap();
}

/// Out of core: the factor solves, and the rank's scratch directory is
/// gone once the factor and its analysis are dropped.
#[test]
fn out_of_core_solves_and_leaves_the_directory_empty() {
    let dir = tempfile::tempdir().unwrap();
    let a = lower(2, &[(0, 0, 4.0), (1, 0, 1.0), (1, 1, 3.0)]);
    {
        let backend = MumpsLlt::new(Some(dir.path().to_path_buf())).unwrap();
        let symbolic = backend.analyze(a.symbolic()).unwrap();
        let mut factor = symbolic.factorize(a.as_ref()).unwrap();
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let x = solve(
            factor.as_mut(),
            Mat::from_fn(2, 1, |i, _| (i + 1) as f64).as_ref(),
        )
        .unwrap();
        assert!((x[(1, 0)] - 7.0 / 11.0).abs() < 1e-15);
        let facts = factor.facts().unwrap();
        assert_eq!(facts.get("out_of_core"), Some(&serde_json::json!(true)));
    }
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    let missing = dir.path().join("missing");
    let e = MumpsLlt::new(Some(missing.clone()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("cannot make a directory in it"), "{e}");
    assert!(e.contains(&missing.display().to_string()), "{e}");
}

/// `LDLᵀ` in a static order: `K = [1 1 1; 1 0 0; 1 0 0]` (one vertex, the
/// same constraint twice) has the null pivot at the second multiplier
/// (unknown 2: `0 − 1·1 − 1·(−1) = 0`), and one negative pivot (`−1`).
#[test]
fn ldlt_flags_the_dependent_multiplier() {
    let k = lower(
        3,
        &[
            (0, 0, 1.0),
            (1, 0, 1.0),
            (2, 0, 1.0),
            (1, 1, 0.0),
            (2, 2, 0.0),
        ],
    );
    let symbolic = MumpsLdlt::default()
        .analyze(k.symbolic(), &[0, 1, 2])
        .unwrap();
    let factor = symbolic.factorize(k.as_ref()).unwrap();
    let rule = PivotRule {
        positive: 1,
        tolerance: 1000.0 * f64::EPSILON,
    };
    // Unknowns 1 and 2 have one pattern: MUMPS merges them into one node and
    // eliminates them in either order, so either copy's pivot is the null
    // one (the KKT formulation names the constraint itself).
    let fault = factor.pivot_fault(k.as_ref(), rule);
    assert!(
        matches!(fault, Some(PivotFault::Null { unknown: 1 | 2, .. })),
        "{fault:?}"
    );
}

/// `K = [2 1 1; 1 2 0; 1 0 0]` is nonsingular in the order 0, 1, 2: no null
/// pivot, one negative (`d = (2, 3/2, −2/3)`), and it solves.
#[test]
fn ldlt_solves_a_regular_kkt_matrix() {
    let k = lower(
        3,
        &[
            (0, 0, 2.0),
            (1, 0, 1.0),
            (2, 0, 1.0),
            (1, 1, 2.0),
            (2, 2, 0.0),
        ],
    );
    let symbolic = MumpsLdlt::default()
        .analyze(k.symbolic(), &[0, 1, 2])
        .unwrap();
    let mut factor = symbolic.factorize(k.as_ref()).unwrap();
    let rule = PivotRule {
        positive: 2,
        tolerance: 1000.0 * f64::EPSILON,
    };
    assert_eq!(factor.pivot_fault(k.as_ref(), rule), None);
    // K [1; 1; 1] = [4; 3; 1].
    let mut x = Mat::from_fn(3, 1, |i, _| [4.0, 3.0, 1.0][i]);
    factor.solve_in_place(x.as_mut()).unwrap();
    for i in 0..3 {
        assert!((x[(i, 0)] - 1.0).abs() < 1e-14, "{x:?}");
    }
    let facts = factor.facts().unwrap();
    assert_eq!(facts.get("ordering"), Some(&serde_json::json!("given")));
}

/// Out of core, the factor's files removed between the factorisation and
/// the solve: the solve fails with a typed error naming the directory it
/// reads from and MUMPS's code, not with a non-finite solution.
#[test]
fn a_missing_out_of_core_file_is_a_typed_solve_error_naming_the_directory() {
    let a = tridiagonal(20_000);
    let dir = tempfile::tempdir().unwrap();
    let backend = MumpsLlt::new(Some(dir.path().to_path_buf())).unwrap();
    let symbolic = backend.analyze(a.symbolic()).unwrap();
    let mut factor = symbolic.factorize(a.as_ref()).unwrap();
    let scratch: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(scratch.len(), 1, "one scratch directory: {scratch:?}");
    let mut removed = 0;
    for file in std::fs::read_dir(&scratch[0]).unwrap() {
        std::fs::remove_file(file.unwrap().path()).unwrap();
        removed += 1;
    }
    assert!(removed > 0, "the factor was written to files");
    let rhs = Mat::from_fn(20_000, 3, |i, c| (i + c) as f64);
    let e = solve(factor.as_mut(), rhs.as_ref()).unwrap_err();
    let message = e.to_string();
    assert!(
        matches!(e, crate::error::NumericalError::Backend { .. }),
        "{e:?}"
    );
    assert!(
        message.contains(&scratch[0].display().to_string()),
        "the directory is named: {message}"
    );
    assert!(message.contains("INFOG(1) = -"), "MUMPS's code: {message}");
}

/// MUMPS's allocation failures (user's guide §8: `INFOG(1)` = −5, −7 and
/// −13, the size in `INFOG(2)`, in millions of entries when negative) are
/// refusals for size (exit 2) quoting the size; a singular matrix (−10)
/// and a workspace that stayed too small (−9) are not.
#[test]
fn allocation_failures_are_refusals_for_size() {
    use super::instance::Failure;
    use super::shared::numerical;
    let as_error =
        |infog1, infog2| crate::Error::from(numerical(Failure::Mumps { infog1, infog2 }));
    for (infog1, infog2, asked) in [
        (-13, 4096, "4096 entries"),
        (-13, -7, "7 million entries"),
        (-5, 12, "12 entries"),
        (-7, 3, "3 entries"),
    ] {
        let e = as_error(infog1, infog2);
        let text = e.to_string();
        assert_eq!(e.exit_code(), 2, "{text}");
        assert!(
            text.contains(asked) && text.contains(&format!("INFOG(1) = {infog1}")),
            "{text}"
        );
    }
    for infog1 in [-10, -9] {
        assert_eq!(as_error(infog1, 0).exit_code(), 3);
    }
}
