//! What one formulation's precompute fixed that the others have no notion
//! of: the penalty weight and its unit, the KKT multiplier scale.

/// The facts specific to the method that was precomputed (serialised in
/// the report under the keys `penalty_weight`, `penalty_weight_unit` and
/// `kkt_multiplier_scale`, `null` where they do not apply).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MethodFacts {
    /// The paper's null-space method: nothing beyond the common record.
    NullSpace,
    /// The penalty method.
    Penalty {
        /// The relative penalty weight `w` of the hard rows, as given.
        weight: f64,
        /// `s`, the power of two `w` is multiplied by: hard rows enter with
        /// weight `w s` (the power of two nearest to the largest column
        /// norm of `A`, `formulation::Penalty`).
        weight_unit: f64,
    },
    /// The KKT method.
    Kkt {
        /// The power-of-two scale `s` of the multiplier rows and columns of
        /// `[AᵀA sBᵀ; sB 0]`.
        multiplier_scale: f64,
    },
    /// Elimination of the position-constrained vertices.
    Eliminate,
}

impl MethodFacts {
    /// The relative penalty weight `w` (penalty only).
    pub(crate) fn penalty_weight(&self) -> Option<f64> {
        match *self {
            MethodFacts::Penalty { weight, .. } => Some(weight),
            _ => None,
        }
    }

    /// The penalty weight's unit `s` (penalty only).
    pub(crate) fn penalty_weight_unit(&self) -> Option<f64> {
        match *self {
            MethodFacts::Penalty { weight_unit, .. } => Some(weight_unit),
            _ => None,
        }
    }

    /// The KKT multiplier scale `s` (KKT only).
    pub(crate) fn kkt_multiplier_scale(&self) -> Option<f64> {
        match *self {
            MethodFacts::Kkt { multiplier_scale } => Some(multiplier_scale),
            _ => None,
        }
    }
}
