//! One MUMPS instance on one rank, and the commands by which rank 0 keeps
//! the other ranks' instances in step with its own.
//!
//! Every method of [`Mumps`] is **collective**: each rank calls it with the
//! same arguments, rank 0 because its back end asked, the other ranks
//! because rank 0 sent them the [`Command`] first ([`serve`]). Only rank 0
//! holds the matrix, the ordering and the right-hand sides (centralised
//! input, `ICNTL(18) = 0`, and a centralised dense solution).

use std::collections::HashMap;
use std::ffi::OsStr;
use std::os::unix::ffi::OsStrExt;
use std::path::Path;

use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use serde::{Deserialize, Serialize};

use super::ffi::{self, Struc};
use super::ranks::{self, agree, gather_to_root};
use super::scratch::{self, ScratchDir};
use crate::limits::MemoryBudget;

/// What rank 0 tells the other ranks to do next.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) enum Command {
    /// Start instance `id` ([`Mumps::create`]).
    Create { id: u64, setup: Setup },
    /// Run `JOB = job` on instance `id` with these parameters.
    Job { id: u64, job: i32, params: Params },
    /// Check every rank's memory estimate against its budget (rank 0's,
    /// with its source; another rank uses the smaller of this and its own).
    CheckMemory { id: u64, budget: MemoryBudget },
    /// Check on every rank that a scratch directory can be made and
    /// written under this out-of-core directory (its path's bytes).
    ProbeDirectory { dir: Vec<u8> },
    /// Free instance `id` (`JOB = −2`) and its scratch directory.
    Destroy { id: u64 },
    /// Finalise MPI and exit with this code.
    Exit { code: u8 },
}

/// How an instance is started.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct Setup {
    /// `SYM`: 1 symmetric positive definite, 2 general symmetric.
    pub sym: i32,
    /// The directory under which each rank makes its own scratch directory
    /// for the out-of-core factor (`ICNTL(22) = 1`), as the bytes of its
    /// path (any name the system takes, UTF-8 or not); `None`: in core.
    pub out_of_core: Option<Vec<u8>>,
}

/// A path from its bytes (Unix).
pub(crate) fn path_of(bytes: &[u8]) -> &Path {
    Path::new(OsStr::from_bytes(bytes))
}

/// `ICNTL` and `CNTL` entries (1-based) set before a job.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub(crate) struct Params {
    pub icntl: Vec<(usize, i32)>,
    pub cntl: Vec<(usize, f64)>,
}

/// Per-rank figures after a job, read from `INFO` (MUMPS 5.5 user's guide,
/// §6.1), in the order of [`RankFigures::from_values`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct RankFigures {
    /// `INFO(24)`: estimated entries of this rank's share of the factor
    /// (after analysis).
    pub factor_entries_estimate: u64,
    /// `INFO(27)`: entries of this rank's share of the factor (after
    /// factorisation).
    pub factor_entries: u64,
    /// `INFO(15)`: estimated bytes of this rank's in-core factorisation.
    pub in_core_bytes_estimate: u64,
    /// `INFO(17)`: estimated bytes of this rank's out-of-core
    /// factorisation.
    pub out_of_core_bytes_estimate: u64,
    /// `INFO(22)`: bytes this rank's factorisation effectively used.
    pub peak_bytes: u64,
}

impl RankFigures {
    fn read(struc: &Struc) -> [u64; 5] {
        [
            ffi::count(struc.info(24)),
            ffi::count(struc.info(27)),
            megabytes(struc.info(15)),
            megabytes(struc.info(17)),
            megabytes(struc.info(22)),
        ]
    }

    fn from_values(v: &[u64]) -> RankFigures {
        RankFigures {
            factor_entries_estimate: v[0],
            factor_entries: v[1],
            in_core_bytes_estimate: v[2],
            out_of_core_bytes_estimate: v[3],
            peak_bytes: v[4],
        }
    }
}

/// MUMPS gives memory in millions of bytes ("MB" in its guide).
fn megabytes(value: i32) -> u64 {
    u64::from(value.max(0).unsigned_abs()) * 1_000_000
}

