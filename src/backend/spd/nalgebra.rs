//! nalgebra-sparse's `CscCholesky` (left-looking, simplicial) behind our own
//! AMD ordering.
//!
//! nalgebra-sparse performs no fill-reducing ordering, so [`NalgebraCsc`]
//! computes one with faer's AMD (`faer::sparse::linalg::amd`, the same
//! algorithm faer's own Cholesky uses) and factors `P A Pᵀ`:
//! - **analysis** (once per pattern): AMD on the pattern, the permuted
//!   *full* symmetric pattern (nalgebra's symbolic phase reads the upper
//!   triangle of a column, its numeric phase the lower one), the map from
//!   every entry of the input lower triangle to its one or two places in the
//!   permuted matrix, and `CscSymbolicCholesky` (elimination tree and the
//!   pattern of `L`);
//! - **numeric** (per [`SpdSymbolic::factorize`]): scatter the values through
//!   the map and run `CscCholesky::factor_numerical` on a copy of the
//!   symbolic factorisation (nalgebra consumes it by value; copying the
//!   pattern is `O(nnz(L))` memory traffic, not a new analysis).
//!
//! **Failing pivot.** nalgebra reports only "not positive definite", without
//! the column and without the partial factor. The pivot is found by running
//! faer's simplicial up-looking `LLᵀ` on the *same permuted matrix* with the
//! identity ordering (so the elimination order is the same), which reports
//! the first column whose pivot is not positive; it is mapped through the
//! AMD permutation to the original unknown. Both compute the same pivots
//! `A_kk − Σ_j L_kj²` in exact arithmetic; they sum in different orders, so
//! for a pivot within rounding of zero faer may succeed where nalgebra
//! failed. Then the unknown reported is that of faer's smallest pivot ratio
//! `L_kk² / A_kk` (the column closest to failing), still an honest answer
//! to "where did positive definiteness get lost". This re-run costs one
//! symbolic and one numeric factorisation and happens only on failure.
//!
//! **Breakdown.** A completed factor is checked with the same pivot-ratio
//! test as every back end ([`BREAKDOWN_RATIO`](super::BREAKDOWN_RATIO)).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltError as DenseLltError, LltRegularization};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholeskyRaw, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{MatMut, Par, Side};
use nalgebra::DMatrix;
use nalgebra_sparse::factorization::{CholeskyError, CscCholesky, CscSymbolicCholesky};
use nalgebra_sparse::pattern::SparsityPattern;
use std::sync::OnceLock;

use super::column_counts::factor_column_counts;
use super::faer_llt::failing_column;
use super::{SpdBackend, SpdFactor, SpdSymbolic, check_breakdown};
use crate::backend::ordering::{AmdFailure, FactorPlan, PlanUsed, amd_order, inverse};
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;
use crate::resources::Threads;

const NAME: &str = "nalgebra";

/// nalgebra-sparse's `CscCholesky` with an AMD ordering supplied by us.
#[derive(Debug, Clone, Copy, Default)]
pub struct NalgebraCsc;

fn backend_error(message: impl Into<String>) -> NumericalError {
    NumericalError::Backend {
        backend: NAME.to_string(),
        message: message.into(),
    }
}

impl SpdBackend for NalgebraCsc {
    fn name(&self) -> crate::backend::BackendName {
        super::SpdKind::Nalgebra.name().into()
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        self.analyze_with(lower, &FactorPlan::own(Threads::Own))
    }

    /// nalgebra-sparse's Cholesky has no ordering of its own: this back
    /// end permutes the matrix itself, with the plan's permutation instead
    /// of its AMD. It is sequential whatever the plan's threads (the
    /// report's `"threads"` is 1).
    fn analyze_planned(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        plan: &FactorPlan,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        self.analyze_with(lower, plan)
    }
}

