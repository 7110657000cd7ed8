//! Performance against CHOLMOD and the memory-bandwidth floor.
//!
//! Every figure is a median of repetitions measured **in this process, side
//! by side**: each repetition runs ours and the reference back to back, so
//! that the noise of a shared 2-core machine hits both alike. The MUMPS
//! rows (feature `mumps`; one rank in this process) are a comparison on the
//! same matrix, without a target. The targets:
//!
//! 1. precompute of the paper's method (QR + preparation + normal matrix +
//!    symbolic + numeric, SparseGivens × faer supernodal) against CHOLMOD's
//!    factorisation of the same reduced normal matrix;
//! 2. per-frame solve (y, right-hand side, two triangular solves, X = Q[y; z])
//!    against CHOLMOD's solve with three right-hand sides on its factor and
//!    against the bandwidth floor 2 × factor bytes / read bandwidth, the
//!    bandwidth measured here with an 8-accumulator streaming sum;
//! 3. precompute with 300 and 2000 relative constraints against positions
//!    only;
//! 4. a 17-weight penalty sweep against 17 numeric factorisations + one
//!    analysis;
//! 5. the large mesh (igea 537k with a mesh directory): precompute, solve,
//!    peak memory (measured in a child process, VmHWM);
//! 6. set-up (read + L + A) of the large mesh;
//! 7. precompute and solve against vertex count, with fitted slopes;
//! 8. the refine phase of a later `auto` refinement with one factor against
//!    the solve phase (at most 1.5×; a correction repeats the solve's passes,
//!    docs/refinement.md §7), on the Bunny and the Dragon
//!    (generated 35k and 50k bumpy spheres without a mesh directory), with
//!    the corrections applied and the condition estimate that explains their
//!    number.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use faer::Mat;
use lse_deform::backend::qr::{QrBackend, RankTolerance, SparseGivens};
use lse_deform::backend::spd::{FaerLlt, SpdBackend, SpdFactor};
use lse_deform::constraints::ConstraintSet;
use lse_deform::formulation::{NullSpaceQr, Penalty, PenaltySweep};
use lse_deform::mesh::{Mesh, generate, read_mesh};
use lse_deform::report::Timings;
use lse_deform::scene::{FixedAndHandle, MixedScene};
use lse_deform::solver::LseSolver;
use lse_deform::sparse::NormalPattern;
use lse_deform::{Deformer, LaplacianKind};
use serde::Serialize;

use crate::harness::context::AnyError;
use crate::harness::context::Context;

mod equal_terms;
use crate::harness::plot::{self, LegendPosition, Output, ScatterFits, Series};
use crate::harness::registry::{Experiment, Input, Summary};
use crate::harness::rows::{fmt_time, markdown_table, median};

/// The folder and command-line word of this experiment.
pub const NAME: &str = "performance";

/// This study's entry in the list of experiments.
pub const EXPERIMENT: Experiment = Experiment {
    name: NAME,
    title: "Performance against CHOLMOD and the bandwidth floor",
    inputs: &[Input::Meshes, Input::SuiteSparse, Input::Mumps],
    run,
};

/// The reference the targets compare against, when it is compiled in.
#[cfg(feature = "suitesparse")]
fn reference_backend() -> Option<Arc<dyn SpdBackend>> {
    Some(Arc::new(lse_deform::backend::spd::Cholmod))
}

#[cfg(not(feature = "suitesparse"))]
fn reference_backend() -> Option<Arc<dyn SpdBackend>> {
    None
}

/// MUMPS on one rank in this process, when it is compiled in: measured
/// beside CHOLMOD on the same matrix, a comparison without a target.
#[cfg(feature = "mumps")]
fn mumps_backend() -> Option<Arc<dyn SpdBackend>> {
    crate::harness::timing::start_mpi();
    Some(Arc::new(
        lse_deform::backend::mumps::MumpsLlt::new(None).ok()?,
    ))
}

#[cfg(not(feature = "mumps"))]
fn mumps_backend() -> Option<Arc<dyn SpdBackend>> {
    None
}

/// The paper's method on our fastest back ends.
fn ours() -> NullSpaceQr {
    NullSpaceQr::new(
        Arc::new(SparseGivens::default()),
        Arc::new(FaerLlt::supernodal()),
    )
}

/// One row of the targets table.
#[derive(Debug, Clone, Serialize)]
struct TargetRow {
    target: String,
    case: String,
    ours: String,
    reference: String,
    ratio: Option<f64>,
    limit: String,
    met: Option<bool>,
}

impl TargetRow {
    fn cells(&self) -> Vec<String> {
        vec![
            self.target.clone(),
            self.case.clone(),
            self.ours.clone(),
            self.reference.clone(),
            self.ratio.map_or("—".into(), |r| format!("{r:.2}")),
            self.limit.clone(),
            match self.met {
                Some(true) => "met".into(),
                Some(false) => "**missed**".into(),
                None => "—".into(),
            },
        ]
    }
}

fn row(
    target: &str,
    case: &str,
    ours: String,
    reference: String,
    ratio: Option<f64>,
    limit: f64,
) -> TargetRow {
    TargetRow {
        target: target.into(),
        case: case.into(),
        ours,
        reference,
        ratio,
        limit: format!("≤ {limit}×"),
        met: ratio.map(|r| r <= limit),
    }
}

/// Single-thread streaming read bandwidth in bytes/s: the median over
/// passes of an 8-accumulator sum over 256 MiB (far larger than the caches),
/// so that the loop is bound by memory, not by a dependency chain of adds.
pub fn read_bandwidth(passes: usize) -> f64 {
    let len = 32 << 20;
    let data: Vec<f64> = (0..len).map(|i| (i % 7) as f64).collect();
    let mut times = Vec::with_capacity(passes);
    for _ in 0..passes {
        let t = Instant::now();
        let mut acc = [0.0f64; 8];
        for chunk in data.chunks_exact(8) {
            for k in 0..8 {
                acc[k] += chunk[k];
            }
        }
        std::hint::black_box(acc);
        times.push(t.elapsed().as_secs_f64());
    }
    (len * 8) as f64 / median(&times)
}

