//! The catalogue of the crate's own back ends: [`SpdKind`] and
//! [`LdltKind`] (with [`crate::backend::qr::QrKind`]) name the built-in
//! back ends that the CLI, Python and the editor parse from words, and
//! make them, with the settings only a built-in has ([`FactorStorage`]:
//! MUMPS's out-of-core directory). A back end from outside this crate is
//! not in the catalogue: it implements the seam's traits
//! ([`crate::backend::spd::SpdBackend`], [`crate::backend::ldlt::LdltBackend`],
//! [`crate::backend::qr::QrBackend`]) and names itself
//! (docs/backends.md).

use std::path::PathBuf;
use std::sync::Arc;

use crate::backend::ldlt::{FaerLdlt, LdltBackend};
use crate::backend::spd::{FaerLlt, NalgebraCsc, SpdBackend};
use crate::error::ProblemError;

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

/// An SPD back end, as a typed choice ([`SpdKind::backend`] makes it;
/// `FromStr` reads the CLI's and Python's names, [`SpdKind::name`] gives
/// them back).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SpdKind {
    /// faer's supernodal Cholesky.
    FaerSupernodal,
    /// faer's simplicial (column by column) Cholesky.
    FaerSimplicial,
    /// faer's choice between the two, from the symbolic factor's density.
    FaerAuto,
    /// nalgebra-sparse's CSC Cholesky.
    Nalgebra,
    /// SuiteSparse CHOLMOD (cargo feature `suitesparse`).
    Cholmod,
    /// MUMPS's multifrontal Cholesky, on one rank or many (cargo feature
    /// `mumps`).
    Mumps,
}

impl SpdKind {
    /// Every kind, in the order they are listed to users.
    pub const ALL: [SpdKind; 6] = [
        SpdKind::FaerSupernodal,
        SpdKind::FaerSimplicial,
        SpdKind::FaerAuto,
        SpdKind::Nalgebra,
        SpdKind::Cholmod,
        SpdKind::Mumps,
    ];

    /// The name the CLI and Python use.
    pub fn name(self) -> &'static str {
        match self {
            SpdKind::FaerSupernodal => "faer-supernodal",
            SpdKind::FaerSimplicial => "faer-simplicial",
            SpdKind::FaerAuto => "faer-auto",
            SpdKind::Nalgebra => "nalgebra",
            SpdKind::Cholmod => "cholmod",
            SpdKind::Mumps => "mumps",
        }
    }

    /// Whether this build has the back end (`Cholmod` needs the cargo
    /// feature `suitesparse`, `Mumps` the feature `mumps`).
    pub fn in_this_build(self) -> bool {
        let missing = (self == SpdKind::Cholmod && !cfg!(feature = "suitesparse"))
            || (self == SpdKind::Mumps && !cfg!(feature = "mumps"));
        !missing
    }

    /// The kinds of this build, in [`SpdKind::ALL`]'s order.
    pub fn available() -> Vec<SpdKind> {
        SpdKind::ALL
            .into_iter()
            .filter(|k| k.in_this_build())
            .collect()
    }

    /// The back end.
    ///
    /// Errors: [`ProblemError::InvalidArgument`] for `Cholmod` in a build
    /// without the `suitesparse` feature (the message says how to enable
    /// it).
    pub fn backend(self) -> Result<Arc<dyn SpdBackend>, ProblemError> {
        self.backend_with(&FactorStorage::InCore)
    }

    /// The back end keeping its factor in `storage`.
    ///
    /// Errors: as [`SpdKind::backend`], and
    /// [`ProblemError::InvalidArgument`] for out-of-core storage with any
    /// back end but `Mumps`.
    pub(crate) fn backend_with(
        self,
        storage: &FactorStorage,
    ) -> Result<Arc<dyn SpdBackend>, ProblemError> {
        if self != SpdKind::Mumps {
            storage.refuse_out_of_core(self.name())?;
        }
        match self {
            SpdKind::FaerSupernodal => Ok(Arc::new(FaerLlt::supernodal())),
            SpdKind::FaerSimplicial => Ok(Arc::new(FaerLlt::simplicial())),
            SpdKind::FaerAuto => Ok(Arc::new(FaerLlt::auto())),
            SpdKind::Nalgebra => Ok(Arc::new(NalgebraCsc)),
            #[cfg(feature = "suitesparse")]
            SpdKind::Cholmod => Ok(Arc::new(crate::backend::spd::Cholmod)),
            #[cfg(not(feature = "suitesparse"))]
            SpdKind::Cholmod => Err(ProblemError::InvalidArgument {
                message: "the SPD back end 'cholmod' (SuiteSparse CHOLMOD) is not in this build: rebuild with `--features suitesparse` (needs the system packages libsuitesparse-dev and libclang-dev)".into(),
            }),
            #[cfg(feature = "mumps")]
            SpdKind::Mumps => Ok(Arc::new(crate::backend::mumps::MumpsLlt::new(
                storage.directory().map(std::path::Path::to_path_buf),
            )?)),
            #[cfg(not(feature = "mumps"))]
            SpdKind::Mumps => Err(ProblemError::InvalidArgument {
                message: MUMPS_MISSING.into(),
            }),
        }
    }
}

