//! What a run may use: the memory budget, the threads of a factorisation
//! and its fill-reducing ordering, in one value ([`Resources`]) that every
//! phase takes, from reading a file to the factor.
//!
//! The default is what a run without options did before this value
//! existed: the process's memory budget ([`MemoryBudget::default`]) and,
//! for threads and ordering, each back end's own choice
//! ([`Threads::Own`], [`FillOrdering::Own`]). Holding the last two equal
//! across back ends is what a fair comparison needs (docs/equal-terms.md):
//! one AMD permutation of the matrix factored, computed once and handed
//! to every back end, and one thread count.

use std::num::NonZeroUsize;

use crate::limits::MemoryBudget;

mod fill_ordering;
#[cfg(not(feature = "suitesparse"))]
pub(crate) use fill_ordering::METIS_NOT_IN_BUILD;
pub mod ordering_file;

pub use fill_ordering::{FillOrdering, OrderingWord};
pub use ordering_file::read_ordering_file;

/// The most threads a count may ask for. faer sizes a factorisation's
/// workspace by its thread count, so a count from user input is bounded
/// (far above any machine this crate runs on) rather than trusted.
pub const MAX_THREADS: usize = 1024;

/// How many threads a factorisation may use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Threads {
    /// Each back end's own choice: faer's above its size threshold,
    /// OpenBLAS's count in effect for CHOLMOD and MUMPS, one for
    /// nalgebra. The report states the count it used.
    #[default]
    Own,
    /// This many threads for every back end that can take a count;
    /// nalgebra is sequential and says so (the report's `"threads"` is 1).
    Count(NonZeroUsize),
}

impl Threads {
    /// `Count(n)`, or `None` for `n = 0` and above [`MAX_THREADS`].
    pub fn count(n: usize) -> Option<Threads> {
        NonZeroUsize::new(n)
            .filter(|n| n.get() <= MAX_THREADS)
            .map(Threads::Count)
    }

    /// The requested count (at most [`MAX_THREADS`], also for a `Count`
    /// built directly), `None` for the back end's own.
    pub(crate) fn requested(self) -> Option<usize> {
        match self {
            Threads::Own => None,
            Threads::Count(n) => Some(n.get().min(MAX_THREADS)),
        }
    }
}

impl std::fmt::Display for Threads {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Threads::Own => f.write_str("own"),
            Threads::Count(n) => write!(f, "{n}"),
        }
    }
}

impl std::str::FromStr for Threads {
    type Err = String;

    /// `own`, or a positive count.
    fn from_str(word: &str) -> Result<Threads, String> {
        if word == "own" {
            return Ok(Threads::Own);
        }
        word.parse::<usize>()
            .ok()
            .and_then(Threads::count)
            .ok_or_else(|| {
                format!(
                    "threads: expected own or a positive count up to {MAX_THREADS}, got {word:?}"
                )
            })
    }
}

/// What a run may use ([module documentation](self)).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Resources {
    /// The memory of every phase ([`crate::limits`]).
    pub budget: MemoryBudget,
    /// The threads of a factorisation.
    pub threads: Threads,
    /// The fill-reducing ordering of a factorisation.
    pub ordering: FillOrdering,
}

impl Resources {
    /// `budget`, with each back end's own threads and ordering.
    pub(crate) fn with_budget(budget: MemoryBudget) -> Resources {
        Resources {
            budget,
            ..Resources::default()
        }
    }

    /// Whether threads and ordering are each back end's own (what a run
    /// without options does; back ends then take their own path,
    /// unchanged).
    pub(crate) fn back_ends_choose(&self) -> bool {
        self.threads == Threads::Own && self.ordering == FillOrdering::Own
    }
}