/// The lower triangle of the reduced normal matrix `(AQ2)ᵀ(AQ2)` that our
/// precompute factors, built by the same public pieces.
fn reduced_normal(d: &Deformer) -> Result<faer::sparse::SparseColMat<usize, f64>, AnyError> {
    let p = d.problem();
    let qr = SparseGivens::default().factor(p.b().as_ref(), RankTolerance::default())?;
    let aq2 = qr.mul_a_q2(p.a().as_ref());
    Ok(NormalPattern::new(aq2.as_ref()).numeric(aq2.as_ref()))
}

fn precompute_total(t: &Timings) -> f64 {
    t.qr + t.preparation + t.normal_matrix + t.symbolic + t.numeric
}

/// Timings of the reference on the reduced normal matrix.
#[derive(Debug, Clone, Default, Serialize)]
struct ReferenceTimes {
    analyse_s: f64,
    factorise_s: f64,
    solve_s: f64,
    factor_nnz: usize,
    factor_bytes: usize,
}

/// Precompute and solve of ours and of the reference, interleaved.
#[derive(Debug, Clone, Serialize)]
struct SideBySide {
    case: String,
    vertices: usize,
    unknowns: usize,
    ours_precompute_s: f64,
    ours_phases_s: [f64; 5],
    /// The solve phase of the null-space method (docs/formulations.md §2:
    /// `y`, right-hand side, two triangular solves, `X = Q[y; z]`;
    /// `report.timings_s.solve`).
    ours_solve_s: f64,
    /// The whole `solve_matrix` call: the solve phase plus the checks and
    /// diagnostics the library computes after it (non-finite check,
    /// constraint residuals, ‖AX − C‖).
    ours_call_s: f64,
    ours_factor_nnz: usize,
    ours_factor_bytes: usize,
    /// CHOLMOD (`None` without `--features suitesparse`).
    reference: Option<ReferenceTimes>,
    /// MUMPS on one rank (`None` without `--features mumps`).
    mumps: Option<ReferenceTimes>,
}

/// The "ours" cell of a solve target: the solve phase, and the whole call.
fn solve_cell(case: &SideBySide) -> String {
    format!(
        "{} (whole call with diagnostics {})",
        ms(case.ours_solve_s),
        ms(case.ours_call_s)
    )
}

/// One reference back end's repetitions on the reduced normal matrix.
struct ReferenceRuns {
    backend: Arc<dyn SpdBackend>,
    analyse: Vec<f64>,
    factorise: Vec<f64>,
    solve: Vec<f64>,
    factor: Option<Box<dyn SpdFactor>>,
}

impl ReferenceRuns {
    fn new(backend: Arc<dyn SpdBackend>) -> ReferenceRuns {
        ReferenceRuns {
            backend,
            analyse: Vec::new(),
            factorise: Vec::new(),
            solve: Vec::new(),
            factor: None,
        }
    }

    /// One analysis and factorisation from scratch, timed.
    fn precompute(
        &mut self,
        normal: &faer::sparse::SparseColMat<usize, f64>,
    ) -> Result<(), AnyError> {
        drop(self.factor.take()); // free the previous factor first
        let t0 = Instant::now();
        let sym = self.backend.analyze(normal.symbolic())?;
        let t1 = Instant::now();
        let factor = sym.factorize(normal.as_ref())?;
        let t2 = Instant::now();
        self.analyse.push((t1 - t0).as_secs_f64());
        self.factorise.push((t2 - t1).as_secs_f64());
        self.factor = Some(factor);
        Ok(())
    }

    /// One solve of `rhs` (copied into `work`), timed; a failed solve is
    /// not timed.
    fn solve(&mut self, rhs: &Mat<f64>, work: &mut Mat<f64>) {
        if let Some(factor) = self.factor.as_mut() {
            work.copy_from(rhs);
            let t = Instant::now();
            if factor.solve_in_place(work.as_mut()).is_ok() {
                self.solve.push(t.elapsed().as_secs_f64());
            }
        }
    }

    /// The medians, with the last factor's size.
    fn times(self) -> Option<ReferenceTimes> {
        let factor = self.factor?;
        Some(ReferenceTimes {
            analyse_s: median(&self.analyse),
            factorise_s: median(&self.factorise),
            solve_s: median(&self.solve),
            factor_nnz: factor.nnz(),
            factor_bytes: factor.bytes(),
        })
    }
}

fn side_by_side(
    case: &str,
    mesh: &Mesh,
    cs: &ConstraintSet,
    reps: usize,
    solves: usize,
) -> Result<SideBySide, AnyError> {
    let mut d = Deformer::new(
        mesh.clone(),
        LaplacianKind::Cotangent,
        cs.clone(),
        &lse_deform::SolveOptions::default(),
    )?;
    let f = ours();
    // CHOLMOD first, then MUMPS.
    let mut refs: Vec<Option<ReferenceRuns>> = [reference_backend(), mumps_backend()]
        .into_iter()
        .map(|b| b.map(ReferenceRuns::new))
        .collect();
    let normal = match refs.iter().any(Option::is_some) {
        true => Some(reduced_normal(&d)?),
        false => None,
    };
    let (mut pre, mut phases) = (Vec::new(), vec![Vec::new(); 5]);
    for _ in 0..reps {
        d.refactor_with(&f, &lse_deform::resources::Resources::default())?;
        let t = &d.report().timings_s;
        pre.push(precompute_total(t));
        for (k, v) in [t.qr, t.preparation, t.normal_matrix, t.symbolic, t.numeric]
            .into_iter()
            .enumerate()
        {
            phases[k].push(v);
        }
        if let Some(normal) = &normal {
            for r in refs.iter_mut().flatten() {
                r.precompute(normal)?;
            }
        }
    }
    let report = d.report().clone();
    let unknowns = normal.as_ref().map_or(0, |n| n.ncols());
    let rhs = Mat::<f64>::from_fn(unknowns, 3, |i, c| ((i * 7 + c * 13) % 17) as f64 - 8.0);
    let mut work = rhs.clone();
    let (mut ts, mut tc) = (Vec::new(), Vec::new());
    for _ in 0..solves {
        let t = Instant::now();
        let x = d.solve_matrix()?;
        tc.push(t.elapsed().as_secs_f64());
        ts.push(d.report().timings_s.solve);
        std::hint::black_box(x);
        for r in refs.iter_mut().flatten() {
            r.solve(&rhs, &mut work);
        }
    }
    let mumps = refs.pop().flatten().and_then(ReferenceRuns::times);
    let reference = refs.pop().flatten().and_then(ReferenceRuns::times);
    Ok(SideBySide {
        case: case.into(),
        vertices: mesh.n_vertices(),
        unknowns,
        ours_precompute_s: median(&pre),
        ours_phases_s: [0, 1, 2, 3, 4].map(|k| median(&phases[k])),
        ours_solve_s: median(&ts),
        ours_call_s: median(&tc),
        ours_factor_nnz: report.nnz.factor.unwrap_or(0),
        ours_factor_bytes: report.nnz.factor_bytes.unwrap_or(0),
        reference,
        mumps,
    })
}

