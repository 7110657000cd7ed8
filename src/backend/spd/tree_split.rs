//! Triangular solves on two threads: the supernodal elimination tree split
//! into two sets of whole subtrees and the "top" of the tree above them.
//!
//! A supernode's pattern rows are its ancestors in the elimination tree, so
//! the forward solve of a subtree reads and writes only the subtree's own
//! rows and those of its ancestors, and the backward solve reads only its
//! ancestors'. With two sets of disjoint subtrees `P0`, `P1` and the top
//! `T` (every supernode not in them, which contains all their ancestors
//! outside themselves):
//!
//! - forward: `P0` on `w` and `P1` on a second buffer `w2` side by side
//!   (`w2` holding `P1`'s rows and zeros in `T`'s, where `P1`'s updates
//!   accumulate), then `P1`'s rows copied back and `w_T += w2_T`, then `T`
//!   on `w`;
//! - backward: `T` on `w`, then `P0` on `w` and `P1` on `w2` (with `T`'s
//!   solved rows copied into it) side by side, `P1`'s rows copied back.
//!
//! Every supernode's own arithmetic is that of the one-thread solve; only
//! the updates of `T`'s rows are summed in another order (two partial sums
//! added), so results agree with it to rounding.
//!
//! The split: starting from the root(s), the heaviest subtree of the
//! frontier is moved into `T` (its children join the frontier) until the
//! frontier's subtrees, dealt to the two parts heaviest first, are within
//! [`BALANCE`] of each other; the best of these steps by
//! `weight(T) + max(weight(P0), weight(P1))` is kept, weights being the
//! factor entries a pass reads. The split is used when that is at most
//! [`WORTH_IT`] of the whole (the Stanford bunny's reduced normal matrix:
//! `T` 12 %, parts 46 % and 42 %, 0.59 of the one-thread work).

use std::ops::Range;

use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};

use super::triangular::Passes;
use crate::cpu::clear_upper_vector_state;

/// Stop moving subtrees into the top once the heavier part is at most this
/// share of the two parts.
const BALANCE: f64 = 0.52;

/// Use the split when its critical path is at most this share of the
/// whole solve.
const WORTH_IT: f64 = 0.8;

/// Factors with fewer entries than this are solved on one thread (a
/// thread hand-off costs microseconds; a solve of this size, hundreds).
pub(super) const SPLIT_MIN_VALUES: usize = 500_000;

/// At most this many subtrees are moved into the top.
const MAX_EXPANSIONS: usize = 256;

/// A split of a supernodal factor's elimination tree for two threads.
///
/// Invariant: `parts[0]`, `parts[1]` and `top` are disjoint ascending
/// ranges of supernodes covering all of them (a parent after its
/// children); each part is a union of whole subtrees whose ancestors
/// outside it are in `top`;
/// `part1_columns` and `top_columns` are the unknowns of `parts[1]` and
/// `top`.
pub(super) struct TreeSplit {
    parts: [Vec<Range<usize>>; 2],
    top: Vec<Range<usize>>,
    part1_columns: Vec<Range<usize>>,
    top_columns: Vec<Range<usize>>,
}

impl TreeSplit {
    /// The split of `symbolic`'s tree, or `None` when the factor is
    /// simplicial, smaller than [`SPLIT_MIN_VALUES`], has a parent before a
    /// child, or its tree does not split well enough ([`WORTH_IT`]).
    pub(super) fn new(symbolic: &SymbolicCholesky<usize>) -> Option<TreeSplit> {
        Self::with_min_values(symbolic, SPLIT_MIN_VALUES)
    }

    /// [`TreeSplit::new`] with another size threshold (tests split small
    /// factors).
    pub(super) fn with_min_values(
        symbolic: &SymbolicCholesky<usize>,
        min_values: usize,
    ) -> Option<TreeSplit> {
        let SymbolicCholeskyRaw::Supernodal(s) = symbolic.raw() else {
            return None;
        };
        if symbolic.len_val() < min_values {
            return None;
        }
        let tree = Tree::new(s)?;
        let (top, bins) = tree.best_split()?;
        let parts = bins.map(|roots| ranges(tree.subtrees(&roots)));
        let top = ranges(top);
        let columns = |ranges: &[Range<usize>]| {
            let (begin, end) = (s.supernode_begin(), s.supernode_end());
            merge(
                ranges
                    .iter()
                    .map(|r| begin[r.start]..end[r.end - 1])
                    .collect(),
            )
        };
        Some(TreeSplit {
            part1_columns: columns(&parts[1]),
            top_columns: columns(&top),
            parts,
            top,
        })
    }