impl NalgebraCsc {
    fn analyze_with(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        plan: &FactorPlan,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        let n = lower.nrows();
        if lower.ncols() != n {
            return Err(backend_error(format!(
                "matrix is {} × {}, not square",
                n,
                lower.ncols()
            )));
        }
        let (col_ptr, row_idx) = (lower.col_ptr(), lower.row_idx());
        let nnz = lower.compute_nnz();

        // AMD or the plan's: fwd[new] = old, inv[old] = new.
        let (fwd, inv) = match &plan.permutation {
            Some(perm) if perm.len() == n => (perm.to_vec(), inverse(perm)),
            Some(_) => return Err(backend_error("the permutation's length")),
            None => amd_order(lower).map_err(|e| match e {
                AmdFailure::Workspace(e) => backend_error(e),
                AmdFailure::Order(e) => backend_error(format!("AMD ordering: {e}")),
            })?,
        };

        // Permuted full pattern: entry (i, j), i ≥ j, goes to (inv i, inv j)
        // and, off the diagonal, to (inv j, inv i). The diagonal is added
        // where the input lacks it (as an explicit zero).
        let mut entries: Vec<(usize, usize, usize, bool)> = Vec::with_capacity(2 * nnz + n);
        let mut has_diag = vec![false; n];
        for j in 0..n {
            for p in lower.col_range(j) {
                let i = row_idx[p];
                if i < j {
                    continue; // upper entries of the input are ignored
                }
                let (pi, pj) = (inv[i], inv[j]);
                entries.push((pj, pi, p, false));
                if i == j {
                    has_diag[j] = true;
                } else {
                    entries.push((pi, pj, p, true));
                }
            }
        }
        for (j, &d) in has_diag.iter().enumerate() {
            if !d {
                entries.push((inv[j], inv[j], usize::MAX, false));
            }
        }
        entries.sort_unstable_by_key(|&(c, r, _, _)| (c, r));
        let mut offsets = vec![0usize; n + 1];
        let mut indices = Vec::with_capacity(entries.len());
        // map[p] = [place of input entry p, its mirror or usize::MAX].
        let mut map = vec![[usize::MAX; 2]; col_ptr[n]];
        for (place, &(c, r, p, mirror)) in entries.iter().enumerate() {
            if place > 0 && entries[place - 1].0 == c && entries[place - 1].1 == r {
                return Err(backend_error(format!(
                    "duplicate entry ({}, {}) in the lower triangle",
                    fwd[r], fwd[c]
                )));
            }
            offsets[c + 1] += 1;
            indices.push(r);
            if p != usize::MAX {
                map[p][usize::from(mirror)] = place;
            }
        }
        drop(entries);
        for c in 0..n {
            offsets[c + 1] += offsets[c];
        }
        let pattern = SparsityPattern::try_from_offsets_and_indices(n, n, offsets, indices)
            .map_err(|e| backend_error(format!("permuted pattern: {e}")))?;
        // The pattern of L is sized here, in O(nnz(A)) memory, and built
        // only once the budget admits it (`check_budget`).
        let column_counts = factor_column_counts(pattern.major_offsets(), pattern.minor_indices());
        let factor_nnz = column_counts.iter().sum();
        Ok(Box::new(NalgebraSymbolic {
            n,
            fwd,
            pattern,
            map,
            lower_nnz: col_ptr[n],
            symbolic: OnceLock::new(),
            factor_nnz,
            ordering: plan.ordering_used("amd"),
        }))
    }
}

struct NalgebraSymbolic {
    n: usize,
    /// `fwd[k]`: original index of permuted unknown `k`.
    fwd: Vec<usize>,
    /// Permuted full pattern (CSC, sorted, diagonal present).
    pattern: SparsityPattern,
    /// Places of each input entry in the permuted full values.
    map: Vec<[usize; 2]>,
    /// Stored entries of the analysed input (`col_ptr[n]`).
    lower_nnz: usize,
    /// nalgebra's symbolic factorisation (the pattern of `L`), built once
    /// the budget admits it ([`SpdSymbolic::check_budget`]), or by the
    /// first factorisation when nobody checked.
    symbolic: OnceLock<CscSymbolicCholesky>,
    /// `nnz(L)` as [`factor_column_counts`] predicts it (exactly what
    /// nalgebra's `l_pattern().nnz()` will be).
    factor_nnz: usize,
    /// The report's word for the ordering used.
    ordering: std::borrow::Cow<'static, str>,
}

impl NalgebraSymbolic {
    /// nalgebra's symbolic factorisation, built on first use.
    fn symbolic_factor(&self) -> &CscSymbolicCholesky {
        self.symbolic
            .get_or_init(|| CscSymbolicCholesky::factor(self.pattern.clone()))
    }

