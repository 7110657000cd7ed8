//! The paper's method (eq. 12–19): null-space QR.
//!
//! `Bᵀ = Q R`, `R1ᵀ y = D`, then `z` from the normal equations of the
//! reduced problem `(A Q2)ᵀ(A Q2) z = (A Q2)ᵀ(C − A Q1 y)` by sparse
//! Cholesky, and `X = Q [y; z]`. Hard constraints hold to rounding:
//! `B_kept Q2 = 0` by construction, so `B_kept X = R1ᵀ y = D_kept`.
//!
//! Phases: precompute = QR, preparation (`A Q2`), normal matrix, symbolic,
//! numeric. Solve = `y`, `X_p = Q[y; 0]` (so `A Q1 y = A X_p`), one sparse
//! product for `C − A X_p`, one for `(AQ2)ᵀ(·)`, two triangular solves with
//! the three coordinates as one block, `X = Q[y; z]`.

use std::sync::Arc;
use std::time::Instant;

use faer::sparse::SparseColMat;
use faer::sparse::SparseColMatRef;
use faer::{Mat, MatMut};
use rayon::prelude::*;

use super::record::{PrecomputeRecord, Precomputed};
use super::util::{factor_normal_matrix, nothing_factored};
use super::{Formulation, Prepared};
use crate::backend::FactorKind;
use crate::backend::qr::{ConstraintQr, QrBackend, RankTolerance, SparseGivens};
use crate::backend::spd::{FaerLlt, SpdBackend, SpdFactor};
use crate::condition::{self, ConditionEstimate, InverseOperator, LowerSymmetricOperator};
use crate::cpu::clear_upper_vector_state;
use crate::error::Error;
use crate::problem::LseProblem;
use crate::report::MethodFacts;
use crate::resources::Resources;
use crate::sparse::NormalPattern;
use crate::sparse::{gather_columns, hard_residual_compensated, lower_to_full, mt_residual};

/// The null-space QR method over a QR back end and an SPD back end.
#[derive(Clone)]
pub struct NullSpaceQr {
    /// QR of `Bᵀ`.
    pub qr: Arc<dyn QrBackend>,
    /// Cholesky of `(AQ2)ᵀ(AQ2)`.
    pub spd: Arc<dyn SpdBackend>,
    /// Rank-detection tolerance.
    pub tolerance: RankTolerance,
}

/// The default pairs [`SparseGivens`] (the same rank decisions in the same
/// priority order as the paper's per-block
/// [`DenseHouseholder`](crate::backend::qr::DenseHouseholder), but its cost
/// follows the sparsity inside a block instead of the block's size squared,
/// and its Q is cheaper to apply) with [`FaerLlt::auto`].
impl Default for NullSpaceQr {
    fn default() -> Self {
        NullSpaceQr {
            qr: Arc::new(SparseGivens::default()),
            spd: Arc::new(FaerLlt::auto()),
            tolerance: RankTolerance::default(),
        }
    }
}

impl NullSpaceQr {
    /// The method over the given back ends with the default tolerance.
    pub fn new(qr: Arc<dyn QrBackend>, spd: Arc<dyn SpdBackend>) -> NullSpaceQr {
        NullSpaceQr {
            qr,
            spd,
            tolerance: RankTolerance::default(),
        }
    }
}

impl Formulation for NullSpaceQr {
    fn method(&self) -> super::Method {
        super::Method::NullSpaceQr
    }

    fn precompute_with(
        &self,
        problem: &LseProblem,
        resources: &Resources,
    ) -> Result<Precomputed, Error> {
        let mut record = PrecomputeRecord::new(
            self.method(),
            FactorKind::Cholesky(self.spd.name()),
            MethodFacts::NullSpace,
        );
        record.qr_backend = Some(self.qr.name());

        let t = Instant::now();
        let qr = self
            .qr
            .factor_with(problem.b().as_ref(), self.tolerance, resources)?;
        record.timings.qr = t.elapsed().as_secs_f64();
        record.rank = Some(qr.rank());
        record.sizes.qr = Some(qr.storage_nnz());

        crate::interrupt::check()?;
        let t = Instant::now();
        let aq2 = qr.mul_a_q2(problem.a().as_ref());
        record.timings.preparation = t.elapsed().as_secs_f64();
        record.sizes.aq2 = Some(aq2.val().len());

        let factor = if aq2.ncols() == 0 {
            // Every degree of freedom is fixed by the hard constraints.
            record.sizes.normal = Some(0);
            record.sizes.factor = Some(0);
            None
        } else {
            let (_, factor) = factor_normal_matrix(
                aq2.as_ref(),
                self.spd.as_ref(),
                "the reduced normal matrix (AQ2)ᵀ(AQ2)",
                |k| Some(qr.free_unknown(k)),
                &mut record,
                resources,
                problem.n(),
            )?;
            Some(factor)
        };
        let workspace = SolveWorkspace::new(qr.n(), qr.rank(), problem.a().nrows());
        let system = Box::new(PreparedNullSpace {
            a_constrained: ConstrainedColumns::new(problem),
            qr,
            aq2,
            factor,
            workspace,
        });
        Ok(Precomputed { system, record })
    }
}

