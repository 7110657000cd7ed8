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
mod shared;

pub use cholesky::MumpsLlt;
pub use ldlt::MumpsLdlt;
pub(crate) use ranks::launched_by_mpirun;
pub use scratch::remove_all as remove_scratch;
pub use shared::MumpsFacts;
pub(crate) use shared::check_driving_rank;

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

#[cfg(test)]
mod tests;
