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

use super::faer_llt::failing_column;
use super::{SpdBackend, SpdFactor, SpdSymbolic, check_breakdown};
use crate::backend::ordering::{AmdFailure, FactorPlan, PlanUsed, amd_order, inverse};
use crate::error::NumericalError;
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
        for c in 0..n {
            offsets[c + 1] += offsets[c];
        }
        let pattern =
            SparsityPattern::try_from_offsets_and_indices(n, n, offsets.clone(), indices.clone())
                .map_err(|e| backend_error(format!("permuted pattern: {e}")))?;
        let symbolic = CscSymbolicCholesky::factor(pattern);
        let factor_nnz = symbolic.l_pattern().nnz();
        Ok(Box::new(NalgebraSymbolic {
            n,
            fwd,
            offsets,
            indices,
            map,
            lower_nnz: col_ptr[n],
            symbolic,
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
    offsets: Vec<usize>,
    indices: Vec<usize>,
    /// Places of each input entry in the permuted full values.
    map: Vec<[usize; 2]>,
    /// Stored entries of the analysed input (`col_ptr[n]`).
    lower_nnz: usize,
    symbolic: CscSymbolicCholesky,
    factor_nnz: usize,
    /// The report's word for the ordering used.
    ordering: std::borrow::Cow<'static, str>,
}

impl NalgebraSymbolic {
    /// The permuted full values of `lower`.
    fn permuted_values(&self, lower: SparseColMatRef<'_, usize, f64>) -> Vec<f64> {
        let mut values = vec![0.0; self.indices.len()];
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
        // Upper triangle of the permuted matrix: with the identity ordering
        // faer's symbolic analysis uses the matrix as given and reads only
        // its upper triangle, whatever `side` says.
        let mut col_ptr = vec![0usize; n + 1];
        let mut row_idx = Vec::new();
        let mut vals = Vec::new();
        for c in 0..n {
            let range = self.offsets[c]..self.offsets[c + 1];
            for (&r, &v) in self.indices[range.clone()].iter().zip(&values[range]) {
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
                    let a = (self.offsets[k]..self.offsets[k + 1])
                        .find(|&p| self.indices[p] == k)
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
        match CscCholesky::factor_numerical(self.symbolic.clone(), &values) {
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
