//! The fill-reducing ordering a run asks for ([`FillOrdering`]) and the
//! words that name it ([`OrderingWord`]). A leaf under
//! [`crate::resources`], which re-exports both: the ordering-file reader
//! beside it makes a [`FillOrdering::Given`], and imports nothing else
//! of `resources`.

use std::sync::Arc;

use crate::choice::Word;
use crate::error::ProblemError;

/// The fill-reducing ordering of a sparse factorisation: which unknown is
/// eliminated when. Fill (the factor's entries) and the factorisation's
/// cost depend on it, so two back ends compared on their own orderings
/// compare orderings as much as factorisations.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub enum FillOrdering {
    /// Each back end's own: AMD for faer, nalgebra and CHOLMOD (each its
    /// own implementation), MUMPS's automatic choice (`ICNTL(7) = 7`).
    #[default]
    Own,
    /// Approximate minimum degree (faer's implementation), computed once
    /// on the matrix factored and given to every back end.
    Amd,
    /// METIS nested dissection (through CHOLMOD's `cholmod_l_metis`:
    /// builds with the feature `suitesparse` only), computed once and
    /// given to every back end.
    Metis,
    /// The unknowns in their own order (no reordering).
    Natural,
    /// A permutation of the problem's unknowns: entry `i` is the unknown
    /// eliminated `i`-th. A factored matrix over a subset of the unknowns
    /// (the null-space method's free unknowns, elimination's free
    /// vertices) is eliminated in the order this induces on the subset.
    Given(Arc<[usize]>),
}

/// Why [`FillOrdering::Metis`] fails in a build without the feature
/// `suitesparse`.
pub(crate) const METIS_NOT_IN_BUILD: &str =
    "the METIS ordering is not in this build (it comes with the feature suitesparse)";

/// The words of the orderings other than [`FillOrdering::Given`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OrderingWord {
    /// [`FillOrdering::Own`].
    Own,
    /// [`FillOrdering::Amd`].
    Amd,
    /// [`FillOrdering::Metis`].
    Metis,
    /// [`FillOrdering::Natural`].
    Natural,
}

impl Word for OrderingWord {
    const WHAT: &'static str = "ordering";

    fn all() -> &'static [OrderingWord] {
        &[
            OrderingWord::Own,
            OrderingWord::Amd,
            OrderingWord::Metis,
            OrderingWord::Natural,
        ]
    }

    fn name(self) -> &'static str {
        match self {
            OrderingWord::Own => "own",
            OrderingWord::Amd => "amd",
            OrderingWord::Metis => "metis",
            OrderingWord::Natural => "natural",
        }
    }
}

crate::choice::word_traits!(OrderingWord);

impl From<OrderingWord> for FillOrdering {
    fn from(word: OrderingWord) -> FillOrdering {
        match word {
            OrderingWord::Own => FillOrdering::Own,
            OrderingWord::Amd => FillOrdering::Amd,
            OrderingWord::Metis => FillOrdering::Metis,
            OrderingWord::Natural => FillOrdering::Natural,
        }
    }
}

impl FillOrdering {
    /// The word of the report and the CLI: `own`, `amd`, `metis`,
    /// `natural` or `given`.
    pub fn name(&self) -> &'static str {
        match self {
            FillOrdering::Own => "own",
            FillOrdering::Amd => "amd",
            FillOrdering::Metis => "metis",
            FillOrdering::Natural => "natural",
            FillOrdering::Given(_) => "given",
        }
    }

    /// `Err` when this build cannot compute the ordering: METIS comes with
    /// the feature `suitesparse` ([`METIS_NOT_IN_BUILD`]). Checked before
    /// every precompute, whatever the method, and by a door that keeps an
    /// ordering before anything is factored (the editor's settings), so
    /// that it is refused when it is given, not at the next factorisation.
    pub(crate) fn check_in_build(&self) -> Result<(), ProblemError> {
        if *self == FillOrdering::Metis && !cfg!(feature = "suitesparse") {
            return Err(ProblemError::InvalidArgument {
                message: METIS_NOT_IN_BUILD.into(),
            });
        }
        Ok(())
    }

    /// A given ordering checked against a problem of `n` unknowns: `n`
    /// entries, each of `0..n` once. Checked before any precompute, so
    /// that every method refuses the same orderings, also one that factors
    /// nothing (every unknown fixed). The other orderings pass.
    pub(crate) fn check_unknowns(&self, n: usize) -> Result<(), ProblemError> {
        let FillOrdering::Given(order) = self else {
            return Ok(());
        };
        let invalid = |message| ProblemError::InvalidArgument { message };
        if order.len() != n {
            return Err(invalid(format!(
                "the given ordering has {} entries; the problem has {n} unknowns",
                order.len()
            )));
        }
        let mut seen = vec![false; n];
        for (i, &unknown) in order.iter().enumerate() {
            if unknown >= n || std::mem::replace(&mut seen[unknown], true) {
                return Err(invalid(format!(
                    "the given ordering is not a permutation of 0..{n}: entry {i} is {unknown}"
                )));
            }
        }
        Ok(())
    }
}
