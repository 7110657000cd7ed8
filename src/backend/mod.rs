//! Linear-algebra back ends behind the traits the formulations are written
//! against: [`qr::QrBackend`] (QR of `Bᵀ` with rank detection),
//! [`spd::SpdBackend`] (sparse Cholesky) and [`ldlt::LdltBackend`] (sparse
//! symmetric indefinite `LDLᵀ` in a given order), the last two with their
//! symbolic and numeric phases kept apart; the [`catalogue`] of the
//! crate's own back ends; and what every back end tells the report: its
//! name ([`BackendName`], [`FactorKind`]) and its own facts
//! ([`BackendFacts`]). The contract a back end must meet, the crate's own
//! or one brought from outside, is docs/backends.md.

pub mod catalogue;
pub(crate) mod faer_kernel;
pub mod ldlt;
#[cfg(feature = "mumps")]
pub mod mumps;
#[cfg(any(feature = "suitesparse", feature = "mumps"))]
pub(crate) mod openblas;
pub mod ordering;
pub mod qr;
pub mod spd;
#[cfg(feature = "suitesparse")]
mod suitesparse;

use std::borrow::Cow;

pub use catalogue::FactorStorage;

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

#[cfg(test)]
mod tests {
    use super::*;
    use catalogue::{LdltKind, SpdKind};

    /// Scripts read these words from reports: they must not change.
    #[test]
    fn factor_kinds_serialise_as_the_report_words() {
        let words: Vec<String> = [
            FactorKind::Cholesky(SpdKind::FaerAuto.name().into()),
            FactorKind::Ldlt(LdltKind::FaerAuto.name().into()),
            FactorKind::Ldlt(LdltKind::FaerSimplicial.name().into()),
            FactorKind::Ldlt(LdltKind::FaerSupernodal.name().into()),
            FactorKind::Cholesky(String::from("my-cg").into()),
        ]
        .iter()
        .map(|k| {
            serde_json::to_value(k)
                .unwrap()
                .as_str()
                .unwrap()
                .to_string()
        })
        .collect();
        assert_eq!(
            words,
            [
                "faer-auto",
                "faer-ldlt-auto",
                "faer-ldlt-simplicial",
                "faer-ldlt-supernodal",
                "my-cg"
            ]
        );
        for spd in SpdKind::ALL {
            let ldlt = LdltKind::for_spd(spd);
            assert_eq!(
                ldlt.is_some(),
                matches!(
                    spd,
                    SpdKind::FaerAuto
                        | SpdKind::FaerSimplicial
                        | SpdKind::FaerSupernodal
                        | SpdKind::Mumps
                ),
                "{spd}"
            );
        }
    }

    #[test]
    fn backend_facts_keep_their_order() {
        let facts = BackendFacts::new("x").with("b", 1).with("a", vec![2, 3]);
        assert_eq!(facts.section, "x");
        assert_eq!(facts.get("a"), Some(&serde_json::json!([2, 3])));
        assert_eq!(
            serde_json::to_string(&facts).unwrap(),
            r#"{"b":1,"a":[2,3]}"#
        );
    }
}