/// Precompute medians (ours) for several constraint sets on one mesh,
/// interleaved repetition by repetition.
fn precompute_medians(
    mesh: &Mesh,
    sets: &[ConstraintSet],
    reps: usize,
) -> Result<Vec<f64>, AnyError> {
    let mut deformers = sets
        .iter()
        .map(|cs| {
            Deformer::new(
                mesh.clone(),
                LaplacianKind::Cotangent,
                cs.clone(),
                &lse_deform::SolveOptions::default(),
            )
        })
        .collect::<Result<Vec<_>, _>>()?;
    let f = ours();
    let mut times = vec![Vec::new(); sets.len()];
    for _ in 0..reps {
        for (k, d) in deformers.iter_mut().enumerate() {
            d.refactor_with(&f, &lse_deform::resources::Resources::default())?;
            times[k].push(precompute_total(&d.report().timings_s));
        }
    }
    Ok(times.iter().map(|t| median(t)).collect())
}

#[derive(Debug, Clone, Serialize)]
struct SweepTimes {
    weights: usize,
    total_s: f64,
    normal_matrix_s: f64,
    analysis_s: f64,
    numeric_sum_s: f64,
    solve_sum_s: f64,
    single_numeric_s: f64,
    single_analysis_s: f64,
    failures: usize,
}

fn weight_sweep(mesh: &Mesh, cs: &ConstraintSet, reps: usize) -> Result<SweepTimes, AnyError> {
    let mut d = Deformer::new(
        mesh.clone(),
        LaplacianKind::Cotangent,
        cs.clone(),
        &lse_deform::SolveOptions::default(),
    )?;
    let weights: Vec<f64> = (0..=16).map(|k| 10f64.powi(k)).collect();
    let spd = FaerLlt::supernodal();
    let (mut num, mut ana) = (Vec::new(), Vec::new());
    for _ in 0..reps {
        d.refactor_with(
            &Penalty::with_backend(1e8, Arc::new(FaerLlt::supernodal())),
            &lse_deform::resources::Resources::default(),
        )?;
        num.push(d.report().timings_s.numeric);
        ana.push(d.report().timings_s.symbolic);
    }
    let t = Instant::now();
    let sweep = PenaltySweep::new(d.problem(), &spd)?;
    let points = sweep.run(d.problem(), &weights);
    let total = t.elapsed().as_secs_f64();
    let ok: Vec<_> = points
        .iter()
        .filter_map(|p| p.result.as_ref().ok())
        .collect();
    Ok(SweepTimes {
        weights: weights.len(),
        total_s: total,
        normal_matrix_s: sweep.normal_matrix_s,
        analysis_s: sweep.symbolic_s,
        numeric_sum_s: ok.iter().map(|s| s.numeric_s).sum(),
        solve_sum_s: ok.iter().map(|s| s.solve_s).sum(),
        single_numeric_s: median(&num),
        single_analysis_s: median(&ana),
        failures: points.len() - ok.len(),
    })
}

/// What the child process reports about peak memory.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct MemoryProbe {
    /// Peak resident set size (VmHWM) of the whole process, bytes.
    pub peak_rss_bytes: u64,
    /// Bytes of the factor (values + indices).
    pub factor_bytes: u64,
    /// Bytes of the mesh in memory (positions + faces).
    pub mesh_bytes: u64,
    /// Vertices.
    pub vertices: usize,
}

/// Peak resident set size of this process (Linux `VmHWM`), bytes.
fn peak_rss() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The child side of the peak-memory measurement: read the mesh, set up the
/// paper's scene, precompute, solve once, print a [`MemoryProbe`] as JSON.
pub fn memory_probe(mesh_path: &Path) -> Result<(), AnyError> {
    let mesh = read_mesh(mesh_path, lse_deform::limits::MemoryBudget::default())?.mesh;
    let cs = FixedAndHandle::paper_default(&mesh).constraints(&mesh)?;
    let mesh_bytes = (mesh.n_vertices() * 24 + mesh.n_faces() * 3 * 8) as u64;
    let vertices = mesh.n_vertices();
    let mut d = Deformer::with_formulation(
        mesh,
        LaplacianKind::Cotangent,
        cs,
        &ours(),
        &lse_deform::resources::Resources::default(),
    )?;
    let x = d.solve_matrix()?;
    std::hint::black_box(x);
    let probe = MemoryProbe {
        peak_rss_bytes: peak_rss()
            .ok_or("no /proc/self/status (peak memory is measured on Linux only)")?,
        factor_bytes: d.report().nnz.factor_bytes.unwrap_or(0) as u64,
        mesh_bytes,
        vertices,
    };
    println!("{}", serde_json::to_string(&probe)?);
    Ok(())
}