struct PreparedNullSpace {
    /// The columns of `A` where `X_p = Q[y; 0]` can be non-zero.
    a_constrained: ConstrainedColumns,
    qr: Box<dyn ConstraintQr>,
    aq2: SparseColMat<usize, f64>,
    factor: Option<Box<dyn SpdFactor>>,
    workspace: SolveWorkspace,
}

/// The columns of `A` at the unknowns that appear in a hard constraint,
/// copied together (CSC).
///
/// `X_p = Q[y; 0]` is supported on those unknowns: `Q[y; 0]` lies in the
/// row space of the kept constraints, and every back end builds `Q1` from
/// reflections or rotations among the unknowns of the constraints. So
/// `A X_p` needs only these columns, and reading them from one compact
/// array instead of scattered across `A` (which the triangular solves have
/// just pushed out of cache) saves a cache miss per column.
struct ConstrainedColumns {
    /// The unknowns, increasing.
    unknowns: Vec<usize>,
    /// Column `t` is column `unknowns[t]` of `A`.
    columns: SparseColMat<usize, f64>,
}

impl ConstrainedColumns {
    fn new(problem: &LseProblem) -> ConstrainedColumns {
        let mut unknowns = problem.b().symbolic().col_idx().to_vec();
        unknowns.sort_unstable();
        unknowns.dedup();
        let columns = gather_columns(problem.a().as_ref(), &unknowns);
        ConstrainedColumns { unknowns, columns }
    }
}

/// Columns of `AQ2` per parallel task of the `(AQ2)ᵀ r` pass (a few tens
/// of KiB of `AQ2` each: scheduling negligible, both cores busy from a few
/// thousand unknowns on).
const ZT_MIN_LEN: usize = 2048;

/// Buffers of one solve, allocated once at precompute so that a drag loop
/// only allocates its output.
struct SolveWorkspace {
    /// `y` (rank × 3).
    y: Mat<f64>,
    /// `z` (free unknowns × 3).
    z: Mat<f64>,
    /// `X_p = Q[y; 0]` (n × 3).
    xp: Mat<f64>,
    /// `C − A X_p`, one `[x, y, z]` per row of A (the three coordinates of
    /// a row in one cache line for the two sparse passes).
    residual: Vec<[f64; 3]>,
    /// `(AQ2)ᵀ (C − A X_p)` row by row, as the parallel pass writes it.
    zt: Vec<[f64; 3]>,
}

impl SolveWorkspace {
    /// `residual ← C` (three columns).
    fn residual_from(&mut self, c: &Mat<f64>) {
        for k in 0..3 {
            for (r, &v) in self.residual.iter_mut().zip(c.col_as_slice(k)) {
                r[k] = v;
            }
        }
    }

    /// `z ← (AQ2)ᵀ residual`: one pass over `AQ2`, parallel over its
    /// columns (each a dot product with the residual).
    fn project_residual(&mut self, aq2: &SparseColMat<usize, f64>) {
        let (ptr, rows, val) = (
            aq2.symbolic().col_ptr(),
            aq2.symbolic().row_idx(),
            aq2.val(),
        );
        // Parallel over the columns of AQ2 (each a dot product with
        // the residual), into `zt`, then copied into z's columns.
        let res = &self.residual;
        self.zt
            .par_iter_mut()
            .enumerate()
            .with_min_len(ZT_MIN_LEN)
            .for_each_init(clear_upper_vector_state, |(), (j, s)| {
                let mut acc = [0.0; 3];
                for (&i, &v) in rows[ptr[j]..ptr[j + 1]]
                    .iter()
                    .zip(&val[ptr[j]..ptr[j + 1]])
                {
                    let r = res[i];
                    acc[0] += v * r[0];
                    acc[1] += v * r[1];
                    acc[2] += v * r[2];
                }
                *s = acc;
            });
        for k in 0..3 {
            for (z, s) in self.z.col_as_slice_mut(k).iter_mut().zip(&self.zt) {
                *z = s[k];
            }
        }
    }

