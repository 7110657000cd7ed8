//! Estimates of the 2-norm condition number `κ₂(M) = |λ|max / |λ|min` of the
//! symmetric matrix `M` a formulation factors (a reduced normal matrix, a
//! penalty normal matrix, or an indefinite KKT matrix).
//!
//! **Method.** Both extremes come from the Lanczos process with full
//! reorthogonalisation ([`lanczos_largest_magnitude`]), started from a fixed
//! pseudo-random vector (so estimates are reproducible):
//! - `|λ|max` from Lanczos on `M` itself (one sparse symmetric product per
//!   step);
//! - `|λ|min = 1 / |μ|max(M⁻¹)` from Lanczos on `M⁻¹`, one solve with the
//!   existing factor per step. This is inverse iteration accelerated by
//!   Krylov subspace extraction: the `k`-th inverse-iteration vector
//!   `M⁻ᵏ v` lies in the Krylov space the `k` steps of Lanczos span, so it is
//!   never slower than inverse iteration and usually much faster.
//!
//! For the indefinite KKT matrix the same process applies to magnitudes: the
//! Ritz value of largest magnitude (from either end of the spectrum) is
//! taken.
//!
//! **Stopping.** After step `k`, with `T_k = S Θ Sᵀ` the tridiagonal
//! Lanczos matrix and `θ` its Ritz value of largest magnitude, the quantity
//! `β_k |s_{k,θ}|` is the residual `‖M y − θ y‖` of the Ritz pair, so some
//! eigenvalue of `M` lies within it of `θ` (Kahan–Parlett bound). We stop
//! when it is `≤ τ |θ|` with `τ =` [`LANCZOS_RELATIVE_TOLERANCE`] `= 1e-4`, or
//! when the Krylov space is exhausted (`β_k ≤ ε |θ|` or `k = n`, then `θ` is
//! exact up to rounding). The cap is [`LANCZOS_MAX_ITERATIONS`] steps per
//! extreme; when it is reached, [`ConditionEstimate::converged`] is `false`
//! and the best Ritz values are reported (for `λmax` of an SPD matrix the
//! Ritz value is then a lower bound; `λmin` an upper bound, so the reported
//! `κ` is an underestimate).
//!
//! With both extremes within `τ` relative of an eigenvalue, `κ` is within a
//! factor `(1+τ)/(1−τ) ≈ 1.0002` of `κ₂` — provided Lanczos found the extreme
//! eigenvalues and not interior ones, which a start vector with components
//! along them ensures (a pseudo-random vector has them almost surely).
//!
//! **Cost.** Up to `2 × 200` products/solves and `O(n k²)` flops and
//! `n k × 8` bytes for the Krylov basis (`k ≤ 200`): on demand only
//! (`Prepared::estimate_condition` of the formulations).

use faer::{Mat, MatMut, MatRef, Side};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::error::{Error, NumericalError};

/// Relative tolerance `τ` on the Ritz residual bound `β_k |s_k| ≤ τ |θ|`.
/// `1e-4` makes each extreme eigenvalue accurate to 1e-4 relative, so `κ` to
/// about 2e-4 — three to four digits, more than a condition number is used
/// for — while keeping the number of steps well under the cap for the
/// meshes of the paper.
pub const LANCZOS_RELATIVE_TOLERANCE: f64 = 1e-4;

/// Maximum number of Lanczos steps per extreme eigenvalue (also bounds the
/// basis memory to `200 n` doubles).
pub const LANCZOS_MAX_ITERATIONS: usize = 200;

/// Seed of the start vector (fixed so that estimates are reproducible).
const SEED: u64 = 0x00c0_ffee_1a2c_705d;

/// How a [`ConditionEstimate`] was obtained.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ConditionMethod {
    /// Lanczos with full reorthogonalisation on the matrix for `|λ|max` and
    /// on its inverse, applied by solves with the factor, for `|λ|min`
    /// ([`estimate`]).
    Lanczos {
        /// The matrix, as the formulation names it (e.g. `(AQ2)ᵀ(AQ2)`).
        matrix: String,
    },
}

