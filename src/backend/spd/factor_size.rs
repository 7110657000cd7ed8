//! The storage of a faer sparse Cholesky factor (`LLᵀ` or `LDLᵀ`), read from
//! its symbolic analysis before any numeric work.

use faer::sparse::SymbolicSparseColMatRef;
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};

/// Sizes of a factor `L` as faer will store it.
///
/// `nnz` counts the lower-triangle entries of `L` including the diagonal (for
/// a supernode of `c` columns and `p` rows below it: `c(c+1)/2 + c p`);
/// `value_bytes` is what faer allocates for the numeric values (8 bytes per
/// stored `f64`, which for supernodes includes the unused upper part of each
/// diagonal block); `index_bytes` is the row-index storage (8 bytes per
/// index).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct FactorSize {
    pub nnz: usize,
    pub value_bytes: usize,
    pub index_bytes: usize,
}

impl FactorSize {
    /// Values and row indices together.
    pub(crate) fn total_bytes(&self) -> usize {
        self.value_bytes + self.index_bytes
    }
}

/// The [`FactorSize`] of the factor `symbolic` describes.
pub(crate) fn factor_size(symbolic: &SymbolicCholesky<usize>) -> FactorSize {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(s) => FactorSize {
            nnz: s.len_val(),
            value_bytes: s.len_val() * 8,
            index_bytes: s.row_idx().len() * 8,
        },
        SymbolicCholeskyRaw::Supernodal(s) => {
            let (begin, end) = (s.supernode_begin(), s.supernode_end());
            let mut nnz = 0;
            let mut idx = 0;
            for (k, &p) in s.nnz_per_super().iter().enumerate() {
                let c = end[k] - begin[k];
                nnz += c * (c + 1) / 2 + c * p;
                idx += p;
            }
            FactorSize {
                nnz,
                value_bytes: s.len_val() * 8,
                index_bytes: idx * 8,
            }
        }
    }
}

/// `nnz(L)` (the diagonal included) of the Cholesky factor of `P A Pᵀ`,
/// `A` symmetric with lower-triangle pattern `lower` (entries above the
/// diagonal are ignored) and `fwd[k]` the unknown eliminated `k`-th:
/// [`super::column_counts::factor_column_counts`] on the permuted full pattern,
/// in `O(nnz(A))` time and memory, before any factor exists.
pub(crate) fn permuted_factor_nnz(
    lower: SymbolicSparseColMatRef<'_, usize>,
    fwd: &[usize],
) -> usize {
    let n = lower.ncols();
    let inv = crate::backend::ordering::inverse(fwd);
    // Column counts of the permuted full pattern, then its rows.
    let mut col_ptr = vec![0usize; n + 1];
    let each_entry = |f: &mut dyn FnMut(usize, usize)| {
        for j in 0..n {
            for i in lower.row_idx_of_col(j).filter(|&i| i > j) {
                f(inv[i], inv[j]);
                f(inv[j], inv[i]);
            }
            f(inv[j], inv[j]);
        }
    };
    each_entry(&mut |_, c| col_ptr[c + 1] += 1);
    for c in 0..n {
        col_ptr[c + 1] += col_ptr[c];
    }
    let mut next = col_ptr.clone();
    let mut rows = vec![0usize; col_ptr[n]];
    each_entry(&mut |r, c| {
        rows[next[c]] = r;
        next[c] += 1;
    });
    drop(next);
    for c in 0..n {
        let column = &mut rows[col_ptr[c]..col_ptr[c + 1]];
        column.sort_unstable();
    }
    let mut unique = 0;
    let mut start = 0;
    let mut dedup_ptr = vec![0usize; n + 1];
    for c in 0..n {
        let end = col_ptr[c + 1];
        let mut last = usize::MAX;
        for p in start..end {
            if rows[p] != last {
                last = rows[p];
                rows[unique] = last;
                unique += 1;
            }
        }
        start = end;
        dedup_ptr[c + 1] = unique;
    }
    rows.truncate(unique);
    super::column_counts::factor_column_counts(&dedup_ptr, &rows)
        .iter()
        .sum()
}

/// Refuses, before a back end's symbolic analysis that builds the
/// factor's structure (faer's), a factor of `P A Pᵀ` ([`permuted_factor_nnz`],
/// `fwd` the elimination order, `ordering` its word for the message)
/// whose values alone (8 bytes an entry, what any back end keeping `L` in
/// memory stores at least) would not fit in `budget` on top of what the
/// process holds; `what` names the factor and its matrix.
pub(crate) fn check_predicted_values(
    lower: SymbolicSparseColMatRef<'_, usize>,
    fwd: &[usize],
    budget: crate::limits::MemoryBudget,
    what: &str,
    ordering: &str,
) -> Result<(), crate::error::ProblemError> {
    if fwd.len() != lower.ncols() {
        return Ok(()); // the analysis reports the length
    }
    let nnz = permuted_factor_nnz(lower, fwd);
    let bytes = (nnz as u64).saturating_mul(8);
    budget
        .check_on_top(bytes, || {
            format!(
                "{what} ({} unknowns, {nnz} entries after fill-in, predicted from the elimination tree of the {ordering} ordering) would need at least",
                lower.ncols(),
            )
        })
        .map_err(|detail| crate::error::ProblemError::TooLarge { detail })
}

#[cfg(test)]
mod prediction_tests {
    use super::*;
    use faer::Side;
    use faer::perm::PermRef;
    use faer::sparse::SymbolicSparseColMat;
    use faer::sparse::linalg::SupernodalThreshold;
    use faer::sparse::linalg::cholesky::{
        CholeskySymbolicParams, SymmetricOrdering, factorize_symbolic_cholesky,
    };
    use proptest::prelude::*;

    proptest! {
        /// The prediction under a permutation is the `nnz` of faer's
        /// simplicial factor of the same matrix under the same ordering.
        #[test]
        fn the_permuted_prediction_is_faers_factor(
            (n, edges, keys) in (1usize..30).prop_flat_map(|n| (
                Just(n),
                proptest::collection::vec((0..n, 0..n), 0..(3 * n)),
                proptest::collection::vec(any::<u32>(), n),
            ))
        ) {
            let mut columns: Vec<Vec<usize>> = (0..n).map(|j| vec![j]).collect();
            for &(a, b) in &edges {
                let (i, j) = (a.max(b), a.min(b));
                columns[j].push(i);
            }
            let (mut col_ptr, mut rows) = (vec![0], Vec::new());
            for mut c in columns {
                c.sort_unstable();
                c.dedup();
                rows.extend(c);
                col_ptr.push(rows.len());
            }
            let lower = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, rows);
            let mut fwd: Vec<usize> = (0..n).collect();
            fwd.sort_by_key(|&k| keys[k]);
            let inv = crate::backend::ordering::inverse(&fwd);
            let params = CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
                ..Default::default()
            };
            let symbolic = factorize_symbolic_cholesky(
                lower.as_ref(),
                Side::Lower,
                SymmetricOrdering::Custom(PermRef::new_checked(&fwd, &inv, n)),
                params,
            )
            .unwrap();
            prop_assert_eq!(permuted_factor_nnz(lower.as_ref(), &fwd), factor_size(&symbolic).nnz);
        }
    }
}
