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