impl std::fmt::Display for ConditionMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ConditionMethod::Lanczos { matrix } => write!(
                f,
                "Lanczos with full reorthogonalisation on {matrix} for |λ|max and on its inverse (solves with the factor) for |λ|min"
            ),
        }
    }
}

/// Serialised as its sentence (`Display`).
impl Serialize for ConditionMethod {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// An estimate of `κ₂(M) = |λ|max / |λ|min` for the symmetric matrix `M`
/// that a formulation factored.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ConditionEstimate {
    /// `κ = lambda_max / lambda_min`.
    pub value: f64,
    /// Largest eigenvalue magnitude `|λ|max`.
    pub lambda_max: f64,
    /// Smallest eigenvalue magnitude `|λ|min`.
    pub lambda_min: f64,
    /// How it was obtained (operator and algorithm), serialised as the
    /// sentence [`ConditionMethod`]'s `Display` writes.
    pub method: ConditionMethod,
    /// Lanczos steps taken, both extremes together.
    pub iterations: usize,
    /// Whether both extremes met the tolerance before the cap.
    pub converged: bool,
    /// The relative tolerance `τ` used on the Ritz residual bounds.
    pub tolerance: f64,
    /// Relative residual bound `β_k|s_k| / |θ|` reached for `|λ|max`.
    pub lambda_max_relative_residual: f64,
    /// Relative residual bound reached for `1/|λ|min` (on `M⁻¹`).
    pub lambda_min_relative_residual: f64,
}

/// A symmetric linear operator `x ↦ M x` (or `M⁻¹ x`) on `ℝⁿ`.
pub trait SymmetricOperator {
    /// `n`.
    fn dim(&self) -> usize;
    /// `y ← M x` for one column (`x`, `y`: n × 1).
    fn apply(&mut self, x: MatRef<'_, f64>, y: MatMut<'_, f64>) -> Result<(), Error>;
}

/// The largest-magnitude Ritz value of a Lanczos run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LanczosResult {
    /// The Ritz value `θ` of largest magnitude (signed).
    pub value: f64,
    /// `β_k |s_{k,θ}| / |θ|`: some eigenvalue lies within this relative
    /// distance of `θ`.
    pub relative_residual: f64,
    /// Steps taken.
    pub iterations: usize,
    /// `relative_residual ≤ tol`, or the Krylov space was exhausted.
    pub converged: bool,
}

