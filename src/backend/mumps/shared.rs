//! What the MUMPS back ends share ([`MumpsLlt`](super::MumpsLlt),
//! [`MumpsLdlt`](super::MumpsLdlt) and their session): the name, the facts
//! a factorisation reports, MUMPS's failures in words and as the seams'
//! errors, and the checks before any work (the driving rank, the
//! out-of-core directory). Below them and above the MPI plumbing
//! (`driver`, `instance`, `ranks`); [`crate::backend::mumps`] re-exports
//! [`MumpsFacts`].

use super::driver;
use super::instance::Failure;
use super::ranks::{self, launched_by_mpirun};
use crate::backend::BackendFacts;
use crate::error::{NumericalError, ProblemError};

/// The name in errors and reports.
pub(super) const NAME: &str = "mumps";

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

impl MumpsFacts {
    /// The facts as the report's `mumps` section, keys in the order of the
    /// fields.
    pub(crate) fn to_backend_facts(&self) -> BackendFacts {
        BackendFacts::new(NAME)
            .with("ranks", self.ranks)
            .with(
                "factor_entries_per_rank",
                self.factor_entries_per_rank.clone(),
            )
            .with("peak_bytes_per_rank", self.peak_bytes_per_rank.clone())
            .with("ordering", self.ordering.clone())
            .with("out_of_core", self.out_of_core)
    }
}

/// Checks that this process can drive MUMPS: not launched by `mpirun` (MUMPS
/// then runs as one rank), or rank 0 of ranks that serve it (every other
/// rank in [`serve_if_worker`](super::serve_if_worker)). Anything else is a usage error, refused
/// before any collective call (which would wait for ranks that never
/// answer): a rank other than 0, or rank 0 of several ranks that do not
/// serve it (the Python module under `mpirun -np 2`, for instance).
pub(crate) fn check_driving_rank() -> Result<(), ProblemError> {
    if !launched_by_mpirun() {
        return Ok(());
    }
    let rt = ranks::runtime();
    let (rank, size) = (rt.rank, rt.size);
    let message = if rank != 0 {
        format!(
            "the MUMPS back end is driven from rank 0 only, and this process is rank {rank} of {size} under mpirun: every other rank serves rank 0's commands (serve_if_worker, as the lse-deform binary does); run this program on one rank, or drive MUMPS from the lse-deform binary under mpirun"
        )
    } else if size > 1 && !ranks::served() {
        format!(
            "this process is rank 0 of {size} under mpirun, but the other ranks do not serve its MUMPS commands (only a program that calls serve_if_worker on every rank, such as the lse-deform binary, can): run this program on one rank"
        )
    } else {
        return Ok(());
    };
    Err(ProblemError::InvalidArgument { message })
}

/// A failure as the seams' error: an allocation MUMPS could not make
/// ([`allocation_refused`]) is [`NumericalError::OutOfMemory`], a refusal
/// for size as an [`crate::Error`]; any other is
/// [`NumericalError::Backend`] in MUMPS's words.
pub(crate) fn numerical(failure: Failure) -> NumericalError {
    if let Some(what) = allocation_refused(&failure) {
        return NumericalError::out_of_memory(NAME, &what);
    }
    NumericalError::Backend {
        backend: NAME.to_string(),
        message: failure_message(failure),
    }
}

/// What MUMPS could not allocate, when `failure` is one of its allocation
/// failures: `INFOG(1)` = −5 or −7 (the analysis) or −13 (any phase), with
/// the size asked in `INFOG(2)` (entries, or millions of them when
/// negative; user's guide, §8). `None` for every other failure.
pub(crate) fn allocation_refused(failure: &Failure) -> Option<String> {
    match *failure {
        Failure::Mumps { infog1, infog2 } if matches!(infog1, -5 | -7 | -13) => Some(format!(
            "its workspace ({} asked) [INFOG(1) = {infog1}]",
            if infog2 < 0 {
                format!("{} million entries", -(infog2 as i64))
            } else {
                format!("{infog2} entries")
            }
        )),
        _ => None,
    }
}

/// A failure in words (MUMPS's code with its meaning, or the rank's
/// message).
pub(crate) fn failure_message(failure: Failure) -> String {
    match failure {
        Failure::Mumps { infog1, infog2 } => describe(infog1, infog2),
        Failure::Memory(m) | Failure::Rank(m) | Failure::Directory(m) => m,
    }
}

/// A refused memory check as the usual refusal; a directory that cannot
/// hold the factor as bad input.
pub(crate) fn too_large(failure: Failure, matrix: &str) -> ProblemError {
    let detail = match failure {
        Failure::Directory(message) => return ProblemError::InvalidArgument { message },
        Failure::Memory(m) | Failure::Rank(m) => m,
        Failure::Mumps { infog1, infog2 } => describe(infog1, infog2),
    };
    ProblemError::TooLarge {
        detail: format!("factoring {matrix}: {detail}"),
    }
}

/// Checks, on every rank, that an out-of-core factor can be kept under
/// `dir`: bad input (naming the directory, the rank and the system's
/// reason) when a rank cannot make and write its scratch directory there.
pub(crate) fn check_out_of_core(dir: Option<&std::path::Path>) -> Result<(), ProblemError> {
    match dir {
        Some(dir) => driver::probe_out_of_core(dir).map_err(|f| ProblemError::InvalidArgument {
            message: match f {
                Failure::Mumps { infog1, infog2 } => describe(infog1, infog2),
                Failure::Memory(m) | Failure::Rank(m) | Failure::Directory(m) => m,
            },
        }),
        None => Ok(()),
    }
}

/// MUMPS's error codes in words (user's guide, §8), with the code.
fn describe(infog1: i32, infog2: i32) -> String {
    let what = match infog1 {
        -5 | -7 | -13 => format!("could not allocate memory ({infog2} entries or MB asked)"),
        -8 | -9 | -11 | -14 | -15 | -17 | -20 => {
            "its workspace was too small even after relaxing ICNTL(14) three times".to_string()
        }
        -10 => "the matrix is numerically singular".to_string(),
        -40 => "the matrix is not positive definite (a pivot that is not positive in the Cholesky factorisation)".to_string(),
        -16 => format!("the order {infog2} is out of range"),
        -90 => format!("out-of-core: a file of the factor could not be written or read (system error {infog2})"),
        e if (-79..=-70).contains(&e) => format!("out-of-core: file error (INFOG(2) = {infog2})"),
        _ => format!("error (INFOG(2) = {infog2})"),
    };
    format!("MUMPS {what} [INFOG(1) = {infog1}]")
}
