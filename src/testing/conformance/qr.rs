//! The kit of the QR seam: [`qr`], its checks through the method and at
//! the matrix level ([`qr_operations`]), and its back end with a trap.

use std::sync::Arc;

use faer::sparse::{SparseColMat, SparseRowMat, Triplet};
use faer::{Mat, MatRef};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::backend::BackendName;
use crate::backend::qr::{ConstraintQr, QrBackend, RankTolerance, particular_solution};
use crate::backend::spd::FaerLlt;
use crate::error::{Error, ProblemError};
use crate::formulation::{Formulation, NullSpaceQr};
use crate::laplacian::LaplacianKind;
use crate::resources::Resources;
use crate::testing::{
    ConstraintMix, ConstructedLse, ConstructedMix, RandomLse, constructed_lses, constructed_mixes,
    laplacian_kinds, random_lses,
};

use super::common::{budget_answers, ensure, random_mat};
use super::kit::{Kit, KitConfig, KitFailure, KitReport, Property, Seam, quarter};
use super::method::{Phase, Trap, exactness, interruption, method_columns, named, oracle, solved};
use super::strategies::mixes;

// ---------------------------------------------------------------------------
// The call.

/// Runs the kit on a QR back end: [`Property::Named`],
/// [`Property::Exactness`], [`Property::RankSets`] and
/// [`Property::Oracle`] through the null-space method (faer's Cholesky),
/// [`Property::Operations`], [`Property::SeveralFactors`],
/// [`Property::Budget`], [`Property::Interruption`], [`Property::Columns`].
///
/// Errors: every failing property with its minimal case ([`KitFailure`]).
pub fn qr(backend: Arc<dyn QrBackend>, config: &KitConfig) -> Result<KitReport, KitFailure> {
    let mut kit = Kit::new(Seam::Qr, backend.name(), config);
    let cases = kit.cases();
    let method = || NullSpaceQr::new(Arc::clone(&backend), Arc::new(FaerLlt::auto()));
    kit.fixed(Property::Named, || {
        let name = backend.name();
        named(&name, &backend.name(), &method(), |r| {
            r.qr_backend.as_ref() == Some(&name)
        })
    });
    kit.generated(Property::Exactness, cases, mixes(), |(mix, kind)| {
        exactness(&method(), &mix, kind)
    });
    kit.generated(Property::RankSets, cases, random_lses(), |lse| {
        qr_random_sets(&*backend, &lse)
    });
    kit.generated(Property::RankSets, cases, constructed_lses(), |lse| {
        qr_constructed_sets(&*backend, &lse)
    });
    kit.generated(Property::RankSets, cases, constructed(), |(mix, kind)| {
        method_sets(&method(), &mix, kind)
    });
    kit.generated(Property::Operations, cases, random_lses(), |lse| {
        qr_operations_of(&*backend, &lse, 3)
    });
    kit.generated(Property::Oracle, cases, mixes(), |(mix, kind)| {
        oracle(&method(), &mix, kind)
    });
    kit.generated(
        Property::SeveralFactors,
        cases,
        (random_lses(), random_lses()),
        |(p, q)| qr_several(&*backend, &p, &q),
    );
    kit.generated(Property::Budget, cases, random_lses(), |lse| {
        qr_budget(&*backend, &lse)
    });
    kit.generated(
        Property::Interruption,
        quarter(cases),
        mixes(),
        |(mix, kind)| {
            let trap = Arc::new(Trap::default());
            let spy: Arc<dyn QrBackend> = Arc::new(SpyQr {
                inner: Arc::clone(&backend),
                trap: Arc::clone(&trap),
            });
            let f = NullSpaceQr::new(spy, Arc::new(FaerLlt::auto()));
            interruption(&f, &trap, &mix, kind, false)
        },
    );
    kit.generated(Property::Columns, cases, random_lses(), |lse| {
        qr_operations_of(&*backend, &lse, 7)
    });
    kit.generated(Property::Columns, cases, mixes(), |(mix, kind)| {
        method_columns(&method(), &mix, kind)
    });
    kit.finish()
}