fn run_probe(mesh_path: &Path) -> Result<MemoryProbe, AnyError> {
    let exe = std::env::current_exe()?;
    let out = crate::harness::environment::child(exe)
        .arg(NAME)
        .arg("--memory-probe")
        .arg(mesh_path)
        .output()?;
    if !out.status.success() {
        return Err(format!(
            "memory probe failed: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        )
        .into());
    }
    Ok(serde_json::from_slice(&out.stdout)?)
}

#[derive(Debug, Clone, Serialize)]
struct ScalingPoint {
    vertices: usize,
    setup_s: f64,
    precompute_s: f64,
    solve_s: f64,
    factor_nnz: usize,
    solve_ns_per_factor_entry: f64,
}

#[derive(Debug, Serialize)]
struct Everything {
    bandwidth_bytes_per_s: f64,
    main: SideBySide,
    relative: Vec<(usize, f64)>,
    sweep: SweepTimes,
    large: SideBySide,
    large_setup_s: f64,
    large_memory: Option<MemoryProbe>,
    scaling: Vec<ScalingPoint>,
    slopes: Vec<(String, f64, f64)>,
    refine: Vec<RefineTimes>,
    /// The main and the large case's reduced normal matrix on each back
    /// end's own terms and on one AMD permutation and one thread.
    equal_terms: Vec<equal_terms::EqualRow>,
    targets: Vec<TargetRow>,
}

/// Target 8 on one mesh: medians of `timings_s.solve` (unrefined) and
/// `timings_s.refine` (a later `auto` refinement of the same unrefined
/// solution, after the factor's first refinement has measured its floor),
/// measured in alternation.
#[derive(Debug, Serialize)]
struct RefineTimes {
    case: String,
    solve_s: f64,
    refine_s: f64,
    /// The sizes of the corrections of a later refinement (relative to the
    /// bounding-box diagonal), the last one's stop reason.
    corrections: Vec<f64>,
    stop_reason: String,
    /// Lanczos estimate of κ of the reduced normal matrix.
    condition: f64,
}

/// Target 8 on `mesh` with the paper's default scene.
fn refine_vs_solve(name: &str, mesh: &Mesh, reps: usize) -> Result<RefineTimes, AnyError> {
    let cs = FixedAndHandle::paper_default(mesh).constraints(mesh)?;
    let d = Deformer::new(
        mesh.clone(),
        LaplacianKind::Cotangent,
        cs,
        &lse_deform::SolveOptions::default(),
    )?;
    let mut solver = LseSolver::with_formulation(
        d.problem().clone(),
        &ours(),
        &lse_deform::resources::Resources::default(),
    )?;
    let mut x0 = Mat::<f64>::zeros(d.problem().n(), 3);
    solver.solve_unrefined_into(x0.as_mut())?;
    let mut x = x0.clone();
    // The factor's first refinement: it measures the floor later ones predict.
    solver.refine_solution(&mut x)?;
    let (mut solve, mut refine) = (Vec::new(), Vec::new());
    let (mut corrections, mut stop_reason) = (Vec::new(), String::new());
    for _ in 0..reps {
        solver.solve_unrefined_into(x.as_mut())?;
        solve.push(solver.report().timings_s.solve);
        x.copy_from(&x0);
        let r = solver.refine_solution(&mut x)?;
        corrections.clone_from(&r.corrections);
        stop_reason = serde_json::to_value(r.stop_reason)?
            .as_str()
            .unwrap_or_default()
            .to_string();
        refine.push(solver.report().timings_s.refine);
    }
    let condition = solver.estimate_condition()?.value;
    Ok(RefineTimes {
        case: name.into(),
        solve_s: median(&solve),
        refine_s: median(&refine),
        corrections,
        stop_reason,
        condition,
    })
}

/// The Bunny and the Dragon, or generated stand-ins of their sizes.
fn refine_cases(ctx: &Context, reps: usize) -> Result<Vec<RefineTimes>, AnyError> {
    let mut out = Vec::new();
    for (file, vertices) in [
        ("bunny-35k-stanford.obj", 35_000),
        ("dragon-50k.obj", 50_000),
    ] {
        let case = match ctx.real_mesh(file)? {
            Some(case) => case,
            None => {
                let size = if ctx.quick { vertices / 7 } else { vertices };
                let kind = generate::GeneratedKind::BumpySphere;
                ctx.generated(&format!("bumpy-sphere-{}k", size / 1000), kind, size)?
            }
        };
        out.push(refine_vs_solve(&case.name, &case.mesh, reps)?);
    }
    Ok(out)
}

/// Target 8: refine ≤ 1.5 × solve.
fn refine_targets(all: &Everything) -> Vec<TargetRow> {
    all.refine
        .iter()
        .map(|r| {
            let sizes: Vec<String> = r.corrections.iter().map(|c| format!("{c:.1e}")).collect();
            row(
                "8 refine (auto, later solve) vs solve",
                &format!("{} (κ ≈ {:.1e})", r.case, r.condition),
                format!(
                    "{} ({} correction{}: {}; {})",
                    ms(r.refine_s),
                    r.corrections.len(),
                    if r.corrections.len() == 1 { "" } else { "s" },
                    sizes.join(", "),
                    r.stop_reason
                ),
                ms(r.solve_s),
                Some(r.refine_s / r.solve_s),
                1.5,
            )
        })
        .collect()
}

fn ms(s: f64) -> String {
    fmt_time(s)
}

fn mib(b: f64) -> String {
    format!("{:.0} MiB", b / (1u64 << 20) as f64)
}

/// The main case: Bunny, or a generated bumpy sphere of the same size.
fn main_case(ctx: &Context) -> Result<(String, Mesh), AnyError> {
    Ok(match ctx.main_mesh("bunny-35k-stanford.obj")? {
        Some(case) => (case.name, case.mesh),
        None => {
            let n = if ctx.quick { 5_000 } else { 35_000 };
            let m =
                generate::with_about_vertices(generate::GeneratedKind::BumpySphere, n, ctx.seed)?;
            (format!("bumpy-sphere-{}k", m.n_vertices() / 1000), m)
        }
    })
}

/// Precompute medians with 0, 300 and 2000 relative constraints.
fn relative_medians(
    mesh: &Mesh,
    base: &FixedAndHandle,
    reps: usize,
) -> Result<Vec<(usize, f64)>, AnyError> {
    let counts = [0usize, 300, 2000];
    let sets = counts
        .iter()
        .map(|&r| {
            MixedScene {
                base: base.clone(),
                relative: r,
                edges: 0,
                faces: 0,
                duplicate: false,
                conflict: false,
            }
            .constraints(mesh)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let times = precompute_medians(mesh, &sets, reps)?;
    Ok(counts.iter().copied().zip(times.iter().copied()).collect())
}

/// Set-up (read, L, A, B) of one mesh file: median of 3, with the mesh.
fn timed_setup_from_file(path: &Path) -> Result<(Mesh, f64), AnyError> {
    let mut times = Vec::new();
    let mut mesh = None;
    for _ in 0..3 {
        let t = Instant::now();
        let m = read_mesh(path, lse_deform::limits::MemoryBudget::default())?.mesh;
        let cs = FixedAndHandle::paper_default(&m).constraints(&m)?;
        let d = Deformer::new(
            m.clone(),
            LaplacianKind::Cotangent,
            cs,
            &lse_deform::SolveOptions::default(),
        )?;
        times.push(t.elapsed().as_secs_f64());
        std::hint::black_box(&d);
        mesh = Some(m);
    }
    Ok((mesh.ok_or("no mesh")?, median(&times)))
}

/// The large case: the subdivided Igea, or a generated 250k-vertex bumpy
/// sphere; its name, mesh, set-up time and file.
fn large_case(ctx: &Context) -> Result<(String, Mesh, f64, Option<PathBuf>), AnyError> {
    let path = ctx
        .mesh_file("igea-537k-subdiv.obj.gz")
        .map(Path::to_path_buf);
    if let Some(path) = path {
        let (mesh, setup) = timed_setup_from_file(&path)?;
        return Ok(("igea-537k".to_string(), mesh, setup, Some(path)));
    }
    let n = if ctx.quick { 20_000 } else { 250_000 };
    let t = Instant::now();
    let m = generate::with_about_vertices(generate::GeneratedKind::BumpySphere, n, ctx.seed)?;
    let cs = FixedAndHandle::paper_default(&m).constraints(&m)?;
    let d = Deformer::new(
        m.clone(),
        LaplacianKind::Cotangent,
        cs,
        &lse_deform::SolveOptions::default(),
    )?;
    std::hint::black_box(&d);
    let setup = t.elapsed().as_secs_f64();
    let name = format!("bumpy-sphere-{}k (generated)", m.n_vertices() / 1000);
    Ok((name, m, setup, None))
}

/// One generated mesh of about `n` vertices: set-up, precompute, solve.
fn scaling_point(ctx: &Context, n: usize) -> Result<ScalingPoint, AnyError> {
    let mesh = generate::with_about_vertices(generate::GeneratedKind::BumpySphere, n, ctx.seed)?;
    let cs = FixedAndHandle::paper_default(&mesh).constraints(&mesh)?;
    let r = if n >= 200_000 { 1 } else { 3 };
    let t = Instant::now();
    let mut d = Deformer::new(
        mesh.clone(),
        LaplacianKind::Cotangent,
        cs,
        &lse_deform::SolveOptions::default(),
    )?;
    let setup = t.elapsed().as_secs_f64();
    let f = ours();
    let mut pre = Vec::new();
    for _ in 0..r {
        d.refactor_with(&f, &lse_deform::resources::Resources::default())?;
        pre.push(precompute_total(&d.report().timings_s));
    }
    let mut ts = Vec::new();
    for _ in 0..if n >= 200_000 { 5 } else { 21 } {
        let t = Instant::now();
        std::hint::black_box(d.solve_matrix()?);
        ts.push(t.elapsed().as_secs_f64());
    }
    let nnz = d.report().nnz.factor.unwrap_or(0);
    let solve = median(&ts);
    Ok(ScalingPoint {
        vertices: mesh.n_vertices(),
        setup_s: setup,
        precompute_s: median(&pre),
        solve_s: solve,
        factor_nnz: nnz,
        solve_ns_per_factor_entry: solve * 1e9 / nnz.max(1) as f64,
    })
}

/// The scaling points on generated meshes.
fn scaling_points(ctx: &Context) -> Result<Vec<ScalingPoint>, AnyError> {
    let sizes: &[usize] = if ctx.quick {
        &[1_000, 4_000, 16_000]
    } else if ctx.has_user_meshes() {
        &[1_000, 4_000, 16_000, 64_000, 256_000, 1_000_000]
    } else {
        &[1_000, 4_000, 16_000, 64_000, 256_000]
    };
    sizes.iter().map(|&n| scaling_point(ctx, n)).collect()
}

/// A point's `(x, y)` for a fit or a series.
type Xy = fn(&ScalingPoint) -> (f64, f64);

/// `(x, y)` of the scaling points.
fn scaling_xy(scaling: &[ScalingPoint], f: Xy) -> Vec<(f64, f64)> {
    scaling.iter().map(f).collect()
}

/// Fitted log–log slopes (name, slope, R²) of the scaling points.
fn slopes(scaling: &[ScalingPoint]) -> Vec<(String, f64, f64)> {
    let pairs: [(&str, Xy); 4] = [
        ("precompute vs vertices", |p| {
            (p.vertices as f64, p.precompute_s)
        }),
        ("solve vs vertices", |p| (p.vertices as f64, p.solve_s)),
        ("factor nnz vs vertices", |p| {
            (p.vertices as f64, p.factor_nnz as f64)
        }),
        ("solve vs factor nnz", |p| (p.factor_nnz as f64, p.solve_s)),
    ];
    pairs
        .into_iter()
        .filter_map(|(name, f)| {
            let fit = plot::fit_power_law(&scaling_xy(scaling, f)).ok()?;
            Some((name.to_string(), fit.slope, fit.r_squared))
        })
        .collect()
}

/// The scaling figure.
fn scaling_figure(dir: &Path, scaling: &[ScalingPoint]) -> Result<(), AnyError> {
    let spec = ScatterFits {
        title: "Precompute and per-frame solve against vertex count (generated bumpy spheres)"
            .into(),
        x_label: "vertices".into(),
        y_label: "seconds".into(),
        series: vec![
            Series::new(
                "precompute",
                scaling_xy(scaling, |p| (p.vertices as f64, p.precompute_s)),
            ),
            Series::new(
                "solve (3 rhs)",
                scaling_xy(scaling, |p| (p.vertices as f64, p.solve_s)),
            ),
            Series::new(
                "set-up",
                scaling_xy(scaling, |p| (p.vertices as f64, p.setup_s)),
            ),
        ],
        legend: LegendPosition::UpperLeft,
    };
    plot::scatter_loglog_with_fits(&spec, &Output::new(dir.join("scaling")))?;
    Ok(())
}

/// The bandwidth floor of a solve reading a factor of `bytes` twice.
fn floor(all: &Everything, bytes: usize) -> f64 {
    2.0 * bytes as f64 / all.bandwidth_bytes_per_s
}

/// The MUMPS rows of a case (beside the targets `numbers`: precompute,
/// solve): ours against MUMPS on one
/// rank in this process, on the same matrix. A comparison, not a target
/// (the targets are stated against CHOLMOD): no limit, no status.
fn mumps_rows(numbers: [&str; 2], case: &SideBySide) -> Vec<TargetRow> {
    let [pre, solve] = numbers;
    let comparison =
        |target: String, ours: String, reference: String, ratio: Option<f64>| TargetRow {
            target,
            case: case.case.clone(),
            ours,
            reference,
            ratio,
            limit: "— (comparison)".into(),
            met: None,
        };
    let Some(m) = &case.mumps else {
        return vec![comparison(
            if pre == solve {
                format!("{pre} vs MUMPS")
            } else {
                format!("{pre}, {solve} vs MUMPS")
            },
            ms(case.ours_precompute_s),
            "not in this build (needs --features mumps)".into(),
            None,
        )];
    };
    vec![
        comparison(
            format!("{pre} precompute vs MUMPS (1 rank) analyse + factorise"),
            ms(case.ours_precompute_s),
            format!(
                "{} (analyse {} + factorise {})",
                ms(m.analyse_s + m.factorise_s),
                ms(m.analyse_s),
                ms(m.factorise_s)
            ),
            Some(case.ours_precompute_s / (m.analyse_s + m.factorise_s)),
        ),
        comparison(
            format!("{solve} solve vs MUMPS (1 rank) solve"),
            solve_cell(case),
            ms(m.solve_s),
            Some(case.ours_solve_s / m.solve_s),
        ),
    ]
}

/// Targets 1–4: the main case against CHOLMOD and the floor, relative
/// constraints, the weight sweep.
fn main_targets(all: &Everything) -> Vec<TargetRow> {
    let (main, relative, sweep) = (&all.main, &all.relative, &all.sweep);
    let mut targets = Vec::new();
    match &main.reference {
        Some(r) => {
            targets.push(row(
                "1 precompute vs CHOLMOD factorise",
                &main.case,
                ms(main.ours_precompute_s),
                format!("{} (+ analyse {})", ms(r.factorise_s), ms(r.analyse_s)),
                Some(main.ours_precompute_s / r.factorise_s),
                1.0,
            ));
            targets.push(row(
                "1' precompute vs CHOLMOD analyse + factorise",
                &main.case,
                ms(main.ours_precompute_s),
                ms(r.analyse_s + r.factorise_s),
                Some(main.ours_precompute_s / (r.analyse_s + r.factorise_s)),
                1.0,
            ));
            targets.push(row(
                "2 solve vs CHOLMOD solve",
                &main.case,
                solve_cell(main),
                ms(r.solve_s),
                Some(main.ours_solve_s / r.solve_s),
                1.0,
            ));
        }
        None => targets.push(TargetRow {
            target: "1, 2 vs CHOLMOD".into(),
            case: main.case.clone(),
            ours: ms(main.ours_precompute_s),
            reference: "not built (needs --features suitesparse)".into(),
            ratio: None,
            limit: "—".into(),
            met: None,
        }),
    }
    targets.extend(mumps_rows(["1", "2"], main));
    let main_floor = floor(all, main.ours_factor_bytes);
    targets.push(row(
        "2 solve vs bandwidth floor",
        &main.case,
        solve_cell(main),
        format!(
            "{} ({} factor, {:.1} GB/s)",
            ms(main_floor),
            mib(main.ours_factor_bytes as f64),
            all.bandwidth_bytes_per_s / 1e9
        ),
        Some(main.ours_solve_s / main_floor),
        2.0,
    ));
    for (k, limit) in [(1usize, 1.1), (2, 1.3)] {
        targets.push(row(
            &format!("3 precompute with {} relative", relative[k].0),
            &main.case,
            ms(relative[k].1),
            format!("{} positions only", ms(relative[0].1)),
            Some(relative[k].1 / relative[0].1),
            limit,
        ));
    }
    let bound = sweep.weights as f64 * sweep.single_numeric_s + sweep.single_analysis_s;
    targets.push(row(
        "4 weight sweep (17 weights) vs 17 × numeric + analysis",
        &main.case,
        format!(
            "{} (analysis {}, Σ numeric {}, Σ solve {}; two weights at a time)",
            ms(sweep.total_s),
            ms(sweep.analysis_s),
            ms(sweep.numeric_sum_s),
            ms(sweep.solve_sum_s)
        ),
        format!("{} (numeric {})", ms(bound), ms(sweep.single_numeric_s)),
        Some(sweep.total_s / bound),
        1.0,
    ));
    targets
}

/// Targets 5–6: the large case.
fn large_targets(all: &Everything) -> Vec<TargetRow> {
    let large = &all.large;
    let mut targets = Vec::new();
    if let Some(r) = &large.reference {
        targets.push(row(
            "5 precompute vs CHOLMOD factorise",
            &large.case,
            ms(large.ours_precompute_s),
            format!("{} (+ analyse {})", ms(r.factorise_s), ms(r.analyse_s)),
            Some(large.ours_precompute_s / r.factorise_s),
            1.0,
        ));
        targets.push(row(
            "5 solve vs CHOLMOD solve",
            &large.case,
            solve_cell(large),
            ms(r.solve_s),
            Some(large.ours_solve_s / r.solve_s),
            1.0,
        ));
    }
    targets.extend(mumps_rows(["5", "5"], large));
    let large_floor = floor(all, large.ours_factor_bytes);
    targets.push(row(
        "5 solve vs bandwidth floor",
        &large.case,
        solve_cell(large),
        format!(
            "{} ({} factor)",
            ms(large_floor),
            mib(large.ours_factor_bytes as f64)
        ),
        Some(large.ours_solve_s / large_floor),
        2.0,
    ));
    if let Some(m) = &all.large_memory {
        let budget = 2.5 * m.factor_bytes as f64 + m.mesh_bytes as f64;
        targets.push(row(
            "5 peak memory vs 2.5 × factor + mesh",
            &large.case,
            mib(m.peak_rss_bytes as f64),
            format!(
                "{} (factor {}, mesh {})",
                mib(budget),
                mib(m.factor_bytes as f64),
                mib(m.mesh_bytes as f64)
            ),
            Some(m.peak_rss_bytes as f64 / budget),
            1.0,
        ));
    }
    targets.push(row(
        "6 set-up (read + L + A) vs 1 s",
        &large.case,
        ms(all.large_setup_s),
        "1 s".into(),
        Some(all.large_setup_s),
        1.0,
    ));
    targets
}

/// Target 7: the fitted slopes.
fn slope_targets(all: &Everything) -> Vec<TargetRow> {
    let range = format!(
        "generated, {}–{} vertices",
        all.scaling.first().map_or(0, |p| p.vertices),
        all.scaling.last().map_or(0, |p| p.vertices)
    );
    all.slopes
        .iter()
        .map(|(name, slope, r2)| TargetRow {
            target: format!("7 slope: {name}"),
            case: range.clone(),
            ours: format!("{slope:.2} (R² {r2:.3})"),
            reference: if name == "solve vs factor nnz" {
                "1 (linear)".into()
            } else {
                "—".into()
            },
            ratio: None,
            limit: "—".into(),
            met: None,
        })
        .collect()
}

/// The columns of `targets.csv` and of the section's table.
const TARGET_HEADER: [&str; 7] = [
    "target",
    "case",
    "ours",
    "reference",
    "ratio",
    "limit",
    "status",
];

/// `performance.json`, `targets.csv` and `scaling.csv`.
fn write_data(ctx: &Context, dir: &Path, all: &Everything) -> Result<(), AnyError> {
    ctx.write_json(&dir.join("performance.json"), all)?;
    let rows: Vec<Vec<String>> = all.targets.iter().map(TargetRow::cells).collect();
    ctx.write_csv(&dir.join("targets.csv"), &TARGET_HEADER, &rows)?;
    let scaling_rows: Vec<Vec<String>> = all
        .scaling
        .iter()
        .map(|p| {
            vec![
                p.vertices.to_string(),
                format!("{:.6}", p.setup_s),
                format!("{:.6}", p.precompute_s),
                format!("{:.6}", p.solve_s),
                p.factor_nnz.to_string(),
                format!("{:.3}", p.solve_ns_per_factor_entry),
            ]
        })
        .collect();
    ctx.write_csv(
        &dir.join("scaling.csv"),
        &[
            "vertices",
            "setup_s",
            "precompute_s",
            "solve_s",
            "factor_nnz",
            "solve_ns_per_factor_entry",
        ],
        &scaling_rows,
    )
}

/// The section (also `performance/README.md` and `performance.md`).
fn section(ctx: &Context, all: &Everything, reps: usize, solves: usize) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "Ours (the paper's method: SparseGivens QR × faer supernodal Cholesky with our own supernodal triangular solve) against CHOLMOD \
         on the same reduced normal matrix `(AQ2)ᵀ(AQ2)`, medians of {reps} precomputes and {solves} solves, each repetition running ours and CHOLMOD back to back in one process. \
         A ratio below the limit meets the target. \
         The MUMPS rows (one rank in this process, the same matrix, measured in the same repetitions) are a comparison without a target. Our solve is the solve phase of docs/formulations.md §2 (y, right-hand side, two triangular solves, X = Q[y; z]; \
         `report.timings_s.solve`); the whole `solve_matrix` call adds the checks and diagnostics the library computes after every solve (constraint residuals, ‖AX − C‖), given in brackets. \
         The numeric factorisation runs on one thread below 50 M factor values and on two above; the triangular solves on one. \
         The bandwidth floor is 2 × the factor's bytes / the single-thread read bandwidth measured in the same run ({:.1} GB/s).\n",
        all.bandwidth_bytes_per_s / 1e9
    );
    let rows: Vec<Vec<String>> = all.targets.iter().map(TargetRow::cells).collect();
    md.push_str(&markdown_table(&TARGET_HEADER, &rows));
    if !all.refine.is_empty() {
        let _ = writeln!(
            md,
            "\nTarget 8 times, in alternation, the unrefined solve phase and a later `auto` refinement of its result with the same factor \
             (after the factor's first refinement has measured its rounding floor), on the paper's default scene; the corrections' sizes are relative to the \
             bounding-box diagonal, and κ is the Lanczos estimate of the reduced normal matrix's condition number. Every correction repeats the solve's passes \
             (docs/refinement.md §7), so the ratio is about the number of corrections: one where the first correction is already near the floor, two where \
             κ is near 1/ε and the first correction leaves about 1e-10 of the diagonal."
        );
    }
    let p = &all.main.ours_phases_s;
    let _ = writeln!(
        md,
        "\nOur precompute by phase on {} (median s): QR {:.4}, preparation {:.4}, normal matrix {:.4}, symbolic {:.4}, numeric {:.4}; factor nnz {} ({}).\n",
        all.main.case,
        p[0],
        p[1],
        p[2],
        p[3],
        p[4],
        all.main.ours_factor_nnz,
        mib(all.main.ours_factor_bytes as f64)
    );
    for (name, r) in [
        ("CHOLMOD", &all.main.reference),
        ("MUMPS (1 rank)", &all.main.mumps),
    ] {
        if let Some(r) = r {
            let _ = writeln!(
                md,
                "{name} factor nnz {} ({}).\n",
                r.factor_nnz,
                mib(r.factor_bytes as f64)
            );
        }
    }
    md.push_str(&equal_terms_section(all));
    let _ = writeln!(
        md,
        "![scaling](performance/scaling.png)\n\nPrecompute, solve and set-up against vertex count on generated bumpy spheres (log–log, least-squares power fits; slopes in the table, data in `performance/scaling.csv`). A solve slope of 1 against factor nnz means the solve stays linear in the factor.\n"
    );
    let _ = writeln!(
        md,
        "Regenerate: `cargo run --release --features suitesparse,mumps --bin experiments -- {NAME}{} --out results` (without `--mesh-dir` the main case is a generated 35k-vertex bumpy sphere and the large case a generated 250k one; without `--features suitesparse` the CHOLMOD rows are missing, without `--features mumps` the MUMPS rows).",
        ctx.mesh_args()
    );
    md
}

/// The equal-terms rows of one case's reduced normal matrix.
fn equal_terms_of(
    case: &str,
    mesh: &Mesh,
    cs: &ConstraintSet,
    reps: usize,
) -> Result<Vec<equal_terms::EqualRow>, AnyError> {
    let d = Deformer::new(
        mesh.clone(),
        LaplacianKind::Cotangent,
        cs.clone(),
        &lse_deform::SolveOptions::default(),
    )?;
    let normal = reduced_normal(&d)?;
    drop(d);
    equal_terms::measure(case, &normal, reps)
}

/// The equal-terms paragraph and table.
fn equal_terms_section(all: &Everything) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "\n**Equal terms.** The same reduced normal matrices, analysed and factored by each back end on its own ordering and threads, and with one AMD permutation \
         (faer's, computed once per repetition and given to every back end: faer's custom ordering, CHOLMOD's `cholmod_l_analyze_p`, MUMPS's `PERM_IN`) and one thread \
         (faer's `Par::Seq`, OpenBLAS set to one thread for CHOLMOD and MUMPS); medians, interleaved repetition by repetition (docs/equal-terms.md). \
         `ordering` is the time computing the held permutation, outside the analysis; with a back end's own ordering it is part of the analysis. \
         nnz(L) is what each back end stores (faer supernodal and MUMPS with their supernodal padding, CHOLMOD the exact fill).\n"
    );
    let rows: Vec<Vec<String>> = all.equal_terms.iter().map(equal_terms::cells).collect();
    md.push_str(&markdown_table(&equal_terms::HEADER, &rows));
    md
}