/// Starts rayon's global thread pool, on which the library's parallel
/// loops run, with rayon's default number of threads, or with one when the
/// default cannot start; `Ok` at once when it runs already (started by an
/// earlier call, or by another library of the process).
///
/// Each thread maps a stack, so under a tight address-space limit
/// (`RLIMIT_AS`) the spawns fail. rayon starts its global pool once per
/// process, on first use if not before, and a start that failed cannot be
/// repeated: every later parallel loop then panics ("The global thread
/// pool has not been initialized"). So each size is first tried on a pool
/// of its own, which can fail and be tried again, and the global pool is
/// started only with a size that started. A door calls this before any
/// work (the command-line tool at start, the Python module before each
/// call) so that a limit too tight for the threads is a refusal.
///
/// Errors: [`crate::error::ProblemError::TooLarge`] naming the limit when
/// not even one thread starts (a later call tries again).
pub fn start_thread_pool() -> Result<(), crate::error::ProblemError> {
    static STARTED: std::sync::Mutex<bool> = std::sync::Mutex::new(false);
    let mut started = STARTED.lock().unwrap_or_else(|e| e.into_inner());
    if *started {
        return Ok(());
    }
    let mut failure = String::new();
    for threads in [None, Some(1)] {
        let builder = || match threads {
            Some(n) => rayon::ThreadPoolBuilder::new().num_threads(n),
            None => rayon::ThreadPoolBuilder::new(),
        };
        if let Err(e) = probe_pool(builder()) {
            failure = e.to_string();
            continue;
        }
        match builder().build_global() {
            Ok(()) => {}
            // rayon's message for a pool that runs already (its
            // `GlobalPoolAlreadyInitialized`, whose kind is private).
            Err(e) if e.to_string().contains("already been initialized") => {}
            Err(e) => return Err(thread_pool_refusal(&e.to_string())),
        }
        *started = true;
        return Ok(());
    }
    Err(thread_pool_refusal(&failure))
}

/// Starts a pool of `builder`'s size and ends it, waiting (up to a second
/// a thread) for its threads to exit, so that their stacks are free (or in
/// the allocator's cache, for the next threads) when the global pool
/// starts.
fn probe_pool(builder: rayon::ThreadPoolBuilder) -> Result<(), rayon::ThreadPoolBuildError> {
    let (exited, exits) = std::sync::mpsc::channel();
    let exited = std::sync::Mutex::new(exited);
    let pool = builder
        .exit_handler(move |_| {
            if let Ok(tx) = exited.lock() {
                let _ = tx.send(());
            }
        })
        .build()?;
    let threads = pool.current_num_threads();
    drop(pool);
    for _ in 0..threads {
        if exits
            .recv_timeout(std::time::Duration::from_secs(1))
            .is_err()
        {
            break;
        }
    }
    Ok(())
}

fn thread_pool_refusal(reason: &str) -> crate::error::ProblemError {
    crate::error::ProblemError::TooLarge {
        detail: format!(
            "the thread pool cannot start ({reason}){}",
            crate::limits::address_space_limit()
                .map(|b| format!(" under the address-space limit (RLIMIT_AS) of {b} bytes"))
                .unwrap_or_default()
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn threads_parse_own_and_positive_counts_only() {
        assert_eq!("own".parse::<Threads>(), Ok(Threads::Own));
        assert_eq!("3".parse::<Threads>().unwrap().requested(), Some(3));
        for bad in ["0", "-1", "two", "", "1025", "99999999999999999999"] {
            let err = bad.parse::<Threads>().unwrap_err();
            assert!(err.contains("positive count"), "{err}");
        }
    }

    #[test]
    fn the_default_lets_back_ends_choose() {
        assert!(Resources::default().back_ends_choose());
        let held = Resources {
            ordering: FillOrdering::Amd,
            ..Resources::default()
        };
        assert!(!held.back_ends_choose());
        assert_eq!(
            "metis".parse::<OrderingWord>().map(FillOrdering::from),
            Ok(FillOrdering::Metis)
        );
        assert!("colamd".parse::<OrderingWord>().is_err());
    }
}