// ---------------------------------------------------------------------------
// Cases.

/// [`constructed_mixes`] with a Laplacian kind.
fn constructed() -> impl Strategy<Value = (ConstructedMix, LaplacianKind)> {
    (constructed_mixes(), laplacian_kinds())
}

// ---------------------------------------------------------------------------
// Through the method.

/// (b) through the method: the report's rank, redundant and conflicting
/// sets are the constructed ones.
fn method_sets(
    f: &dyn Formulation,
    mix: &ConstructedMix,
    kind: LaplacianKind,
) -> Result<(), String> {
    let as_mix = ConstraintMix {
        mesh: mix.mesh.clone(),
        constraints: mix.constraints.clone(),
        rank: mix.kept.len(),
        redundant: mix.redundant.clone(),
        conflicting: mix.conflicting.clone(),
    };
    let (d, _) = solved(f, &as_mix, kind)?;
    let r = d.report();
    let conflicting: Vec<usize> = r.conflicting.iter().map(|c| c.index).collect();
    ensure(r.rank == Some(mix.kept.len()), || {
        format!("rank {:?}, constructed {}", r.rank, mix.kept.len())
    })?;
    ensure(r.redundant == mix.redundant, || {
        format!(
            "redundant {:?}, constructed {:?}",
            r.redundant, mix.redundant
        )
    })?;
    ensure(conflicting == mix.conflicting, || {
        format!(
            "conflicting {conflicting:?}, constructed {:?}",
            mix.conflicting
        )
    })
}

// ---------------------------------------------------------------------------
// QR at the matrix level.

/// `rows` sorted.
fn sorted(rows: &[usize]) -> Vec<usize> {
    let mut rows = rows.to_vec();
    rows.sort_unstable();
    rows
}

/// The factor's rank, kept and skipped rows are `kept` and `skipped`.
fn sets_are(qr: &dyn ConstraintQr, kept: &[usize], skipped: &[usize]) -> Result<(), String> {
    ensure(qr.rank() == kept.len(), || {
        format!("rank {}, constructed {}", qr.rank(), kept.len())
    })?;
    ensure(sorted(qr.kept()) == sorted(kept), || {
        format!("kept {:?}, constructed {kept:?}", sorted(qr.kept()))
    })?;
    ensure(qr.skipped() == skipped, || {
        format!(
            "skipped {:?} (increasing), constructed {skipped:?}",
            qr.skipped()
        )
    })
}

/// (b) on [`random_lses`]: independent, redundant and conflicting rows.
fn qr_random_sets(backend: &dyn QrBackend, lse: &RandomLse) -> Result<(), String> {
    let b = lse.problem.b();
    let qr = backend
        .factor(b.as_ref(), RankTolerance::default())
        .map_err(|e| format!("QR: {e}"))?;
    let skipped = sorted(&[&lse.redundant[..], &lse.conflicting[..]].concat());
    sets_are(&*qr, &lse.independent_rows, &skipped)
}

/// (b) on [`constructed_lses`]: rows either side of the tolerance, scaled
/// by `10^±8`.
fn qr_constructed_sets(backend: &dyn QrBackend, lse: &ConstructedLse) -> Result<(), String> {
    let b = lse.problem.b();
    let qr = backend
        .factor(b.as_ref(), RankTolerance::default())
        .map_err(|e| format!("QR: {e}"))?;
    let skipped = sorted(&[&lse.redundant[..], &lse.conflicting[..]].concat());
    sets_are(&*qr, &lse.kept, &skipped)
}

/// [`Property::Operations`] (and with `cols = 7`, [`Property::Columns`])
/// on the factor of `lse`'s `B`.
fn qr_operations_of(backend: &dyn QrBackend, lse: &RandomLse, cols: usize) -> Result<(), String> {
    let b = lse.problem.b();
    let qr = backend
        .factor(b.as_ref(), RankTolerance::default())
        .map_err(|e| format!("QR: {e}"))?;
    qr_operations(&*qr, b, cols, lse.problem.n() as u64)
}

