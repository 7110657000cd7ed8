//! The studies, one module per section of `results/README.md`. Each one
//! exports its [`Experiment`](crate::harness::registry::Experiment) entry
//! as `EXPERIMENT`; `main.rs` lists them. A study imports the harness and
//! the library, never another study.

pub mod accuracy;
pub mod arap;
pub mod breakdown;
pub mod conflicts;
pub mod distributed;
pub mod drag;
pub mod editor;
pub mod mpi_in_process;
pub mod performance;
pub mod python;
pub mod relative;
pub mod renders;
pub mod scaling;
pub mod table1;
pub mod weight_sweep;
