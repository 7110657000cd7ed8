//! QR factorisation of the hard-constraint matrix `Bᵀ` (n × m) with rank
//! detection in priority order, and the operations the null-space method
//! needs from it — without ever forming `Q`.
//!
//! `Bᵀ = Q R`, `Q = [Q1 Q2]` with `r = rank(B)` columns in `Q1`, and
//! `R1` (r × r, upper triangular) built from the *kept* constraints. A
//! constraint (a column of `Bᵀ`) whose remaining norm, after the earlier
//! kept constraints have been projected out, is at most
//! `η ‖b_j‖₂` is *skipped* as numerically dependent on earlier ones
//! ([`RankTolerance`]). Since constraints are processed in list order, the
//! earlier of two dependent constraints is the one kept.
//!
//! Rows of `B` that repeat an earlier row up to sign are dependent whatever
//! the tolerance; every back end decides them in linear time before
//! factoring (`distinct_rows.rs`), so a constraint repeated `k` times costs
//! `O(k)`, not the `O(k²)` of a dense `k × k` block of `B Bᵀ`. Then, when
//! every row is a position or relative row and an unknown is shared by many
//! of them (a hub), rank is decided by union–find and the rows are replaced
//! by an equivalent set with a sparse `B Bᵀ` (`graph_rows.rs`); and the fill
//! of `R` is counted before factoring and checked against the memory budget
//! (`fill.rs`).
//!
//! Back ends ([`QrKind`]): [`DenseHouseholder`] (the paper's method per
//! independent block, the reference), [`SparseGivens`] (row-by-row Givens on
//! the whole sparse `Bᵀ`, Heath's rank test) and, with the cargo feature
//! `suitesparse`, `Spqr` (SuiteSparseQR). All three use the same relative
//! test and return the same rank and skipped set whenever the dependencies
//! are well separated from the tolerance; each module documents where they
//! can differ near it.

mod dense_householder;
mod distinct_rows;
mod fill;
mod givens_merge;
mod graph_rows;
mod seam;
mod sparse_columns;
mod sparse_givens;
#[cfg(feature = "suitesparse")]
mod spqr;

pub use crate::backend::kinds::QrKind;
pub use dense_householder::DenseHouseholder;
pub use graph_rows::HUB_DEGREE;
#[cfg(any(test, feature = "proptest"))]
pub(crate) use seam::particular_solution;
pub use seam::{ConstraintQr, QrBackend, RankTolerance};
pub use sparse_givens::{GivensQr, GivensRowOrder, SparseGivens};
#[cfg(feature = "suitesparse")]
pub use spqr::{Spqr, SpqrQr};