/// `max |m|`.
fn max_abs(m: MatRef<'_, f64>) -> f64 {
    let mut x = 0.0f64;
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            x = x.max(m[(i, j)].abs());
        }
    }
    x
}

/// The rows `rows` of `b` as a CSC matrix.
fn rows_as_csc(b: &SparseRowMat<usize, f64>, rows: &[usize]) -> SparseColMat<usize, f64> {
    let mut triplets = Vec::new();
    for (k, &i) in rows.iter().enumerate() {
        let range = b.symbolic().row_range(i);
        let cols = &b.symbolic().col_idx()[range.clone()];
        triplets.extend(
            cols.iter()
                .zip(&b.val()[range])
                .map(|(&j, &v)| Triplet::new(k, j, v)),
        );
    }
    SparseColMat::try_new_from_triplets(rows.len(), b.ncols(), &triplets).expect("in range")
}

/// The checks of [`Property::Operations`] on a factor `qr` of `b`, with
/// operands of `cols ≥ 3` columns drawn from `seed`: `Q` applied after `Qᵀ`
/// is the identity and `Qᵀ` keeps norms (to `1e-12`), `B_kept Q2 = 0`,
/// `A Q2` equals `A` times `Q [0; I]` (for a random sparse `A`), and
/// `x = Q [R1⁻ᵀ D_kept; 0]` satisfies `B_kept x = D_kept`. Public so that
/// a QR back end's own fixed cases can use it.
///
/// Errors: the first check that fails, in words.
pub fn qr_operations(
    qr: &dyn ConstraintQr,
    b: &SparseRowMat<usize, f64>,
    cols: usize,
    seed: u64,
) -> Result<(), String> {
    let (n, r) = (qr.n(), qr.rank());
    ensure(n == b.ncols() && r <= n, || {
        format!("n = {n}, rank {r} for B of {} columns", b.ncols())
    })?;
    ensure((0..n - r).all(|k| qr.free_unknown(k) < n), || {
        "free_unknown names no unknown".into()
    })?;
    round_trip(qr, cols, seed)?;
    let bq2 = qr.mul_a_q2(rows_as_csc(b, qr.kept()).as_ref()).to_dense();
    let scale = max_abs(b.to_dense().as_ref()).max(1.0);
    let err = max_abs(bq2.as_ref());
    ensure(
        bq2.ncols() == n - r && err < 1e-13 * scale * (n as f64).sqrt(),
        || {
            format!(
                "B_kept Q2 has {} columns and entries up to {err:e}",
                bq2.ncols()
            )
        },
    )?;
    a_q2_agrees(qr, seed)?;
    particular_solves(qr, b, cols, seed)
}

/// `Q Qᵀ x = x` and `‖Qᵀ x‖ = ‖x‖` for `cols` random columns.
fn round_trip(qr: &dyn ConstraintQr, cols: usize, seed: u64) -> Result<(), String> {
    let (n, r) = (qr.n(), qr.rank());
    let x = random_mat(n, cols, seed);
    let (mut y, mut z) = (Mat::zeros(r, cols), Mat::zeros(n - r, cols));
    qr.apply_qt(x.as_ref(), y.as_mut(), z.as_mut());
    let mut back = Mat::zeros(n, cols);
    qr.apply_q(y.as_ref(), z.as_ref(), back.as_mut());
    let err = max_abs((&back - &x).as_ref());
    ensure(err < 1e-12, || {
        format!("Q Qᵀ x differs from x by {err:e} ({cols} columns)")
    })?;
    let (nx, nyz) = (
        x.norm_l2(),
        (y.norm_l2().powi(2) + z.norm_l2().powi(2)).sqrt(),
    );
    ensure((nx - nyz).abs() < 1e-12 * nx.max(1.0), || {
        format!("‖Qᵀx‖ = {nyz}, ‖x‖ = {nx}")
    })
}

