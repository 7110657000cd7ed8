//! Constraints that form a graph, with a hub: rank by union–find, and an
//! equivalent set of rows whose `B Bᵀ` is sparse.
//!
//! **When.** Every row of `B` is a position row `e_u` (its coefficient
//! exactly 1) or a relative row `e_u − e_v` (coefficients exactly `+1`, `−1`) — the
//! constraints of the paper's eq. 3 and 6 — and some unknown is shared by
//! more than [`HUB_DEGREE`] of the independent ones. Then `B Bᵀ` has a dense
//! block of that size, which any QR of `Bᵀ` fills into `R` (`RᵀR = B Bᵀ`):
//! 200,000 relative constraints from one hub to distinct vertices would need
//! `2·10¹⁰` entries. Otherwise the back end factors `B` as it is.
//!
//! **Rank, exactly.** Read the rows as edges of a graph on the unknowns plus
//! a *ground* node `G` (`e_u` is the edge `u–G`, `p_G = 0`). A set of such
//! rows is linearly independent iff its edges form a forest, so walking the
//! rows in priority order with a union–find keeps an edge iff it joins two
//! trees: the same kept and skipped sets as the QR's priority-order test
//! (a dependent row's remainder is exactly zero, an independent one's is
//! at least `1/√(tree size)`, far above the tolerance), in `O(m α(m))`.
//!
//! **Equivalent rows.** The kept rows fix exactly this: on each tree `T`,
//! `p_a − p_b = φ(a) − φ(b)` for the *potential* `φ` obtained by summing the
//! right-hand sides along tree paths (`φ(G) = 0`). So they can be replaced by
//! any rows with the same span and the matching right-hand sides:
//! - a tree containing `G` pins each of its unknowns: rows `e_v`, right-hand
//!   side `φ(v)` — `R` diagonal, no rotation;
//! - a tree without `G` whose largest degree exceeds [`HUB_DEGREE`] becomes
//!   a binomial tree over its unknowns `v_0, …, v_{k−1}` in depth-first
//!   order: rows `e_{v_i} − e_{v_{i+s}}` for `s = 1, 2, 4, …` and
//!   `i ≡ 0 (mod 2s)`, right-hand sides `φ(v_i) − φ(v_{i+s})`. Every unknown
//!   is in at most `⌈log₂ k⌉` rows, so `B Bᵀ` stays sparse; and the
//!   rotations that eliminate it merge columns of `A` pairwise, level by
//!   level (`O(k log k)` fill in `A Q`), where a path `v_0 − v_1 − ⋯` would
//!   merge them one after another (`O(k²)`: 20,000 partners took 90 s and
//!   17 GB that way);
//! - other trees keep their rows.
//!
//! The minimiser of `‖AX − C‖` on `{X : B_kept X = D_kept}` is unchanged
//! (the same affine set). `φ` is recomputed from `D` at every solve
//! (`O(m)`), so targets can still change without refactoring. Rounding: a
//! potential sums at most `depth` right-hand sides, so a kept row holds to
//! about `depth · ε · max|d|`.

use faer::sparse::{
    SparseColMat, SparseColMatRef, SparseRowMat, SparseRowMatRef, SymbolicSparseRowMat,
};
use faer::{Mat, MatMut, MatRef};

use super::ConstraintQr;
use crate::error::Error;

/// An unknown shared by more independent graph rows than this makes the
/// rows be replaced (see the module documentation). Meshes have vertex
/// degrees around 6, so constraint trees built along mesh edges stay below
/// it and keep their rows; a hub constrained to many vertices does not.
pub const HUB_DEGREE: usize = 32;

/// A row of `B` read as an edge `a − b` (`b = None`: the ground).
#[derive(Debug, Clone, Copy)]
struct Edge {
    a: usize,
    b: Option<usize>,
}

/// Row `j` as an edge, if it is a graph row.
fn edge(cols: &[usize], vals: &[f64]) -> Option<Edge> {
    match (cols, vals) {
        ([u], [v]) if *v == 1.0 => Some(Edge { a: *u, b: None }),
        ([u, w], [x, y]) if *x == 1.0 && *y == -1.0 && u != w => Some(Edge { a: *u, b: Some(*w) }),
        ([u, w], [x, y]) if *x == -1.0 && *y == 1.0 && u != w => Some(Edge { a: *w, b: Some(*u) }),
        _ => None,
    }
}

