//! Linear-algebra back ends behind the traits the formulations are written
//! against: [`qr::QrBackend`] (QR of `Bᵀ` with rank detection),
//! [`spd::SpdBackend`] (sparse Cholesky) and [`ldlt::LdltBackend`] (sparse
//! symmetric indefinite `LDLᵀ` in a given order), the last two with their
//! symbolic and numeric phases kept apart; and [`FactorKind`], which of the
//! two factorisations a formulation ran.

pub(crate) mod faer_kernel;
pub mod ldlt;
#[cfg(feature = "mumps")]
pub mod mumps;
pub mod qr;
pub mod spd;
#[cfg(feature = "suitesparse")]
mod suitesparse;

use std::path::PathBuf;

use ldlt::LdltKind;
use spd::SpdKind;

/// Where a factor is kept while it is used.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub enum FactorStorage {
    /// In memory (every back end).
    #[default]
    InCore,
    /// In files under this directory, which must exist (MUMPS only,
    /// `ICNTL(22) = 1`): each rank makes its own subdirectory there and
    /// removes it with its files when the factor is dropped, also after an
    /// error. Only what MUMPS keeps in memory counts against the budget.
    OutOfCore(PathBuf),
}

impl FactorStorage {
    /// The directory, out of core.
    pub fn directory(&self) -> Option<&std::path::Path> {
        match self {
            FactorStorage::InCore => None,
            FactorStorage::OutOfCore(dir) => Some(dir),
        }
    }

    /// Refuses out-of-core storage for the back end named `backend`, which
    /// is not MUMPS (the only one that keeps a factor in files).
    pub(crate) fn refuse_out_of_core(
        &self,
        backend: &str,
    ) -> Result<(), crate::error::ProblemError> {
        match self.directory() {
            Some(_) => Err(crate::error::ProblemError::InvalidArgument {
                message: format!(
                    "out-of-core storage of the factor needs the back end 'mumps', not '{backend}'"
                ),
            }),
            None => Ok(()),
        }
    }

    /// Refuses an out-of-core directory that is not an existing directory
    /// (bad input, before any work; each rank still reports its own failure
    /// to make its subdirectory there).
    pub fn check(&self) -> Result<(), crate::error::ProblemError> {
        match self.directory() {
            Some(dir) if !dir.is_dir() => Err(crate::error::ProblemError::InvalidArgument {
                message: format!(
                    "the out-of-core directory {} does not exist or is not a directory",
                    dir.display()
                ),
            }),
            _ => Ok(()),
        }
    }
}

/// What a MUMPS factorisation reports of its ranks (the report's `mumps`
/// object; its keys are the field names).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct MumpsFacts {
    /// The number of MPI ranks that factored.
    pub ranks: usize,
    /// Entries of each rank's share of the factor (`INFO(27)`), rank by
    /// rank.
    pub factor_entries_per_rank: Vec<u64>,
    /// Bytes each rank's factorisation effectively used (`INFO(22)`, which
    /// MUMPS counts in millions of bytes), rank by rank.
    pub peak_bytes_per_rank: Vec<u64>,
    /// The fill-reducing ordering MUMPS used (`INFOG(7)`): `given` when the
    /// caller fixed the order (KKT).
    pub ordering: String,
    /// Whether the factor was kept out of core.
    pub out_of_core: bool,
}

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
                    SpdKind::FaerAuto
                        | SpdKind::FaerSimplicial
                        | SpdKind::FaerSupernodal
                        | SpdKind::Mumps
                ),
                "{spd}"
            );
        }
    }
}
