//! Elimination of known unknowns — what libigl's `min_quad_with_fixed` does
//! for "known" values: with position constraints only, the hard rows fix
//! the vertices `K`; the remaining vertices `U` solve
//!
//! `(A_Uᵀ A_U) X_U = A_Uᵀ (C − A_K X_K)`
//!
//! where `A_U`, `A_K` are the columns of `A` on `U` and `K`. This is the
//! null-space method with `Q = I` (a position row of `B` is a unit vector),
//! so it is exact: `X_K` is the target itself, bit for bit.
//!
//! Any other hard kind (edge, face, relative) couples several unknowns and
//! cannot be eliminated by dropping columns: [`ProblemError::Unsupported`]
//! names the first such constraint and its kind (inferred from its row:
//! the problem keeps rows, not kinds). Two hard positions on the same
//! vertex: the earlier (list priority) fixes it, the later is reported by
//! [`Prepared::skipped`] — redundant if its target is equal, conflicting
//! (with its residual) otherwise, as classified by the generic diagnostics.

use std::sync::Arc;
use std::time::Instant;

use faer::Mat;
use faer::sparse::SparseColMat;

use super::record::{PrecomputeRecord, Precomputed};
use super::util::{RowKind, factor_normal_matrix, nothing_factored};
use super::{Formulation, Prepared};
use crate::backend::FactorKind;
use crate::backend::spd::{FaerLlt, SpdBackend, SpdFactor};
use crate::condition::{self, ConditionEstimate, InverseOperator, LowerSymmetricOperator};
use crate::error::{Error, ProblemError};
use crate::problem::LseProblem;
use crate::report::MethodFacts;
use crate::resources::Resources;
use crate::sparse::{at_residual, at_times, gather_columns, lower_to_full, row_entries};

/// Elimination of position-constrained vertices over an SPD back end.
#[derive(Clone)]
pub struct Elimination {
    /// Cholesky of `A_Uᵀ A_U`.
    pub spd: Arc<dyn SpdBackend>,
}

impl Default for Elimination {
    fn default() -> Self {
        Elimination {
            spd: Arc::new(FaerLlt::auto()),
        }
    }
}

impl Elimination {
    /// Elimination over the given back end.
    pub fn new(spd: Arc<dyn SpdBackend>) -> Elimination {
        Elimination { spd }
    }
}

/// A vertex fixed by hard row `row` of `B`: `coefficient · p_vertex = d_row`.
#[derive(Debug, Clone, Copy)]
struct Known {
    vertex: usize,
    row: usize,
    coefficient: f64,
}

impl Formulation for Elimination {
    fn method(&self) -> super::Method {
        super::Method::Eliminate
    }

    fn precompute_with(
        &self,
        problem: &LseProblem,
        resources: &Resources,
    ) -> Result<Precomputed, Error> {
        let mut record = PrecomputeRecord::new(
            self.method(),
            FactorKind::Cholesky(self.spd.name()),
            MethodFacts::Eliminate,
        );
        let n = problem.n();
        let b = problem.b().as_ref();

        let t = Instant::now();
        let mut fixed_by: Vec<Option<usize>> = vec![None; n];
        let mut known = Vec::new();
        let mut skipped = Vec::new();
        for k in 0..b.nrows() {
            let (cols, vals) = row_entries(b, k);
            if cols.len() != 1 {
                return Err(ProblemError::Unsupported {
                    method: self.name(),
                    index: problem.hard_constraints()[k],
                    kind: RowKind::of_row(b, k).name(),
                    reason: "elimination fixes unknowns by dropping their columns, which only a hard position constraint (one vertex, one target) allows; use nullspace-qr or kkt, or make it soft",
                }
                .into());
            }
            let v = cols[0];
            if fixed_by[v].is_some() {
                skipped.push(k);
            } else {
                fixed_by[v] = Some(k);
                known.push(Known {
                    vertex: v,
                    row: k,
                    coefficient: vals[0],
                });
            }
        }
        let unknown: Vec<usize> = (0..n).filter(|&v| fixed_by[v].is_none()).collect();
        record.rank = Some(known.len());

        // A_U: the columns of A on the unknown vertices.
        let a_u = gather_columns(problem.a().as_ref(), &unknown);
        record.timings.preparation = t.elapsed().as_secs_f64();

        let (lower, factor) = if unknown.is_empty() {
            record.sizes.normal = Some(0);
            record.sizes.factor = Some(0);
            (None, None)
        } else {
            let (lower, factor) = factor_normal_matrix(
                a_u.as_ref(),
                self.spd.as_ref(),
                "the eliminated normal matrix A_UᵀA_U",
                |k| unknown.get(k).copied(),
                &mut record,
                resources,
                problem.n(),
            )?;
            (Some(lower), Some(factor))
        };
        let system = Box::new(PreparedElimination {
            known,
            unknown,
            skipped,
            lower,
            factor,
        });
        Ok(Precomputed { system, record })
    }
}