    /// Bytes a factorisation still allocates, at its peak, with `p` the
    /// permuted full pattern's entries and `l = nnz(L)`:
    /// - nalgebra's symbolic factorisation, unless built already: its copy
    ///   of the pattern (`8 (p + n + 1)`), the patterns of `L` and of `Lᵀ`
    ///   (`8 (l + n + 1)` each), and the elimination tree and marks it
    ///   works with (`16 n`);
    /// - per factorisation: the copy of all that which `factor_numerical`
    ///   consumes, the permuted values (`8 p`), the values of `L` (`8 l`),
    ///   nalgebra's work vector, our diagonal and permutation (`24 n`).
    ///
    /// The failing-pivot re-run (faer's simplicial factor, `16 l` at most)
    /// happens after nalgebra's failed factor and its copy are freed.
    fn bytes_to_come(&self) -> u64 {
        let (n, p, l) = (
            self.n as u64,
            self.pattern.nnz() as u64,
            self.factor_nnz as u64,
        );
        let symbolic = (p + n + 1)
            .saturating_add(l.saturating_add(n + 1).saturating_mul(2))
            .saturating_add(2 * n)
            .saturating_mul(8);
        let factor =
            symbolic.saturating_add(p.saturating_add(l).saturating_add(3 * n).saturating_mul(8));
        match self.symbolic.get() {
            Some(_) => factor,
            None => factor.saturating_add(symbolic),
        }
    }

    /// The permuted full values of `lower`.
    fn permuted_values(&self, lower: SparseColMatRef<'_, usize, f64>) -> Vec<f64> {
        let mut values = vec![0.0; self.pattern.nnz()];
        for (&[a, b], &v) in self.map.iter().zip(lower.val()) {
            if a != usize::MAX {
                values[a] = v;
            }
            if b != usize::MAX {
                values[b] = v;
            }
        }
        values
    }

    /// The failing pivot after nalgebra reported failure (see the module
    /// documentation): faer's simplicial `LLᵀ` on the same permuted matrix.
    fn failing_pivot(&self, values: &[f64]) -> Result<usize, NumericalError> {
        let n = self.n;
        let (offsets, indices) = (self.pattern.major_offsets(), self.pattern.minor_indices());
        // Upper triangle of the permuted matrix: with the identity ordering
        // faer's symbolic analysis uses the matrix as given and reads only
        // its upper triangle, whatever `side` says.
        let mut col_ptr = vec![0usize; n + 1];
        let mut row_idx = Vec::new();
        let mut vals = Vec::new();
        for c in 0..n {
            let range = offsets[c]..offsets[c + 1];
            for (&r, &v) in indices[range.clone()].iter().zip(&values[range]) {
                if r <= c {
                    row_idx.push(r);
                    vals.push(v);
                }
            }
            col_ptr[c + 1] = row_idx.len();
        }
        let sym = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        let permuted = SparseColMat::new(sym, vals);
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
            ..Default::default()
        };
        let symbolic = factorize_symbolic_cholesky(
            permuted.symbolic(),
            Side::Upper,
            SymmetricOrdering::Identity,
            params,
        )
        .map_err(|e| backend_error(format!("{e:?}")))?;
        let mut l_values = vec![0.0f64; symbolic.len_val()];
        let mut mem = MemBuffer::try_new(
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        )
        .map_err(|e| backend_error(format!("{e:?}")))?;
        let result = symbolic.factorize_numeric_llt(
            &mut l_values,
            permuted.as_ref(),
            Side::Upper,
            LltRegularization::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        );
        match result {
            Err(DenseLltError::NonPositivePivot { index }) => Ok(failing_column(&symbolic, index)),
            Ok(_) => {
                // Succeeded within rounding: the smallest pivot ratio.
                let SymbolicCholeskyRaw::Simplicial(s) = symbolic.raw() else {
                    return Err(backend_error("expected a simplicial factor"));
                };
                let cp = s.col_ptr();
                let mut worst = (0usize, f64::INFINITY);
                for k in 0..n {
                    let l = l_values[cp[k]];
                    let a = (offsets[k]..offsets[k + 1])
                        .find(|&p| indices[p] == k)
                        .map_or(0.0, |p| values[p]);
                    let ratio = l * l / a;
                    let better = ratio >= worst.1; // false for NaN
                    if !better {
                        worst = (k, ratio);
                    }
                }
                Ok(worst.0)
            }
        }
    }
}

