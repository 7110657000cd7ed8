//! The local step: the rotation that best maps rest edges onto deformed
//! ones (orthogonal Procrustes with the reflection fixed).

use nalgebra::Matrix3;

/// A 3 × 3 matrix, row-major.
pub type Mat3 = [[f64; 3]; 3];

/// The identity rotation.
pub const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// Relative size of the second singular value below which a covariance
/// counts as rank ≤ 1: its optimal rotation is then not unique (any
/// rotation about the one well-defined direction is as good), and the
/// previous rotation is kept when it is still optimal to this tolerance.
/// `1e-12` is four orders of magnitude above the SVD's relative accuracy
/// (`~ε = 2.2e-16` times a small constant).
pub const RANK_TOLERANCE: f64 = 1e-12;

/// How a rotation was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fit {
    /// From the SVD of the covariance.
    Svd,
    /// From the Newton polar iteration ([`polar_newton`]).
    Newton,
    /// The previous rotation, kept: the covariance was zero, non-finite or
    /// of rank ≤ 1 with the previous rotation still optimal, or the SVD did
    /// not converge.
    Kept,
}

/// The rotation `R ∈ SO(3)` maximising `tr(Rᵀ M)`, i.e. minimising
/// `Σ w ‖x − R p‖²` for `M = Σ w x pᵀ`: with `M = U Σ Vᵀ` (singular values
/// decreasing), `R = U Vᵀ`, and when `det(U Vᵀ) < 0` the last column of `U`
/// is negated (the best rotation, not the best reflection). Never returns
/// a non-finite matrix: where `M` gives no unique answer (see [`Fit::Kept`])
/// `previous` is returned.
pub(crate) fn fit_rotation(m: &Mat3, previous: &Mat3) -> (Mat3, Fit) {
    let scale = m.iter().flatten().fold(0.0f64, |s, v| s.max(v.abs()));
    if !(scale.is_finite() && scale > 0.0) {
        return (*previous, Fit::Kept);
    }
    let a = Matrix3::from_fn(|i, j| m[i][j] / scale);
    let Some(svd) = a.try_svd(true, true, f64::EPSILON, 1000) else {
        return (*previous, Fit::Kept);
    };
    let (Some(mut u), Some(v_t)) = (svd.u, svd.v_t) else {
        return (*previous, Fit::Kept);
    };
    let mut r = u * v_t;
    if r.determinant() < 0.0 {
        let last = u.column(2).clone_owned();
        u.set_column(2, &(-last));
        r = u * v_t;
    }
    let rotation: Mat3 = std::array::from_fn(|i| std::array::from_fn(|j| r[(i, j)]));
    if rotation.iter().flatten().any(|v| !v.is_finite()) {
        return (*previous, Fit::Kept);
    }
    let sigma = svd.singular_values;
    if sigma[1] <= RANK_TOLERANCE * sigma[0] {
        let objective = |q: &Mat3| -> f64 {
            (0..3)
                .map(|i| (0..3).map(|j| q[i][j] * a[(i, j)]).sum::<f64>())
                .sum()
        };
        if objective(previous) >= objective(&rotation) - RANK_TOLERANCE * sigma[0] {
            return (*previous, Fit::Kept);
        }
    }
    (rotation, Fit::Svd)
}

/// Smallest `det(M / max|M_ij|)` for which [`fit_rotation_fast`] uses the
/// Newton polar iteration: then `σ₃ ≥ det / (σ₁σ₂) ≥ det / 9` (every
/// singular value of the scaled matrix is `≤ ‖·‖_F ≤ 3`), i.e. the
/// condition number is `≤ 8.1e5`, well inside the range where the scaled
/// Newton iteration converges in a handful of steps and is as accurate as
/// the SVD (Higham 1986; Kielbasiński & Ziętak 2003). Below it (nearly
/// singular, or `det ≤ 0`: a reflection to fix) the SVD path decides.
pub const NEWTON_MIN_DET: f64 = 1e-5;

/// Newton steps allowed before falling back to the SVD; scaled Newton
/// needs at most 9 for condition numbers up to `1e16` (Higham 1986).
const NEWTON_MAX_STEPS: usize = 20;

/// The Newton iteration stops when a step changes the iterate by less than
/// this (Frobenius norm): the error of the new iterate is then about the
/// square of the change, below `1e-16`.
const NEWTON_STEP_TOLERANCE: f64 = 1e-8;

fn det3(a: &Mat3) -> f64 {
    a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
}

/// `cof(A)`, so that `A⁻ᵀ = cof(A) / det A`.
fn cofactor(a: &Mat3) -> Mat3 {
    std::array::from_fn(|i| {
        let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
        std::array::from_fn(|j| {
            let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
            a[i1][j1] * a[i2][j2] - a[i1][j2] * a[i2][j1]
        })
    })
}

fn frobenius(a: &Mat3) -> f64 {
    a.iter().flatten().map(|v| v * v).sum::<f64>().sqrt()
}

