//! Linear-algebra back ends behind the traits the formulations are written
//! against: [`qr::QrBackend`] (QR of `Bᵀ` with rank detection),
//! [`spd::SpdBackend`] (sparse Cholesky) and [`ldlt::LdltBackend`] (sparse
//! symmetric indefinite `LDLᵀ` in a given order), the last two with their
//! symbolic and numeric phases kept apart; and [`FactorKind`], which of the
//! two factorisations a formulation ran.

pub mod ldlt;
pub mod qr;
pub mod spd;
#[cfg(feature = "suitesparse")]
mod suitesparse;

use ldlt::LdltKind;
use spd::SpdKind;

/// The factorisation a formulation ran, for the report: an SPD back end's
/// Cholesky, or (the KKT method) an `LDLᵀ` back end's factorisation.
/// Serialised as its kind's word (`faer-auto`, `faer-ldlt-simplicial`, ...).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FactorKind {
    /// `LLᵀ` by this back end.
    Cholesky(SpdKind),
    /// `LDLᵀ` by this back end.
    Ldlt(LdltKind),
}

impl FactorKind {
    /// The word in reports.
    pub fn name(self) -> &'static str {
        match self {
            FactorKind::Cholesky(kind) => kind.name(),
            FactorKind::Ldlt(kind) => kind.name(),
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

    /// Scripts read these words from reports: they must not change.
    #[test]
    fn factor_kinds_serialise_as_the_report_words() {
        let words: Vec<String> = [
            FactorKind::Cholesky(SpdKind::FaerAuto),
            FactorKind::Ldlt(LdltKind::FaerAuto),
            FactorKind::Ldlt(LdltKind::FaerSimplicial),
            FactorKind::Ldlt(LdltKind::FaerSupernodal),
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
                "faer-ldlt-supernodal"
            ]
        );
        for spd in SpdKind::ALL {
            let ldlt = LdltKind::for_spd(spd);
            assert_eq!(
                ldlt.is_some(),
                matches!(
                    spd,
                    SpdKind::FaerAuto | SpdKind::FaerSimplicial | SpdKind::FaerSupernodal
                ),
                "{spd}"
            );
        }
    }
}
