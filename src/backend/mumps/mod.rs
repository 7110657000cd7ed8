//! MUMPS (feature `mumps`): the multifrontal sparse direct solver, in
//! Debian's MPI build, behind the SPD seam ([`MumpsLlt`], `SYM = 1`) and
//! the `LDLᵀ` seam ([`MumpsLdlt`], `SYM = 2`), in one process or on many
//! under `mpirun` (docs/distributed.md).
//!
//! **Phases.** Analysis once (`JOB = 1`), a numeric factorisation per
//! matrix of the analysed pattern (`JOB = 2`: per weight of a sweep), and
//! one solve of all right-hand sides together (`JOB = 3`).
//!
//! **Ranks.** Rank 0 reads the inputs, assembles, and does everything but
//! the factorisation and the solves, which run on every rank; only rank 0
//! holds the matrix and the right-hand sides (centralised input,
//! `ICNTL(18) = 0`). The binary calls [`serve_if_worker`] first: on the
//! other ranks it carries out rank 0's MUMPS commands until rank 0 calls
//! [`end_ranks`] with its exit code, and every rank exits with that code.
//!
//! **Memory.** After the analysis every rank checks MUMPS's estimate of
//! its own share (`INFO(15)` in core, `INFO(17)` out of core: what stays
//! in memory) plus what the process already holds (its resident set)
//! against its budget; any refusal refuses the run on every
//! rank, before the factorisation.

mod cholesky;
mod driver;
mod ffi;
mod instance;
mod ldlt;
mod ranks;
mod scratch;
mod session;

pub use cholesky::MumpsLlt;
pub use ldlt::MumpsLdlt;
pub use ranks::launched_by_mpirun;
pub use scratch::remove_all as remove_scratch;

use instance::Failure;

use crate::backend::BackendFacts;
use crate::error::{NumericalError, ProblemError};

/// The name in errors and reports.
const NAME: &str = "mumps";

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

/// What a process launched by `mpirun` is, once its ranks agreed on how
/// the run starts ([`serve_if_worker`]).
#[derive(Debug)]
pub enum RankRole {
    /// Rank 0, or a process not launched by `mpirun`: go on with the
    /// command, unless some rank's start-up check failed (`Err`: the
    /// message of the lowest failing rank, naming it); either way end with
    /// [`end_ranks`].
    Lead(Result<(), String>),
    /// Any other rank, after serving rank 0's MUMPS commands until rank 0
    /// ended the run: exit with this code (rank 0's).
    Served(u8),
}

/// What the binary calls before anything else, with this process's own
/// start-up check (`start`: the environment it reads before any work, such
/// as a malformed memory budget). Launched by `mpirun`, it starts MPI and
/// makes every rank agree on `start` (a check that fails on rank 1 alone
/// fails the run on every rank, named by rank); on rank 0 it returns
/// [`RankRole::Lead`], on any other rank it serves rank 0's MUMPS commands
/// until rank 0 ends the run and returns [`RankRole::Served`] with rank 0's
/// exit code. Not launched by `mpirun`, it returns `Lead(start)` (MUMPS
/// then starts MPI as one rank when first used).
pub fn serve_if_worker(start: Result<(), String>) -> RankRole {
    if !launched_by_mpirun() {
        return RankRole::Lead(start);
    }
    let rt = ranks::runtime();
    if rt.size > 1 {
        ranks::abort_all_on_panic();
    }
    let start = ranks::agree(&rt.world(), start);
    if rt.rank == 0 {
        ranks::mark_served();
        return RankRole::Lead(start);
    }
    let code = instance::serve(&rt.world());
    ranks::finalize();
    RankRole::Served(code)
}

/// Checks that this process can drive MUMPS: not launched by `mpirun` (MUMPS
/// then runs as one rank), or rank 0 of ranks that serve it (every other
/// rank in [`serve_if_worker`]). Anything else is a usage error, refused
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

/// What rank 0 (or a lone process) calls last, once every MUMPS object is
/// dropped: tells the other ranks to exit with `exit_code`, then ends MPI.
/// Does nothing if MPI was never started.
pub fn end_ranks(exit_code: u8) {
    if !ranks::started() {
        return;
    }
    let rt = ranks::runtime();
    if rt.rank == 0 {
        let _turn = rt.serial();
        instance::send(&rt.world(), &instance::Command::Exit { code: exit_code });
    }
    ranks::finalize();
}

/// The number of ranks (starting MPI if needed).
pub fn ranks() -> usize {
    ranks::runtime().size as usize
}

/// A failure as the seams' error.
pub(crate) fn numerical(failure: Failure) -> NumericalError {
    NumericalError::Backend {
        backend: NAME.to_string(),
        message: failure_message(failure),
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

#[cfg(test)]
mod tests;
