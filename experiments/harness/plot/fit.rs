//! The power-law fit of the scatter plots: least squares in log–log space.

/// Why [`fit_power_law`] failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// Fewer than two points.
    #[error("needs at least 2 points, got {got}")]
    TooFewPoints {
        /// Number of points given.
        got: usize,
    },
    /// A coordinate that is not finite and positive.
    #[error("point {index} ({x}, {y}) is not finite and positive")]
    NotPositive {
        /// Index of the point.
        index: usize,
        /// Its x.
        x: f64,
        /// Its y.
        y: f64,
    },
    /// All x equal: the slope is undefined.
    #[error("all x are equal: the slope is undefined")]
    ConstantX,
}

/// A least-squares fit `log10 y = intercept + slope · log10 x`, i.e.
/// `y = 10^intercept · x^slope`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerFit {
    /// The exponent.
    pub slope: f64,
    /// log10 of the coefficient.
    pub intercept: f64,
    /// Coefficient of determination of the fit in log–log space (1 when all
    /// points are on the line, or when all y are equal).
    pub r_squared: f64,
    /// Number of points fitted.
    pub n: usize,
}

/// Least-squares fit of `log10 y` on `log10 x` (a power law `y = c·x^k`).
/// Every coordinate must be finite and `> 0`; at least two distinct x.
pub fn fit_power_law(points: &[(f64, f64)]) -> Result<PowerFit, FitError> {
    if points.len() < 2 {
        return Err(FitError::TooFewPoints { got: points.len() });
    }
    let mut logs = Vec::with_capacity(points.len());
    for (index, &(x, y)) in points.iter().enumerate() {
        if !(x.is_finite() && y.is_finite() && x > 0.0 && y > 0.0) {
            return Err(FitError::NotPositive { index, x, y });
        }
        logs.push((x.log10(), y.log10()));
    }
    let n = logs.len() as f64;
    let mx = logs.iter().map(|p| p.0).sum::<f64>() / n;
    let my = logs.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = logs.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = logs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let syy: f64 = logs.iter().map(|p| (p.1 - my).powi(2)).sum();
    // Relative test: x spread below rounding of the mean is no spread.
    if sxx <= (f64::EPSILON * (1.0 + mx.abs())).powi(2) * n {
        return Err(FitError::ConstantX);
    }
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let ss_res: f64 = logs
        .iter()
        .map(|p| (p.1 - intercept - slope * p.0).powi(2))
        .sum();
    let r_squared = if syy > 0.0 {
        (1.0 - ss_res / syy).clamp(0.0, 1.0)
    } else {
        1.0
    };
    Ok(PowerFit {
        slope,
        intercept,
        r_squared,
        n: logs.len(),
    })
}
