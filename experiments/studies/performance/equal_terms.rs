//! The performance section's equal-terms table: the analysis and the
//! numeric factorisation of one reduced normal matrix on faer supernodal,
//! CHOLMOD and MUMPS (those in the build), each on its own ordering and
//! threads and with one AMD permutation (computed once per repetition and
//! given to every back end) and one thread, interleaved repetition by
//! repetition (docs/equal-terms.md).

use std::sync::Arc;
use std::time::Instant;

use faer::sparse::SparseColMat;
use lse_deform::backend::ordering::FactorPlan;
use lse_deform::backend::spd::{FaerLlt, SpdBackend, SpdSymbolic};
use lse_deform::resources::{FillOrdering, Threads};
use serde::Serialize;

use crate::harness::context::AnyError;
use crate::harness::rows::{fmt_time, median};
use crate::harness::timing::Terms;

/// One back end on one matrix under one set of terms (medians).
#[derive(Debug, Clone, Serialize)]
pub struct EqualRow {
    pub case: String,
    pub backend: String,
    pub terms: Terms,
    /// What the back end reports it used.
    pub ordering: String,
    pub threads: Option<usize>,
    /// Computing the held permutation (0 for the back end's own, which is
    /// inside the analysis).
    pub ordering_s: f64,
    pub analyse_s: f64,
    pub factorise_s: f64,
    pub factor_nnz: usize,
}

/// The back ends compared: faer supernodal, and CHOLMOD and MUMPS (one
/// rank, this process) when built.
fn backends() -> Vec<Arc<dyn SpdBackend>> {
    let mut out: Vec<Arc<dyn SpdBackend>> = vec![Arc::new(FaerLlt::supernodal())];
    out.extend(super::reference_backend());
    out.extend(super::mumps_backend());
    out
}

/// Timings of one back end under one set of terms.
#[derive(Default)]
struct Runs {
    ordering: Vec<f64>,
    analyse: Vec<f64>,
    factorise: Vec<f64>,
    used: Option<(String, Option<usize>, usize)>,
}

impl Runs {
    /// One analysis (own, or with `plan`) and factorisation, timed.
    fn run(
        &mut self,
        backend: &dyn SpdBackend,
        normal: &SparseColMat<usize, f64>,
        plan: Option<(&FactorPlan, f64)>,
    ) -> Result<(), AnyError> {
        let t0 = Instant::now();
        let symbolic: Box<dyn SpdSymbolic> = match plan {
            None => backend.analyze(normal.symbolic())?,
            Some((plan, _)) => backend.analyze_planned(normal.symbolic(), plan)?,
        };
        let t1 = Instant::now();
        let factor = symbolic.factorize(normal.as_ref())?;
        let t2 = Instant::now();
        self.ordering.push(plan.map_or(0.0, |(_, s)| s));
        self.analyse.push((t1 - t0).as_secs_f64());
        self.factorise.push((t2 - t1).as_secs_f64());
        let used = symbolic.plan_used();
        self.used = Some((used.ordering.into_owned(), used.threads, factor.nnz()));
        Ok(())
    }
}

/// `reps` interleaved repetitions on `normal` (its lower triangle): every
/// back end on its own terms, then the held permutation (computed once
/// per repetition, timed) on every back end with one thread.
pub fn measure(
    case: &str,
    normal: &SparseColMat<usize, f64>,
    reps: usize,
) -> Result<Vec<EqualRow>, AnyError> {
    let backends = backends();
    let mut runs: Vec<[Runs; 2]> = backends.iter().map(|_| Default::default()).collect();
    let one = Threads::count(1).unwrap_or_default();
    for _ in 0..reps.max(1) {
        let t = Instant::now();
        let plan = FactorPlan::new(
            &FillOrdering::Amd,
            one,
            normal.symbolic(),
            &|k| k,
            normal.ncols(),
        )?;
        let ordering_s = t.elapsed().as_secs_f64();
        for (b, r) in backends.iter().zip(runs.iter_mut()) {
            r[0].run(b.as_ref(), normal, None)?;
            r[1].run(b.as_ref(), normal, Some((&plan, ordering_s)))?;
        }
    }
    let mut rows = Vec::new();
    for (b, pair) in backends.iter().zip(runs) {
        for (terms, r) in Terms::ALL.into_iter().zip(pair) {
            let (ordering, threads, factor_nnz) = r.used.unwrap_or_default();
            rows.push(EqualRow {
                case: case.into(),
                backend: b.name().into_owned(),
                terms,
                ordering,
                threads,
                ordering_s: median(&r.ordering),
                analyse_s: median(&r.analyse),
                factorise_s: median(&r.factorise),
                factor_nnz,
            });
        }
    }
    Ok(rows)
}

/// The table's header.
pub const HEADER: [&str; 9] = [
    "matrix",
    "back end",
    "terms",
    "ordering used",
    "threads",
    "ordering",
    "analysis",
    "factorisation",
    "nnz(L)",
];

/// A table row.
pub fn cells(r: &EqualRow) -> Vec<String> {
    vec![
        r.case.clone(),
        r.backend.clone(),
        r.terms.word().into(),
        r.ordering.clone(),
        r.threads.map_or("—".into(), |t| t.to_string()),
        if r.ordering_s > 0.0 {
            fmt_time(r.ordering_s)
        } else {
            "(in analysis)".into()
        },
        fmt_time(r.analyse_s),
        fmt_time(r.factorise_s),
        format!("{:.2}M", r.factor_nnz as f64 / 1e6),
    ]
}
