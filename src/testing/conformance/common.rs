//! What the checks of every seam share: [`ensure`], the tolerances, dense
//! arithmetic on a lower triangle (the backward error of a matrix-level
//! solve) and the answer to a budget.

use faer::sparse::SparseColMatRef;
use faer::{Mat, MatMut, MatRef};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;

/// `Ok(())` when `condition` holds, else the message.
pub(super) fn ensure(condition: bool, message: impl FnOnce() -> String) -> Result<(), String> {
    if condition { Ok(()) } else { Err(message()) }
}

// ---------------------------------------------------------------------------
// Tolerances.

/// How closely a kept hard row must hold through the method: its residual
/// `‖b_k X − d_k‖₂` against its scale `Σ_j |b_kj| ‖X_j‖₂ + ‖d_k‖₂`, after
/// the solver's default refinement (what tests/rank_properties.rs holds
/// every exact method to).
pub const EXACTNESS: f64 = 1e-12;

/// How closely the method's solution must agree with the dense oracle,
/// `max |X − X*| / max |X*|` (the documented example of
/// [`crate::testing`]).
pub const ORACLE: f64 = 1e-8;

/// The largest normwise backward error
/// `‖K x − b‖∞ / (‖K‖∞ ‖x‖∞ + ‖b‖∞)` of a matrix-level solve: a stable
/// direct solve gives a small multiple of `ε`; an iterative one must
/// iterate to this.
pub const BACKWARD_ERROR: f64 = 1e-12;

/// How closely columns solved together must agree with the same columns
/// solved otherwise (relative to the solution's largest entry).
pub const COLUMNS: f64 = 1e-9;

// ---------------------------------------------------------------------------
// Dense arithmetic on the lower triangle.

/// `K X` for the symmetric `K` given by its lower triangle.
fn lower_times(lower: SparseColMatRef<'_, usize, f64>, x: MatRef<'_, f64>) -> Mat<f64> {
    let (ptr, rows, val) = (
        lower.symbolic().col_ptr(),
        lower.symbolic().row_idx(),
        lower.val(),
    );
    let mut y = Mat::<f64>::zeros(x.nrows(), x.ncols());
    for c in 0..x.ncols() {
        for j in 0..lower.ncols() {
            for p in ptr[j]..ptr[j + 1] {
                let i = rows[p];
                y[(i, c)] += val[p] * x[(j, c)];
                if i != j {
                    y[(j, c)] += val[p] * x[(i, c)];
                }
            }
        }
    }
    y
}

/// `‖K‖∞` for the symmetric `K` given by its lower triangle.
fn lower_norm_inf(lower: SparseColMatRef<'_, usize, f64>) -> f64 {
    let (ptr, rows, val) = (
        lower.symbolic().col_ptr(),
        lower.symbolic().row_idx(),
        lower.val(),
    );
    let mut sums = vec![0.0f64; lower.ncols()];
    for j in 0..lower.ncols() {
        for p in ptr[j]..ptr[j + 1] {
            sums[rows[p]] += val[p].abs();
            if rows[p] != j {
                sums[j] += val[p].abs();
            }
        }
    }
    sums.into_iter().fold(0.0, f64::max)
}

/// The largest normwise backward error over the columns of `x` as a
/// solution of `K x = b`; infinite for a non-finite `x`.
fn backward_error(lower: SparseColMatRef<'_, usize, f64>, x: &Mat<f64>, b: &Mat<f64>) -> f64 {
    let kx = lower_times(lower, x.as_ref());
    let norm = lower_norm_inf(lower);
    let mut worst = 0.0f64;
    for c in 0..x.ncols() {
        let column = |m: &Mat<f64>| (0..m.nrows()).map(|i| m[(i, c)].abs()).fold(0.0, f64::max);
        let residual = (0..x.nrows())
            .map(|i| (kx[(i, c)] - b[(i, c)]).abs())
            .fold(0.0, f64::max);
        let eta = residual / (norm * column(x) + column(b));
        worst = worst.max(if eta.is_nan() { f64::INFINITY } else { eta });
    }
    worst
}

/// `rows × cols` entries in `[−1, 1)` from `seed`.
pub(super) fn random_mat(rows: usize, cols: usize, seed: u64) -> Mat<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Mat::from_fn(rows, cols, |_, _| rng.random_range(-1.0..1.0))
}

/// Solves `K x = b` for `cols` random columns with `solve` and checks the
/// backward error against `lower`.
pub(super) fn check_solve(
    lower: SparseColMatRef<'_, usize, f64>,
    cols: usize,
    seed: u64,
    solve: impl FnOnce(MatMut<'_, f64>) -> Result<(), NumericalError>,
) -> Result<(), String> {
    let b = random_mat(lower.ncols(), cols, seed);
    let mut x = b.clone();
    solve(x.as_mut()).map_err(|e| format!("a solve of {cols} columns failed: {e}"))?;
    let eta = backward_error(lower, &x, &b);
    ensure(eta <= BACKWARD_ERROR, || {
        format!(
            "a solve of {cols} columns has a backward error of {eta:e} (at most {BACKWARD_ERROR:e})"
        )
    })
}

// ---------------------------------------------------------------------------
// Budgets.

/// `check` refuses one byte as too large and accepts an unlimited budget.
pub(super) fn budget_answers(
    check: impl Fn(MemoryBudget) -> Result<(), ProblemError>,
) -> Result<(), String> {
    match check(MemoryBudget::bytes(1)) {
        Err(ProblemError::TooLarge { detail }) => {
            ensure(!detail.is_empty(), || "an empty message".into())?
        }
        Err(e) => return Err(format!("a budget of one byte refused otherwise: {e}")),
        Ok(()) => return Err("a budget of one byte was accepted".into()),
    }
    check(MemoryBudget::unlimited()).map_err(|e| format!("an unlimited budget was refused: {e}"))
}