fn find(parent: &mut [usize], mut x: usize) -> usize {
    while parent[x] != x {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    x
}

/// One step of the potential: `φ[node] = φ[parent] + sign · d[row]`
/// (`parent == usize::MAX`: a root, `φ = 0`). Indices into the traversal.
#[derive(Debug, Clone, Copy)]
struct Step {
    parent: usize,
    row: usize,
    sign: f64,
}

/// Right-hand side of a replacement row, from the potentials (traversal
/// indices) or an original row.
#[derive(Debug, Clone, Copy)]
enum Rhs {
    Pin(usize),
    Diff(usize, usize),
    Row(usize),
}

/// Factors `b` with `factor`, replacing hub-shaped graph rows first when
/// the module's conditions hold; otherwise calls `factor(b)`.
pub(super) fn factor_graph_rows(
    b: SparseRowMatRef<'_, usize, f64>,
    factor: impl Fn(SparseRowMatRef<'_, usize, f64>) -> Result<Box<dyn ConstraintQr>, Error>,
) -> Result<Box<dyn ConstraintQr>, Error> {
    let Some(plan) = Plan::new(b) else {
        return factor(b);
    };
    let inner = factor(plan.rows.as_ref())?;
    if inner.rank() != plan.rhs.len() {
        // Cannot happen for exact ±1 rows; stay safe rather than wrong.
        return factor(b);
    }
    Ok(Box::new(GraphRows {
        inner,
        steps: plan.steps,
        rhs: plan.rhs,
        kept: plan.kept,
        skipped: plan.skipped,
    }))
}

struct Plan {
    rows: SparseRowMat<usize, f64>,
    steps: Vec<Step>,
    rhs: Vec<Rhs>,
    kept: Vec<usize>,
    skipped: Vec<usize>,
}

impl Plan {
    /// The plan for `b`, if every row is a graph row ([`edge`]) and the
    /// kept forest ([`kept_forest`]) has a hub: each tree is walked
    /// depth-first ([`Walk::tree`], ground's tree first) and given its
    /// replacement rows ([`Walk::replacement_rows`]), assembled by
    /// [`assemble_rows`].
    fn new(b: SparseRowMatRef<'_, usize, f64>) -> Option<Plan> {
        let (m, n) = (b.nrows(), b.ncols());
        let (ptr, col, val) = (b.symbolic().row_ptr(), b.symbolic().col_idx(), b.val());
        let ground = n;
        let mut edges = Vec::with_capacity(m);
        for j in 0..m {
            edges.push(edge(&col[ptr[j]..ptr[j + 1]], &val[ptr[j]..ptr[j + 1]])?);
        }
        let (kept, skipped, degree) = kept_forest(&edges, n);
        if degree[..n].iter().all(|&d| d <= HUB_DEGREE) {
            return None;
        }
        let (adj_ptr, adj) = forest_adjacency(&edges, &kept, n);
        let mut walk = Walk {
            slot: vec![usize::MAX; n + 1],
            steps: Vec::new(),
            nodes: Vec::new(),
            stack: Vec::new(),
            triplets: Vec::new(),
            rhs: Vec::new(),
        };
        let roots = std::iter::once(ground).chain(0..n);
        for root in roots {
            if walk.slot[root] != usize::MAX || adj_ptr[root + 1] == adj_ptr[root] {
                continue;
            }
            let first = walk.steps.len();
            let max_degree = walk.tree(root, ground, &edges, &degree, &adj_ptr, &adj);
            walk.replacement_rows(first, root == ground, max_degree, &edges);
        }
        Some(Plan {
            rows: assemble_rows(&walk.triplets, n),
            steps: walk.steps,
            rhs: walk.rhs,
            kept,
            skipped,
        })
    }
}

/// Walks `edges` (rows of `B`, over `n` unknowns and the ground `n`) in
/// priority order with a union–find: a row is kept iff it joins two
/// trees. Returns the kept rows, the skipped ones, and each node's degree
/// in the kept forest.
fn kept_forest(edges: &[Edge], n: usize) -> (Vec<usize>, Vec<usize>, Vec<usize>) {
    let ground = n;
    let mut parent: Vec<usize> = (0..=n).collect();
    let mut kept = Vec::new();
    let mut skipped = Vec::new();
    let mut degree = vec![0usize; n + 1];
    for (j, e) in edges.iter().enumerate() {
        let b_node = e.b.unwrap_or(ground);
        let (ra, rb) = (find(&mut parent, e.a), find(&mut parent, b_node));
        if ra == rb {
            skipped.push(j);
        } else {
            parent[ra] = rb;
            kept.push(j);
            degree[e.a] += 1;
            degree[b_node] += 1;
        }
    }
    (kept, skipped, degree)
}

/// The adjacency of the kept forest, CSR over the nodes `0..=n` (the
/// ground `n`): `(neighbour, row)` pairs, in kept order at each node.
fn forest_adjacency(edges: &[Edge], kept: &[usize], n: usize) -> (Vec<usize>, Vec<(usize, usize)>) {
    let ground = n;
    let mut adj_ptr = vec![0usize; n + 2];
    for &j in kept {
        let e = edges[j];
        adj_ptr[e.a + 1] += 1;
        adj_ptr[e.b.unwrap_or(ground) + 1] += 1;
    }
    for v in 0..=n {
        adj_ptr[v + 1] += adj_ptr[v];
    }
    let mut fill = adj_ptr.clone();
    let mut adj = vec![(0usize, 0usize); adj_ptr[n + 1]];
    for &j in kept {
        let e = edges[j];
        let bn = e.b.unwrap_or(ground);
        adj[fill[e.a]] = (bn, j);
        fill[e.a] += 1;
        adj[fill[bn]] = (e.a, j);
        fill[bn] += 1;
    }
    (adj_ptr, adj)
}

/// The depth-first traversal of the kept forest: each node's traversal
/// index (`slot`), the potential steps and nodes in traversal order, and
/// the replacement rows (`triplets`: `(a, 1, b)` for `e_a − e_b`, `b =
/// None` for `e_a`) with their right-hand sides.
struct Walk {
    slot: Vec<usize>,
    steps: Vec<Step>,
    nodes: Vec<usize>,
    stack: Vec<usize>,
    triplets: Vec<(usize, f64, Option<usize>)>,
    rhs: Vec<Rhs>,
}

impl Walk {
    /// Walks the tree of `root` depth-first (neighbours in reverse
    /// adjacency order onto the stack), recording a step per node; returns
    /// the largest degree of its unknowns (the ground not counted).
    fn tree(
        &mut self,
        root: usize,
        ground: usize,
        edges: &[Edge],
        degree: &[usize],
        adj_ptr: &[usize],
        adj: &[(usize, usize)],
    ) -> usize {
        self.slot[root] = self.steps.len();
        self.steps.push(Step {
            parent: usize::MAX,
            row: 0,
            sign: 0.0,
        });
        self.nodes.push(root);
        let mut max_degree = 0;
        self.stack.push(root);
        while let Some(v) = self.stack.pop() {
            if v != ground {
                max_degree = max_degree.max(degree[v]);
            }
            for &(w, j) in adj[adj_ptr[v]..adj_ptr[v + 1]].iter().rev() {
                if self.slot[w] != usize::MAX {
                    continue;
                }
                // Row j: p_a − p_b = d_j.
                let sign = if edges[j].a == w { 1.0 } else { -1.0 };
                self.slot[w] = self.steps.len();
                self.steps.push(Step {
                    parent: self.slot[v],
                    row: j,
                    sign,
                });
                self.nodes.push(w);
                self.stack.push(w);
            }
        }
        max_degree
    }

    /// The replacement rows of the tree walked from traversal index
    /// `first` on (see the module documentation): pins for the ground's
    /// tree, a binomial tree when `max_degree > HUB_DEGREE`, else the tree's
    /// own rows.
    fn replacement_rows(
        &mut self,
        first: usize,
        grounded: bool,
        max_degree: usize,
        edges: &[Edge],
    ) {
        let tree = first..self.steps.len();
        if grounded {
            for t in tree.start + 1..tree.end {
                self.triplets.push((self.nodes[t], 1.0, None));
                self.rhs.push(Rhs::Pin(t));
            }
        } else if max_degree > HUB_DEGREE {
            // A binomial tree over the depth-first order: pairs at
            // distance 1, then 2, 4, … (every unknown in at most
            // ⌈log₂ k⌉ rows).
            let k = tree.end - tree.start;
            let mut step = 1;
            while step < k {
                for i in (0..k).step_by(2 * step) {
                    if i + step < k {
                        let (s, t) = (tree.start + i, tree.start + i + step);
                        self.triplets
                            .push((self.nodes[s], 1.0, Some(self.nodes[t])));
                        self.rhs.push(Rhs::Diff(s, t));
                    }
                }
                step *= 2;
            }
        } else {
            for t in tree.start + 1..tree.end {
                let e = edges[self.steps[t].row];
                self.triplets.push((e.a, 1.0, e.b));
                self.rhs.push(Rhs::Row(self.steps[t].row));
            }
        }
    }
}

/// The replacement rows as a sparse matrix over `n` unknowns: `e_a`, or
/// `e_a − e_b` with its columns in increasing order.
fn assemble_rows(triplets: &[(usize, f64, Option<usize>)], n: usize) -> SparseRowMat<usize, f64> {
    let mut row_ptr = Vec::with_capacity(triplets.len() + 1);
    row_ptr.push(0);
    let mut cols = Vec::with_capacity(2 * triplets.len());
    let mut vals = Vec::with_capacity(2 * triplets.len());
    for &(a, _, b_node) in triplets {
        match b_node {
            None => {
                cols.push(a);
                vals.push(1.0);
            }
            Some(w) => {
                let (lo, hi, vlo, vhi) = if a < w {
                    (a, w, 1.0, -1.0)
                } else {
                    (w, a, -1.0, 1.0)
                };
                cols.extend([lo, hi]);
                vals.extend([vlo, vhi]);
            }
        }
        row_ptr.push(cols.len());
    }
    let symbolic = SymbolicSparseRowMat::new_checked(triplets.len(), n, row_ptr, None, cols);
    SparseRowMat::new(symbolic, vals)
}

/// The factorisation of the replacement rows, answering for the rows of
/// `B`.
struct GraphRows {
    inner: Box<dyn ConstraintQr>,
    steps: Vec<Step>,
    rhs: Vec<Rhs>,
    kept: Vec<usize>,
    skipped: Vec<usize>,
}

impl GraphRows {
    /// The right-hand sides of the replacement rows for `d` (rows of `B`).
    fn replacement_rhs(&self, d: MatRef<'_, f64>) -> Mat<f64> {
        let k = d.ncols();
        let mut phi = Mat::<f64>::zeros(self.steps.len(), k);
        for (t, s) in self.steps.iter().enumerate() {
            if s.parent != usize::MAX {
                for c in 0..k {
                    phi[(t, c)] = phi[(s.parent, c)] + s.sign * d[(s.row, c)];
                }
            }
        }
        Mat::from_fn(self.rhs.len(), k, |i, c| match self.rhs[i] {
            Rhs::Pin(t) => phi[(t, c)],
            Rhs::Diff(s, t) => phi[(s, c)] - phi[(t, c)],
            Rhs::Row(j) => d[(j, c)],
        })
    }
}

impl ConstraintQr for GraphRows {
    fn n(&self) -> usize {
        self.inner.n()
    }

    fn rank(&self) -> usize {
        self.inner.rank()
    }

    fn kept(&self) -> &[usize] {
        &self.kept
    }

    fn skipped(&self) -> &[usize] {
        &self.skipped
    }

    fn solve_r1t(&self, d: MatRef<'_, f64>, y: MatMut<'_, f64>) {
        let replaced = self.replacement_rhs(d);
        self.inner.solve_r1t(replaced.as_ref(), y);
    }

    fn apply_q(&self, y: MatRef<'_, f64>, z: MatRef<'_, f64>, x: MatMut<'_, f64>) {
        self.inner.apply_q(y, z, x);
    }

    fn apply_qt(&self, x: MatRef<'_, f64>, y: MatMut<'_, f64>, z: MatMut<'_, f64>) {
        self.inner.apply_qt(x, y, z);
    }

    fn mul_a_q2(&self, a: SparseColMatRef<'_, usize, f64>) -> SparseColMat<usize, f64> {
        self.inner.mul_a_q2(a)
    }

    fn free_unknown(&self, k: usize) -> usize {
        self.inner.free_unknown(k)
    }

    fn storage_nnz(&self) -> usize {
        self.inner.storage_nnz()
    }
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod phase_tests {
    use super::*;

    fn e(a: usize, b: Option<usize>) -> Edge {
        Edge { a, b }
    }

    /// Over unknowns 0, 1, 2 and the ground 3: 0–G, 0–1, 1–G (closes a
    /// cycle), 2–1.
    fn cycle_edges() -> Vec<Edge> {
        vec![e(0, None), e(0, Some(1)), e(1, None), e(2, Some(1))]
    }

    #[test]
    fn forest_keeps_rows_joining_two_trees_and_counts_degrees() {
        let (kept, skipped, degree) = kept_forest(&cycle_edges(), 3);
        assert_eq!((kept, skipped), (vec![0, 1, 3], vec![2]));
        assert_eq!(degree, [2, 2, 1, 1]);
        let (adj_ptr, adj) = forest_adjacency(&cycle_edges(), &[0, 1, 3], 3);
        assert_eq!(adj_ptr, [0, 2, 4, 5, 6]);
        assert_eq!(adj, [(3, 0), (1, 1), (0, 1), (2, 3), (1, 3), (0, 0)]);
    }

    #[test]
    fn walk_from_the_ground_pins_every_unknown_of_its_tree() {
        let edges = cycle_edges();
        let (adj_ptr, adj) = forest_adjacency(&edges, &[0, 1, 3], 3);
        let mut walk = Walk {
            slot: vec![usize::MAX; 4],
            steps: Vec::new(),
            nodes: Vec::new(),
            stack: Vec::new(),
            triplets: Vec::new(),
            rhs: Vec::new(),
        };
        let max_degree = walk.tree(3, 3, &edges, &[2, 2, 1, 1], &adj_ptr, &adj);
        assert_eq!(max_degree, 2);
        assert_eq!(walk.nodes, [3, 0, 1, 2]);
        assert_eq!(walk.slot, [1, 2, 3, 0]);
        let steps: Vec<_> = walk
            .steps
            .iter()
            .map(|s| (s.parent, s.row, s.sign))
            .collect();
        assert_eq!(
            steps,
            [(usize::MAX, 0, 0.0), (0, 0, 1.0), (1, 1, -1.0), (2, 3, 1.0)]
        );
        walk.replacement_rows(0, true, max_degree, &edges);
        assert_eq!(
            walk.triplets,
            [(0, 1.0, None), (1, 1.0, None), (2, 1.0, None)]
        );
        assert_eq!(format!("{:?}", walk.rhs), "[Pin(1), Pin(2), Pin(3)]");
    }

    #[test]
    fn a_hub_tree_becomes_a_binomial_tree() {
        let root = Step {
            parent: usize::MAX,
            row: 0,
            sign: 0.0,
        };
        let mut walk = Walk {
            slot: Vec::new(),
            steps: vec![root; 5],
            nodes: vec![10, 11, 12, 13, 14],
            stack: Vec::new(),
            triplets: Vec::new(),
            rhs: Vec::new(),
        };
        walk.replacement_rows(0, false, HUB_DEGREE + 1, &[]);
        assert_eq!(
            walk.triplets,
            [
                (10, 1.0, Some(11)),
                (12, 1.0, Some(13)),
                (10, 1.0, Some(12)),
                (10, 1.0, Some(14))
            ]
        );
        assert_eq!(
            format!("{:?}", walk.rhs),
            "[Diff(0, 1), Diff(2, 3), Diff(0, 2), Diff(0, 4)]"
        );
    }

    #[test]
    fn assembled_rows_sort_their_two_columns() {
        let rows = assemble_rows(&[(2, 1.0, None), (3, 1.0, Some(1))], 4);
        assert_eq!(rows.symbolic().row_ptr(), [0, 1, 3]);
        assert_eq!(rows.symbolic().col_idx(), [2, 1, 3]);
        assert_eq!(rows.val(), [1.0, -1.0, 1.0]);
    }
}
