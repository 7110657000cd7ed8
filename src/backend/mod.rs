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
mod facts;
pub(crate) mod faer_kernel;
mod kinds;
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

pub use catalogue::FactorStorage;
pub use facts::{BackendFacts, BackendName, FactorKind};

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
