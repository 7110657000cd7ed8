//! # lse-deform
//!
//! Laplacian mesh deformation with hard and soft constraints by the
//! constrained least-squares method of Masuda, Yoshioka & Furukawa
//! (SMI 2006).
#![deny(missing_docs)]

pub mod error;
pub mod mesh;

pub use error::{Error, Result};
pub use mesh::Mesh;
