//! The linear-algebra back ends: every QR back end agrees with the dense
//! Householder reference on rank and skipped constraints, its implicit `Q`
//! is orthogonal and annihilates the kept constraints, the paper's method
//! gives the same solution over every QR × SPD pair, and every SPD back end
//! solves, refactors, and names its failing pivot in the original ordering.

use std::sync::Arc;
use std::time::Instant;

use faer::Mat;
use faer::sparse::{SparseColMat, SparseRowMat, Triplet};
use lse_deform::backend::qr::{self, ConstraintQr, QrBackend, QrKind, RankTolerance};
use lse_deform::backend::spd::{self, SpdBackend, SpdKind};
use lse_deform::constraints::{Constraint, ConstraintKind, ConstraintSet};
use lse_deform::error::{NumericalError, ProblemError};
use lse_deform::testing::{dense_reference, random_surface, relative_difference};
use lse_deform::{Deformer, LaplacianKind, NullSpaceQr};
use proptest::prelude::*;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

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

const COEFFS: [f64; 5] = [0.2, 0.35, 0.5, 0.65, 0.8];

/// A random constraint-like `B` (m × n) in priority order and the indices of
/// its dependent rows.
///
/// Base rows are position / edge / face / relative rows. Each base row puts
/// a nonzero coefficient on a "fresh" unknown that no earlier row touches, so
/// the base rows are independent (triangular after a column permutation).
/// Dependent rows are duplicates, scaled copies and combinations of one to
/// three base rows, each inserted somewhere after the last base row it uses:
/// exactly they must be skipped.
fn random_b(
    n: usize,
    n_base: usize,
    n_dep: usize,
    seed: u64,
) -> (SparseRowMat<usize, f64>, Vec<usize>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(&mut rng);
    let mut used = vec![false; n];
    let mut base: Vec<Vec<(usize, f64)>> = Vec::new();
    let mut fresh = order.into_iter();
    while base.len() < n_base {
        let Some(v) = fresh.by_ref().find(|&v| !used[v]) else {
            break;
        };
        let others: Vec<usize> = {
            let mut o = Vec::new();
            while o.len() < 2 {
                let u = rng.random_range(0..n);
                if u != v && !o.contains(&u) {
                    o.push(u);
                }
            }
            o
        };
        let t = COEFFS[rng.random_range(0..5)];
        let row = match rng.random_range(0..4) {
            0 => vec![(v, 1.0)],
            1 => vec![(v, t), (others[0], 1.0 - t)],
            2 => vec![(v, t), (others[0], 0.25), (others[1], 0.75 - t)],
            _ => vec![(v, 1.0), (others[0], -1.0)],
        };
        for &(u, _) in &row {
            used[u] = true;
        }
        base.push(row);
    }
    // Dependent rows: (insert after base row, row).
    let mut deps: Vec<(usize, Vec<(usize, f64)>)> = Vec::new();
    for _ in 0..n_dep {
        let k = rng.random_range(1..=3.min(base.len()));
        let mut idx: Vec<usize> = (0..base.len()).collect();
        idx.shuffle(&mut rng);
        idx.truncate(k);
        let mut acc = vec![0.0; n];
        for &b in &idx {
            let alpha = [1.0, -1.0, 0.5, 2.0, 0.3][rng.random_range(0..5)];
            for &(u, x) in &base[b] {
                acc[u] += alpha * x;
            }
        }
        let row: Vec<(usize, f64)> = (0..n)
            .filter(|&u| acc[u] != 0.0)
            .map(|u| (u, acc[u]))
            .collect();
        let last = idx.iter().copied().max().unwrap_or(0);
        let after = rng.random_range(last..base.len());
        deps.push((after, row));
    }
    let mut rows: Vec<Vec<(usize, f64)>> = Vec::new();
    let mut dependent = Vec::new();
    for (k, row) in base.into_iter().enumerate() {
        rows.push(row);
        for (after, dep) in &deps {
            if *after == k {
                dependent.push(rows.len());
                rows.push(dep.clone());
            }
        }
    }
    let trip: Vec<Triplet<usize, usize, f64>> = rows
        .iter()
        .enumerate()
        .flat_map(|(i, r)| r.iter().map(move |&(u, x)| Triplet::new(i, u, x)))
        .collect();
    let b = SparseRowMat::try_new_from_triplets(rows.len(), n, &trip).unwrap();
    (b, dependent)
}

fn dense(b: &SparseRowMat<usize, f64>) -> Mat<f64> {
    b.to_dense()
}

