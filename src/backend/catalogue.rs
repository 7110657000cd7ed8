//! The catalogue of the crate's own back ends: [`SpdKind`] and
//! [`LdltKind`] (with [`crate::backend::qr::QrKind`]) name the built-in
//! back ends that the CLI, Python and the editor parse from words, and
//! the catalogue makes them ([`SpdKind::backend`], [`LdltKind::backend`],
//! [`QrKind::backend`]), with the settings only a built-in has
//! ([`FactorStorage`]: MUMPS's out-of-core directory). The kinds
//! themselves are defined below the seams (`backend/kinds.rs`), so that
//! the back ends name themselves by them; the catalogue sits above the
//! seams and no back end imports it. A back end from outside this crate
//! is not in the catalogue: it implements the seam's traits
//! ([`crate::backend::spd::SpdBackend`], [`crate::backend::ldlt::LdltBackend`],
//! [`crate::backend::qr::QrBackend`]) and names itself
//! (docs/backends.md).

use std::path::PathBuf;
use std::sync::Arc;

pub use crate::backend::kinds::{LdltKind, SpdKind};

use crate::backend::kinds::QrKind;
use crate::backend::ldlt::{FaerLdlt, LdltBackend};
#[cfg(feature = "suitesparse")]
use crate::backend::qr::Spqr;
use crate::backend::qr::{DenseHouseholder, QrBackend, SparseGivens};
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

impl SpdKind {
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

impl LdltKind {
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

impl QrKind {
    /// The back end.
    ///
    /// Errors: [`ProblemError::InvalidArgument`] for `Spqr` in a build
    /// without the `suitesparse` feature (the message says how to enable
    /// it).
    pub fn backend(self) -> Result<Arc<dyn QrBackend>, ProblemError> {
        match self {
            QrKind::DenseHouseholder => Ok(Arc::new(DenseHouseholder)),
            QrKind::SparseGivens => Ok(Arc::new(SparseGivens::default())),
            #[cfg(feature = "suitesparse")]
            QrKind::Spqr => Ok(Arc::new(Spqr)),
            #[cfg(not(feature = "suitesparse"))]
            QrKind::Spqr => Err(ProblemError::InvalidArgument {
                message: "the QR back end 'spqr' (SuiteSparseQR) is not in this build: rebuild with `--features suitesparse` (needs the system packages libsuitesparse-dev and libclang-dev)".into(),
            }),
        }
    }
}