/// The section, `performance/README.md` and `performance.md`.
fn write_pages(ctx: &Context, dir: &Path, md: &str) -> Result<(), AnyError> {
    ctx.write_section(NAME, md)?;
    let mut page = format!("# Performance\n\n{}\n\n", ctx.machine.one_line());
    page.push_str(&md.replace("](performance/", "]("));
    std::fs::write(dir.join("README.md"), &page)?;
    std::fs::write(
        ctx.out.join("performance.md"),
        page.replace("](scaling", "](performance/scaling"),
    )?;
    Ok(())
}

/// Runs the performance experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let started = Instant::now();
    let dir = ctx.dir(NAME)?;
    let quick = ctx.quick;
    let (reps, solves) = if quick { (3, 9) } else { (7, 41) };
    let bandwidth = read_bandwidth(if quick { 3 } else { 9 });
    let (main_name, main_mesh) = main_case(ctx)?;
    let base = FixedAndHandle::paper_default(&main_mesh);
    let cs = base.constraints(&main_mesh)?;
    let main = side_by_side(&main_name, &main_mesh, &cs, reps, solves)?;
    let mut equal = equal_terms_of(&main_name, &main_mesh, &cs, reps)?;
    let relative = relative_medians(&main_mesh, &base, reps)?;
    let sweep = weight_sweep(&main_mesh, &cs, if quick { 1 } else { 3 })?;
    let (large_name, large_mesh, large_setup_s, large_path) = large_case(ctx)?;
    let large_cs = FixedAndHandle::paper_default(&large_mesh).constraints(&large_mesh)?;
    let (large_reps, large_solves) = if quick { (1, 3) } else { (3, 11) };
    let large = side_by_side(
        &large_name,
        &large_mesh,
        &large_cs,
        large_reps,
        large_solves,
    )?;
    equal.extend(equal_terms_of(
        &large_name,
        &large_mesh,
        &large_cs,
        large_reps,
    )?);
    drop(large_mesh);
    let large_memory = large_path.as_deref().map(run_probe).transpose()?;
    let scaling = scaling_points(ctx)?;
    scaling_figure(&dir, &scaling)?;
    let refine = refine_cases(ctx, solves)?;
    let mut all = Everything {
        bandwidth_bytes_per_s: bandwidth,
        main,
        relative,
        sweep,
        large,
        large_setup_s,
        large_memory,
        slopes: slopes(&scaling),
        scaling,
        refine,
        equal_terms: equal,
        targets: Vec::new(),
    };
    all.targets = [
        main_targets(&all),
        large_targets(&all),
        slope_targets(&all),
        refine_targets(&all),
    ]
    .concat();
    write_data(ctx, &dir, &all)?;
    write_pages(ctx, &dir, &section(ctx, &all, reps, solves))?;
    let missed: Vec<&str> = all
        .targets
        .iter()
        .filter(|t| t.met == Some(false))
        .map(|t| t.target.as_str())
        .collect();
    Ok(Summary::measured(format!(
        "{} targets checked, {} missed{}; solve {} vs floor {} ({:.0} s)",
        all.targets.iter().filter(|t| t.met.is_some()).count(),
        missed.len(),
        if missed.is_empty() {
            String::new()
        } else {
            format!(" ({})", missed.join("; "))
        },
        ms(all.main.ours_solve_s),
        ms(floor(&all, all.main.ours_factor_bytes)),
        started.elapsed().as_secs_f64()
    )))
}