/// Invariant: `known` and `unknown` partition the vertices; `lower` and
/// `factor` are `tril(A_UᵀA_U)` and its factor (both `None` iff `unknown`
/// is empty); `skipped` holds the rows of `B` on an already fixed vertex.
struct PreparedElimination {
    known: Vec<Known>,
    unknown: Vec<usize>,
    skipped: Vec<usize>,
    lower: Option<SparseColMat<usize, f64>>,
    factor: Option<Box<dyn SpdFactor>>,
}

impl Prepared for PreparedElimination {
    fn solve(&mut self, problem: &LseProblem) -> Result<Mat<f64>, Error> {
        let n = problem.n();
        let d = problem.d();
        let mut x = Mat::<f64>::zeros(n, 3);
        for k in &self.known {
            for c in 0..3 {
                x[(k.vertex, c)] = d[(k.row, c)] / k.coefficient;
            }
        }
        if let Some(factor) = self.factor.as_mut() {
            // C − A_K X_K (X is zero on U), then A_Uᵀ(·) restricted to U.
            let residual = problem.c() - problem.a_times(&x);
            let full = at_times(problem.a().as_ref(), residual.as_ref());
            let mut z =
                Mat::<f64>::from_fn(self.unknown.len(), 3, |j, c| full[(self.unknown[j], c)]);
            factor.solve_in_place(z.as_mut())?;
            for (j, &v) in self.unknown.iter().enumerate() {
                for c in 0..3 {
                    x[(v, c)] = z[(j, c)];
                }
            }
        }
        Ok(x)
    }

    /// Corrected semi-normal equations with `Q2` the selection of the free
    /// columns: `Δx_U = (A_UᵀA_U)⁻¹ [Aᵀ(C − A X)]_U`; the fixed vertices
    /// never move.
    fn correction(
        &mut self,
        problem: &LseProblem,
        x: &Mat<f64>,
    ) -> Result<Option<Mat<f64>>, Error> {
        let Some(factor) = self.factor.as_mut() else {
            return Ok(None);
        };
        let gradient = at_residual(problem.a().as_ref(), problem.c().as_ref(), x.as_ref());
        let k = x.ncols();
        let mut dz =
            Mat::<f64>::from_fn(self.unknown.len(), k, |j, c| gradient[(self.unknown[j], c)]);
        factor.solve_in_place(dz.as_mut())?;
        let mut dx = Mat::<f64>::zeros(x.nrows(), k);
        for (j, &v) in self.unknown.iter().enumerate() {
            for c in 0..k {
                dx[(v, c)] = dz[(j, c)];
            }
        }
        Ok(Some(dx))
    }

    fn refactorizations(&self) -> usize {
        self.factor.as_ref().map_or(0, |f| f.refactorizations())
    }

    fn skipped(&self) -> &[usize] {
        &self.skipped
    }

    fn estimate_condition(&mut self) -> Result<ConditionEstimate, Error> {
        let (Some(lower), Some(factor)) = (self.lower.as_ref(), self.factor.as_mut()) else {
            return Err(nothing_factored());
        };
        let mut matrix = LowerSymmetricOperator::new(lower.as_ref());
        let mut inverse = InverseOperator::new(lower.ncols(), |rhs| {
            factor.solve_in_place(rhs)?;
            Ok(())
        });
        condition::estimate(&mut matrix, &mut inverse, "A_UᵀA_U")
    }

    fn factored_matrix(&self) -> Option<SparseColMat<usize, f64>> {
        self.lower.as_ref().map(|l| lower_to_full(l.as_ref()))
    }
}
