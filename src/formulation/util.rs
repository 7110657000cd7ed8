//! Problem-aware helpers shared by the formulations: the split normal
//! matrix `AᵀA`, `BᵀB` on one pattern, the analyse → size-check →
//! factorise sequence of a normal matrix with its errors put in context,
//! and the kind of a constraint row read from its coefficients
//! ([`RowKind`]). The plain sparse kernels are in [`crate::sparse`].

use std::time::Instant;

use faer::sparse::{
    SparseColMat, SparseColMatRef, SparseRowMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef,
};

use super::record::PrecomputeRecord;
use crate::backend::ordering::{FactorPlan, PlanUsed};
use crate::backend::spd::{SpdBackend, SpdFactor, SpdSymbolic};
use crate::error::{Error, NumericalError, ProblemError};
use crate::resources::Resources;
use crate::sparse::{NormalPattern, stack_rows};

/// `tril(pattern(AᵀA + BᵀB))` and the values of `AᵀA` and of `BᵀB` on it
/// (each term's entries are kept, as explicit zeros where only the other
/// term has one), so that `AᵀA + γ BᵀB` for any `γ` has this pattern.
pub(crate) fn split_normal(
    problem: &crate::problem::LseProblem,
) -> (SymbolicSparseColMat<usize>, Vec<f64>, Vec<f64>) {
    let l = problem.a().nrows();
    let stacked = stack_rows(problem.a().as_ref(), problem.b().as_ref(), 1.0);
    let normal = NormalPattern::new(stacked.as_ref());
    let (ptr, rows) = (stacked.symbolic().col_ptr(), stacked.symbolic().row_idx());
    let mut only_a = stacked.val().to_vec();
    let mut only_b = stacked.val().to_vec();
    for j in 0..stacked.ncols() {
        for p in ptr[j]..ptr[j + 1] {
            if rows[p] < l {
                only_b[p] = 0.0;
            } else {
                only_a[p] = 0.0;
            }
        }
    }
    let ata = normal.numeric(SparseColMatRef::new(stacked.symbolic(), &only_a));
    let btb = normal.numeric(SparseColMatRef::new(stacked.symbolic(), &only_b));
    (
        normal.symbolic().clone(),
        ata.val().to_vec(),
        btb.val().to_vec(),
    )
}

/// The kind of a hard row of `B`, read from its coefficients (the
/// assembled problem keeps rows, not the constraints' kinds): one entry →
/// position, two entries summing to zero → relative, two other entries →
/// edge, three → face. An edge with `t ∈ {0, 1}` has one nonzero
/// coefficient and *is* a position constraint; a face with a zero
/// barycentric coordinate is an edge. Named in messages by
/// [`RowKind::name`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum RowKind {
    /// No entry.
    Empty,
    /// One entry.
    Position,
    /// Two entries summing to zero (to `1e-12` of their magnitudes).
    Relative,
    /// Two other entries.
    Edge,
    /// Three entries.
    Face,
    /// More than three entries (a problem given as matrices).
    General,
}

impl RowKind {
    /// The kind of hard row `k` of `b`.
    pub(crate) fn of_row(b: SparseRowMatRef<'_, usize, f64>, k: usize) -> RowKind {
        let range = b.symbolic().row_range(k);
        let vals = &b.val()[range];
        match vals.len() {
            0 => RowKind::Empty,
            1 => RowKind::Position,
            2 => {
                let norm = vals[0].abs() + vals[1].abs();
                if (vals[0] + vals[1]).abs() <= 1e-12 * norm {
                    RowKind::Relative
                } else {
                    RowKind::Edge
                }
            }
            3 => RowKind::Face,
            _ => RowKind::General,
        }
    }

    /// Its word in messages (the constraints file's kinds).
    pub(crate) fn name(self) -> &'static str {
        match self {
            RowKind::Empty => "empty",
            RowKind::Position => "position",
            RowKind::Relative => "relative",
            RowKind::Edge => "edge",
            RowKind::Face => "face",
            RowKind::General => "general",
        }
    }
}

impl std::fmt::Display for RowKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// `tril(MᵀM)` and its Cholesky factor.
pub(crate) type FactoredNormal = (SparseColMat<usize, f64>, Box<dyn SpdFactor>);

/// What a planned symbolic analysis took and used.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Analysed {
    /// Seconds computing the ordering given to the back end (0 when the
    /// back end ordered by itself, inside its analysis).
    pub ordering_s: f64,
    /// Seconds of the back end's analysis.
    pub symbolic_s: f64,
    /// The ordering and threads used.
    pub used: PlanUsed,
}

impl Analysed {
    /// Records the times and what was used.
    pub(crate) fn record(&self, record: &mut PrecomputeRecord) {
        record.timings.ordering = self.ordering_s;
        record.timings.symbolic = self.symbolic_s;
        record.ordering = Some(self.used.ordering.clone());
        record.threads = self.used.threads;
    }
}

