//! Graph rows around a hub replaced, and every back end agreeing with the
//! plain priority-order Givens QR on them. A child file of `graph_rows`: it
//! runs the back ends, which import `graph_rows`, so `graph_rows` itself
//! must not.

use super::*;
use crate::backend::qr::{
    DenseHouseholder, GivensQr, GivensRowOrder, QrBackend, RankTolerance, SparseGivens,
    particular_solution,
};
use faer::sparse::Triplet;
use proptest::prelude::*;

/// Rows from edges: `(a, None)` = `e_a`, `(a, Some(b))` = `e_a − e_b`.
fn b_of(n: usize, edges: &[(usize, Option<usize>)]) -> SparseRowMat<usize, f64> {
    let mut t = Vec::new();
    for (i, &(a, b)) in edges.iter().enumerate() {
        t.push(Triplet::new(i, a, 1.0));
        if let Some(b) = b {
            t.push(Triplet::new(i, b, -1.0));
        }
    }
    SparseRowMat::try_new_from_triplets(edges.len(), n, &t).unwrap()
}

/// Checks a back end against the plain priority-order Givens QR (no
/// replacement): same kept and skipped rows, `B_kept Q2 = 0`, and the
/// particular solution meets every kept row.
fn agrees(n: usize, edges: &[(usize, Option<usize>)], backend: &dyn QrBackend) {
    let b = b_of(n, edges);
    let plain = GivensQr::new(
        b.as_ref(),
        RankTolerance::default(),
        GivensRowOrder::Natural,
    )
    .unwrap();
    let qr = backend
        .factor(b.as_ref(), RankTolerance::default())
        .unwrap();
    assert_eq!(qr.skipped(), plain.skipped(), "{}", backend.name());
    let mut kept = qr.kept().to_vec();
    kept.sort_unstable();
    let mut plain_kept = plain.kept().to_vec();
    plain_kept.sort_unstable();
    assert_eq!(kept, plain_kept, "{}", backend.name());
    assert_eq!(qr.rank(), kept.len());
    // B_kept Q2 = 0.
    let mut t = Vec::new();
    for (r, &j) in kept.iter().enumerate() {
        let (a, b_node) = edges[j];
        t.push(Triplet::new(r, a, 1.0));
        if let Some(w) = b_node {
            t.push(Triplet::new(r, w, -1.0));
        }
    }
    let bk = SparseColMat::try_new_from_triplets(kept.len(), n, &t).unwrap();
    let bq2 = qr.mul_a_q2(bk.as_ref()).to_dense();
    let worst = (0..bq2.nrows())
        .flat_map(|i| (0..bq2.ncols()).map(move |c| (i, c)))
        .map(|(i, c)| bq2[(i, c)].abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-12, "{}: B_kept Q2 = {worst:e}", backend.name());
    // Particular solution for d_j = j + 1 (and a second column).
    let d = Mat::from_fn(edges.len(), 2, |j, c| (j + 1) as f64 * (1.0 + c as f64));
    let (_, x) = particular_solution(qr.as_ref(), d.as_ref());
    for &j in &kept {
        let (a, b_node) = edges[j];
        for c in 0..2 {
            let got = x[(a, c)] - b_node.map_or(0.0, |w| x[(w, c)]);
            assert!(
                (got - d[(j, c)]).abs() < 1e-9 * d[(j, c)].abs().max(1.0),
                "{}: row {j}: {got} ≠ {}",
                backend.name(),
                d[(j, c)]
            );
        }
    }
}

fn backends() -> Vec<Box<dyn QrBackend>> {
    vec![
        Box::new(SparseGivens::default()),
        Box::new(DenseHouseholder),
    ]
}

#[test]
fn a_star_from_a_hub_becomes_a_binomial_tree() {
    // 100 relative rows hub 0 → v, v = 1..=100, a repeat-free cycle row
    // (1 − 2, dependent), and a pin elsewhere.
    let mut edges: Vec<(usize, Option<usize>)> = (1..=100).map(|v| (0, Some(v))).collect();
    edges.push((1, Some(2)));
    edges.push((150, None));
    edges.push((2, Some(0))); // dependent: −(0 − 2)
    let plan = Plan::new(b_of(160, &edges).as_ref()).expect("a hub of degree 100");
    assert_eq!(plan.skipped, vec![100, 102]);
    // 100 tree rows (101 unknowns in one tree) + 1 pin.
    assert_eq!(plan.rhs.len(), 101);
    let ptr = plan.rows.symbolic().row_ptr();
    assert!((0..101).all(|i| ptr[i + 1] - ptr[i] <= 2));
    for backend in backends() {
        agrees(160, &edges, backend.as_ref());
    }
}

#[test]
fn a_hub_tied_to_the_ground_pins_every_vertex() {
    let mut edges: Vec<(usize, Option<usize>)> = vec![(0, None)];
    edges.extend((1..=40).map(|v| (v, Some(0))));
    edges.push((5, None)); // dependent: 5 is pinned through the hub
    let plan = Plan::new(b_of(50, &edges).as_ref()).unwrap();
    assert_eq!(plan.skipped, vec![41]);
    assert!(matches!(plan.rhs[0], Rhs::Pin(_)));
    assert_eq!(plan.rows.symbolic().col_idx().len(), 41, "one entry a row");
    for backend in backends() {
        agrees(50, &edges, backend.as_ref());
    }
}

#[test]
fn other_rows_are_left_alone() {
    // No hub: a chain.
    let edges: Vec<(usize, Option<usize>)> = (0..50).map(|v| (v, Some(v + 1))).collect();
    assert!(Plan::new(b_of(60, &edges).as_ref()).is_none());
    // A hub, but one row is not ±1.
    let mut t: Vec<Triplet<usize, usize, f64>> = Vec::new();
    for v in 1..=40 {
        t.push(Triplet::new(v - 1, 0, 1.0));
        t.push(Triplet::new(v - 1, v, -1.0));
    }
    t.push(Triplet::new(40, 3, 0.5));
    let b = SparseRowMat::try_new_from_triplets(41, 50, &t).unwrap();
    assert!(Plan::new(b.as_ref()).is_none());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    /// Random graph rows around a hub (cycles, repeats up to sign,
    /// pins): every back end agrees with the plain QR.
    #[test]
    fn random_hub_graphs_agree_with_the_plain_qr(
        raw in proptest::collection::vec((0usize..4, 0usize..40, 0usize..40), 40..120)
    ) {
        let edges: Vec<(usize, Option<usize>)> = raw
            .iter()
            .map(|&(kind, u, v)| match kind {
                0 => (u, None),
                1 | 2 if u != 0 => (0, Some(u)), // hub 0
                1 | 2 => (0, None),
                _ if u != v => (u, Some(v)),
                _ => (u, None),
            })
            .collect();
        for backend in backends() {
            agrees(40, &edges, backend.as_ref());
        }
    }
}