    /// `L Lᵀ w = w` in place like [`super::triangular::solve_lanes`], on
    /// this thread and one of rayon's, with `w2`, `scratch2` the second
    /// thread's buffers (`w2` as long as `w`).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn solve<const W: usize>(
        &self,
        passes: Passes<W>,
        symbolic: &SymbolicCholesky<usize>,
        values: &[f64],
        inv_diag: &[f64],
        (w, scratch): (&mut [[f64; W]], &mut Vec<[f64; W]>),
        (w2, scratch2): (&mut [[f64; W]], &mut Vec<[f64; W]>),
    ) {
        let SymbolicCholeskyRaw::Supernodal(s) = symbolic.raw() else {
            return;
        };
        let run = |ranges: &[Range<usize>], w: &mut [[f64; W]], forward: bool, sc: &mut Vec<_>| {
            clear_upper_vector_state();
            if forward {
                passes.forward(s, values, inv_diag, ranges, w);
            } else {
                passes.backward(s, values, inv_diag, ranges, w, sc);
            }
        };
        for r in &self.top_columns {
            w2[r.clone()].fill([0.0; W]);
        }
        for r in &self.part1_columns {
            w2[r.clone()].copy_from_slice(&w[r.clone()]);
        }
        self.side_by_side(w, w2, scratch, scratch2, |ranges, w, sc| {
            run(ranges, w, true, sc)
        });
        for r in &self.part1_columns {
            w[r.clone()].copy_from_slice(&w2[r.clone()]);
        }
        for r in &self.top_columns {
            for (a, b) in w[r.clone()].iter_mut().zip(&w2[r.clone()]) {
                for q in 0..W {
                    a[q] += b[q];
                }
            }
        }
        run(&self.top, w, true, scratch);
        run(&self.top, w, false, scratch);
        for r in &self.top_columns {
            w2[r.clone()].copy_from_slice(&w[r.clone()]);
        }
        self.side_by_side(w, w2, scratch, scratch2, |ranges, w, sc| {
            run(ranges, w, false, sc)
        });
        for r in &self.part1_columns {
            w[r.clone()].copy_from_slice(&w2[r.clone()]);
        }
    }

    /// `pass(parts[0], w)` on this thread and `pass(parts[1], w2)` on
    /// rayon's pool, side by side (`in_place_scope`, see the faer back
    /// end's wide solve).
    fn side_by_side<const W: usize>(
        &self,
        w: &mut [[f64; W]],
        w2: &mut [[f64; W]],
        scratch: &mut Vec<[f64; W]>,
        scratch2: &mut Vec<[f64; W]>,
        pass: impl Fn(&[Range<usize>], &mut [[f64; W]], &mut Vec<[f64; W]>) + Sync,
    ) {
        let pass = &pass;
        rayon::in_place_scope(|scope| {
            scope.spawn(move |_| pass(&self.parts[1], w2, scratch2));
            pass(&self.parts[0], w, scratch);
        });
    }
}

/// The supernodes `nodes` as ascending ranges.
fn ranges(mut nodes: Vec<usize>) -> Vec<Range<usize>> {
    nodes.sort_unstable();
    merge(nodes.into_iter().map(|k| k..k + 1).collect())
}

/// Consecutive ranges joined.
fn merge(ranges: Vec<Range<usize>>) -> Vec<Range<usize>> {
    let mut out: Vec<Range<usize>> = Vec::with_capacity(ranges.len());
    for r in ranges {
        match out.last_mut() {
            Some(last) if last.end == r.start => last.end = r.end,
            _ => out.push(r),
        }
    }
    out
}

