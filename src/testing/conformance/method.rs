//! Checks through a method (a [`Formulation`] on a mesh's problem) that
//! several kits run, and the trap that interrupts a wrapped back end.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};

use faer::Mat;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::backend::BackendName;
use crate::constraints::ConstraintSet;
use crate::deform::Deformer;
use crate::error::{Error, ProblemError};
use crate::formulation::{Formulation, Refine};
use crate::laplacian::LaplacianKind;
use crate::limits::MemoryBudget;
use crate::problem::LseProblem;
use crate::resources::Resources;
use crate::solver::LseSolver;
use crate::testing::{
    ConstraintMix, dense_reference, independent_constraints, random_surface, relative_difference,
};

use super::common::{COLUMNS, EXACTNESS, ORACLE, ensure};

// ---------------------------------------------------------------------------
// Through the method.

/// The constraints of `mix` as a set.
fn constraint_set(mix: &ConstraintMix) -> Result<ConstraintSet, String> {
    ConstraintSet::from_vec(mix.constraints.clone()).map_err(|e| e.to_string())
}

/// The assembled problem of `mix` (in its units), not factored.
pub(super) fn problem(mix: &ConstraintMix, kind: LaplacianKind) -> Result<LseProblem, String> {
    Deformer::assemble(&mix.mesh, kind, &constraint_set(mix)?)
        .map_err(|e| format!("the case is not a problem: {e}"))
}

/// `mix` precomputed with `f` (the outer error: the case is not a
/// problem; the inner: the precompute's).
pub(super) fn factored(
    f: &dyn Formulation,
    mix: &ConstraintMix,
    kind: LaplacianKind,
) -> Result<Result<Deformer, Error>, String> {
    problem(mix, kind)?;
    let set = constraint_set(mix)?;
    Ok(Deformer::with_formulation(
        mix.mesh.clone(),
        kind,
        set,
        f,
        &Resources::default(),
    ))
}

/// `mix` precomputed with `f` and solved: `X` in the problem's units.
pub(super) fn solved(
    f: &dyn Formulation,
    mix: &ConstraintMix,
    kind: LaplacianKind,
) -> Result<(Deformer, Mat<f64>), String> {
    let mut d = factored(f, mix, kind)?.map_err(|e| format!("precompute: {e}"))?;
    let x = d.solve_matrix().map_err(|e| format!("solve: {e}"))?;
    Ok((d, x))
}