/// The rows `rows` of `b` as a CSC matrix (for `mul_a_q2`).
fn rows_as_csc(b: &SparseRowMat<usize, f64>, rows: &[usize]) -> SparseColMat<usize, f64> {
    let d = dense(b);
    let mut trip = Vec::new();
    for (k, &i) in rows.iter().enumerate() {
        for j in 0..d.ncols() {
            if d[(i, j)] != 0.0 {
                trip.push(Triplet::new(k, j, d[(i, j)]));
            }
        }
    }
    SparseColMat::try_new_from_triplets(rows.len(), d.ncols(), &trip).unwrap()
}

fn max_abs(m: &Mat<f64>) -> f64 {
    let mut x = 0.0f64;
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            x = x.max(m[(i, j)].abs());
        }
    }
    x
}

fn frob(m: &Mat<f64>) -> f64 {
    let mut s = 0.0;
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            s += m[(i, j)] * m[(i, j)];
        }
    }
    s.sqrt()
}

fn random_mat(rows: usize, cols: usize, rng: &mut ChaCha8Rng) -> Mat<f64> {
    Mat::from_fn(rows, cols, |_, _| rng.random_range(-1.0..1.0))
}

/// All the checks on one factorisation of `b`.
fn check_qr_operations(name: &str, qr: &dyn ConstraintQr, b: &SparseRowMat<usize, f64>, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (n, r) = (qr.n(), qr.rank());
    let bd = dense(b);
    let scale = max_abs(&bd).max(1.0);

    // Round trip and norm preservation.
    let x = random_mat(n, 3, &mut rng);
    let mut y = Mat::zeros(r, 3);
    let mut z = Mat::zeros(n - r, 3);
    qr.apply_qt(x.as_ref(), y.as_mut(), z.as_mut());
    let mut back = Mat::zeros(n, 3);
    qr.apply_q(y.as_ref(), z.as_ref(), back.as_mut());
    let err = max_abs(&(&back - &x));
    assert!(err < 1e-12, "{name}: Q Qᵀ x ≠ x (error {err:e})");
    let (nx, nyz) = (frob(&x), (frob(&y).powi(2) + frob(&z).powi(2)).sqrt());
    assert!(
        (nx - nyz).abs() < 1e-12 * nx,
        "{name}: ‖Qᵀx‖ = {nyz} ≠ ‖x‖ = {nx}"
    );

    // B_kept Q2 = 0, by mul_a_q2 on the kept rows of B.
    let kept = qr.kept().to_vec();
    let bk = rows_as_csc(b, &kept);
    let bq2 = qr.mul_a_q2(bk.as_ref()).to_dense();
    assert_eq!(bq2.ncols(), n - r);
    let err = max_abs(&bq2);
    assert!(
        err < 1e-13 * scale * (n as f64).sqrt(),
        "{name}: B_kept Q2 = {err:e}"
    );

    // mul_a_q2 equals A · (Q [0; I]) computed column by column with apply_q.
    let mut trip = Vec::new();
    for i in 0..7 {
        for j in 0..n {
            if rng.random_bool(0.3) {
                trip.push(Triplet::new(i, j, rng.random_range(-1.0..1.0)));
            }
        }
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(7, n, &trip).unwrap();
    let aq2 = qr.mul_a_q2(a.as_ref()).to_dense();
    let mut q2 = Mat::<f64>::zeros(n, n - r);
    let ident = Mat::<f64>::identity(n - r, n - r);
    qr.apply_q(
        Mat::<f64>::zeros(r, n - r).as_ref(),
        ident.as_ref(),
        q2.as_mut(),
    );
    let reference = a.to_dense() * &q2;
    let err = max_abs(&(&aq2 - &reference));
    assert!(err < 1e-12, "{name}: mul_a_q2 differs from A Q2 by {err:e}");

    // R1ᵀ y = D_kept gives B_kept x = D_kept for x = Q [y; 0].
    let d = random_mat(b.nrows(), 3, &mut rng);
    let (_, xp) = qr::particular_solution(qr, d.as_ref());
    let bx = &bd * &xp;
    let norm_xp = max_abs(&xp).max(1.0);
    for &i in &kept {
        for c in 0..3 {
            let e = (bx[(i, c)] - d[(i, c)]).abs();
            assert!(
                e < 1e-10 * norm_xp * scale,
                "{name}: row {i} residual {e:e}"
            );
        }
    }
    // free_unknown names an unknown.
    for k in 0..n - r {
        assert!(qr.free_unknown(k) < n);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Every QR back end finds the rank and exactly the dependent rows
    /// (duplicates, scaled copies, combinations) in priority order, and its
    /// operations are consistent.
    #[test]
    fn qr_backends_agree_on_rank_and_skipped(
        seed in any::<u64>(),
        n in 6usize..150,
        n_base_frac in 0.2f64..0.9,
        n_dep in 0usize..12,
    ) {
        let n_base = ((n as f64 * n_base_frac) as usize / 2).max(1);
        let (b, dependent) = random_b(n, n_base, n_dep, seed);
        let tol = RankTolerance::default();
        let reference = QrKind::DenseHouseholder.backend().unwrap().factor(b.as_ref(), tol).unwrap();
        prop_assert_eq!(reference.rank(), b.nrows() - dependent.len());
        prop_assert_eq!(reference.skipped(), &dependent[..]);
        for backend in qr_backends() {
            let f = backend.factor(b.as_ref(), tol).unwrap();
            prop_assert_eq!(f.rank(), reference.rank(), "{}", backend.name());
            prop_assert_eq!(f.skipped(), reference.skipped(), "{}", backend.name());
            let mut kept = f.kept().to_vec();
            kept.sort_unstable();
            let mut ref_kept = reference.kept().to_vec();
            ref_kept.sort_unstable();
            prop_assert_eq!(kept, ref_kept, "{}", backend.name());
            check_qr_operations(&backend.name(), &*f, &b, seed ^ 0xabc);
        }
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

fn jitter(rng: &mut ChaCha8Rng, p: [f64; 3], amount: f64) -> [f64; 3] {
    p.map(|x| x + rng.random_range(-amount..amount))
}

/// A random full-rank problem: independent hard constraints of all four
/// kinds (each on a fresh vertex) plus soft positions.
fn random_problem(seed: u64) -> Deformer {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mesh = random_surface(rng.random_range(3..7), rng.random_range(3..7), seed);
    let n = mesh.n_vertices();
    let p = mesh.positions().to_vec();
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(&mut rng);
    let mut used = vec![false; n];
    let mut cs = Vec::new();
    let n_hard = rng.random_range(3..10);
    let mut fresh = order.into_iter();
    while cs.len() < n_hard {
        let Some(v) = fresh.by_ref().find(|&v| !used[v]) else {
            break;
        };
        let pick = |rng: &mut ChaCha8Rng, not: &[usize]| loop {
            let u = rng.random_range(0..n);
            if !not.contains(&u) {
                break u;
            }
        };
        let kind = if cs.len() < 2 {
            0
        } else {
            rng.random_range(0..4)
        };
        let c = match kind {
            0 => ConstraintKind::Position {
                vertex: v,
                target: jitter(&mut rng, p[v], 0.2),
            },
            1 => {
                let u = pick(&mut rng, &[v]);
                used[u] = true;
                ConstraintKind::Edge {
                    vertices: [v, u],
                    t: COEFFS[rng.random_range(0..5)],
                    target: jitter(&mut rng, p[v], 0.2),
                }
            }
            2 => {
                let u = pick(&mut rng, &[v]);
                let w = pick(&mut rng, &[v, u]);
                used[u] = true;
                used[w] = true;
                ConstraintKind::Face {
                    vertices: [v, u, w],
                    barycentric: [COEFFS[rng.random_range(0..5)], 0.15],
                    target: jitter(&mut rng, p[v], 0.2),
                }
            }
            _ => {
                let u = pick(&mut rng, &[v]);
                used[u] = true;
                ConstraintKind::Relative {
                    vertices: [v, u],
                    vector: jitter(&mut rng, [0.0; 3], 0.2),
                }
            }
        };
        used[v] = true;
        cs.push(Constraint::hard(c));
    }
    for _ in 0..rng.random_range(0..3) {
        let v = rng.random_range(0..n);
        cs.push(Constraint::soft(
            ConstraintKind::Position {
                vertex: v,
                target: jitter(&mut rng, p[v], 0.2),
            },
            rng.random_range(0.5..5.0),
        ));
    }
    let kind = LaplacianKind::ALL[rng.random_range(0..LaplacianKind::ALL.len())];
    Deformer::new(mesh, kind, ConstraintSet::from_vec(cs).unwrap()).unwrap()
}

#[test]
fn null_space_method_agrees_over_every_backend_pair() {
    let qrs = qr_backends();
    let spds = spd_backends();
    assert!(qrs.len() >= 2 && spds.len() >= 4);
    for seed in 0..30u64 {
        let mut d = random_problem(seed);
        let rows: Vec<usize> = (0..d.problem().b().nrows()).collect();
        let reference = dense_reference(d.problem(), &rows);
        let mut first: Option<Mat<f64>> = None;
        for q in &qrs {
            for s in &spds {
                d.precompute(&NullSpaceQr::new(Arc::clone(q), Arc::clone(s)))
                    .unwrap_or_else(|e| panic!("{} × {}: {e}", q.name(), s.name()));
                assert_eq!(d.report().rank, Some(rows.len()));
                let x = d.solve_matrix().unwrap();
                let diff = relative_difference(&x, &reference);
                assert!(
                    diff < 1e-8,
                    "seed {seed}, {} × {}: {diff:e} from the dense reference",
                    q.name(),
                    s.name()
                );
                match &first {
                    None => first = Some(x),
                    Some(f) => {
                        let diff = relative_difference(&x, f);
                        assert!(
                            diff < 1e-8,
                            "seed {seed}, {} × {}: {diff:e} from the first pair",
                            q.name(),
                            s.name()
                        );
                    }
                }
            }
        }
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

/// A 2-D grid Laplacian (`k × k`) plus `shift` on the diagonal, with
/// slightly perturbed off-diagonal weights (seeded): SPD for `shift > 0`.
fn grid_spd(k: usize, shift: f64, seed: u64) -> (usize, Vec<(usize, usize, f64)>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = k * k;
    let mut diag = vec![shift; n];
    let mut full = Vec::new();
    for i in 0..k {
        for j in 0..k {
            let a = i * k + j;
            for b in [(i + 1 < k).then(|| a + k), (j + 1 < k).then(|| a + 1)]
                .into_iter()
                .flatten()
            {
                let w = rng.random_range(0.5..1.5);
                full.push((a, b, -w));
                full.push((b, a, -w));
                diag[a] += w;
                diag[b] += w;
            }
        }
    }
    for (a, d) in diag.into_iter().enumerate() {
        full.push((a, a, d));
    }
    (n, full)
}

fn full_dense(n: usize, full: &[(usize, usize, f64)]) -> Mat<f64> {
    let mut m = Mat::zeros(n, n);
    for &(i, j, v) in full {
        m[(i, j)] += v;
    }
    m
}

#[test]
fn spd_backends_solve_and_refactor() {
    let (n, full1) = grid_spd(12, 0.1, 1);
    let (_, full2) = grid_spd(12, 0.7, 2); // same pattern, new values
    let m1 = lower(n, &full1);
    let m2 = lower(n, &full2);
    assert_eq!(m1.symbolic().row_idx(), m2.symbolic().row_idx());
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let rhs = random_mat(n, 3, &mut rng);
    for backend in spd_backends() {
        let name = backend.name();
        let symbolic = backend.analyze(m1.symbolic()).unwrap();
        assert!(symbolic.factor_nnz() >= n, "{name}");
        for (m, full) in [(&m1, &full1), (&m2, &full2)] {
            // Same symbolic object, new values: numeric phase only.
            let mut f = symbolic.factorize(m.as_ref()).unwrap();
            assert_eq!(f.dim(), n);
            assert!(f.nnz() >= n && f.bytes() > 0, "{name}");
            let x = spd::solve(&mut *f, rhs.as_ref()).unwrap();
            let res = full_dense(n, full) * &x - &rhs;
            let rel = max_abs(&res) / max_abs(&rhs);
            assert!(rel < 1e-12, "{name}: residual {rel:e}");
        }
    }
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

/// Timings on a 35k-vertex surface (run with
/// `cargo test --release --test backends -- --ignored --nocapture`):
/// 7,000 separate positions plus 300 others; and 2,000 relative constraints
/// linking a connected region.
#[test]
#[ignore]
fn timing_large() {
    let mesh = random_surface(186, 186, 5);
    let n = mesh.n_vertices();
    let p = mesh.positions().to_vec();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut cs: Vec<Constraint> = Vec::new();
    let mut verts: Vec<usize> = (0..n).collect();
    verts.shuffle(&mut rng);
    for &v in &verts[..7000] {
        cs.push(Constraint::hard(ConstraintKind::Position {
            vertex: v,
            target: p[v],
        }));
    }
    for k in 0..300 {
        let (a, b) = (verts[7000 + 2 * k], verts[7001 + 2 * k]);
        cs.push(Constraint::hard(ConstraintKind::Edge {
            vertices: [a, b],
            t: 0.3,
            target: p[a],
        }));
    }
    report("7000 positions + 300 edges", &mesh, cs);

    // A connected region: the grid rows 20..45 × columns 20..60 (~1000
    // vertices); relative constraints along its grid edges (cycles included:
    // dependent ones get skipped), plus one position pinning everything.
    let side = 187;
    let mut rel = vec![Constraint::hard(ConstraintKind::Position {
        vertex: 0,
        target: p[0],
    })];
    'outer: for j in 20..45 {
        for i in 20..60 {
            let a = j * side + i;
            for b in [a + 1, a + side] {
                rel.push(Constraint::hard(ConstraintKind::Relative {
                    vertices: [a, b],
                    vector: [0, 1, 2].map(|c| p[a][c] - p[b][c]),
                }));
                if rel.len() > 2000 {
                    break 'outer;
                }
            }
        }
    }
    report("2000 relative constraints in a region", &mesh, rel.clone());
    // The same constraints in a random priority order (R's fill follows it).
    let (first, rest) = rel.split_at_mut(1);
    let _ = first;
    rest.shuffle(&mut rng);
    report("the same, shuffled priority", &mesh, rel);
    // A star: 2000 vertices each tied to one anchor by a relative constraint.
    let anchor = 100 * side + 100;
    let mut star = vec![Constraint::hard(ConstraintKind::Position {
        vertex: anchor,
        target: p[anchor],
    })];
    for &v in verts.iter().filter(|&&v| v != anchor).take(2000) {
        star.push(Constraint::hard(ConstraintKind::Relative {
            vertices: [v, anchor],
            vector: [0, 1, 2].map(|c| p[v][c] - p[anchor][c]),
        }));
    }
    report("2000 relative constraints to one anchor", &mesh, star);
}

fn report(label: &str, mesh: &lse_deform::Mesh, cs: Vec<Constraint>) {
    let d = Deformer::new(
        mesh.clone(),
        LaplacianKind::Cotangent,
        ConstraintSet::from_vec(cs).unwrap(),
    )
    .unwrap();
    let b = d.problem().b();
    let a = d.problem().a();
    println!("{label}: n = {}, m = {}", b.ncols(), b.nrows());
    for backend in qr_backends() {
        let t = Instant::now();
        let f = backend
            .factor(b.as_ref(), RankTolerance::default())
            .unwrap();
        let t_qr = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let aq2 = f.mul_a_q2(a.as_ref());
        let t_aq2 = t.elapsed().as_secs_f64();
        println!(
            "  {:18} rank {:5}  QR {:8.2} ms  AQ2 {:8.2} ms  nnz(AQ2) {:9}  stored {:9}",
            backend.name(),
            f.rank(),
            t_qr * 1e3,
            t_aq2 * 1e3,
            aq2.val().len(),
            f.storage_nnz()
        );
    }
    for order in [
        qr::GivensRowOrder::LeadingConstraint,
        qr::GivensRowOrder::Natural,
    ] {
        let t = Instant::now();
        let f = qr::GivensQr::new(b.as_ref(), RankTolerance::default(), order).unwrap();
        let t_qr = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let aq2 = f.mul_a_q2(a.as_ref());
        let t_aq2 = t.elapsed().as_secs_f64();
        println!(
            "  givens {:?}: QR {:8.2} ms, rotations {}, nnz(R) {}, AQ2 {:8.2} ms nnz {}",
            order,
            t_qr * 1e3,
            f.n_rotations(),
            f.r_nnz(),
            t_aq2 * 1e3,
            aq2.val().len()
        );
    }
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
    let mut d = Deformer::new(mesh.clone(), LaplacianKind::Cotangent, cs).unwrap();
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
    d.precompute(&NullSpaceQr::default()).unwrap();
    let x = d.solve_matrix().unwrap();
    assert!(d.report().max_constraint_residual <= 1e-12 * mesh.bbox_diagonal());
    let paper = NullSpaceQr::new(
        Arc::new(qr::DenseHouseholder),
        Arc::new(spd::FaerLlt::auto()),
    );
    d.precompute(&paper).unwrap();
    let reference = d.solve_matrix().unwrap();
    let diff = relative_difference(&x, &reference);
    assert!(diff < 1e-9, "differs from DenseHouseholder by {diff:e}");
}

/// Finding 5 of issue 38: faer's factorisations checked only their
/// factor's estimate (12 bytes an entry) against the budget, not what the
/// process already holds nor their workspace: with a budget of exactly
/// that estimate and a process holding more than it already, they went
/// ahead. Now what the process holds (its resident set) is counted on
/// top, and the refusal says so.
#[test]
fn faer_counts_what_the_process_holds_against_the_budget() {
    use lse_deform::backend::ldlt::LdltKind;
    use lse_deform::limits::{FACTOR_BYTES_PER_ENTRY, MemoryBudget};
    let (n, full) = grid_spd(60, 0.1, 3);
    let m = lower(n, &full);
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
