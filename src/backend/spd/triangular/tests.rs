//! The lane kernels, and the solve split over the elimination tree
//! (`tree_split`), against faer's own supernodal and simplicial solves. A
//! child file of `triangular`: it imports `tree_split`, which imports
//! `triangular`'s passes, so `triangular` itself must not.

use super::*;
use faer::Mat;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, Par, Side};

/// The lower triangle of the 2-D 5-point Laplacian on a `k × k` grid
/// plus `shift` on the diagonal (SPD), with some longer-range entries
/// so that supernodes of several widths and pattern lengths occur.
fn spd_lower(k: usize, shift: f64) -> SparseColMat<usize, f64> {
    let n = k * k;
    let mut t = Vec::new();
    for i in 0..n {
        t.push(Triplet::new(i, i, 4.0 + shift + (i % 7) as f64 * 0.1));
        if i % k + 1 < k {
            t.push(Triplet::new(i + 1, i, -1.0));
        }
        if i + k < n {
            t.push(Triplet::new(i + k, i, -1.0 + (i % 3) as f64 * 0.05));
        }
        if i + 3 * k + 2 < n && i % 5 == 0 {
            t.push(Triplet::new(i + 3 * k + 2, i, 0.3));
        }
    }
    SparseColMat::try_new_from_triplets(n, n, &t).unwrap()
}

/// A factor of [`spd_lower`]`(k, 0.5)`: the symbolic factor, faer's
/// column-major values, the values in our row layout, `1 / L_ii`, and
/// the permutation.
struct Factor {
    symbolic: faer::sparse::linalg::cholesky::SymbolicCholesky<usize>,
    values: Vec<f64>,
    rows_layout: Vec<f64>,
    inv_diag: Vec<f64>,
    perm: Option<Vec<usize>>,
}

fn factor(k: usize, threshold: SupernodalThreshold) -> Factor {
    let lower = spd_lower(k, 0.5);
    let params = CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: threshold,
        ..Default::default()
    };
    let symbolic = factorize_symbolic_cholesky(
        lower.symbolic(),
        Side::Lower,
        SymmetricOrdering::Amd,
        params,
    )
    .unwrap();
    let mut values = vec![0.0; symbolic.len_val()];
    let mut mem =
        MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()));
    symbolic
        .factorize_numeric_llt(
            &mut values,
            lower.as_ref(),
            Side::Lower,
            LltRegularization::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .unwrap();
    let perm = symbolic.perm().map(|p| p.arrays().0.to_vec());
    let inv_diag: Vec<f64> = factor_diagonal(&symbolic, &values)
        .iter()
        .map(|d| 1.0 / d)
        .collect();
    let mut rows_layout = values.clone();
    SupernodalRows::transpose_in_place(&symbolic, &mut rows_layout);
    Factor {
        symbolic,
        values,
        rows_layout,
        inv_diag,
        perm,
    }
}

/// faer's own solve of `L Lᵀ X = B` (on the column-major values).
fn faer_solve(f: &Factor, b: &Mat<f64>) -> Mat<f64> {
    let mut expected = b.clone();
    let llt = faer::sparse::linalg::cholesky::LltRef::new(&f.symbolic, &f.values);
    let mut mem = MemBuffer::new(
        f.symbolic
            .solve_in_place_scratch::<f64>(b.ncols(), Par::Seq),
    );
    llt.solve_in_place_with_conj(
        Conj::No,
        expected.as_mut(),
        Par::Seq,
        MemStack::new(&mut mem),
    );
    expected
}

/// A right-hand side with `k` columns and `n` rows.
fn rhs(n: usize, k: usize) -> Mat<f64> {
    Mat::<f64>::from_fn(n, k, |i, c| ((i * 7 + c * 13) % 17) as f64 - 8.0)
}

