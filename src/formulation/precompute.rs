//! The seam of a formulation: [`Formulation`], whose precompute factors
//! what depends on the matrices only and returns the [`Precomputed`]
//! system ([`super::Prepared`] with its record).

use super::record::Precomputed;
use crate::choice::Method;
use crate::error::Error;
use crate::problem::LseProblem;
use crate::resources::Resources;

/// A way to solve `min ‖AX − C‖ s.t. BX = D`.
pub trait Formulation: Send + Sync {
    /// The method this formulation implements.
    fn method(&self) -> Method;

    /// Short name for messages: the method's word.
    fn name(&self) -> String {
        self.method().name().into()
    }

    /// The precompute phase under `resources`: factor everything that
    /// depends on the matrices only, with the resources' ordering and
    /// threads ([`crate::resources`]), refusing with
    /// [`ProblemError::TooLarge`] a factor whose estimated size exceeds the
    /// budget (checked before it is allocated). Returns the system with the
    /// record of what was computed (sizes, timings, rank, warnings, the
    /// ordering and threads used, the method's own facts).
    fn precompute_with(
        &self,
        problem: &LseProblem,
        resources: &Resources,
    ) -> Result<Precomputed, Error>;

    /// [`Formulation::precompute_with`] the default resources
    /// ([`Resources::default`]: the process's budget, each back end's own
    /// threads and ordering).
    fn precompute(&self, problem: &LseProblem) -> Result<Precomputed, Error> {
        self.precompute_with(problem, &Resources::default())
    }
}
