//! The QR seam: the traits a QR back end implements ([`QrBackend`],
//! [`ConstraintQr`]), the rank-detection tolerance they share
//! ([`RankTolerance`]) and [`particular_solution`]. A leaf under
//! [`crate::backend::qr`], which re-exports it: the back ends and their
//! pre-passes import it, it imports none of them.

use faer::sparse::{SparseColMat, SparseColMatRef, SparseRowMatRef};
use faer::{MatMut, MatRef};

use crate::error::Error;
use crate::resources::Resources;

/// The rank-detection tolerance `η`: constraint `j` is skipped when the norm
/// of what remains of it after projecting out the earlier kept constraints
/// is `≤ η ‖b_j‖₂`.
///
/// Default `η = 1e-10`. Justification: rounding leaves a truly dependent
/// constraint a remainder of about `k ε ‖b_j‖` after `k` reflections, i.e.
/// below `1e-12 ‖b_j‖` for blocks of up to ~10⁴ constraints, so `η` sits two
/// orders above that noise; SPQR's default `20 (m+n) ε max‖b‖` sits right
/// at it, which keeps near-dependent constraints as independent. Keeping a
/// constraint whose new information is below `1e-10` relative would put a
/// diagonal `< 1e-10 ‖b_j‖` into `R1` and amplify its target by up to `10¹⁰`
/// into the solution; constraint coefficients (edge parameters, barycentric
/// coordinates from picking) rarely carry more than ten correct digits, so a
/// difference below that is indistinguishable from redundancy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RankTolerance {
    /// `η`, relative to each constraint's coefficient norm.
    pub relative: f64,
}

impl Default for RankTolerance {
    fn default() -> Self {
        RankTolerance { relative: 1e-10 }
    }
}

/// A QR factorisation method for `Bᵀ`: the crate's own ([`QrKind`]'s
/// catalogue) or one brought from outside (docs/backends.md,
/// `lse_deform::testing::conformance::qr`).
pub trait QrBackend: Send + Sync {
    /// The back end's name in reports and `compare` rows (a built-in's
    /// word; an outside back end chooses its own).
    fn name(&self) -> crate::backend::BackendName;

    /// Factors `Bᵀ` for the hard-constraint matrix `b` (m × n, one row per
    /// constraint, in priority order), refusing with
    /// [`ProblemError::TooLarge`](crate::error::ProblemError::TooLarge) a
    /// factor whose estimated storage exceeds the budget of `resources`.
    /// The rows keep their priority order (rank detection depends on it),
    /// so the resources' fill-reducing ordering is not a QR's to take; the
    /// crate's QR back ends run on one thread.
    fn factor_with(
        &self,
        b: SparseRowMatRef<'_, usize, f64>,
        tolerance: RankTolerance,
        resources: &Resources,
    ) -> Result<Box<dyn ConstraintQr>, Error>;

    /// [`QrBackend::factor_with`] the default resources
    /// ([`Resources::default`]).
    fn factor(
        &self,
        b: SparseRowMatRef<'_, usize, f64>,
        tolerance: RankTolerance,
    ) -> Result<Box<dyn ConstraintQr>, Error> {
        self.factor_with(b, tolerance, &Resources::default())
    }
}

/// A factorisation `Bᵀ = Q R` kept in implicit form.
///
/// Coordinates: `x = Q [y; z]` with `y ∈ ℝ^r` (the constrained directions,
/// fixed by `R1ᵀ y = d_kept`) and `z ∈ ℝ^{n−r}` (the free directions, the
/// unknowns of the reduced least-squares problem). All operands have three
/// columns (x, y, z coordinates) or more.
pub trait ConstraintQr: Send + Sync {
    /// `n`, the number of unknowns (columns of `B`).
    fn n(&self) -> usize;

    /// The numerical rank `r` of `B`.
    fn rank(&self) -> usize;

    /// The kept rows of `B`, in the order of `y` (length `r`).
    fn kept(&self) -> &[usize];

    /// The skipped (dependent) rows of `B`, increasing.
    fn skipped(&self) -> &[usize];

    /// Solves `R1ᵀ y = D_kept` where `d` holds all `m` rows of `D`.
    fn solve_r1t(&self, d: MatRef<'_, f64>, y: MatMut<'_, f64>);

    /// `x = Q [y; z]` (`x`: n × k, `y`: r × k, `z`: (n−r) × k).
    fn apply_q(&self, y: MatRef<'_, f64>, z: MatRef<'_, f64>, x: MatMut<'_, f64>);

    /// `[y; z] = Qᵀ x`.
    fn apply_qt(&self, x: MatRef<'_, f64>, y: MatMut<'_, f64>, z: MatMut<'_, f64>);

    /// `A Q2` (l × (n−r)) for a sparse `A` (l × n), sorted rows.
    fn mul_a_q2(&self, a: SparseColMatRef<'_, usize, f64>) -> SparseColMat<usize, f64>;

    /// The mesh unknown most associated with free direction `k` (for error
    /// messages that name a vertex).
    fn free_unknown(&self, k: usize) -> usize;

    /// Stored entries of the implicit `Q` and of `R`.
    fn storage_nnz(&self) -> usize;
}

/// `y = R1⁻ᵀ d` and then `x = Q [y; 0]`: the minimum-norm solution of
/// `B_kept x = d_kept` (for the tests and the conformance kit).
#[cfg(any(test, feature = "proptest"))]
pub(crate) fn particular_solution(
    qr: &dyn ConstraintQr,
    d: MatRef<'_, f64>,
) -> (faer::Mat<f64>, faer::Mat<f64>) {
    let k = d.ncols();
    let mut y = faer::Mat::zeros(qr.rank(), k);
    qr.solve_r1t(d, y.as_mut());
    let z = faer::Mat::zeros(qr.n() - qr.rank(), k);
    let mut x = faer::Mat::zeros(qr.n(), k);
    qr.apply_q(y.as_ref(), z.as_ref(), x.as_mut());
    (y, x)
}
