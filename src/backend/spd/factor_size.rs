//! The storage of a faer sparse Cholesky factor (`LLᵀ` or `LDLᵀ`), read from
//! its symbolic analysis before any numeric work.

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