/// The eigenvalue of largest magnitude of a symmetric operator by Lanczos
/// with full reorthogonalisation (classical Gram–Schmidt applied twice at
/// every step), stopping at relative Ritz residual `tol` or after
/// `max_iterations` steps (see the module documentation).
pub(crate) fn lanczos_largest_magnitude(
    op: &mut dyn SymmetricOperator,
    tol: f64,
    max_iterations: usize,
) -> Result<LanczosResult, Error> {
    let n = op.dim();
    if n == 0 {
        return Err(NumericalError::Backend {
            backend: "lanczos".into(),
            message: "the operator has dimension 0".into(),
        }
        .into());
    }
    let cap = max_iterations.clamp(1, n);
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    let mut v = Mat::<f64>::from_fn(n, 1, |_, _| rng.random_range(-1.0..1.0));
    let norm = v.norm_l2();
    for i in 0..n {
        v[(i, 0)] /= norm;
    }
    let mut basis: Vec<Mat<f64>> = Vec::with_capacity(cap);
    let mut alpha: Vec<f64> = Vec::with_capacity(cap);
    let mut beta: Vec<f64> = Vec::with_capacity(cap);
    let mut w = Mat::<f64>::zeros(n, 1);
    let mut best = LanczosResult {
        value: 0.0,
        relative_residual: f64::INFINITY,
        iterations: 0,
        converged: false,
    };
    for k in 0..cap {
        crate::interrupt::check()?;
        op.apply(v.as_ref(), w.as_mut())?;
        if !w.is_all_finite() {
            return Err(NumericalError::Backend {
                backend: "lanczos".into(),
                message: format!("the operator produced a non-finite vector at step {k}"),
            }
            .into());
        }
        let a = dot(&w, &v);
        axpy(&mut w, -a, &v);
        if let (Some(prev), Some(&b)) = (basis.last(), beta.last()) {
            axpy(&mut w, -b, prev);
        }
        basis.push(v.clone());
        alpha.push(a);
        for _ in 0..2 {
            for q in &basis {
                let c = dot(&w, q);
                axpy(&mut w, -c, q);
            }
        }
        let b = w.norm_l2();
        let steps = k + 1;
        let exhausted = steps == n;
        let tiny = b <= f64::EPSILON * best.value.abs().max(a.abs());
        let check = steps <= 40 || steps % 5 == 0 || steps == cap || exhausted || tiny;
        if check {
            let (theta, last) = extreme_ritz(&alpha, &beta)?;
            let rel = if theta != 0.0 {
                b * last.abs() / theta.abs()
            } else {
                f64::INFINITY
            };
            let invariant = b <= f64::EPSILON * theta.abs();
            best = LanczosResult {
                value: theta,
                relative_residual: if exhausted || invariant { 0.0 } else { rel },
                iterations: steps,
                converged: exhausted || invariant || rel <= tol,
            };
            if best.converged {
                return Ok(best);
            }
        }
        if b == 0.0 {
            // Invariant subspace in exact arithmetic with θ = 0: the
            // operator annihilates the start vector's Krylov space.
            break;
        }
        beta.push(b);
        let inv = 1.0 / b;
        v = Mat::from_fn(n, 1, |i, _| w[(i, 0)] * inv);
    }
    Ok(best)
}

fn dot(x: &Mat<f64>, y: &Mat<f64>) -> f64 {
    let mut s = 0.0;
    for i in 0..x.nrows() {
        s += x[(i, 0)] * y[(i, 0)];
    }
    s
}

fn axpy(y: &mut Mat<f64>, a: f64, x: &Mat<f64>) {
    for i in 0..y.nrows() {
        y[(i, 0)] += a * x[(i, 0)];
    }
}

/// The Ritz value of largest magnitude of the tridiagonal `T` (diagonal
/// `alpha`, off-diagonal `beta`) and the last component of its eigenvector.
fn extreme_ritz(alpha: &[f64], beta: &[f64]) -> Result<(f64, f64), Error> {
    let k = alpha.len();
    let t = Mat::<f64>::from_fn(k, k, |i, j| {
        if i == j {
            alpha[i]
        } else if i == j + 1 {
            beta[j]
        } else if j == i + 1 {
            beta[i]
        } else {
            0.0
        }
    });
    let eig = t
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| NumericalError::Backend {
            backend: "lanczos (tridiagonal eigensolver)".into(),
            message: format!("{e:?}"),
        })?;
    let s = eig.S().column_vector();
    let u = eig.U();
    // Eigenvalues are sorted increasingly: the largest magnitude is at
    // either end.
    let idx = if s[0].abs() > s[k - 1].abs() {
        0
    } else {
        k - 1
    };
    Ok((s[idx], u[(k - 1, idx)]))
}