impl SpdSymbolic for NalgebraSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn SpdFactor>, NumericalError> {
        if lower.nrows() != self.n
            || lower.ncols() != self.n
            || lower.symbolic().col_ptr()[self.n] != self.lower_nnz
            || lower.val().len() < self.lower_nnz
        {
            return Err(backend_error(
                "the matrix does not have the pattern that was analysed",
            ));
        }
        let values = self.permuted_values(lower);
        let symbolic = self.symbolic_factor().clone();
        match CscCholesky::factor_numerical(symbolic, &values) {
            Ok(chol) => {
                let l = chol.l();
                let (offsets, rows, lv) = (l.col_offsets(), l.row_indices(), l.values());
                let diag: Vec<f64> = (0..self.n)
                    .map(|k| {
                        let p = offsets[k];
                        if p < offsets[k + 1] && rows[p] == k {
                            lv[p]
                        } else {
                            0.0
                        }
                    })
                    .collect();
                check_breakdown(&diag, &self.fwd, lower)?;
                Ok(Box::new(NalgebraFactor {
                    chol,
                    fwd: self.fwd.clone(),
                }))
            }
            Err(CholeskyError::NotPositiveDefinite) | Err(_) => {
                let k = self.failing_pivot(&values)?;
                Err(NumericalError::NotPositiveDefinite {
                    matrix: String::new(),
                    unknown: self.fwd.get(k).copied().unwrap_or(k),
                    vertex: None,
                    pivot: None,
                })
            }
        }
    }

    fn factor_nnz(&self) -> usize {
        self.factor_nnz
    }

    /// Refuses a factorisation whose storage, predicted from the column
    /// counts before nalgebra allocates anything of `L`
    /// ([`NalgebraSymbolic::bytes_to_come`]), would not fit in `budget` on
    /// top of what the process holds ([`MemoryBudget::check_on_top`]);
    /// when it fits, nalgebra's symbolic factorisation is built here.
    fn check_budget(
        &self,
        budget: MemoryBudget,
        dim: usize,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        let bytes = self.bytes_to_come();
        budget
            .check_on_top(bytes, || {
                format!(
                    "nalgebra's Cholesky factorisation of {matrix} ({dim} unknowns, {} entries of L after fill-in, predicted from the elimination tree): the pattern of L, its copy and the values would need",
                    self.factor_nnz
                )
            })
            .map_err(|detail| ProblemError::TooLarge { detail })?;
        self.symbolic_factor();
        Ok(())
    }

    fn plan_used(&self) -> PlanUsed {
        PlanUsed {
            ordering: self.ordering.clone(),
            threads: Some(1),
        }
    }
}

struct NalgebraFactor {
    chol: CscCholesky<f64>,
    fwd: Vec<usize>,
}

impl SpdFactor for NalgebraFactor {
    fn dim(&self) -> usize {
        self.fwd.len()
    }

