//! Accuracy measures shared by the stability studies (Table 1, the weight
//! sweep, accuracy, conflicts): the table's Laplacians and penalty weight,
//! the Laplacian energy and its gap to a sparse-QR reference, and how a
//! failure or a small number is written in a cell.

use faer::Mat;
use lse_deform::problem::LseProblem;
use lse_deform::{Error, LaplacianKind};

use crate::harness::context::AnyError;

/// The penalty weight of the "soft only" column (see the section text for
/// why this one).
pub const TABLE_WEIGHT: f64 = 1e8;

/// The Laplacians of the table.
pub const LAPLACIANS: [LaplacianKind; 3] = [
    LaplacianKind::Uniform,
    LaplacianKind::Cotangent,
    LaplacianKind::IntrinsicDelaunay,
];

/// `‖A X − C‖²`, the Laplacian energy (plus soft rows) of `X`.
pub fn energy(problem: &LseProblem, x: &Mat<f64>) -> f64 {
    let r = problem.least_squares_residual(x);
    r * r
}

/// The relative energy gap `(E − E*)/E*` of `X` against the exact solution
/// `X*`, computed without cancellation as
/// `(‖AΔ‖² + 2⟨AΔ, AX* − C⟩) / ‖AX* − C‖²` with `Δ = X − X*` (the same
/// number as `(‖AX − C‖² − ‖AX* − C‖²) / ‖AX* − C‖²` in exact arithmetic,
/// but accurate also when the gap is far below machine precision times
/// `E*`). Negative when `X` violates the hard constraints and so reaches a
/// lower energy than the constrained minimum (a penalty solution). `NaN`
/// when `E* = 0`.
pub fn energy_gap(problem: &LseProblem, x: &Mat<f64>, x_star: &Mat<f64>) -> f64 {
    let delta = x - x_star;
    let a_delta = problem.a_times(&delta);
    let r_star = problem.a_times(x_star) - problem.c();
    let mut quad = 0.0;
    let mut cross = 0.0;
    for c in 0..a_delta.ncols() {
        for i in 0..a_delta.nrows() {
            quad += a_delta[(i, c)] * a_delta[(i, c)];
            cross += a_delta[(i, c)] * r_star[(i, c)];
        }
    }
    let e_star = r_star.norm_l2().powi(2);
    if e_star > 0.0 {
        (quad + 2.0 * cross) / e_star
    } else {
        f64::NAN
    }
}