/// `Σ_j |b_kj| ‖X_j‖₂ + ‖d_k‖₂`: the scale of hard row `k`'s residual.
fn row_scale(problem: &LseProblem, k: usize, x: &Mat<f64>) -> f64 {
    let b = problem.b();
    let range = b.symbolic().row_range(k);
    let cols = &b.symbolic().col_idx()[range.clone()];
    let norm = |j: usize| {
        (0..x.ncols())
            .map(|c| x[(j, c)].powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let d = (0..x.ncols())
        .map(|c| problem.d()[(k, c)].powi(2))
        .sum::<f64>()
        .sqrt();
    cols.iter()
        .zip(&b.val()[range])
        .map(|(&j, &v)| v.abs() * norm(j))
        .sum::<f64>()
        + d
}

/// (a): every kept hard row (the first `rank`) holds to [`EXACTNESS`].
pub(super) fn exactness(
    f: &dyn Formulation,
    mix: &ConstraintMix,
    kind: LaplacianKind,
) -> Result<(), String> {
    let (d, x) = solved(f, mix, kind)?;
    let problem = d.problem();
    for k in 0..mix.rank {
        let (r, size) = (problem.hard_residual(k, &x), row_scale(problem, k, &x));
        ensure(r <= EXACTNESS * size, || {
            format!(
                "kept constraint {k} misses by {r:e}, {:e} of its scale {size:e}",
                r / size
            )
        })?;
    }
    Ok(())
}

/// (c): the solution agrees with the dense oracle on the kept rows.
pub(super) fn oracle(
    f: &dyn Formulation,
    mix: &ConstraintMix,
    kind: LaplacianKind,
) -> Result<(), String> {
    let (d, x) = solved(f, mix, kind)?;
    let kept: Vec<usize> = (0..mix.rank).collect();
    let reference = dense_reference(d.problem(), &kept);
    let diff = relative_difference(&x, &reference);
    ensure(diff <= ORACLE, || {
        format!("{diff:e} from the dense oracle (at most {ORACLE:e})")
    })
}

/// The name is not empty and stable, and the report of `f` on a fixed
/// problem satisfies `carries`.
pub(super) fn named(
    name: &BackendName,
    again: &BackendName,
    f: &dyn Formulation,
    carries: impl Fn(&crate::Report) -> bool,
) -> Result<(), String> {
    ensure(!name.trim().is_empty(), || "the name is empty".into())?;
    ensure(name == again, || {
        format!("the name changes between calls: '{name}', then '{again}'")
    })?;
    let mesh = random_surface(4, 4, 1);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let constraints = independent_constraints(&mesh, &mut rng, 5, false);
    let mix = ConstraintMix {
        rank: constraints.len(),
        mesh,
        constraints,
        redundant: Vec::new(),
        conflicting: Vec::new(),
    };
    let (d, _) = solved(f, &mix, LaplacianKind::Cotangent)?;
    let report = d.report();
    ensure(carries(report), || {
        format!(
            "the report does not carry the name '{name}': factor_backend {:?}, qr_backend {:?}",
            report.factor_backend, report.qr_backend
        )
    })
}

/// (f): a precompute within one byte is refused as too large.
pub(super) fn method_budget(
    f: &dyn Formulation,
    mix: &ConstraintMix,
    kind: LaplacianKind,
) -> Result<(), String> {
    let p = problem(mix, kind)?;
    match f.precompute_with(&p, &Resources::with_budget(MemoryBudget::bytes(1))) {
        Err(Error::Problem(ProblemError::TooLarge { .. })) => Ok(()),
        Err(e) => Err(format!(
            "a precompute within one byte failed otherwise: {e}"
        )),
        Ok(_) => Err("a precompute within one byte was not refused".into()),
    }
}

/// (g) through the method: seven columns `[C, 2C, C₀ + C₁]` (and `D`
/// alike) solved together give `[X, 2X, X₀ + X₁]` for the three-column
/// solution `X`.
pub(super) fn method_columns(
    f: &dyn Formulation,
    mix: &ConstraintMix,
    kind: LaplacianKind,
) -> Result<(), String> {
    let p = problem(mix, kind)?;
    let mut solver = LseSolver::with_formulation(p.clone(), f, &Resources::default())
        .map_err(|e| format!("precompute: {e}"))?;
    let x = solver.solve().map_err(|e| format!("solve: {e}"))?;
    let widen = |m: &Mat<f64>| {
        Mat::from_fn(m.nrows(), 7, |i, c| match c {
            0..3 => m[(i, c)],
            3..6 => 2.0 * m[(i, c - 3)],
            _ => m[(i, 0)] + m[(i, 1)],
        })
    };
    let (c, dd) = (widen(p.c()), widen(p.d()));
    let (wide, _) = solver
        .solve_columns(c.as_ref(), dd.as_ref(), Refine::Auto)
        .map_err(|e| format!("a solve of seven columns failed: {e}"))?;
    let diff = relative_difference(&wide, &widen(&x));
    ensure(diff <= COLUMNS, || {
        format!(
            "seven columns solved together differ from the three-column solution by {diff:e} (at most {COLUMNS:e})"
        )
    })
}

// ---------------------------------------------------------------------------
// Interruption: a back end wrapped to spring a trap at one phase.

/// Where the trap springs.
#[derive(Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub(super) enum Phase {
    None = 0,
    Factorize = 1,
    Solve = 2,
}

/// A trap armed for one phase: when the wrapped back end has done that
/// phase, the trap springs (once) and waits one consult interval, so that
/// the library's next check asks the hook, which then says stop.
#[derive(Default)]
pub(super) struct Trap {
    armed: AtomicU8,
    sprung: Arc<AtomicBool>,
}

impl Trap {
    fn arm(&self, phase: Phase) {
        self.sprung.store(false, Ordering::SeqCst);
        self.armed.store(phase as u8, Ordering::SeqCst);
    }

    pub(super) fn at(&self, phase: Phase) {
        let armed = self.armed.compare_exchange(
            phase as u8,
            Phase::None as u8,
            Ordering::SeqCst,
            Ordering::SeqCst,
        );
        if armed.is_ok() {
            self.sprung.store(true, Ordering::SeqCst);
            std::thread::sleep(crate::interrupt::CONSULT_INTERVAL);
        }
    }

    fn sprung(&self) -> bool {
        self.sprung.load(Ordering::SeqCst)
    }

    /// Runs `f` with a hook that says stop once the trap has sprung.
    fn run<T>(&self, f: impl FnOnce() -> T) -> T {
        let sprung = Arc::clone(&self.sprung);
        crate::interrupt::with_hook(move || sprung.load(Ordering::SeqCst), f)
    }
}

/// (f): interrupted after the back end factored (and, when `solves`,
/// after it solved), the method ends in [`Error::Interrupted`], then
/// precomputes and solves as before.
pub(super) fn interruption(
    f: &dyn Formulation,
    trap: &Trap,
    mix: &ConstraintMix,
    kind: LaplacianKind,
    solves: bool,
) -> Result<(), String> {
    trap.arm(Phase::Factorize);
    let outcome = trap.run(|| factored(f, mix, kind))?.map(|_| ());
    ensure(trap.sprung(), || {
        "the back end was never asked to factor".into()
    })?;
    ensure(matches!(outcome, Err(Error::Interrupted)), || {
        format!("a precompute interrupted after the factorisation ended in {outcome:?}")
    })?;
    trap.arm(Phase::None);
    let mut d =
        factored(f, mix, kind)?.map_err(|e| format!("precompute after an interruption: {e}"))?;
    let x = d
        .solve_matrix()
        .map_err(|e| format!("solve after an interrupted precompute: {e}"))?;
    if solves {
        trap.arm(Phase::Solve);
        let outcome = trap.run(|| d.solve_matrix());
        ensure(matches!(outcome, Err(Error::Interrupted)), || {
            format!("a solve interrupted after the back end solved ended in {outcome:?}")
        })?;
        trap.arm(Phase::None);
        let again = d
            .solve_matrix()
            .map_err(|e| format!("solve after an interrupted solve: {e}"))?;
        let diff = relative_difference(&again, &x);
        ensure(diff <= COLUMNS, || {
            format!("after an interrupted solve, the solution moved by {diff:e}")
        })?;
    }
    Ok(())
}