/// The symbolic analysis of `lower` by `spd` under `resources`: the back
/// end's own analysis when threads and ordering are its own (unchanged),
/// otherwise the plan ([`FactorPlan::new`]: the ordering computed once,
/// on this matrix, timed apart) through [`SpdBackend::analyze_planned`].
/// The matrix's unknown `k` is the problem's `original_of(k)`, of
/// `n_original` (for a given ordering). The factor's size is then checked
/// against the memory budget
/// ([`crate::backend::spd::SpdSymbolic::check_budget`], `matrix` names
/// the matrix for its message) within the symbolic phase's time: a back
/// end may size its factor first and build its pattern only once the
/// budget admits it (nalgebra's).
pub(crate) fn analyze_under(
    spd: &dyn SpdBackend,
    lower: SymbolicSparseColMatRef<'_, usize>,
    resources: &Resources,
    (original_of, n_original): (&dyn Fn(usize) -> usize, usize),
    matrix: &str,
) -> Result<(Box<dyn SpdSymbolic>, Analysed), Error> {
    let t = Instant::now();
    let plan = if resources.back_ends_choose() {
        None
    } else {
        let plan = FactorPlan::new(
            &resources.ordering,
            resources.threads,
            lower,
            original_of,
            n_original,
        )?;
        Some(plan)
    };
    let ordering_s = match plan {
        Some(ref p) if p.permutation.is_some() => t.elapsed().as_secs_f64(),
        _ => 0.0,
    };
    crate::interrupt::check()?;
    let t = Instant::now();
    let symbolic = match &plan {
        None => spd.analyze(lower)?,
        Some(plan) => {
            spd.check_plan_budget(lower, plan, resources.budget, matrix)?;
            spd.analyze_planned(lower, plan)?
        }
    };
    symbolic.check_budget(resources.budget, lower.ncols(), matrix)?;
    let analysed = Analysed {
        ordering_s,
        symbolic_s: t.elapsed().as_secs_f64(),
        used: symbolic.plan_used(),
    };
    Ok((symbolic, analysed))
}

/// `tril(MᵀM)` and its Cholesky factor by `spd`: the normal matrix, the
/// symbolic analysis under `resources` ([`analyze_under`]), the factor's
/// size checked against the memory budget
/// ([`crate::backend::spd::SpdSymbolic::check_budget`]) before the numeric factorisation, and the
/// numeric factorisation, each phase's time and size recorded in `record`.
/// `matrix` names `MᵀM` in errors and `vertex_of` gives the vertex of one
/// of its unknowns (of `n_vertices`).
pub(crate) fn factor_normal_matrix(
    m: SparseColMatRef<'_, usize, f64>,
    spd: &dyn SpdBackend,
    matrix: &str,
    vertex_of: impl Fn(usize) -> Option<usize>,
    record: &mut PrecomputeRecord,
    resources: &Resources,
    n_vertices: usize,
) -> Result<FactoredNormal, Error> {
    crate::interrupt::check()?;
    let t = Instant::now();
    let pattern = NormalPattern::new(m);
    let normal = pattern.numeric(m);
    record.timings.normal_matrix = t.elapsed().as_secs_f64();
    record.sizes.normal = Some(pattern.full_nnz());

    let original_of = |k: usize| vertex_of(k).unwrap_or(k);
    let (symbolic, analysed) = analyze_under(
        spd,
        normal.symbolic(),
        resources,
        (&original_of, n_vertices),
        matrix,
    )?;
    analysed.record(record);

    // The numeric factorisation is one back-end call: not interruptible
    // inside (crate::interrupt), checked before and after.
    crate::interrupt::check()?;
    let t = Instant::now();
    let factor = symbolic
        .factorize(normal.as_ref())
        .map_err(|e| with_context(e, matrix, vertex_of))?;
    crate::interrupt::check()?;
    record.timings.numeric = t.elapsed().as_secs_f64();
    record.sizes.factor = Some(factor.nnz());
    record.sizes.factor_bytes = Some(factor.bytes());
    record.backend_facts = factor.facts();
    Ok((normal, factor))
}

/// Fills in the matrix name and the vertex of a back end's numerical error.
pub(crate) fn with_context(
    e: NumericalError,
    matrix: &str,
    vertex_of: impl Fn(usize) -> Option<usize>,
) -> NumericalError {
    match e {
        NumericalError::NotPositiveDefinite { unknown, pivot, .. } => {
            NumericalError::NotPositiveDefinite {
                matrix: matrix.to_string(),
                unknown,
                vertex: vertex_of(unknown),
                pivot,
            }
        }
        NumericalError::Breakdown {
            unknown,
            ratio,
            threshold,
            ..
        } => NumericalError::Breakdown {
            matrix: matrix.to_string(),
            unknown,
            vertex: vertex_of(unknown),
            ratio,
            threshold,
        },
        other => other,
    }
}

/// The error of a condition estimate when every unknown is fixed.
pub(crate) fn nothing_factored() -> Error {
    ProblemError::InvalidArgument {
        message: "no matrix was factored (every unknown is fixed by the hard constraints), so it has no condition number".into(),
    }
    .into()
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::{SparseRowMat, SymbolicSparseRowMat};

    #[test]
    fn row_kinds_from_coefficients() {
        let b = SparseRowMat::new(
            SymbolicSparseRowMat::new_checked(3, 3, vec![0, 1, 3, 5], None, vec![1, 0, 2, 0, 1]),
            vec![1.0, 0.3, 0.7, 1.0, -1.0],
        );
        assert_eq!(RowKind::of_row(b.as_ref(), 0), RowKind::Position);
        assert_eq!(RowKind::of_row(b.as_ref(), 1), RowKind::Edge);
        assert_eq!(RowKind::of_row(b.as_ref(), 2), RowKind::Relative);
        assert_eq!(RowKind::Relative.to_string(), "relative");
    }
}