/// The reference solution `X*` for problems whose hard rows are all
/// position constraints (one vertex, nonzero coefficient, each vertex at
/// most once): the known vertices are substituted and the remaining
/// unconstrained least-squares problem `min ‖A_U X_U − (C − A_K X_K)‖` is
/// solved by faer's sparse QR of `A_U`. Unlike every formulation compared
/// (which all factor a normal matrix, `κ(A_UᵀA_U) = κ(A_U)²`), this never
/// squares the condition number, so it is the most accurate `X*` available:
/// on a mesh whose reduced normal matrix has `κ ≈ 1e15` the formulations
/// keep only a digit or so while this keeps about eight. `None` when a hard
/// row is not a position constraint.
pub fn qr_reference(problem: &LseProblem) -> Result<Option<Mat<f64>>, AnyError> {
    use faer::linalg::solvers::SolveLstsq;
    use faer::sparse::{SparseColMat, SymbolicSparseColMat};
    let n = problem.n();
    let b = problem.b();
    let mut known: Vec<Option<[f64; 3]>> = vec![None; n];
    for k in 0..b.nrows() {
        let range = b.symbolic().row_range(k);
        let cols = &b.symbolic().col_idx()[range.clone()];
        let vals = &b.val()[range];
        if cols.len() != 1 || vals[0] == 0.0 || known[cols[0]].is_some() {
            return Ok(None);
        }
        let a = vals[0];
        known[cols[0]] = Some([0, 1, 2].map(|c| problem.d()[(k, c)] / a));
    }
    let unknown: Vec<usize> = (0..n).filter(|&v| known[v].is_none()).collect();
    let mut xk = Mat::<f64>::zeros(n, 3);
    for (v, t) in known.iter().enumerate() {
        if let Some(t) = t {
            for c in 0..3 {
                xk[(v, c)] = t[c];
            }
        }
    }
    if unknown.is_empty() {
        return Ok(Some(xk));
    }
    let a = problem.a();
    let (ptr, rows, val) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
    let mut col_ptr = vec![0usize];
    let mut row_idx = Vec::new();
    let mut values = Vec::new();
    for &v in &unknown {
        row_idx.extend_from_slice(&rows[ptr[v]..ptr[v + 1]]);
        values.extend_from_slice(&val[ptr[v]..ptr[v + 1]]);
        col_ptr.push(row_idx.len());
    }
    let symbolic =
        SymbolicSparseColMat::new_checked(a.nrows(), unknown.len(), col_ptr, None, row_idx);
    let a_u = SparseColMat::new(symbolic, values);
    let mut rhs = problem.c() - problem.a_times(&xk);
    let qr = a_u
        .sp_qr()
        .map_err(|e| format!("sparse QR of A_U failed: {e:?}"))?;
    qr.solve_lstsq_in_place(rhs.as_mut());
    let mut x = xk;
    for (j, &v) in unknown.iter().enumerate() {
        for c in 0..3 {
            x[(v, c)] = rhs[(j, c)];
        }
    }
    if x.col_iter().any(|col| col.iter().any(|v| !v.is_finite())) {
        return Err("sparse QR reference: non-finite solution".into());
    }
    Ok(Some(x))
}

/// `‖X − X*‖_F / ‖X*‖_F`.
pub fn relative_difference(x: &Mat<f64>, x_star: &Mat<f64>) -> f64 {
    let d = (x - x_star).norm_l2();
    let s = x_star.norm_l2();
    if s > 0.0 { d / s } else { d }
}

/// Formats a number as `1.2e-9` (or `0`).
pub fn sci(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if !v.is_finite() {
        format!("{v}")
    } else {
        let s = format!("{v:.1e}");
        // "1.0e8" → "1e8"
        s.replace(".0e", "e")
    }
}

/// A short kind of failure for tables: the variant of the library's error.
pub fn failure_kind(e: &Error) -> &'static str {
    use lse_deform::error::NumericalError as N;
    match e {
        Error::Numerical(N::NotPositiveDefinite { .. }) => "not positive definite",
        Error::Numerical(N::Breakdown { .. }) => "Cholesky breakdown",
        Error::Numerical(N::Singular { .. }) => "singular",
        Error::Numerical(N::FreeUnknown { .. }) => "singular (free unknown)",
        Error::Numerical(N::InaccurateSolution { .. }) => "inaccurate solution",
        Error::Numerical(N::LostAccuracy { .. }) => "lost accuracy (rejected)",
        Error::Numerical(N::NonFiniteSolution { .. }) => "non-finite solution",
        Error::Numerical(N::NonFiniteEnergy { .. }) => "non-finite ARAP energy",
        Error::Numerical(N::TargetOutOfRange { .. }) => "target out of range",
        Error::Numerical(N::SoftWeightOutOfRange { .. }) => "soft weight out of range",
        Error::Numerical(N::SoftWeightTooLarge { .. }) => "soft weight too large",
        Error::Numerical(N::Backend { .. }) => "back-end error",
        Error::Numerical(N::OutOfMemory { .. }) => "out of memory",
        Error::Problem(_) => "unsupported problem",
        Error::Constraint(_) => "bad constraint",
        Error::Mesh(_) => "bad mesh",
        Error::Io { .. } => "I/O error",
        Error::MatrixFile(_) => "bad matrix file",
        Error::MemoryLimit(_) => "bad LSE_MEMORY_LIMIT",
        Error::Interrupted => "interrupted",
    }
}
