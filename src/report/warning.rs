//! Typed warnings: what the user should know about a deformation, each
//! with a stable code ([`WarningKind::code`]) that scripts can match on
//! instead of the text, which may be reworded.

use serde::{Serialize, Serializer};

use crate::mesh::MeshWarning;

/// What a [`Warning`] is about. Serialised in the report's
/// `"warning_codes"` (parallel to `"warnings"`, one code per text) as its
/// stable code (docs/warnings.md):
///
/// | code | variant | issued when |
/// |---|---|---|
/// | `degenerate-faces` | [`WarningKind::DegenerateFaces`] | the mesh has faces of zero area |
/// | `non-manifold-edge` | [`WarningKind::NonManifoldEdge`] | an edge is shared by more than two faces |
/// | `constraints-mesh-mismatch` | [`WarningKind::ConstraintsMeshMismatch`] | the constraints file was made for another mesh (CLI without `--strict`) |
/// | `penalty-approximate` | [`WarningKind::PenaltyApproximate`] | the penalty method holds the hard constraints only approximately |
/// | `conflicting-constraint` | [`WarningKind::ConflictingConstraint`] | a hard constraint conflicts with earlier ones and was dropped |
/// | `more-conflicting-constraints` | [`WarningKind::MoreConflictingConstraints`] | the count of conflicting constraints beyond those named one by one |
/// | `conflict-residual-overflow` | [`WarningKind::ConflictResidualOverflow`] | a conflicting constraint's residual is not a finite double |
/// | `refinement-stalled` | [`WarningKind::RefinementStalled`] | the penalty method's multiplier updates stopped on a residual that does not shrink: the hard constraints conflict |
/// | `lost-accuracy` | [`WarningKind::LostAccuracy`] | the forward-error estimate exceeds `1e-8` of the length scale after refinement (conditioning) |
/// | `lost-accuracy-unrefined` | [`WarningKind::LostAccuracyUnrefined`] | the same, with refinement off (estimate only) |
/// | `lost-accuracy-step-limit` | [`WarningKind::LostAccuracyStepLimit`] | the same, refinement stopped at its step limit |
///
/// The codes are part of the report's format: a code is never reused for
/// another meaning; new kinds get new codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum WarningKind {
    /// Faces of zero area ([`MeshWarning::DegenerateFaces`]).
    DegenerateFaces,
    /// An edge of more than two faces ([`MeshWarning::NonManifoldEdge`]).
    NonManifoldEdge,
    /// The constraints file names another mesh than the one deformed.
    ConstraintsMeshMismatch,
    /// Penalty method: hard constraints are soft rows of a large weight.
    PenaltyApproximate,
    /// One conflicting hard constraint, dropped, with what it contradicts.
    ConflictingConstraint,
    /// The conflicting constraints not named one by one, counted.
    MoreConflictingConstraints,
    /// A conflicting constraint whose residual overflows a double.
    ConflictResidualOverflow,
    /// The method of multipliers stopped: its residual stopped shrinking
    /// (conflicting hard constraints).
    RefinementStalled,
    /// Estimated forward error above the warning threshold after
    /// refinement.
    LostAccuracy,
    /// Estimated forward error above the threshold, refinement off.
    LostAccuracyUnrefined,
    /// Estimated forward error above the threshold, refinement at its step
    /// limit.
    LostAccuracyStepLimit,
}

impl WarningKind {
    /// Every kind, in the order of the table above.
    pub const ALL: [WarningKind; 11] = [
        WarningKind::DegenerateFaces,
        WarningKind::NonManifoldEdge,
        WarningKind::ConstraintsMeshMismatch,
        WarningKind::PenaltyApproximate,
        WarningKind::ConflictingConstraint,
        WarningKind::MoreConflictingConstraints,
        WarningKind::ConflictResidualOverflow,
        WarningKind::RefinementStalled,
        WarningKind::LostAccuracy,
        WarningKind::LostAccuracyUnrefined,
        WarningKind::LostAccuracyStepLimit,
    ];

    /// The stable code (the table above).
    pub fn code(self) -> &'static str {
        match self {
            WarningKind::DegenerateFaces => "degenerate-faces",
            WarningKind::NonManifoldEdge => "non-manifold-edge",
            WarningKind::ConstraintsMeshMismatch => "constraints-mesh-mismatch",
            WarningKind::PenaltyApproximate => "penalty-approximate",
            WarningKind::ConflictingConstraint => "conflicting-constraint",
            WarningKind::MoreConflictingConstraints => "more-conflicting-constraints",
            WarningKind::ConflictResidualOverflow => "conflict-residual-overflow",
            WarningKind::RefinementStalled => "refinement-stalled",
            WarningKind::LostAccuracy => "lost-accuracy",
            WarningKind::LostAccuracyUnrefined => "lost-accuracy-unrefined",
            WarningKind::LostAccuracyStepLimit => "lost-accuracy-step-limit",
        }
    }
}

impl std::fmt::Display for WarningKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.code())
    }
}

/// Serialised as its code.
impl Serialize for WarningKind {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.code())
    }
}

/// One warning: its kind and the sentence shown to the user (`Display`);
/// serialised as the message (the report adds the codes under
/// `"warning_codes"`). Code that needs to tell warnings apart matches on
/// [`Warning::kind`], never on the sentence.
#[derive(Debug, Clone, PartialEq)]
pub struct Warning {
    /// What it is about.
    pub kind: WarningKind,
    /// The sentence shown to the user.
    pub message: String,
    /// The data the sentence was made from, where code acts on it (a
    /// conflicting constraint's index); `None` for a warning that only
    /// informs.
    pub subject: Option<WarningSubject>,
}

/// What a warning is about, typed: code that acts on a warning reads this,
/// never the sentence.
#[derive(Debug, Clone, PartialEq)]
pub enum WarningSubject {
    /// A hard constraint dropped because it contradicts kept ones.
    ConflictingConstraint {
        /// Its index in the constraints file.
        index: usize,
        /// The earlier constraints it contradicts, where they were found
        /// (empty: not determined).
        with: Vec<usize>,
        /// `‖b·X − d‖₂` in the report's units.
        residual: f64,
    },
}

impl Warning {
    /// A warning of `kind` saying `message`.
    pub fn new(kind: WarningKind, message: impl Into<String>) -> Warning {
        Warning {
            kind,
            message: message.into(),
            subject: None,
        }
    }

    /// The same warning, carrying the data it was made from.
    pub(crate) fn about(self, subject: WarningSubject) -> Warning {
        Warning {
            subject: Some(subject),
            ..self
        }
    }

    /// The stable code of its kind.
    pub fn code(&self) -> &'static str {
        self.kind.code()
    }
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl Serialize for Warning {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.message)
    }
}

impl From<&MeshWarning> for Warning {
    fn from(w: &MeshWarning) -> Warning {
        let kind = match w {
            MeshWarning::DegenerateFaces { .. } => WarningKind::DegenerateFaces,
            MeshWarning::NonManifoldEdge { .. } => WarningKind::NonManifoldEdge,
        };
        Warning::new(kind, w.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_distinct_kebab_words() {
        let codes: Vec<&str> = WarningKind::ALL.iter().map(|k| k.code()).collect();
        let mut unique = codes.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), codes.len());
        for c in codes {
            assert!(
                c.chars().all(|ch| ch.is_ascii_lowercase() || ch == '-'),
                "{c}"
            );
        }
    }
}