/// The supernodal elimination tree with what the split needs.
struct Tree {
    /// Entries of `L` per supernode (what a pass reads).
    weight: Vec<f64>,
    /// Entries of the subtree rooted at each supernode.
    subtree: Vec<f64>,
    children: Vec<Vec<usize>>,
    roots: Vec<usize>,
}

impl Tree {
    /// The tree of `s` (a supernode's parent: the supernode of its first
    /// pattern row). `None` if a parent does not come after its child,
    /// which the ascending passes of the split rely on.
    fn new(s: &SymbolicSupernodalCholesky<usize>) -> Option<Tree> {
        let ns = s.n_supernodes();
        let (begin, end) = (s.supernode_begin(), s.supernode_end());
        let (rows, row_ptr) = (s.row_idx(), s.col_ptr_for_row_idx());
        let mut supernode_of = vec![0usize; s.nrows()];
        for k in 0..ns {
            supernode_of[begin[k]..end[k]].fill(k);
        }
        let mut weight = Vec::with_capacity(ns);
        let (mut children, mut roots) = (vec![Vec::new(); ns], Vec::new());
        let mut subtree = vec![0.0; ns];
        for k in 0..ns {
            let c = (end[k] - begin[k]) as f64;
            let pattern = &rows[row_ptr[k]..row_ptr[k + 1]];
            weight.push(c * (c + 1.0) / 2.0 + c * pattern.len() as f64);
            subtree[k] += weight[k];
            match pattern.iter().min() {
                Some(&r) => {
                    let p = supernode_of[r];
                    if p <= k {
                        return None;
                    }
                    children[p].push(k);
                    subtree[p] += subtree[k];
                }
                None => roots.push(k),
            }
        }
        Some(Tree {
            weight,
            subtree,
            children,
            roots,
        })
    }

    /// Every supernode of the subtrees rooted at `roots`.
    fn subtrees(&self, roots: &[usize]) -> Vec<usize> {
        let (mut nodes, mut stack) = (Vec::new(), roots.to_vec());
        while let Some(k) = stack.pop() {
            nodes.push(k);
            stack.extend_from_slice(&self.children[k]);
        }
        nodes
    }

    /// The best top and the roots of the two parts (see the module
    /// documentation), or `None` when it is not worth it.
    fn best_split(&self) -> Option<(Vec<usize>, [Vec<usize>; 2])> {
        let total: f64 = self.weight.iter().sum();
        let (mut top, mut frontier) = (Vec::new(), self.roots.clone());
        let mut top_weight = 0.0;
        let mut best: Option<(f64, Vec<usize>, [Vec<usize>; 2])> = None;
        for _ in 0..MAX_EXPANSIONS {
            let (bins, loads) = self.deal(&frontier);
            let cost = top_weight + loads[0].max(loads[1]);
            if best.as_ref().is_none_or(|b| cost < b.0) {
                best = Some((cost, top.clone(), bins));
            }
            let parts = loads[0] + loads[1];
            if parts <= 0.0 || loads[0].max(loads[1]) <= BALANCE * parts {
                break;
            }
            let Some((i, _)) = frontier
                .iter()
                .enumerate()
                .max_by(|a, b| self.subtree[*a.1].total_cmp(&self.subtree[*b.1]))
            else {
                break;
            };
            let k = frontier.swap_remove(i);
            top.push(k);
            top_weight += self.weight[k];
            frontier.extend_from_slice(&self.children[k]);
        }
        let (cost, top, bins) = best?;

        (cost <= WORTH_IT * total && !bins[0].is_empty() && !bins[1].is_empty())
            .then_some((top, bins))
    }

    /// The subtrees rooted at `frontier` dealt to two bins, heaviest first
    /// to the lighter bin; the bins and their weights.
    fn deal(&self, frontier: &[usize]) -> ([Vec<usize>; 2], [f64; 2]) {
        let mut order = frontier.to_vec();
        order.sort_by(|a, b| self.subtree[*b].total_cmp(&self.subtree[*a]));
        let (mut bins, mut loads) = ([Vec::new(), Vec::new()], [0.0, 0.0]);
        for k in order {
            let b = usize::from(loads[1] < loads[0]);
            bins[b].push(k);
            loads[b] += self.subtree[k];
        }
        (bins, loads)
    }
}
