//! Sparse symmetric positive definite solvers.
//!
//! A back end analyses a sparsity pattern once ([`SpdBackend::analyze`]:
//! fill-reducing ordering and symbolic factorisation) and then factors any
//! matrix with that pattern numerically ([`SpdSymbolic::factorize`]) as
//! often as needed (a new penalty weight, new soft weights), without a new
//! analysis. Matrices are given as their **lower triangle** in CSC form with
//! sorted row indices, diagonal included.
//!
//! Numerical failure is a typed
//! [`NumericalError`](crate::error::NumericalError) naming the failing pivot
//! in the *original* (unpermuted) ordering: either a pivot that is not
//! positive, or a pivot that lost all its digits to cancellation
//! ([`BREAKDOWN_RATIO`]).

pub use crate::backend::kinds::SpdKind;

#[cfg(feature = "suitesparse")]
mod cholmod;
mod column_counts;
mod factor_size;
mod faer_llt;
mod nalgebra;
mod seam;
mod tree_split;
mod triangular;

#[cfg(feature = "suitesparse")]
pub use cholmod::Cholmod;
pub(crate) use factor_size::check_predicted_values;
pub(crate) use factor_size::factor_size;
pub use faer_llt::FaerLlt;
pub use nalgebra::NalgebraCsc;
pub(crate) use seam::check_breakdown;
pub use seam::{BREAKDOWN_RATIO, SpdBackend, SpdFactor, SpdSymbolic, check_factor_size, solve};
