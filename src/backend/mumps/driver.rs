//! Rank 0's handle on one MUMPS instance: each call sends the command to
//! the other ranks, then makes the same collective call itself, all under
//! the process-wide lock of [`super::ranks`].

use std::os::unix::ffi::OsStrExt;
use std::sync::atomic::{AtomicU64, Ordering};

use super::ffi::{DMUMPS_STRUC_C, Struc};
use super::instance::{Command, Failure, Mumps, Params, RankFigures, Setup, send};
use super::ranks::runtime;
use crate::limits::MemoryBudget;

/// Numbers instances so that the other ranks can tell them apart.
static NEXT_ID: AtomicU64 = AtomicU64::new(0);

/// A MUMPS instance driven from rank 0.
pub(crate) struct Driver {
    id: u64,
    /// `None` only while dropping.
    mumps: Option<Mumps>,
}

impl Driver {
    /// Starts an instance with `SYM = sym` on every rank, out of core under
    /// `out_of_core` when given.
    pub(crate) fn create(
        sym: i32,
        out_of_core: Option<&std::path::Path>,
    ) -> Result<Driver, Failure> {
        let rt = runtime();
        if rt.rank != 0 {
            return Err(Failure::Rank(
                "the MUMPS back end is driven from rank 0 only".into(),
            ));
        }
        let _turn = rt.serial();
        let world = rt.world();
        let id = NEXT_ID.fetch_add(1, Ordering::Relaxed);
        let setup = Setup {
            sym,
            out_of_core: out_of_core.map(|p| p.as_os_str().as_bytes().to_vec()),
        };
        send(
            &world,
            &Command::Create {
                id,
                setup: setup.clone(),
            },
        );
        let mumps = Mumps::create(&world, &setup)?;
        Ok(Driver {
            id,
            mumps: Some(mumps),
        })
    }

    fn mumps(&self) -> &Mumps {
        self.mumps.as_ref().expect("present until dropped")
    }

    /// Runs `job` with `params` on every rank; `host` first points rank 0's
    /// struct at the arrays of this job (matrix, ordering, right-hand sides),
    /// which must stay alive until the call returns.
    pub fn job(
        &mut self,
        job: i32,
        params: &Params,
        host: impl FnOnce(&mut DMUMPS_STRUC_C),
    ) -> Result<(), Failure> {
        let rt = runtime();
        let _turn = rt.serial();
        let world = rt.world();
        send(
            &world,
            &Command::Job {
                id: self.id,
                job,
                params: params.clone(),
            },
        );
        let mumps = self.mumps.as_mut().expect("present until dropped");
        host(&mut mumps.struc.0);
        mumps.job(&world, job, params)
    }

    /// Every rank checks its memory estimate against `budget` (or its own
    /// smaller budget).
    pub(crate) fn check_memory(&self, budget: MemoryBudget) -> Result<(), Failure> {
        let rt = runtime();
        let _turn = rt.serial();
        let world = rt.world();
        send(
            &world,
            &Command::CheckMemory {
                id: self.id,
                budget,
            },
        );
        self.mumps().check_memory(&world, budget)
    }

    /// Rank 0's struct (`INFOG`, the null-pivot list).
    pub(crate) fn struc(&self) -> &Struc {
        &self.mumps().struc
    }

    /// Every rank's figures after the last job.
    pub(crate) fn figures(&self) -> &[RankFigures] {
        &self.mumps().figures
    }

    /// Whether the factor is kept out of core.
    pub(crate) fn out_of_core(&self) -> bool {
        self.mumps().out_of_core()
    }

    /// Rank 0's scratch directory of the out-of-core factor, if any.
    pub(crate) fn scratch_directory(&self) -> Option<&std::path::Path> {
        self.mumps().scratch_directory()
    }
}

/// Every rank checks that it can keep an out-of-core factor under `dir`
/// ([`super::instance::probe_directory`]).
pub(crate) fn probe_out_of_core(dir: &std::path::Path) -> Result<(), Failure> {
    let rt = runtime();
    if rt.rank != 0 {
        return Err(Failure::Rank(
            "the MUMPS back end is driven from rank 0 only".into(),
        ));
    }
    let _turn = rt.serial();
    let world = rt.world();
    let dir = dir.as_os_str().as_bytes().to_vec();
    send(&world, &Command::ProbeDirectory { dir: dir.clone() });
    super::instance::probe_directory(&world, &dir)
}

impl Drop for Driver {
    fn drop(&mut self) {
        let rt = runtime();
        let _turn = rt.serial();
        let world = rt.world();
        send(&world, &Command::Destroy { id: self.id });
        if let Some(mumps) = self.mumps.take() {
            mumps.destroy();
        }
    }
}
