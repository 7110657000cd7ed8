//! Experiment `weight_sweep` (not written yet).

use crate::context::Context;
use crate::{AnyError, Summary};

/// Runs the experiment.
pub fn run(_ctx: &Context) -> Result<Summary, AnyError> {
    Err("not implemented yet".into())
}
