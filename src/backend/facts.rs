//! What every back end tells the report: its name ([`BackendName`]), the
//! factorisation it ran ([`FactorKind`]) and its own facts
//! ([`BackendFacts`]). A leaf of [`crate::backend`]: the seams and the
//! back ends under them import it, it imports none of them.

use std::borrow::Cow;

/// A back end's name, as it appears in reports, `compare` rows, CSVs and
/// plots: a built-in's word (`faer-auto`, `mumps-ldlt`, ...) or whatever
/// name a back end from outside gives itself. Names are compared as
/// strings; a name is the back end's identity in every table, so two back
/// ends that differ in anything that changes a computed number must not
/// share one (docs/backends.md §2).
pub type BackendName = Cow<'static, str>;

/// What a back end reports of one factorisation beyond the generic
/// record (sizes, timings): a section of the report under its own key
/// (`mumps` for MUMPS: ranks, per-rank entries and peaks, ordering,
/// out-of-core), holding key → value pairs in the back end's own terms.
/// The one channel for such facts: the formulations and the solver pass
/// it through without reading it.
#[derive(Clone, Debug, PartialEq)]
pub struct BackendFacts {
    /// The report key the facts appear under.
    pub section: BackendName,
    /// The facts, in the order the back end gives them (and the report
    /// keeps).
    pub values: Vec<(BackendName, serde_json::Value)>,
}

impl BackendFacts {
    /// No facts yet, under `section`.
    pub fn new(section: impl Into<BackendName>) -> Self {
        BackendFacts {
            section: section.into(),
            values: Vec::new(),
        }
    }

    /// These facts and `key` → `value`.
    pub fn with(
        mut self,
        key: impl Into<BackendName>,
        value: impl Into<serde_json::Value>,
    ) -> Self {
        self.values.push((key.into(), value.into()));
        self
    }

    /// The value of `key`, if given.
    pub fn get(&self, key: &str) -> Option<&serde_json::Value> {
        self.values.iter().find(|(k, _)| k == key).map(|(_, v)| v)
    }
}

/// The facts as a JSON object (their section is the key it is stored
/// under, not part of it).
impl serde::Serialize for BackendFacts {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = s.serialize_map(Some(self.values.len()))?;
        for (key, value) in &self.values {
            map.serialize_entry(key, value)?;
        }
        map.end()
    }
}

/// The factorisation a formulation ran, for the report: an SPD back end's
/// Cholesky, or (the KKT method) an `LDLᵀ` back end's factorisation, each
/// by its back end's name. Serialised as the name (`faer-auto`,
/// `faer-ldlt-simplicial`, or an outside back end's own).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum FactorKind {
    /// `LLᵀ` by the back end of this name.
    Cholesky(BackendName),
    /// `LDLᵀ` by the back end of this name.
    Ldlt(BackendName),
}

impl FactorKind {
    /// The word in reports: the back end's name.
    pub fn name(&self) -> &str {
        match self {
            FactorKind::Cholesky(name) | FactorKind::Ldlt(name) => name,
        }
    }
}

impl std::fmt::Display for FactorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl serde::Serialize for FactorKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}
