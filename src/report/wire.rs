//! The report's serialised form: the keys and values scripts, the Python
//! package and the editor read, in the order they have always had, with
//! the keys added since (`factor_backend`, `warning_codes`,
//! `refactorizations`, and a back end's own section such as `mumps`,
//! present only when that back end factored). The typed
//! fields of [`Report`] map onto them here and nowhere else.

use serde::{Serialize, Serializer};

use super::{ArapReport, Conflict, Detected, EnergyOperator, Nnz, Report, SoftResidual, Timings};
use super::{Warning, WarningKind};
use crate::backend::{BackendFacts, FactorKind};
use crate::choice::Method;
use crate::condition::ConditionEstimate;
use crate::limits::MemoryBudget;
use crate::refinement_types::Refinement;

/// [`Report`] as its JSON object, borrowed.
#[derive(Serialize)]
struct Wire<'a> {
    method: Method,
    qr_backend: Option<&'a str>,
    /// Deprecated alias of `factor_backend`, kept for one release.
    spd_backend: Option<&'a FactorKind>,
    factor_backend: Option<&'a FactorKind>,
    laplacian: Option<EnergyOperator>,
    vertices: usize,
    constraints: usize,
    hard_constraints: usize,
    soft_constraints: usize,
    rank: Option<usize>,
    redundant: &'a Detected<usize>,
    conflicting: &'a Detected<Conflict>,
    max_constraint_residual: f64,
    max_constraint_residual_relative: f64,
    least_squares_residual: f64,
    least_squares_residual_relative: f64,
    soft_residuals: &'a [SoftResidual],
    length_scale: f64,
    length_unit: f64,
    soft_weight_scale: Option<f64>,
    refinement: Option<&'a Refinement>,
    forward_error_estimate: Option<f64>,
    conflict_tolerance: f64,
    nnz: &'a Nnz,
    timings_s: &'a Timings,
    warnings: &'a [Warning],
    warning_codes: Vec<WarningKind>,
    condition_estimate: Option<&'a ConditionEstimate>,
    penalty_weight: Option<f64>,
    penalty_weight_unit: Option<f64>,
    kkt_multiplier_scale: Option<f64>,
    arap: Option<&'a ArapReport>,
    memory_budget: Option<MemoryBudget>,
    ordering: Option<&'a str>,
    threads: Option<usize>,
    refactorizations: usize,
    /// The back end's own section, under its key (`mumps`), when it has
    /// one.
    #[serde(flatten)]
    backend_facts: Option<Section<'a>>,
}

/// A back end's facts under the key of their section.
struct Section<'a>(&'a BackendFacts);

impl Serialize for Section<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = s.serialize_map(Some(1))?;
        map.serialize_entry(&self.0.section, self.0)?;
        map.end()
    }
}

impl Serialize for Report {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        Wire {
            method: self.method,
            qr_backend: self.qr_backend.as_deref(),
            spd_backend: self.factor_backend.as_ref(),
            factor_backend: self.factor_backend.as_ref(),
            laplacian: self.energy,
            vertices: self.vertices,
            constraints: self.constraints,
            hard_constraints: self.hard_constraints,
            soft_constraints: self.soft_constraints,
            rank: self.rank,
            redundant: &self.redundant,
            conflicting: &self.conflicting,
            max_constraint_residual: self.max_constraint_residual,
            max_constraint_residual_relative: self.max_constraint_residual_relative,
            least_squares_residual: self.least_squares_residual,
            least_squares_residual_relative: self.least_squares_residual_relative,
            soft_residuals: &self.soft_residuals,
            length_scale: self.length_scale,
            length_unit: self.length_unit,
            soft_weight_scale: self.soft_weight_scale,
            refinement: self.refinement.as_ref(),
            forward_error_estimate: self.forward_error_estimate,
            conflict_tolerance: self.conflict_tolerance,
            nnz: &self.nnz,
            timings_s: &self.timings_s,
            warnings: &self.warnings,
            warning_codes: self.warnings.iter().map(|w| w.kind).collect(),
            condition_estimate: self.condition_estimate.as_ref(),
            penalty_weight: self.penalty_weight(),
            penalty_weight_unit: self.penalty_weight_unit(),
            kkt_multiplier_scale: self.kkt_multiplier_scale(),
            arap: self.arap.as_ref(),
            memory_budget: self.memory_budget,
            ordering: self.ordering.as_deref(),
            threads: self.threads,
            refactorizations: self.refactorizations,
            backend_facts: self.backend_facts.as_ref().map(Section),
        }
        .serialize(s)
    }
}
