//! Repeated rows found, and every back end reporting them as skipped. A
//! child file of `distinct_rows`: it runs the back ends, which import
//! `distinct_rows`, so `distinct_rows` itself must not.

use super::*;
use crate::backend::qr::{DenseHouseholder, QrBackend, RankTolerance, SparseGivens};

fn rows(n: usize, list: &[&[(usize, f64)]]) -> SparseRowMat<usize, f64> {
    let triplets: Vec<faer::sparse::Triplet<usize, usize, f64>> = list
        .iter()
        .enumerate()
        .flat_map(|(i, r)| {
            r.iter()
                .map(move |&(u, v)| faer::sparse::Triplet::new(i, u, v))
        })
        .collect();
    SparseRowMat::try_new_from_triplets(list.len(), n, &triplets).unwrap()
}

#[test]
fn repeats_up_to_sign_are_found() {
    let b = rows(
        4,
        &[
            &[(0, 1.0), (1, -1.0)],
            &[(2, 1.0)],
            &[(1, 1.0), (0, -1.0)], // −row 0
            &[(0, 1.0), (1, -1.0)], // row 0
            &[(0, 1.0), (1, -0.5)], // not a repeat
            &[(2, 1.0)],            // row 1
            &[(2, 2.0)],            // a multiple, left to the QR
        ],
    );
    assert_eq!(
        first_occurrences(b.as_ref()).unwrap(),
        vec![0, 1, 0, 0, 4, 1, 6]
    );
}

#[test]
fn every_back_end_reports_repeats_as_skipped_and_keeps_the_rest() {
    // Rank by hand: rows 0, 1, 4 independent (distinct unknown patterns,
    // row 4 not parallel to row 0); rows 2, 3, 5 repeat; row 6 = 2·row 1.
    let b = rows(
        4,
        &[
            &[(0, 1.0), (1, -1.0)],
            &[(2, 1.0)],
            &[(1, 1.0), (0, -1.0)],
            &[(0, 1.0), (1, -1.0)],
            &[(0, 1.0), (1, -0.5)],
            &[(2, 1.0)],
            &[(2, 2.0)],
        ],
    );
    let backends: Vec<Box<dyn QrBackend>> = vec![
        Box::new(DenseHouseholder),
        Box::new(SparseGivens::default()),
    ];
    for backend in backends {
        let qr = backend
            .factor(b.as_ref(), RankTolerance::default())
            .unwrap();
        assert_eq!(qr.rank(), 3, "{}", backend.name());
        // In the order of y: per block for dense-householder.
        let mut kept = qr.kept().to_vec();
        kept.sort_unstable();
        assert_eq!(kept, [0, 1, 4], "{}", backend.name());
        assert_eq!(qr.skipped(), &[2, 3, 5, 6], "{}", backend.name());
        // R1ᵀ y = d_kept with d of all 7 rows: X = Q[y; 0] satisfies
        // the kept rows.
        let d = Mat::from_fn(7, 1, |i, _| [1.0, 2.0, -1.0, 1.0, 3.0, 2.0, 4.0][i]);
        let (_, x) = crate::backend::qr::particular_solution(qr.as_ref(), d.as_ref());
        assert!((x[(0, 0)] - x[(1, 0)] - 1.0).abs() < 1e-12);
        assert!((x[(2, 0)] - 2.0).abs() < 1e-12);
        assert!((x[(0, 0)] - 0.5 * x[(1, 0)] - 3.0).abs() < 1e-12);
    }
}