    fn solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) -> Result<(), NumericalError> {
        let (n, k) = (rhs.nrows(), rhs.ncols());
        // P b, solve, Pᵀ x.
        let mut b = DMatrix::<f64>::zeros(n, k);
        for c in 0..k {
            for (new, &old) in self.fwd.iter().enumerate() {
                b[(new, c)] = rhs[(old, c)];
            }
        }
        self.chol.solve_mut(&mut b);
        for c in 0..k {
            for (new, &old) in self.fwd.iter().enumerate() {
                rhs[(old, c)] = b[(new, c)];
            }
        }
        Ok(())
    }

    fn nnz(&self) -> usize {
        self.chol.l().nnz()
    }

    fn bytes(&self) -> usize {
        let l = self.chol.l();
        l.nnz() * 16 + (l.ncols() + 1) * 8
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The full sorted pattern with the diagonal of the symmetric matrix
    /// whose strictly lower entries are `edges` (either order, repeats
    /// allowed).
    fn full_pattern(n: usize, edges: &[(usize, usize)]) -> SparsityPattern {
        let mut columns: Vec<Vec<usize>> = (0..n).map(|j| vec![j]).collect();
        for &(a, b) in edges {
            if a != b {
                columns[a].push(b);
                columns[b].push(a);
            }
        }
        let mut offsets = vec![0];
        let mut indices = Vec::new();
        for mut c in columns {
            c.sort_unstable();
            c.dedup();
            indices.extend(c);
            offsets.push(indices.len());
        }
        SparsityPattern::try_from_offsets_and_indices(n, n, offsets, indices).unwrap()
    }

    /// The predicted counts against the columns of nalgebra's own `L`.
    fn assert_counts_are_nalgebras(pattern: &SparsityPattern) {
        let counts = factor_column_counts(pattern.major_offsets(), pattern.minor_indices());
        let l = CscSymbolicCholesky::factor(pattern.clone());
        let l = l.l_pattern();
        let actual: Vec<usize> = (0..l.major_dim()).map(|j| l.lane(j).len()).collect();
        assert_eq!(counts, actual);
        assert_eq!(counts.iter().sum::<usize>(), l.nnz());
    }

    /// Fixed shapes: a path (no fill), an arrow pointing at the first
    /// unknown (fills in completely), its reverse (no fill), two
    /// components, a cycle, a dense matrix and the empty matrix.
    #[test]
    fn predicted_counts_are_nalgebras_on_fixed_patterns() {
        let path: Vec<_> = (1..8).map(|i| (i, i - 1)).collect();
        let arrow_first: Vec<_> = (1..8).map(|i| (i, 0)).collect();
        let arrow_last: Vec<_> = (0..7).map(|i| (7, i)).collect();
        let two = vec![(1, 0), (2, 0), (4, 3), (5, 3), (5, 4)];
        let cycle: Vec<_> = (0..9).map(|i| ((i + 1) % 9, i)).collect();
        let dense: Vec<_> = (0..6).flat_map(|i| (0..i).map(move |j| (i, j))).collect();
        for (n, edges) in [
            (8, path),
            (8, arrow_first.clone()),
            (8, arrow_last),
            (6, two),
            (9, cycle),
            (6, dense),
            (0, vec![]),
        ] {
            assert_counts_are_nalgebras(&full_pattern(n, &edges));
        }
        // The arrow at the first unknown fills L completely.
        let p = full_pattern(8, &arrow_first);
        let total: usize = factor_column_counts(p.major_offsets(), p.minor_indices())
            .iter()
            .sum();
        assert_eq!(total, 8 * 9 / 2);
    }

    proptest! {
        /// On random symmetric patterns (random graphs, so random
        /// elimination trees and fill) the prediction is nalgebra's `L`
        /// column by column.
        #[test]
        fn predicted_counts_are_nalgebras_on_random_patterns(
            (n, edges) in (1usize..40).prop_flat_map(|n| {
                (Just(n), proptest::collection::vec((0..n, 0..n), 0..(3 * n)))
            })
        ) {
            assert_counts_are_nalgebras(&full_pattern(n, &edges));
        }
    }

    /// A budget below the predicted factor is refused before nalgebra's
    /// symbolic factorisation exists, and the message gives the
    /// predicted `nnz(L)`; a sufficient one builds it, with that `nnz`.
    #[test]
    fn a_refused_budget_builds_no_pattern_of_l() {
        // The arrow pointing at unknown 0, in the natural order: L is full.
        let n = 300;
        let mut col_ptr = vec![0usize];
        let mut rows = Vec::new();
        for j in 0..n {
            rows.push(j);
            if j == 0 {
                rows.extend(1..n);
            }
            col_ptr.push(rows.len());
        }
        let lower = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, rows);
        let plan = FactorPlan {
            permutation: Some((0..n).collect::<Vec<_>>().into()),
            ordering: "natural",
            threads: Threads::Own,
        };
        let symbolic = NalgebraCsc.analyze_planned(lower.as_ref(), &plan).unwrap();
        let full = n * (n + 1) / 2;
        assert_eq!(symbolic.factor_nnz(), full);
        let e = symbolic
            .check_budget(MemoryBudget::bytes(1), n, "A")
            .unwrap_err()
            .to_string();
        assert!(e.contains(&format!("{full} entries of L")), "{e}");
        assert!(e.contains("more than the memory budget"), "{e}");
        symbolic
            .check_budget(MemoryBudget::unlimited(), n, "A")
            .unwrap();
        let factor = symbolic.factorize(nalgebra_test_matrix(lower.as_ref()).as_ref());
        assert_eq!(factor.unwrap().nnz(), full);
    }

    /// `lower` with a dominant diagonal (SPD).
    fn nalgebra_test_matrix(lower: SymbolicSparseColMatRef<'_, usize>) -> SparseColMat<usize, f64> {
        let n = lower.nrows();
        let values: Vec<f64> = (0..n)
            .flat_map(|j| {
                lower
                    .row_idx_of_col(j)
                    .map(move |i| if i == j { n as f64 } else { -0.5 })
            })
            .collect();
        SparseColMat::new(lower.to_owned().unwrap(), values)
    }
}
