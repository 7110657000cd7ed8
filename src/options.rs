//! The request layer: what a deformation is asked to do, as typed options
//! with their defaults written once, here. [`DeformOptions`] covers the
//! energy operator (the Laplacian), the formulation with its back ends, the
//! refinement, the memory budget and strictness; [`ArapOptions`] the ARAP
//! iterations. The front doors (the CLI's flags, Python's keywords, the
//! editor's settings) only parse their words into these types, starting
//! from [`Default`]: no door holds a default of its own, so "no options
//! given" means the same everywhere.
//!
//! Layering: below [`crate::deform`] and [`crate::arap`] (which take these
//! types), above [`crate::solver`] ([`SolveOptions`], which this wraps).

use crate::choice::{ArapEnergy, ArapInit, Energy};
use crate::laplacian::LaplacianKind;
use crate::solver::SolveOptions;

/// The Laplacian of a default deformation: cotangent weights over mixed
/// Voronoi areas (paper eq. 9), the operator the paper's results use.
pub const DEFAULT_LAPLACIAN: LaplacianKind = LaplacianKind::Cotangent;

/// The most ARAP iterations a default run performs. Ten iterations bring
/// the Bunny's energy from the linear initial guess to within the
/// measured plateau (results/arap/README.md).
pub const DEFAULT_ARAP_ITERATIONS: usize = 10;

/// The default ARAP stop tolerance on the relative energy decrease: `0`,
/// run all [`DEFAULT_ARAP_ITERATIONS`] (unless the energy reaches zero).
pub const DEFAULT_ARAP_TOLERANCE: f64 = 0.0;

/// The penalty weight an interactive front door (the editor) shows before
/// one is chosen, so that switching to the penalty method has a weight to
/// start from. [`DeformOptions::default`] has no weight (the penalty method
/// then asks for one): a weight is a modelling choice, not a default.
pub const SUGGESTED_PENALTY_WEIGHT: f64 = 1e3;

/// ARAP iterations an interactive front door (the editor) runs per frame
/// of a drag: few enough to keep a frame short, warm-started from the last
/// frame's positions and rotations.
pub const INTERACTIVE_ARAP_ITERATIONS_PER_FRAME: usize = 2;

/// How to deform: the energy operator, how to solve, and whether warnings
/// that have a strict form are errors.
///
/// The default ([`DeformOptions::default`]) is the paper's set-up: the
/// Laplacian energy with [`DEFAULT_LAPLACIAN`], the null-space QR method on
/// its default back ends with the formulation's default refinement and the
/// process's memory budget ([`SolveOptions::default`]), not strict.
#[derive(Clone, Debug, PartialEq)]
pub struct DeformOptions {
    /// The energy: the linear Laplacian one ([`crate::Deformer`]) or ARAP
    /// ([`crate::arap::ArapDeformer`], whose own options are
    /// [`ArapOptions`]). Default [`Energy::default`]: Laplacian.
    pub energy: Energy,
    /// The Laplacian weights of the Laplacian energy (ARAP always uses
    /// cotangent weights). Default [`DEFAULT_LAPLACIAN`].
    pub laplacian: LaplacianKind,
    /// The formulation with its back ends and penalty weight, the
    /// refinement and the memory budget. Default [`SolveOptions::default`].
    pub solve: SolveOptions,
    /// Warnings that have a strict form (an estimated forward error above
    /// the tolerance, a constraints file made for another mesh, a
    /// conflicting hard constraint) are errors. Default `false`.
    pub strict: bool,
}

impl Default for DeformOptions {
    fn default() -> DeformOptions {
        DeformOptions {
            energy: Energy::default(),
            laplacian: DEFAULT_LAPLACIAN,
            solve: SolveOptions::default(),
            strict: false,
        }
    }
}

/// How to run the ARAP iterations ([`crate::arap::ArapDeformer`]).
///
/// The default ([`ArapOptions::default`]): the spokes-and-rims energy
/// ([`ArapEnergy::default`]), [`DEFAULT_ARAP_ITERATIONS`] iterations with
/// tolerance [`DEFAULT_ARAP_TOLERANCE`], from the linear initial guess
/// ([`ArapInit::default`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArapOptions {
    /// Which ARAP energy. Default [`ArapEnergy::default`]: spokes and rims
    /// (Chao et al. 2010, libigl's default for triangle meshes).
    pub energy: ArapEnergy,
    /// The most iterations to run. Default [`DEFAULT_ARAP_ITERATIONS`].
    pub iterations: usize,
    /// Stop when an iteration's relative energy decrease is at most this
    /// ([`crate::arap::ArapDeformer::run`]). Default
    /// [`DEFAULT_ARAP_TOLERANCE`].
    pub tolerance: f64,
    /// The initial guess. Default [`ArapInit::default`]: the linear
    /// solution (lower energy than the rest pose at every iteration count
    /// measured on the Bunny, results/arap/README.md).
    pub init: ArapInit,
}

impl Default for ArapOptions {
    fn default() -> ArapOptions {
        ArapOptions {
            energy: ArapEnergy::default(),
            iterations: DEFAULT_ARAP_ITERATIONS,
            tolerance: DEFAULT_ARAP_TOLERANCE,
            init: ArapInit::default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::{qr::QrKind, spd::SpdKind};
    use crate::choice::Method;

    /// The documented defaults, value by value (the CLI's `--help`, the
    /// Python stub `_native.pyi`).
    #[test]
    fn the_defaults_are_the_documented_ones() {
        let d = DeformOptions::default();
        assert_eq!(d.energy, Energy::Laplacian);
        assert_eq!(d.laplacian, LaplacianKind::Cotangent);
        assert_eq!(d.solve.formulation.method, Method::NullSpaceQr);
        assert_eq!(d.solve.formulation.qr, QrKind::SparseGivens);
        assert_eq!(d.solve.formulation.spd, SpdKind::FaerAuto);
        assert_eq!(d.solve.formulation.weight, None);
        assert_eq!(d.solve.refine, None);
        assert_eq!(d.solve.resources, crate::resources::Resources::default());
        assert!(!d.strict);
        let a = ArapOptions::default();
        assert_eq!(a.energy, ArapEnergy::SpokesAndRims);
        assert_eq!(a.iterations, 10);
        assert_eq!(a.tolerance, 0.0);
        assert_eq!(a.init, ArapInit::Linear);
    }
}