/// `κ` from a run on `M` (largest magnitude) and a run on `M⁻¹` (whose
/// largest magnitude is `1/|λ|min`), with the standard tolerance and cap.
pub fn estimate(
    matrix: &mut dyn SymmetricOperator,
    inverse: &mut dyn SymmetricOperator,
    what: &str,
) -> Result<ConditionEstimate, Error> {
    let hi = lanczos_largest_magnitude(matrix, LANCZOS_RELATIVE_TOLERANCE, LANCZOS_MAX_ITERATIONS)?;
    let lo =
        lanczos_largest_magnitude(inverse, LANCZOS_RELATIVE_TOLERANCE, LANCZOS_MAX_ITERATIONS)?;
    let lambda_max = hi.value.abs();
    if lo.value == 0.0 || !lo.value.is_finite() {
        return Err(NumericalError::Backend {
            backend: "lanczos".into(),
            message: format!("the inverse of {what} has no nonzero eigenvalue estimate"),
        }
        .into());
    }
    let lambda_min = 1.0 / lo.value.abs();
    Ok(ConditionEstimate {
        value: lambda_max / lambda_min,
        lambda_max,
        lambda_min,
        method: ConditionMethod::Lanczos {
            matrix: what.to_string(),
        },
        iterations: hi.iterations + lo.iterations,
        converged: hi.converged && lo.converged,
        tolerance: LANCZOS_RELATIVE_TOLERANCE,
        lambda_max_relative_residual: hi.relative_residual,
        lambda_min_relative_residual: lo.relative_residual,
    })
}

/// `x ↦ M x` for a symmetric sparse `M` stored as its lower triangle.
pub struct LowerSymmetricOperator<'a> {
    lower: faer::sparse::SparseColMatRef<'a, usize, f64>,
}

impl<'a> LowerSymmetricOperator<'a> {
    /// Wraps the lower triangle (CSC, sorted rows, diagonal included).
    pub fn new(lower: faer::sparse::SparseColMatRef<'a, usize, f64>) -> Self {
        LowerSymmetricOperator { lower }
    }
}

impl SymmetricOperator for LowerSymmetricOperator<'_> {
    fn dim(&self) -> usize {
        self.lower.ncols()
    }

    fn apply(&mut self, x: MatRef<'_, f64>, y: MatMut<'_, f64>) -> Result<(), Error> {
        crate::sparse::lower_sym_mul(self.lower, x, y);
        Ok(())
    }
}

/// `x ↦ M⁻¹ x` through a solve-in-place closure (a factor of `M`).
pub struct InverseOperator<F> {
    dim: usize,
    solve: F,
}

impl<F: FnMut(MatMut<'_, f64>) -> Result<(), Error>> InverseOperator<F> {
    /// `solve(rhs)` must overwrite `rhs` (n × 1) with `M⁻¹ rhs`.
    pub fn new(dim: usize, solve: F) -> Self {
        InverseOperator { dim, solve }
    }
}

impl<F: FnMut(MatMut<'_, f64>) -> Result<(), Error>> SymmetricOperator for InverseOperator<F> {
    fn dim(&self) -> usize {
        self.dim
    }

    fn apply(&mut self, x: MatRef<'_, f64>, mut y: MatMut<'_, f64>) -> Result<(), Error> {
        y.copy_from(x);
        (self.solve)(y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Dense(Mat<f64>);

    impl SymmetricOperator for Dense {
        fn dim(&self) -> usize {
            self.0.nrows()
        }
        fn apply(&mut self, x: MatRef<'_, f64>, mut y: MatMut<'_, f64>) -> Result<(), Error> {
            y.copy_from(&self.0 * x);
            Ok(())
        }
    }

    #[test]
    fn finds_the_extreme_eigenvalues_of_a_diagonal_matrix() {
        let n = 300;
        let d: Vec<f64> = (0..n).map(|i| 1.0 + i as f64 * 0.01).collect();
        let mut m = Dense(Mat::from_fn(n, n, |i, j| if i == j { d[i] } else { 0.0 }));
        let r = lanczos_largest_magnitude(&mut m, 1e-10, 300).unwrap();
        assert!((r.value - d[n - 1]).abs() < 1e-8, "{r:?}");
        // Indefinite: the negative end has the larger magnitude.
        let mut m = Dense(Mat::from_fn(5, 5, |i, j| {
            if i == j {
                [-7.0, 1.0, 2.0, 3.0, 6.5][i]
            } else {
                0.0
            }
        }));
        let r = lanczos_largest_magnitude(&mut m, 1e-12, 50).unwrap();
        assert!((r.value + 7.0).abs() < 1e-10 && r.converged, "{r:?}");
    }
}
