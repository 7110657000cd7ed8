//! The MPI processes ("ranks") a MUMPS factorisation runs on, and the few
//! collective steps that keep them in step.
//!
//! MPI is started once per process, on first use ([`runtime`]): by the
//! binary at start-up when `mpirun` launched it ([`launched_by_mpirun`]),
//! otherwise lazily by the first MUMPS call, as a singleton (one rank).
//! Every call into MUMPS is collective, so the whole conversation with the
//! other ranks (a command, then the call) is made under one process-wide
//! lock ([`Runtime::serial`]): threads of rank 0 (a parallel weight sweep,
//! parallel tests) take turns, and the ranks see the calls in one order.
//!
//! **Agreement on failure.** A step that can fail on one rank alone (a
//! scratch directory, a rank's memory budget) ends with [`agree`]: every
//! rank learns whether any rank failed and the first failing rank's
//! message, so that all of them return the same error; none is left
//! waiting in a collective call that another has abandoned. MUMPS's own
//! errors need no such step: `INFOG(1)` is the same on every rank.

use std::sync::atomic::{AtomicBool, Ordering as AtomicOrdering};
use std::sync::{Mutex, MutexGuard, OnceLock};
use std::time::Duration;

use mpi::collective::SystemOperation;
use mpi::environment::Universe;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// Environment variables by which `mpirun` (Open MPI, MPICH's Hydra, PMIx)
/// tells a process that it is one rank of a job.
const LAUNCHER_VARIABLES: [&str; 4] = [
    "OMPI_COMM_WORLD_SIZE",
    "PMIX_RANK",
    "PMI_SIZE",
    "MPI_LOCALNRANKS",
];

/// How long a waiting rank sleeps between two tests of the next command
/// (rank 0 may be reading a mesh for minutes; a busy wait would take a core
/// from it on a small machine).
const POLL_INTERVAL: Duration = Duration::from_millis(1);

/// Whether a launcher such as `mpirun` started this process.
pub(crate) fn launched_by_mpirun() -> bool {
    LAUNCHER_VARIABLES
        .iter()
        .any(|v| std::env::var_os(v).is_some())
}

/// This process's place among the ranks.
pub(crate) struct Runtime {
    /// This process's rank in `MPI_COMM_WORLD`.
    pub rank: i32,
    /// The number of ranks.
    pub size: i32,
    /// Finalised (dropped) by [`finalize`]; `None` when MPI was already
    /// started by someone else in this process.
    universe: Mutex<Option<Universe>>,
    /// Held for a whole collective conversation.
    serial: Mutex<()>,
}

static RUNTIME: OnceLock<Runtime> = OnceLock::new();

/// Set on rank 0 once every other rank serves its commands
/// ([`super::serve_if_worker`]).
static SERVED: AtomicBool = AtomicBool::new(false);

/// Rank 0 records that the other ranks serve it.
pub(crate) fn mark_served() {
    SERVED.store(true, AtomicOrdering::Relaxed);
}

/// Whether the other ranks serve this one (rank 0 of the binary).
pub(crate) fn served() -> bool {
    SERVED.load(AtomicOrdering::Relaxed)
}

/// The runtime, starting MPI on first use (with `MPI_THREAD_SERIALIZED`:
/// any thread may call, one at a time, under [`Runtime::serial`]).
pub(crate) fn runtime() -> &'static Runtime {
    RUNTIME.get_or_init(|| {
        let universe = mpi::initialize_with_threading(mpi::Threading::Serialized)
            .map(|(universe, _)| universe);
        let world = SimpleCommunicator::world();
        Runtime {
            rank: world.rank(),
            size: world.size(),
            universe: Mutex::new(universe),
            serial: Mutex::new(()),
        }
    })
}

/// Whether MPI was started in this process (by us).
pub fn started() -> bool {
    RUNTIME.get().is_some()
}

impl Runtime {
    /// The communicator of all ranks.
    pub(crate) fn world(&self) -> SimpleCommunicator {
        SimpleCommunicator::world()
    }

