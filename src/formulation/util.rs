//! Problem-aware helpers shared by the formulations: the split normal
//! matrix `AᵀA`, `BᵀB` on one pattern, the analyse → size-check →
//! factorise sequence of a normal matrix with its errors put in context,
//! and naming a constraint row's kind from its coefficients. The plain sparse kernels are in [`crate::sparse`].

use std::time::Instant;

use faer::sparse::{SparseColMat, SparseColMatRef, SparseRowMatRef, SymbolicSparseColMat};

use crate::backend::spd::{SpdBackend, SpdFactor, check_factor_size};
use crate::error::{Error, NumericalError, ProblemError};
use crate::limits::MemoryBudget;
use crate::report::Report;
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

/// The kind of hard row `k` of `B`, inferred from its coefficients (the
/// assembled problem keeps rows, not kinds): one entry → `position`, two
/// entries summing to zero → `relative`, two other entries → `edge`, three →
/// `face`. An edge with `t ∈ {0, 1}` has one nonzero coefficient and *is* a
/// position constraint; a face with a zero barycentric coordinate is an edge.
pub(crate) fn row_kind(b: SparseRowMatRef<'_, usize, f64>, k: usize) -> &'static str {
    let range = b.symbolic().row_range(k);
    let vals = &b.val()[range];
    match vals.len() {
        0 => "empty",
        1 => "position",
        2 => {
            let norm = vals[0].abs() + vals[1].abs();
            if (vals[0] + vals[1]).abs() <= 1e-12 * norm {
                "relative"
            } else {
                "edge"
            }
        }
        3 => "face",
        _ => "general",
    }
}

/// `tril(MᵀM)` and its Cholesky factor.
pub(crate) type FactoredNormal = (SparseColMat<usize, f64>, Box<dyn SpdFactor>);

/// `tril(MᵀM)` and its Cholesky factor by `spd`: the normal matrix, the
/// symbolic analysis, the factor's size checked against the memory `budget`
/// ([`check_factor_size`]) before the numeric factorisation, and the
/// numeric factorisation, each phase's time and size recorded in `report`.
/// `matrix` names `MᵀM` in errors and `vertex_of` gives the vertex of one
/// of its unknowns.
pub(crate) fn factor_normal_matrix(
    m: SparseColMatRef<'_, usize, f64>,
    spd: &dyn SpdBackend,
    matrix: &str,
    vertex_of: impl Fn(usize) -> Option<usize>,
    report: &mut Report,
    budget: MemoryBudget,
) -> Result<FactoredNormal, Error> {
    crate::interrupt::check()?;
    let t = Instant::now();
    let pattern = NormalPattern::new(m);
    let normal = pattern.numeric(m);
    report.timings_s.normal_matrix = t.elapsed().as_secs_f64();
    report.nnz.normal = Some(pattern.full_nnz());

    crate::interrupt::check()?;
    let t = Instant::now();
    let symbolic = spd.analyze(normal.symbolic())?;
    report.timings_s.symbolic = t.elapsed().as_secs_f64();
    check_factor_size(symbolic.factor_nnz(), normal.ncols(), matrix, budget)?;

    // The numeric factorisation is one back-end call: not interruptible
    // inside (crate::interrupt), checked before and after.
    crate::interrupt::check()?;
    let t = Instant::now();
    let factor = symbolic
        .factorize(normal.as_ref())
        .map_err(|e| with_context(e, matrix, vertex_of))?;
    crate::interrupt::check()?;
    report.timings_s.numeric = t.elapsed().as_secs_f64();
    report.nnz.factor = Some(factor.nnz());
    report.nnz.factor_bytes = Some(factor.bytes());
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
        assert_eq!(row_kind(b.as_ref(), 0), "position");
        assert_eq!(row_kind(b.as_ref(), 1), "edge");
        assert_eq!(row_kind(b.as_ref(), 2), "relative");
    }
}