    fn new(n: usize, rank: usize, a_rows: usize) -> SolveWorkspace {
        SolveWorkspace {
            y: Mat::zeros(rank, 3),
            z: Mat::zeros(n - rank, 3),
            xp: Mat::zeros(n, 3),
            residual: vec![[0.0; 3]; a_rows],
            zt: vec![[0.0; 3]; n - rank],
        }
    }
}

/// `residual −= A X` over the columns of `a` (three columns of `x`;
/// column `t` of `a` multiplies row `unknown(t)` of `x`): one pass over
/// those columns, each residual row `[x, y, z]` in one cache line.
fn subtract_product(
    residual: &mut [[f64; 3]],
    a: SparseColMatRef<'_, usize, f64>,
    unknown: impl Fn(usize) -> usize,
    x: &Mat<f64>,
) {
    let (ptr, rows, val) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
    let (x0, x1, x2) = (x.col_as_slice(0), x.col_as_slice(1), x.col_as_slice(2));
    for t in 0..a.ncols() {
        let j = unknown(t);
        let u = [x0[j], x1[j], x2[j]];
        for (&i, &v) in rows[ptr[t]..ptr[t + 1]]
            .iter()
            .zip(&val[ptr[t]..ptr[t + 1]])
        {
            let r = &mut residual[i];
            r[0] -= v * u[0];
            r[1] -= v * u[1];
            r[2] -= v * u[2];
        }
    }
}

impl Prepared for PreparedNullSpace {
    fn solve(&mut self, problem: &LseProblem) -> Result<Mat<f64>, Error> {
        let mut x = Mat::<f64>::zeros(self.qr.n(), 3);
        self.solve_into(problem, x.as_mut())?;
        Ok(x)
    }

    fn solve_into(&mut self, problem: &LseProblem, x: MatMut<'_, f64>) -> Result<(), Error> {
        let qr = &*self.qr;
        let ws = &mut self.workspace;
        // The passes below are SSE loops on this thread, which may just
        // have run faer's AVX kernels (crate::cpu).
        clear_upper_vector_state();
        qr.solve_r1t(problem.d().as_ref(), ws.y.as_mut());
        if let Some(factor) = self.factor.as_mut() {
            // X_p = Q[y; 0], so that A Q1 y = A X_p.
            ws.z.fill(0.0);
            qr.apply_q(ws.y.as_ref(), ws.z.as_ref(), ws.xp.as_mut());
            // residual ← C − A X_p: one pass over the columns of A where X_p
            // can be non-zero.
            ws.residual_from(problem.c());
            let ac = &self.a_constrained;
            subtract_product(
                &mut ws.residual,
                ac.columns.as_ref(),
                |t| ac.unknowns[t],
                &ws.xp,
            );
            // z ← (AQ2)ᵀ residual: one pass over AQ2.
            ws.project_residual(&self.aq2);
            factor.solve_in_place(ws.z.as_mut())?;
            clear_upper_vector_state();
        }
        qr.apply_q(ws.y.as_ref(), ws.z.as_ref(), x);
        Ok(())
    }

    /// The same solution for any width `k`, as [`Prepared::solve_into`]
    /// computes it with its 3-column kernels: `y = R1⁻ᵀ D`,
    /// `X_p = Q[y; 0]` (so `B X_p = D` on the kept rows),
    /// `z = H⁻¹ (AQ2)ᵀ (C − A X_p)` with `A X_p` over the constrained
    /// columns of `A` only, `X = Q[y; z]`.
    fn solve_wide_into(
        &mut self,
        problem: &LseProblem,
        out: MatMut<'_, f64>,
    ) -> Result<bool, Error> {
        let qr = &*self.qr;
        let k = out.ncols();
        let mut y = Mat::<f64>::zeros(qr.rank(), k);
        qr.solve_r1t(problem.d().as_ref(), y.as_mut());
        let mut z = Mat::<f64>::zeros(qr.n() - qr.rank(), k);
        if let Some(factor) = self.factor.as_mut() {
            let mut xp = Mat::<f64>::zeros(qr.n(), k);
            qr.apply_q(y.as_ref(), z.as_ref(), xp.as_mut());
            let ac = &self.a_constrained;
            z = mt_residual(
                self.aq2.as_ref(),
                ac.columns.as_ref(),
                Some(&ac.unknowns),
                problem.c().as_ref(),
                xp.as_ref(),
            );
            factor.solve_in_place(z.as_mut())?;
            clear_upper_vector_state();
        }
        qr.apply_q(y.as_ref(), z.as_ref(), out);
        Ok(true)
    }