/// `A Q2` by [`ConstraintQr::mul_a_q2`] equals `A` times `Q [0; I]` for a
/// random sparse `A` of seven rows.
fn a_q2_agrees(qr: &dyn ConstraintQr, seed: u64) -> Result<(), String> {
    let (n, r) = (qr.n(), qr.rank());
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5a);
    let mut triplets = Vec::new();
    for i in 0..7 {
        for j in 0..n {
            if rng.random_bool(0.3) {
                triplets.push(Triplet::new(i, j, rng.random_range(-1.0..1.0)));
            }
        }
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(7, n, &triplets).expect("in range");
    let aq2 = qr.mul_a_q2(a.as_ref()).to_dense();
    let mut q2 = Mat::<f64>::zeros(n, n - r);
    let identity = Mat::<f64>::identity(n - r, n - r);
    qr.apply_q(
        Mat::<f64>::zeros(r, n - r).as_ref(),
        identity.as_ref(),
        q2.as_mut(),
    );
    let err = max_abs((&aq2 - a.to_dense() * &q2).as_ref());
    ensure(err < 1e-12, || {
        format!("mul_a_q2 differs from A Q2 by {err:e}")
    })
}

/// `x = Q [R1⁻ᵀ D_kept; 0]` satisfies every kept row, for `cols` columns.
fn particular_solves(
    qr: &dyn ConstraintQr,
    b: &SparseRowMat<usize, f64>,
    cols: usize,
    seed: u64,
) -> Result<(), String> {
    let d = random_mat(b.nrows(), cols, seed ^ 0xd);
    let (_, x) = particular_solution(qr, d.as_ref());
    let bx = b.to_dense() * &x;
    let size = max_abs(x.as_ref()).max(1.0) * max_abs(b.to_dense().as_ref()).max(1.0);
    for &i in qr.kept() {
        for c in 0..cols {
            let e = (bx[(i, c)] - d[(i, c)]).abs();
            ensure(e < 1e-10 * size, || {
                format!("kept row {i}, column {c}: B x − D = {e:e}")
            })?;
        }
    }
    Ok(())
}

/// (e) QR: two factorisations alive at once, each solving for its own
/// `B`.
fn qr_several(backend: &dyn QrBackend, p: &RandomLse, q: &RandomLse) -> Result<(), String> {
    let tol = RankTolerance::default();
    let fp = backend
        .factor(p.problem.b().as_ref(), tol)
        .map_err(|e| format!("QR: {e}"))?;
    let fq = backend
        .factor(q.problem.b().as_ref(), tol)
        .map_err(|e| format!("QR: {e}"))?;
    for (i, (f, b)) in [
        (&fp, p.problem.b()),
        (&fq, q.problem.b()),
        (&fp, p.problem.b()),
    ]
    .into_iter()
    .enumerate()
    {
        particular_solves(&**f, b, 3, i as u64)
            .map_err(|e| format!("factor {} of two: {e}", i % 2))?;
    }
    Ok(())
}

/// (f) QR: a factorisation within one byte is refused as too large, an
/// unlimited one is not.
fn qr_budget(backend: &dyn QrBackend, lse: &RandomLse) -> Result<(), String> {
    let b = lse.problem.b();
    let within = |budget| match backend.factor_with(
        b.as_ref(),
        RankTolerance::default(),
        &Resources::with_budget(budget),
    ) {
        Ok(_) => Ok(()),
        Err(Error::Problem(e)) => Err(e),
        Err(e) => Err(ProblemError::InvalidArgument {
            message: format!("(not a problem error) {e}"),
        }),
    };
    budget_answers(within)
}

// ---------------------------------------------------------------------------
// Interruption: the back end with a trap.

/// A QR back end with a [`Trap`] (its factorisation is its one phase).
struct SpyQr {
    inner: Arc<dyn QrBackend>,
    trap: Arc<Trap>,
}

impl QrBackend for SpyQr {
    fn name(&self) -> BackendName {
        self.inner.name()
    }

    fn factor_with(
        &self,
        b: faer::sparse::SparseRowMatRef<'_, usize, f64>,
        tolerance: RankTolerance,
        resources: &Resources,
    ) -> Result<Box<dyn ConstraintQr>, Error> {
        let qr = self.inner.factor_with(b, tolerance, resources)?;
        self.trap.at(Phase::Factorize);
        Ok(qr)
    }
}
