//! # lse-deform
//!
//! Laplacian mesh deformation with hard and soft constraints by the
//! constrained least-squares method of Masuda, Yoshioka & Furukawa,
//! "A Constrained Least Squares Approach to Interactive Mesh Deformation"
//! (SMI 2006), next to penalty and KKT formulations over interchangeable QR
//! and Cholesky back ends.
//!
//! The problem (paper eq. 11) is `min ‖A X − C‖ s.t. B X = D` with
//! `A = [L; w·B_soft]`, `C = [δ; w·D_soft]`, `δ = L P` the Laplacian
//! coordinates of the original positions and `B X = D` the hard constraints;
//! `X` has three columns (x, y, z) solved together.
//!
//! The mathematics the code cites (`docs/formulations.md §2` and the like)
//! is in the repository's `docs/` directory.
//!
//! Module map, imports pointing down:
//! - foundations: [`error`], [`choice`] (typed configuration words and
//!   their one parse error), [`limits`] (the memory budget), [`atomic`]
//!   (every output file written whole or not at all), [`interrupt`]
//!   (cancellation of long calls by a caller's hook), [`sparse`] (sparse
//!   kernels: products, normal matrices), [`mtx`] (Matrix Market I/O);
//! - [`mesh`] (types, I/O, validation, generators) → [`laplacian`] →
//!   [`constraints`] (model and JSON file) → [`problem`] (assembly of
//!   `A, C, B, D`);
//! - [`backend`] (QR, SPD Cholesky and `LDLᵀ` traits and their
//!   implementations),
//!   [`condition`] (condition-number estimates of the factored matrix) and
//!   [`refinement_types`] (refinement modes, the record of a refinement,
//!   stop reasons, thresholds) →
//!   [`report`] (diagnostics of a solve) → [`formulation`] (the paper's
//!   method and its alternatives, refinement) → [`solver`] (precompute and
//!   solve of any problem, including general ones from their matrices, and
//!   [`SolveOptions`]: formulation, refinement, memory budget);
//! - [`options`] (the request layer: [`DeformOptions`], [`ArapOptions`],
//!   every default of a deformation written once) →
//!   [`deform`] (the three-phase mesh API), [`handle`] (affine handles:
//!   per-frame positions from a precomputed response basis), [`arap`]
//!   (as-rigid-as-possible iterations on the same formulations), [`compare`]
//!   (every formulation and back end against one reference), [`scene`]
//!   (generated constraint scenes), [`export`] (Matrix Market files for
//!   MATLAB/SciPy), [`interop`] (conversions to `sprs` and
//!   `nalgebra-sparse`);
//! - with features: `render` (software rasteriser for pictures of results),
//!   `editor` (the interactive HTTP editor, a front door), `python` (the
//!   Python module, a front door), `testing` (proptest strategies).
#![deny(missing_docs)]
// Numerical kernels index several arrays with one loop variable; iterator
// chains would obscure the mathematics.
#![allow(clippy::needless_range_loop)]

pub mod arap;
pub mod atomic;
pub mod backend;
pub mod choice;
pub mod compare;
pub mod condition;
pub mod constraints;
pub(crate) mod cpu;
pub mod deform;
#[cfg(feature = "editor")]
pub mod editor;
pub mod error;
pub mod export;
pub mod formulation;
pub mod handle;
pub mod input;
pub mod interop;
pub mod interrupt;
pub mod laplacian;
pub mod limits;
pub mod mesh;
pub mod mtx;
pub mod options;
pub mod problem;
#[cfg(feature = "python")]
pub mod python;
pub mod refinement_types;
#[cfg(feature = "render")]
pub mod render;
pub mod report;
pub mod request;
pub mod resources;
pub mod scene;
pub mod solver;
pub mod sparse;
#[cfg(feature = "proptest")]
pub mod testing;

// The crate root names the dozen things a deformation is written with;
// everything else is reached through its module.
pub use backend::{qr::QrKind, spd::SpdKind};
pub use choice::Method;
pub use constraints::{Constraint, ConstraintSet};
pub use deform::Deformer;
pub use error::Error;
pub use laplacian::LaplacianKind;
pub use mesh::Mesh;
pub use report::Report;
pub use solver::{LseSolver, SolveOptions};

/// The guide `docs/rust.md`, whose examples are compiled and run as
/// doctests.
#[cfg(doctest)]
#[doc = include_str!("../docs/rust.md")]
pub struct RustGuide;