/// A failure of a collective step, the same on every rank.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Failure {
    /// MUMPS returned `INFOG(1) < 0`.
    Mumps { infog1: i32, infog2: i32 },
    /// A rank's memory estimate exceeds its budget (the message says whose).
    Memory(String),
    /// A step outside MUMPS failed on some rank (the message says where).
    Rank(String),
    /// The out-of-core directory cannot hold the factor on some rank (the
    /// message names the directory, the rank and the system's reason).
    Directory(String),
}

/// One MUMPS instance on this rank.
pub(crate) struct Mumps {
    pub struc: Struc,
    scratch: Option<ScratchDir>,
    /// Every rank's figures after the last job (rank 0 only; empty
    /// elsewhere).
    pub figures: Vec<RankFigures>,
}

impl Mumps {
    /// Collective: `JOB = −1` with `PAR = 1` (rank 0 works too), output
    /// silenced, and, out of core, this rank's scratch directory.
    /// This rank's scratch directory of the out-of-core factor, if any.
    pub(crate) fn scratch_directory(&self) -> Option<&Path> {
        self.scratch.as_ref().map(ScratchDir::path)
    }

    pub(crate) fn create(world: &SimpleCommunicator, setup: &Setup) -> Result<Mumps, Failure> {
        let job = scratch_job(world);
        let scratch = setup
            .out_of_core
            .as_ref()
            .map(|parent| ScratchDir::create(path_of(parent), job));
        let local = match &scratch {
            Some(Err(e)) => Err(e.clone()),
            _ => Ok(()),
        };
        agree(world, local).map_err(Failure::Directory)?;
        let scratch = scratch.and_then(Result::ok);
        let mut struc = Struc::zeroed();
        struc.0.comm_fortran = ffi::USE_COMM_WORLD;
        struc.0.par = 1;
        struc.0.sym = setup.sym;
        struc.call(-1);
        check(&struc)?;
        // Silence: no error, diagnostic or global output streams.
        for (i, v) in [(1, -1), (2, -1), (3, -1), (4, 0)] {
            struc.set_icntl(i, v);
        }
        if let Some(dir) = &scratch {
            struc.set_icntl(22, 1);
            // Checked to fit by ScratchDir::create.
            let _ = write_c_string(&mut struc.0.ooc_tmpdir, dir.bytes());
        }
        Ok(Mumps {
            struc,
            scratch,
            figures: Vec::new(),
        })
    }

    /// Collective: sets `params`, runs `job`, gathers every rank's figures
    /// to rank 0.
    pub fn job(
        &mut self,
        world: &SimpleCommunicator,
        job: i32,
        params: &Params,
    ) -> Result<(), Failure> {
        for &(i, v) in &params.icntl {
            self.struc.set_icntl(i, v);
        }
        for &(i, v) in &params.cntl {
            self.struc.set_cntl(i, v);
        }
        self.struc.call(job);
        let gathered = gather_to_root(world, &RankFigures::read(&self.struc));
        self.figures = gathered
            .iter()
            .map(|v| RankFigures::from_values(v))
            .collect();
        check(&self.struc)
    }

    /// Collective: each rank checks its own estimate of the factorisation's
    /// memory (out of core: what stays in memory) against its budget: rank
    /// 0's `budget`, or a rank's own when that is smaller; out of core,
    /// also its estimate of its share of the factor (`INFO(24)` entries)
    /// against the space free in its scratch directory.
    pub(crate) fn check_memory(
        &self,
        world: &SimpleCommunicator,
        budget: MemoryBudget,
    ) -> Result<(), Failure> {
        let own = MemoryBudget::default();
        let budget = if own.limit() < budget.limit() {
            own
        } else {
            budget
        };
        let (info, what) = if self.scratch.is_some() {
            (17, "its out-of-core factorisation (INFO(17))")
        } else {
            (15, "its in-core factorisation (INFO(15))")
        };
        // The budget is of the whole process: what it holds already (on
        // rank 0 the mesh, the problem and the matrix) comes on top of what
        // MUMPS will allocate.
        let resident = crate::limits::resident_bytes().unwrap_or(0);
        let estimate = megabytes(self.struc.info(info)).saturating_add(resident);
        let local = budget.check(estimate, || {
            format!(
                "MUMPS estimates that {what} would need {} on top of the {} this process holds; together",
                crate::limits::format_bytes(megabytes(self.struc.info(info))),
                crate::limits::format_bytes(resident)
            )
        });
        agree(world, local).map_err(Failure::Memory)?;
        match &self.scratch {
            // Out of core, this rank's share of the factor goes to disk.
            Some(dir) => {
                let needed = ffi::count(self.struc.info(24)).saturating_mul(8);
                let local = scratch::check_space(dir.path(), needed);
                agree(world, local).map_err(Failure::Directory)
            }
            None => Ok(()),
        }
    }