/// The orthogonal polar factor of `a` by the scaled Newton iteration
/// `X ← ½(γX + γ⁻¹X⁻ᵀ)`, `γ = (‖X⁻¹‖_F / ‖X‖_F)^½` (Higham 1986), scaling
/// dropped once the steps are small so the last steps converge
/// quadratically. `None` unless `a` is well conditioned with `det a > 0`
/// (see [`NEWTON_MIN_DET`]; `a` scaled to `max|a_ij| = 1`) and the
/// iteration converges: the factor then has `det = +1`, i.e. it is the
/// rotation maximising `tr(Rᵀ a)`.
pub(crate) fn polar_newton(a: &Mat3) -> Option<Mat3> {
    let det = det3(a);
    if det.is_nan() || det <= NEWTON_MIN_DET {
        return None;
    }
    let mut x = *a;
    let mut scaled = true;
    for _ in 0..NEWTON_MAX_STEPS {
        let c = cofactor(&x);
        let det = x[0][0] * c[0][0] + x[0][1] * c[0][1] + x[0][2] * c[0][2];
        if !(det > 0.0 && det.is_finite()) {
            return None;
        }
        let gamma = if scaled {
            (frobenius(&c) / det.abs() / frobenius(&x)).sqrt()
        } else {
            1.0
        };
        let (g, h) = (0.5 * gamma, 0.5 / (gamma * det));
        let next: Mat3 =
            std::array::from_fn(|i| std::array::from_fn(|j| g * x[i][j] + h * c[i][j]));
        let step = frobenius(&std::array::from_fn(|i| {
            std::array::from_fn(|j| next[i][j] - x[i][j])
        }));
        x = next;
        if step <= NEWTON_STEP_TOLERANCE {
            return x.iter().flatten().all(|v| v.is_finite()).then_some(x);
        }
        scaled = step > 1e-2;
    }
    None
}

/// [`fit_rotation`], by the Newton polar iteration ([`polar_newton`]) where
/// the covariance is well conditioned with a positive determinant (the
/// common case, several times faster than the SVD), else by the SVD with
/// its reflection fix and rank rule. Same result to rounding.
pub(crate) fn fit_rotation_fast(m: &Mat3, previous: &Mat3) -> (Mat3, Fit) {
    let scale = m.iter().flatten().fold(0.0f64, |s, v| s.max(v.abs()));
    if scale.is_finite() && scale > 0.0 {
        let a: Mat3 = m.map(|row| row.map(|v| v / scale));
        if let Some(r) = polar_newton(&a) {
            return (r, Fit::Newton);
        }
    }
    fit_rotation(m, previous)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rot_z(angle: f64) -> Mat3 {
        let (s, c) = angle.sin_cos();
        [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    }

    fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
        std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
    }

    #[test]
    fn recovers_a_rotation_times_a_symmetric_positive_matrix() {
        let r = rot_z(0.7);
        let s = [[2.0, 0.3, 0.1], [0.3, 1.5, 0.2], [0.1, 0.2, 0.8]];
        let (fit, how) = fit_rotation(&mul(&r, &s), &IDENTITY);
        assert_eq!(how, Fit::Svd);
        for i in 0..3 {
            for j in 0..3 {
                assert!((fit[i][j] - r[i][j]).abs() < 1e-14, "{fit:?}");
            }
        }
    }

    #[test]
    fn a_reflection_gives_the_best_rotation() {
        // M = diag(1, 2, -3): the best reflection would be diag(1, 1, -1);
        // the best rotation negates the axis of the smallest singular
        // value (1): diag(-1, 1, -1).
        let m = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, -3.0]];
        let (fit, _) = fit_rotation(&m, &IDENTITY);
        let expected = [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]];
        for i in 0..3 {
            for j in 0..3 {
                assert!((fit[i][j] - expected[i][j]).abs() < 1e-14, "{fit:?}");
            }
        }
    }

    #[test]
    fn zero_rank_one_and_non_finite_covariances_keep_a_still_optimal_rotation() {
        let previous = rot_z(0.3);
        let zero = [[0.0; 3]; 3];
        assert_eq!(fit_rotation(&zero, &previous), (previous, Fit::Kept));
        let nan = [[f64::NAN, 0.0, 0.0], [0.0; 3], [0.0; 3]];
        assert_eq!(fit_rotation(&nan, &previous), (previous, Fit::Kept));
        // Rank one along z: the previous rotation (about z) maps z to z and
        // is optimal.
        let rank_one = [[0.0; 3], [0.0; 3], [0.0, 0.0, 2.0]];
        assert_eq!(fit_rotation(&rank_one, &previous), (previous, Fit::Kept));
        // Rank one along x, which the previous rotation moves: refitted.
        let along_x = [[2.0, 0.0, 0.0], [0.0; 3], [0.0; 3]];
        let (fit, how) = fit_rotation(&along_x, &previous);
        assert_eq!(how, Fit::Svd);
        assert!((fit[0][0] - 1.0).abs() < 1e-14);
    }

    #[test]
    fn newton_polar_matches_the_svd_on_random_covariances() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut newton = 0;
        for _ in 0..2000 {
            // R · S with S symmetric, eigenvalues spread over 1e-4 .. 1, and
            // a random sign: both paths (Newton and the SVD fallback).
            let m: Mat3 =
                std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
            let scale = 10f64.powi(rng.random_range(-4..2));
            let m = m.map(|row| row.map(|v| v * scale));
            let (fast, how) = fit_rotation_fast(&m, &IDENTITY);
            let (svd, _) = fit_rotation(&m, &IDENTITY);
            newton += usize::from(how == Fit::Newton);
            for i in 0..3 {
                for j in 0..3 {
                    assert!(
                        (fast[i][j] - svd[i][j]).abs() < 1e-9,
                        "{m:?}: {fast:?} vs {svd:?}"
                    );
                }
            }
            assert!(det3(&fast) > 0.999_999_999_999);
        }
        assert!(newton > 500, "only {newton} Newton fits");
    }

    #[test]
    fn newton_polar_declines_reflections_and_near_singular_matrices() {
        let reflection = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, -3.0]];
        assert_eq!(polar_newton(&reflection.map(|r| r.map(|v| v / 3.0))), None);
        let flat = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1e-7]];
        assert_eq!(polar_newton(&flat), None);
        let (r, how) = fit_rotation_fast(&flat, &IDENTITY);
        assert_eq!(how, Fit::Svd);
        assert!((r[2][2] - 1.0).abs() < 1e-14);
    }
}
