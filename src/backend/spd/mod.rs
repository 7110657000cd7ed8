//! Sparse symmetric positive definite solvers.
//!
//! A back end analyses a sparsity pattern once ([`SpdBackend::analyze`]:
//! fill-reducing ordering and symbolic factorisation) and then factors any
//! matrix with that pattern numerically ([`SpdSymbolic::factorize`]) as
//! often as needed (a new penalty weight, new soft weights), without a new
//! analysis. Matrices are given as their **lower triangle** in CSC form with
//! sorted row indices, diagonal included.
//!
//! Numerical failure is a typed [`NumericalError`] naming the failing pivot
//! in the *original* (unpermuted) ordering: either a pivot that is not
//! positive, or a pivot that lost all its digits to cancellation
//! ([`BREAKDOWN_RATIO`]).

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{MatMut, MatRef};

use crate::error::NumericalError;

mod faer_llt;

pub use faer_llt::FaerLlt;

/// Threshold on `L_kk² / A_kk` below which a completed Cholesky
/// factorisation is declared broken down.
///
/// The computed pivot `L_kk² = A_kk − Σ_j L_kj²` carries a rounding error of a
/// small multiple of `ε·A_kk` (each `L_kj² ≤ A_kk` for an SPD matrix), so a
/// ratio below `1000 ε ≈ 2.2e-13` leaves at most about three significant
/// digits in the pivot. Since `L_kk² ≥ λ_min` and `A_kk ≤ λ_max`, such a ratio
/// also certifies `κ(A) > 4.5e12`: the solve would lose twelve or more of
/// sixteen digits. We stop there rather than return such a solution.
pub const BREAKDOWN_RATIO: f64 = 1000.0 * f64::EPSILON;

/// A sparse SPD solver family.
pub trait SpdBackend: Send + Sync {
    /// Name used on the command line and in reports.
    fn name(&self) -> &'static str;

    /// Symbolic analysis (ordering + symbolic factorisation) of the lower
    /// triangle pattern `lower` (square, sorted rows, diagonal present).
    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError>;
}

/// The result of a symbolic analysis: factors any matrix with its pattern.
pub trait SpdSymbolic: Send + Sync {
    /// Numeric factorisation of `lower` (same pattern as analysed).
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn SpdFactor>, NumericalError>;

    /// Number of stored entries of the factor `L` (lower triangle, diagonal
    /// included), known after analysis.
    fn factor_nnz(&self) -> usize;
}

/// A numeric factorisation `P A Pᵀ = L Lᵀ`.
pub trait SpdFactor: Send + Sync {
    /// Dimension of the factored matrix.
    fn dim(&self) -> usize;

    /// Solves `A X = B` in place for all columns of `rhs` together.
    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>);

    /// Number of stored entries of `L`.
    fn nnz(&self) -> usize;

    /// Bytes of the factor's numerical values and indices (what a solve must
    /// read twice: the bandwidth floor of a solve).
    fn bytes(&self) -> usize;
}

/// Solves with a factor, returning the solution (convenience).
pub fn solve(factor: &mut dyn SpdFactor, rhs: MatRef<'_, f64>) -> faer::Mat<f64> {
    let mut x = rhs.to_owned();
    factor.solve_in_place(x.as_mut());
    x
}