/// `b` gathered into lanes of `W` in the factor's order.
fn gather<const W: usize>(f: &Factor, b: &Mat<f64>) -> Vec<[f64; W]> {
    let mut w = vec![[0.0; W]; b.nrows()];
    for (i, lane) in w.iter_mut().enumerate() {
        let src = f.perm.as_ref().map_or(i, |p| p[i]);
        for c in 0..b.ncols() {
            lane[c] = b[(src, c)];
        }
    }
    w
}

/// Lanes `w` (in the factor's order) against `expected`, and unused
/// lanes still zero.
fn compare<const W: usize>(f: &Factor, w: &[[f64; W]], expected: &Mat<f64>) {
    let k = expected.ncols();
    for (i, lane) in w.iter().enumerate() {
        let dst = f.perm.as_ref().map_or(i, |p| p[i]);
        for c in 0..k {
            let (got, want) = (lane[c], expected[(dst, c)]);
            assert!(
                (got - want).abs() <= 1e-12 * want.abs().max(1.0),
                "k = {k}, unknown {dst}, column {c}: {got} vs {want}"
            );
        }
        assert!(lane[k..].iter().all(|&v| v == 0.0));
    }
}

/// Solves with our lanes and with faer's own solve and compares, for
/// several column counts.
fn check(threshold: SupernodalThreshold) {
    let f = factor(23, threshold);
    let n = f.symbolic.nrows();
    for k in [1, 3, 4] {
        let b = rhs(n, k);
        let mut w = gather::<LANES>(&f, &b);
        solve_lanes(
            &f.symbolic,
            &f.rows_layout,
            &f.inv_diag,
            &mut w,
            &mut Vec::new(),
        );
        compare(&f, &w, &faer_solve(&f, &b));
    }
}

/// The solve split over the elimination tree on two threads
/// ([`super::super::tree_split::TreeSplit`]) against faer's, with both
/// lane widths.
#[test]
fn split_solves_match_faers_solve() {
    use super::super::tree_split::TreeSplit;
    let f = factor(48, SupernodalThreshold::FORCE_SUPERNODAL);
    let split = TreeSplit::with_min_values(&f.symbolic, 0).expect("a grid's tree splits");
    let check = |k: usize, solve: &dyn Fn(&Mat<f64>) -> Mat<f64>| {
        let b = rhs(f.symbolic.nrows(), k);
        let got = solve(&b);
        let want = faer_solve(&f, &b);
        assert!(
            (&got - &want).norm_max() <= 1e-12 * want.norm_max(),
            "k = {k}"
        );
    };
    for k in [1, 3, 4] {
        check(k, &|b| split_solve(&f, &split, passes(), b));
    }
    for k in [1, 5, 7, 8] {
        check(k, &|b| split_solve(&f, &split, wide_passes(), b));
    }
}

/// `b` solved by `split` with `passes`, back in the original order
/// (unused lanes checked to stay zero).
fn split_solve<const W: usize>(
    f: &Factor,
    split: &super::super::tree_split::TreeSplit,
    passes: Passes<W>,
    b: &Mat<f64>,
) -> Mat<f64> {
    let n = b.nrows();
    let mut w = gather::<W>(f, b);
    let (mut w2, mut s, mut s2) = (vec![[0.0; W]; n], Vec::new(), Vec::new());
    let buffers = ((&mut w[..], &mut s), (&mut w2[..], &mut s2));
    split.solve(
        passes,
        &f.symbolic,
        &f.rows_layout,
        &f.inv_diag,
        buffers.0,
        buffers.1,
    );
    let mut x = Mat::zeros(n, b.ncols());
    for (i, lane) in w.iter().enumerate() {
        let dst = f.perm.as_ref().map_or(i, |p| p[i]);
        for c in 0..b.ncols() {
            x[(dst, c)] = lane[c];
        }
        assert!(lane[b.ncols()..].iter().all(|&v| v == 0.0));
    }
    x
}

#[test]
fn supernodal_lanes_match_faers_solve() {
    check(SupernodalThreshold::FORCE_SUPERNODAL);
}

#[test]
fn simplicial_lanes_match_faers_solve() {
    check(SupernodalThreshold::FORCE_SIMPLICIAL);
}