    /// Whether the factor is kept out of core.
    pub(crate) fn out_of_core(&self) -> bool {
        self.scratch.is_some()
    }

    /// Collective: `JOB = −2`, then the scratch directory goes.
    pub(crate) fn destroy(mut self) {
        self.struc.call(-2);
    }
}

/// `Err` for `INFOG(1) < 0` (the same on every rank).
fn check(struc: &Struc) -> Result<(), Failure> {
    match struc.infog(1) {
        e if e < 0 => Err(Failure::Mumps {
            infog1: e,
            infog2: struc.infog(2),
        }),
        _ => Ok(()),
    }
}

/// Copies `bytes` into a C `char` array with its terminating zero (`Err`
/// when they do not fit or hold a zero).
fn write_c_string(target: &mut [std::os::raw::c_char], bytes: &[u8]) -> Result<(), ()> {
    if bytes.len() >= target.len() || bytes.contains(&0) {
        return Err(());
    }
    for (t, &b) in target.iter_mut().zip(bytes) {
        *t = b as std::os::raw::c_char;
    }
    target[bytes.len()] = 0;
    Ok(())
}

/// What a rank other than 0 does for the whole run: carries out rank 0's
/// commands on its own instances until rank 0 says [`Command::Exit`], and
/// returns that exit code. A failed step needs no action here: the
/// collective step already told rank 0, which decides what comes next.
pub fn serve(world: &SimpleCommunicator) -> u8 {
    let mut instances: HashMap<u64, Mumps> = HashMap::new();
    loop {
        let mut bytes = Vec::new();
        ranks::broadcast_from_root(world, &mut bytes);
        let command: Command = match serde_json::from_slice(&bytes) {
            Ok(c) => c,
            // Rank 0 and this rank run the same binary: a command that does
            // not parse is a bug, and only an abort keeps everyone from
            // waiting.
            Err(e) => panic!("rank {} cannot read rank 0's command: {e}", world.rank()),
        };
        match command {
            Command::Create { id, setup } => {
                if let Ok(m) = Mumps::create(world, &setup) {
                    instances.insert(id, m);
                }
            }
            Command::Job { id, job, params } => {
                if let Some(m) = instances.get_mut(&id) {
                    let _ = m.job(world, job, &params);
                }
            }
            Command::CheckMemory { id, budget } => {
                if let Some(m) = instances.get(&id) {
                    let _ = m.check_memory(world, budget);
                }
            }
            Command::ProbeDirectory { dir } => {
                let _ = probe_directory(world, &dir);
            }
            Command::Destroy { id } => {
                if let Some(m) = instances.remove(&id) {
                    m.destroy();
                }
            }
            Command::Exit { code } => return code,
        }
    }
}

/// Collective: every rank makes a scratch directory under `dir` and writes
/// in it ([`scratch::probe`]); the first rank that cannot says why, on
/// every rank.
pub(crate) fn probe_directory(world: &SimpleCommunicator, dir: &[u8]) -> Result<(), Failure> {
    let local = scratch::probe(path_of(dir), scratch_job(world));
    agree(world, local).map_err(Failure::Directory)
}

/// Collective: this rank's place in the job whose scratch directories are
/// made now (one token, drawn by rank 0, names them all).
fn scratch_job(world: &SimpleCommunicator) -> scratch::Job {
    scratch::Job {
        token: ranks::shared_random(world),
        rank: world.rank(),
        ranks: world.size(),
    }
}

/// Rank 0: sends `command` to the other ranks (nothing to do alone).
pub(crate) fn send(world: &SimpleCommunicator, command: &Command) {
    if world.size() > 1 {
        let mut bytes = serde_json::to_vec(command).expect("a command serialises");
        ranks::broadcast_from_root(world, &mut bytes);
    }
}