    /// The lock of a collective conversation (poison is ignored: the
    /// guarded state is the other ranks' position, which a panic on this
    /// rank ends anyway by aborting the job).
    pub(crate) fn serial(&self) -> MutexGuard<'_, ()> {
        self.serial.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Ends MPI in this process (`MPI_Finalize`), if it was started here; a
/// second call does nothing.
pub(crate) fn finalize() {
    if let Some(runtime) = RUNTIME.get() {
        let universe = runtime
            .universe
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take();
        drop(universe);
    }
}

/// Makes a panic on any rank end every rank: the default message, then
/// `MPI_Abort` (which `mpirun` turns into the end of the job).
pub(crate) fn abort_all_on_panic() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        default(info);
        SimpleCommunicator::world().abort(101);
    }));
}

/// Broadcasts `bytes` from rank 0 (collective): rank 0 passes its bytes,
/// the others an empty vector that is replaced. The length goes first by a
/// non-blocking broadcast that waiting ranks test every
/// [`POLL_INTERVAL`] (so that they sleep rather than spin).
pub(crate) fn broadcast_from_root(world: &SimpleCommunicator, bytes: &mut Vec<u8>) {
    let root = world.process_at_rank(0);
    let mut len = bytes.len() as u64;
    mpi::request::scope(|scope| {
        let mut request = root.immediate_broadcast_into(scope, &mut len);
        loop {
            match request.test() {
                Ok(_) => break,
                Err(pending) => {
                    request = pending;
                    std::thread::sleep(POLL_INTERVAL);
                }
            }
        }
    });
    bytes.resize(len as usize, 0);
    if len > 0 {
        root.broadcast_into(&mut bytes[..]);
    }
}

/// Collective: a random number drawn by rank 0, the same on every rank.
pub(crate) fn shared_random(world: &SimpleCommunicator) -> u32 {
    let mut bytes = if world.rank() == 0 {
        rand::random::<u32>().to_le_bytes().to_vec()
    } else {
        Vec::new()
    };
    broadcast_from_root(world, &mut bytes);
    let mut word = [0u8; 4];
    word.iter_mut().zip(&bytes).for_each(|(w, b)| *w = *b);
    u32::from_le_bytes(word)
}

/// Collective: every rank passes its own outcome of a step; all return
/// `Ok` when every rank succeeded, otherwise the same error on every rank:
/// the message of the lowest failing rank, naming that rank.
pub(crate) fn agree(world: &SimpleCommunicator, local: Result<(), String>) -> Result<(), String> {
    let size = world.size();
    if size == 1 {
        return local;
    }
    let rank = world.rank();
    let mine = if local.is_err() { rank } else { i32::MAX };
    let mut first = i32::MAX;
    world.all_reduce_into(&mine, &mut first, SystemOperation::min());
    if first == i32::MAX {
        return Ok(());
    }
    let mut text = match local {
        Err(message) if first == rank => message.into_bytes(),
        _ => Vec::new(),
    };
    let from = world.process_at_rank(first);
    let mut len = text.len() as u64;
    from.broadcast_into(&mut len);
    text.resize(len as usize, 0);
    if len > 0 {
        from.broadcast_into(&mut text[..]);
    }
    Err(format!(
        "on rank {first} of {size}: {}",
        String::from_utf8_lossy(&text)
    ))
}

/// Collective: rank 0 receives every rank's `values` (rank by rank); the
/// other ranks receive nothing.
pub(crate) fn gather_to_root(world: &SimpleCommunicator, values: &[u64]) -> Vec<Vec<u64>> {
    let root = world.process_at_rank(0);
    if world.rank() != 0 {
        root.gather_into(values);
        return Vec::new();
    }
    let size = world.size() as usize;
    let mut all = vec![0u64; values.len() * size];
    root.gather_into_root(values, &mut all[..]);
    all.chunks(values.len().max(1))
        .map(<[u64]>::to_vec)
        .collect()
}