/// Why `mumps` is refused by a build without it.
#[cfg(not(feature = "mumps"))]
pub(crate) const MUMPS_MISSING: &str = "the back end 'mumps' (MUMPS over MPI) is not in this build: rebuild with `--features mumps` (needs the system packages libmumps-ptscotch-dev, libmumps-headers-dev, libopenmpi-dev, openmpi-bin and libclang-dev)";

impl crate::choice::Word for SpdKind {
    const WHAT: &'static str = "SPD back end";
    fn all() -> &'static [Self] {
        &SpdKind::ALL
    }
    fn name(self) -> &'static str {
        SpdKind::name(self)
    }
    fn listed() -> Vec<Self> {
        SpdKind::available()
    }
}

crate::choice::word_traits!(SpdKind);

/// An `LDLᵀ` back end, as a typed choice ([`LdltKind::backend`] makes
/// it); serialised in reports as its word.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum LdltKind {
    /// faer's choice between the two below, from the symbolic factor's
    /// density.
    #[default]
    FaerAuto,
    /// faer's simplicial (column by column) `LDLᵀ`.
    FaerSimplicial,
    /// faer's supernodal `LDLᵀ` (dense blocks of columns).
    FaerSupernodal,
    /// MUMPS's multifrontal `LDLᵀ` in the given order, on one rank or many
    /// (cargo feature `mumps`).
    Mumps,
}

impl LdltKind {
    /// Every kind, in the order they are listed to users.
    pub const ALL: [LdltKind; 4] = [
        LdltKind::FaerAuto,
        LdltKind::FaerSimplicial,
        LdltKind::FaerSupernodal,
        LdltKind::Mumps,
    ];

    /// The word in reports.
    pub fn name(self) -> &'static str {
        match self {
            LdltKind::FaerAuto => "faer-ldlt-auto",
            LdltKind::FaerSimplicial => "faer-ldlt-simplicial",
            LdltKind::FaerSupernodal => "faer-ldlt-supernodal",
            LdltKind::Mumps => "mumps-ldlt",
        }
    }

    /// The `LDLᵀ` variant an SPD back-end choice selects (the CLI's and
    /// Python's `spd` for the KKT method): faer's automatic, simplicial or
    /// supernodal factorisation for the faer kinds; `None` for the others,
    /// which have no `LDLᵀ`.
    pub fn for_spd(spd: crate::backend::spd::SpdKind) -> Option<LdltKind> {
        use crate::backend::spd::SpdKind;
        match spd {
            SpdKind::FaerAuto => Some(LdltKind::FaerAuto),
            SpdKind::FaerSimplicial => Some(LdltKind::FaerSimplicial),
            SpdKind::FaerSupernodal => Some(LdltKind::FaerSupernodal),
            SpdKind::Mumps => Some(LdltKind::Mumps),
            SpdKind::Nalgebra | SpdKind::Cholmod => None,
        }
    }

    /// Whether this build has the back end (`Mumps` needs the cargo
    /// feature `mumps`).
    pub(crate) fn in_this_build(self) -> bool {
        self != LdltKind::Mumps || cfg!(feature = "mumps")
    }

    /// The back end, keeping its factor in core.
    ///
    /// Errors: [`ProblemError::InvalidArgument`] for `Mumps` in a build
    /// without the feature `mumps`.
    pub fn backend(self) -> Result<Arc<dyn LdltBackend>, ProblemError> {
        self.backend_with(&FactorStorage::InCore)
    }

    /// The back end keeping its factor in `storage` (out of core: `Mumps`
    /// only).
    pub(crate) fn backend_with(
        self,
        storage: &FactorStorage,
    ) -> Result<Arc<dyn LdltBackend>, ProblemError> {
        match self {
            #[cfg(feature = "mumps")]
            LdltKind::Mumps => Ok(Arc::new(crate::backend::mumps::MumpsLdlt::new(
                storage.directory().map(std::path::Path::to_path_buf),
            )?)),
            #[cfg(not(feature = "mumps"))]
            LdltKind::Mumps => Err(ProblemError::InvalidArgument {
                message: MUMPS_MISSING.into(),
            }),
            _ => {
                storage.refuse_out_of_core(self.name())?;
                Ok(Arc::new(FaerLdlt::new(self)))
            }
        }
    }
}

impl crate::choice::Word for LdltKind {
    const WHAT: &'static str = "LDLT back end";
    fn all() -> &'static [Self] {
        &LdltKind::ALL
    }
    fn name(self) -> &'static str {
        LdltKind::name(self)
    }
}

crate::choice::word_traits!(LdltKind);
