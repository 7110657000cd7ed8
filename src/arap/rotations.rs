//! The local step: the rotation that best maps rest edges onto deformed
//! ones (orthogonal Procrustes with the reflection fixed).

use nalgebra::Matrix3;

use super::energy::Mat3;

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
pub fn fit_rotation(m: &Mat3, previous: &Mat3) -> (Mat3, Fit) {
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
        let (fit, how) = fit_rotation(&mul(&r, &s), &super::super::energy::IDENTITY);
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
        let (fit, _) = fit_rotation(&m, &super::super::energy::IDENTITY);
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
}
