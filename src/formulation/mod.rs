//! Formulations of the constrained least-squares problem: the same inputs
//! (`A, C, B, D` of an [`LseProblem`]) and the same [`Report`], so that the
//! paper's method can be compared with the alternatives on equal terms.

use faer::Mat;

use crate::error::Error;
use crate::problem::LseProblem;
use crate::report::Report;

mod null_space;

pub use null_space::NullSpaceQr;

/// A way to solve `min ‖AX − C‖ s.t. BX = D`.
pub trait Formulation: Send + Sync {
    /// Short name for reports and the CLI.
    fn name(&self) -> String;

    /// The precompute phase: factor everything that depends on the matrices
    /// only. Fills the timings and sizes it knows into `report`.
    fn precompute(
        &self,
        problem: &LseProblem,
        report: &mut Report,
    ) -> Result<Box<dyn Prepared>, Error>;
}

/// A precomputed system: solves for new right-hand sides (`C`, `D`) of the
/// same matrices without refactoring.
pub trait Prepared: Send {
    /// Solves for the current `C` and `D` of `problem` (which must have the
    /// matrices the system was prepared with). Returns `X` (n × 3).
    fn solve(&mut self, problem: &LseProblem) -> Result<Mat<f64>, Error>;

    /// Rows of `B` that the method does not enforce because they depend on
    /// earlier ones (increasing). Empty for methods that enforce all rows
    /// or fail.
    fn skipped(&self) -> &[usize];

    /// `false` for methods that only approximate hard constraints
    /// (penalty), whose residuals are then reported but not "kept exactly".
    fn exact(&self) -> bool {
        true
    }
}