    /// One step of refinement of both parts of `X = Q [y; z]`:
    /// `Δy = R1⁻ᵀ (D − B X)_kept` for the constrained directions, then
    /// corrected semi-normal equations (Björck 1987) on the reduced problem
    /// at the moved point `X' = X + Q [Δy; 0]`: `g = (AQ2)ᵀ (C − A X')` (the
    /// residual of the original rows, projected by the `AQ2` the factor was
    /// built from, as the solve does), `Δz = H⁻¹ g`; `ΔX = Q [Δy; Δz]`.
    ///
    /// `Δy` is below a unit in the last place when the kept rows are well
    /// separated from the rank tolerance (the hard constraints hold to
    /// rounding either way). But a kept row whose remainder `ρ` is small
    /// puts `1/ρ` into `R1⁻ᵀ`, and with it an error of about `ε/ρ` into
    /// `y` that no residual of `A` sees, and that the row's own residual
    /// evaluated in working precision does not see either (it reproduces
    /// the rounding that caused it). The residual `D − B X` is therefore
    /// evaluated in twice the working precision
    /// ([`hard_residual_compensated`]): `Δy` is then that error, the
    /// forward-error estimate reports it, and applying it removes it
    /// (mixed-precision refinement, which converges while `ε/ρ < 1`).
    fn correction(
        &mut self,
        problem: &LseProblem,
        x: &Mat<f64>,
    ) -> Result<Option<Mat<f64>>, Error> {
        let Some(factor) = self.factor.as_mut() else {
            return Ok(None);
        };
        let qr = &*self.qr;
        let k = x.ncols();
        let a = problem.a();
        let rd = hard_residual_compensated(problem.b().as_ref(), problem.d().as_ref(), x.as_ref());
        let mut gy = Mat::<f64>::zeros(qr.rank(), k);
        qr.solve_r1t(rd.as_ref(), gy.as_mut());
        // X' = X + Q[Δy; 0] (X itself when Δy = 0, the common case).
        let shifted;
        let moved = if gy.norm_max() > 0.0 {
            let mut dxp = Mat::<f64>::zeros(qr.n(), k);
            let zero = Mat::<f64>::zeros(qr.n() - qr.rank(), k);
            qr.apply_q(gy.as_ref(), zero.as_ref(), dxp.as_mut());
            shifted = x + &dxp;
            &shifted
        } else {
            x
        };
        let mut dx = Mat::<f64>::zeros(qr.n(), k);
        if k == 3 {
            // The solve's 3-column kernels, over every column of A.
            let ws = &mut self.workspace;
            ws.residual_from(problem.c());
            subtract_product(&mut ws.residual, a.as_ref(), |j| j, moved);
            ws.project_residual(&self.aq2);
            factor.solve_in_place(ws.z.as_mut())?;
            clear_upper_vector_state();
            qr.apply_q(gy.as_ref(), ws.z.as_ref(), dx.as_mut());
        } else {
            let mut gz = mt_residual(
                self.aq2.as_ref(),
                a.as_ref(),
                None,
                problem.c().as_ref(),
                moved.as_ref(),
            );
            factor.solve_in_place(gz.as_mut())?;
            clear_upper_vector_state();
            qr.apply_q(gy.as_ref(), gz.as_ref(), dx.as_mut());
        }
        Ok(Some(dx))
    }

    fn refactorizations(&self) -> usize {
        self.factor.as_ref().map_or(0, |f| f.refactorizations())
    }

    fn skipped(&self) -> &[usize] {
        self.qr.skipped()
    }

    fn estimate_condition(&mut self) -> Result<ConditionEstimate, Error> {
        let Some(factor) = self.factor.as_mut() else {
            return Err(nothing_factored());
        };
        // The reduced normal matrix is rebuilt from `AQ2` (kept for the
        // solves) rather than stored: it costs one sparse product, and only
        // here and in `factored_matrix`.
        let lower = reduced_normal(&self.aq2);
        let mut matrix = LowerSymmetricOperator::new(lower.as_ref());
        let mut inverse = InverseOperator::new(lower.ncols(), |rhs| {
            factor.solve_in_place(rhs)?;
            Ok(())
        });
        condition::estimate(&mut matrix, &mut inverse, "(AQ2)ᵀ(AQ2)")
    }

    fn factored_matrix(&self) -> Option<SparseColMat<usize, f64>> {
        self.factor.as_ref()?;
        Some(lower_to_full(reduced_normal(&self.aq2).as_ref()))
    }
}

/// `tril((AQ2)ᵀ(AQ2))`.
fn reduced_normal(aq2: &SparseColMat<usize, f64>) -> SparseColMat<usize, f64> {
    NormalPattern::new(aq2.as_ref()).numeric(aq2.as_ref())
}
