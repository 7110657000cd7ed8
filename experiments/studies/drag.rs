//! `drag`: an interactive drag — the handle of the paper's scene moved
//! along a smooth closed path for 300 frames; each frame translates the
//! handle group ([`Deformer::transform_group`] with `[I | t]`) and solves
//! without refactoring. Per method and back end: per-frame latency p50 /
//! p99 of the solve phase and of the whole frame (targets + solve + the
//! library's per-solve diagnostics), and the frames per second they imply.
//! Further rows of the library default drag the same frames with
//! refinement off through [`Deformer::solve_into`] (no correction, no
//! diagnostics), by the handle basis ([`HandleBasis::evaluate`], built once:
//! docs/handles.md), and through Python ([`python`]: the basis and
//! `transform_group` + `solve`): what each frame costs and how far its
//! shape is from the refined one's.

mod python;

use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use faer::Mat;
use lse_deform::backend::qr::QrKind;
use lse_deform::backend::spd::SpdKind;
use lse_deform::constraints::ConstraintSet;
use lse_deform::deform::Affine;
use lse_deform::formulation::{Refine, max_hard_residual};
use lse_deform::handle::HandleBasis;
use lse_deform::mesh::Mesh;
use lse_deform::scene::{FixedAndHandle, HANDLE_GROUP};
use lse_deform::{
    Deformer, LaplacianKind, Method, formulation::Formulation, formulation::FormulationChoice,
};
use serde::Serialize;

use python::PythonRows;

use crate::harness::context::AnyError;
use crate::harness::context::{Context, MeshCase};
use crate::harness::plot::{
    self, Axis, Category, LegendPosition, LineChart, Output, Series, StackedBars,
};
use crate::harness::registry::{Experiment, Input, Summary};
use crate::harness::rows::{fmt_time, markdown_table, median, percentile};
use crate::harness::timing::{
    PENALTY_RELATIVE_WEIGHT, link, note_drawn, qr_backends, short_error, spd_backends,
};

pub const NAME: &str = "drag";

/// This study's entry in the list of experiments.
pub const EXPERIMENT: Experiment = Experiment {
    name: NAME,
    title: "Interactive drag",
    inputs: &[Input::OneMesh, Input::Python],
    run,
};

/// A method and back-end configuration of the drag.
struct Config {
    /// Label for tables and figures.
    label: String,
    choice: FormulationChoice,
    formulation: Box<dyn Formulation>,
    /// What every frame calls.
    frame_call: FrameCall,
}

/// What a frame of the drag calls.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FrameCall {
    /// [`Deformer::solve_matrix`]: the method's default refinement, then
    /// the diagnostics.
    SolveMatrix,
    /// [`Deformer::solve_into`] with [`Refine::EstimateOnly`] into a buffer kept
    /// across frames: no correction, no diagnostics.
    UnrefinedSolveInto,
    /// [`HandleBasis::evaluate`] of the handle group's basis (built once
    /// after the warm-up solve) into a buffer kept across frames.
    Basis,
    /// Python, `Deformer.basis(["handle"]).evaluate({"handle": M})`
    /// (`drag_python.py`).
    PythonBasis,
    /// Python, `transform_group("handle", M)` then `solve()` (the default
    /// refinement, and the diagnostics).
    PythonSolve,
}

impl FrameCall {
    /// The library call's name, for the rows.
    fn name(self) -> &'static str {
        match self {
            FrameCall::SolveMatrix => "solve_matrix",
            FrameCall::UnrefinedSolveInto => "solve_into",
            FrameCall::Basis => "HandleBasis::evaluate",
            FrameCall::PythonBasis => "Python basis.evaluate",
            FrameCall::PythonSolve => "Python transform_group + solve",
        }
    }

    /// Measured by `drag_python.py`, not in this process.
    fn is_python(self) -> bool {
        matches!(self, FrameCall::PythonBasis | FrameCall::PythonSolve)
    }
}

impl Config {
    fn new(label: String, choice: FormulationChoice) -> Result<Config, AnyError> {
        Config::calling(label, choice, FrameCall::SolveMatrix)
    }

    fn calling(
        label: String,
        choice: FormulationChoice,
        frame_call: FrameCall,
    ) -> Result<Config, AnyError> {
        Ok(Config {
            label,
            formulation: choice.build()?,
            choice,
            frame_call,
        })
    }
}

/// The library default's other frame calls, after its `solve_matrix` row:
/// refinement off through `solve_into`, the handle basis in Rust and in
/// Python, and Python's `transform_group` + `solve`.
fn default_variants(prefix: &str, choice: FormulationChoice) -> Result<Vec<Config>, AnyError> {
    [
        ("refine off, solve_into", FrameCall::UnrefinedSolveInto),
        ("handle basis (Rust)", FrameCall::Basis),
        ("handle basis (Python)", FrameCall::PythonBasis),
        ("Python transform_group + solve", FrameCall::PythonSolve),
    ]
    .into_iter()
    .map(|(what, call)| Config::calling(format!("{prefix}, {what}"), choice.clone(), call))
    .collect()
}

/// The configurations, the library default (null-space QR with the default
/// QR and SPD back ends) first, then the same with the other frame calls
/// ([`default_variants`]); null-space QR with the default QR back end
/// on every SPD back end but `faer-supernodal` (what `faer-auto` selects on
/// meshes of this size: the same factor, see `scaling`), with every other QR
/// back end on the default SPD back end; penalty, KKT (faer LDLᵀ, automatic
/// choice) and elimination on the default SPD back end. The other
/// combinations are left out to keep the drag within its time budget: their
/// solve phase is the SPD back end's, measured by `scaling`.
///
/// `slow_backends`: also null-space QR on faer-simplicial and nalgebra (2–4×
/// slower per frame; left out of the run on generated meshes to keep it
/// within its budget).
fn configs(weight: f64, slow_backends: bool) -> Result<Vec<Config>, AnyError> {
    let default = FormulationChoice::new(Method::NullSpaceQr);
    let (default_qr, default_spd) = (default.qr.name(), default.spd.name());
    let (default_qr, default_spd) = (default_qr.as_ref(), default_spd.as_ref());
    let mut spds: Vec<&str> = vec![default_spd];
    spds.extend(spd_backends().into_iter().filter(|&s| {
        s != default_spd
            && s != "faer-supernodal"
            && (slow_backends || !matches!(s, "faer-simplicial" | "nalgebra"))
    }));
    let mut out = Vec::new();
    for &s in &spds {
        let choice = FormulationChoice {
            spd: s.parse::<SpdKind>()?.into(),
            ..default.clone()
        };
        out.push(Config::new(
            format!("null-space {default_qr} + {s}"),
            choice.clone(),
        )?);
        if s == default_spd {
            out.extend(default_variants(
                &format!("null-space {default_qr} + {s}"),
                choice,
            )?);
        }
    }
    for q in qr_backends().into_iter().filter(|&q| q != default_qr) {
        let choice = FormulationChoice {
            qr: q.parse::<QrKind>()?.into(),
            ..default.clone()
        };
        out.push(Config::new(
            format!("null-space {q} + {default_spd}"),
            choice,
        )?);
    }
    let penalty = FormulationChoice {
        weight: Some(weight),
        ..FormulationChoice::new(Method::Penalty)
    };
    out.push(Config::new(format!("penalty + {default_spd}"), penalty)?);
    let kkt = FormulationChoice::new(Method::Kkt);
    out.push(Config::new("KKT LDLᵀ faer-auto".into(), kkt)?);
    let eliminate = FormulationChoice::new(Method::Eliminate);
    out.push(Config::new(
        format!("elimination + {default_spd}"),
        eliminate,
    )?);
    Ok(out)
}

/// The handle's displacement at path parameter `t ∈ [0, 1]`: a closed loop
/// starting and ending at rest, sideways by `sin 2πt` and along the long
/// axis by `(1 − cos 2πt)/2`, both scaled by `amplitude`.
fn path(t: f64, axis: usize, amplitude: f64) -> [f64; 3] {
    let mut d = [0.0; 3];
    d[(axis + 1) % 3] = amplitude * (2.0 * PI * t).sin();
    d[axis] += amplitude * 0.5 * (1.0 - (2.0 * PI * t).cos());
    d
}

/// The handle's transform for the path displacement `d`: the translation
/// `[I | d − offset]`, which takes the handle's rest targets (the scene's
/// `p + offset`) to `p + d`. Every row drags by it: `transform_group`, the
/// basis, and Python's both.
fn handle_transform(d: [f64; 3], offset: [f64; 3]) -> Affine {
    let mut m = [[0.0; 4]; 3];
    for (k, row) in m.iter_mut().enumerate() {
        row[k] = 1.0;
        row[3] = d[k] - offset[k];
    }
    m
}

/// Summary of one configuration's drag.
#[derive(Debug, Clone, Default, Serialize)]
struct Row {
    label: String,
    method: &'static str,
    qr_backend: Option<String>,
    spd_backend: String,
    /// What a frame calls: `solve_matrix` (the method's default
    /// refinement, then the diagnostics) or `solve_into` (refinement off,
    /// no diagnostics).
    frame_call: &'static str,
    precompute_s: Option<f64>,
    /// The handle basis rows: seconds to build it (once, after the
    /// precompute and the warm-up solve).
    basis_build_s: Option<f64>,
    frames: usize,
    solve_p50_s: Option<f64>,
    solve_p99_s: Option<f64>,
    solve_max_s: Option<f64>,
    frame_p50_s: Option<f64>,
    frame_p99_s: Option<f64>,
    /// Moving the handle's targets (`transform_group`), p50; 0 for the
    /// basis rows, whose evaluation takes the transform.
    targets_p50_s: Option<f64>,
    /// The refine phase (`timings_s.refine`), p50.
    refine_p50_s: Option<f64>,
    diagnostics_p50_s: Option<f64>,
    /// 1 / frame p50.
    fps_p50: Option<f64>,
    /// 1 / frame p99.
    fps_p99: Option<f64>,
    /// 1 / solve p50 (the solve phase alone).
    solve_fps_p50: Option<f64>,
    nnz_factor: Option<usize>,
    /// Max over frames of the hard-constraint residual relative to the
    /// bounding-box diagonal (penalty: of the former hard rows).
    max_constraint_residual_relative: Option<f64>,
    /// Max distance of the mid-path frame from the reference configuration's
    /// (the first one), relative to the bounding-box diagonal.
    deviation_from_reference: Option<f64>,
    status: String,
}

/// One frame of one configuration (`drag_frames.csv`).
#[derive(Debug, Clone, Serialize)]
struct FrameRow {
    label: String,
    frame: usize,
    targets_s: f64,
    solve_s: f64,
    refine_s: f64,
    diagnostics_s: f64,
    frame_s: f64,
}

/// Per-frame timings of one configuration. For the basis rows, `solve`
/// and `frame` are both the evaluation.
#[derive(Debug, Clone, Default)]
struct Frames {
    targets: Vec<f64>,
    solve: Vec<f64>,
    refine: Vec<f64>,
    diagnostics: Vec<f64>,
    frame: Vec<f64>,
    max_residual: f64,
    /// The mid-drag shape, in the mesh's units.
    middle: Option<Vec<[f64; 3]>>,
    /// The output of `solve_into`, reused from frame to frame.
    buffer: Option<Mat<f64>>,
    /// The output of the basis, reused from frame to frame.
    positions: Vec<[f64; 3]>,
}

/// The drag's scene: the regions, constraints and path.
struct Drag {
    axis: usize,
    fixed: Vec<usize>,
    handle: Vec<usize>,
    constraints: ConstraintSet,
    amplitude: f64,
    /// The scene's handle offset: its rest targets are `p + offset`.
    offset: [f64; 3],
    original: Vec<[f64; 3]>,
    diagonal: f64,
    frames: usize,
}

impl Drag {
    fn new(ctx: &Context, mesh: &Mesh) -> Result<Drag, AnyError> {
        let scene = FixedAndHandle::paper_default(mesh);
        let (fixed, handle) = scene.regions(mesh)?;
        Ok(Drag {
            axis: scene.axis.index(),
            fixed,
            handle,
            constraints: scene.constraints(mesh)?,
            amplitude: 0.15 * mesh.bbox_diagonal(),
            offset: scene.offset,
            original: mesh.positions().to_vec(),
            diagonal: mesh.bbox_diagonal(),
            frames: match (ctx.quick, ctx.has_user_meshes()) {
                (true, _) => 60,
                (false, true) => 300,
                // Generated meshes: within the ten minutes of `all`.
                (false, false) => 150,
            },
        })
    }

    /// The handle's transform at frame `f` (0-based): the path at
    /// `t = (f + 1) / frames`.
    fn transform(&self, f: usize) -> Affine {
        let t = (f + 1) as f64 / self.frames as f64;
        handle_transform(path(t, self.axis, self.amplitude), self.offset)
    }

    /// Every frame's transform.
    fn transforms(&self) -> Vec<Affine> {
        (0..self.frames).map(|f| self.transform(f)).collect()
    }

    /// The 0-based frame whose shape every row keeps.
    fn middle(&self) -> usize {
        self.frames / 2 - 1
    }

    /// The largest hard-constraint residual of `positions` (mesh units)
    /// at the handle transform `m`, over the diagonal.
    fn residual(&self, m: &Affine, positions: &[[f64; 3]]) -> f64 {
        let off = |v: usize, target: [f64; 3]| {
            let p = positions[v];
            (0..3)
                .map(|k| (p[k] - target[k]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let fixed = self.fixed.iter().map(|&v| off(v, self.original[v]));
        let handle = self.handle.iter().map(|&v| {
            let p = self.original[v];
            off(v, [0, 1, 2].map(|k| p[k] + self.offset[k] + m[k][3]))
        });
        fixed.chain(handle).fold(0.0, f64::max) / self.diagonal
    }
}

/// One configuration's deformer (dropped when it fails), or its handle
/// basis, and record.
#[derive(Default)]
struct Slot {
    deformer: Option<Deformer>,
    basis: Option<HandleBasis>,
    rec: Frames,
    error: Option<String>,
    /// Why a row was not measured (the Python rows without a Python).
    not_measured: Option<String>,
    precompute: Option<f64>,
    basis_build: Option<f64>,
    nnz_factor: Option<usize>,
}

/// One deformer per configuration, precomputed, with a warm-up solve (not
/// counted: caches, penalty's one-off accuracy check, and the first
/// refinement, which measures the factor's rounding floor); the basis rows
/// then build the handle group's basis and keep only it. The Python rows
/// are left empty (measured by [`python_frames`]).
fn precompute_all(mesh: &Mesh, drag: &Drag, configs: &[Config]) -> Vec<Slot> {
    configs
        .iter()
        .map(|c| {
            let mut slot = Slot::default();
            if c.frame_call.is_python() {
                return slot;
            }
            if let Err(e) = prepare(&mut slot, mesh, drag, c) {
                slot.error = Some(e.to_string());
                slot.deformer = None;
            }
            slot
        })
        .collect()
}

/// The precompute, warm-up solve and, for the basis row, the basis of
/// configuration `c` into `slot`.
fn prepare(slot: &mut Slot, mesh: &Mesh, drag: &Drag, c: &Config) -> Result<(), AnyError> {
    let mut d = Deformer::with_formulation(
        mesh.clone(),
        LaplacianKind::Cotangent,
        drag.constraints.clone(),
        c.formulation.as_ref(),
        &lse_deform::resources::Resources::default(),
    )?;
    slot.precompute = Some(d.report().timings_s.precompute());
    slot.nnz_factor = d.report().nnz.factor;
    if c.frame_call == FrameCall::UnrefinedSolveInto {
        d.solver_mut().set_refine(Some(Refine::EstimateOnly));
    }
    d.solve_matrix()?;
    if c.frame_call == FrameCall::Basis {
        let basis = HandleBasis::new(&mut d, &[HANDLE_GROUP])?;
        slot.basis_build = Some(basis.build_time_s());
        slot.basis = Some(basis);
    } else {
        slot.deformer = Some(d);
    }
    Ok(())
}

/// Frame `f`: the handle's targets moved by the frame's transform
/// (`transform_group`), then a solve as `call` says (after `solve_into`,
/// the hard-constraint residual is measured once the frame's clock has
/// stopped). The mid-drag shape is kept in the mesh's units.
fn solve_frame(
    deformer: &mut Deformer,
    drag: &Drag,
    f: usize,
    call: FrameCall,
    rec: &mut Frames,
) -> Result<(), AnyError> {
    let m = drag.transform(f);
    let start = Instant::now();
    deformer.transform_group(HANDLE_GROUP, &m)?;
    let targets = start.elapsed().as_secs_f64();
    let unrefined = call == FrameCall::UnrefinedSolveInto;
    let x = if unrefined {
        let n = deformer.problem().n();
        let mut x = rec.buffer.take().unwrap_or_else(|| Mat::zeros(n, 3));
        deformer.solver_mut().solve_into(x.as_mut())?;
        x
    } else {
        deformer.solve_matrix()?
    };
    let frame = start.elapsed().as_secs_f64();
    let r = deformer.report();
    rec.targets.push(targets);
    rec.solve.push(r.timings_s.solve);
    rec.refine.push(r.timings_s.refine);
    rec.frame.push(frame);
    if unrefined {
        rec.diagnostics.push(0.0);
        let p = deformer.problem();
        let residual = max_hard_residual(p, &x) / p.length_scale();
        rec.max_residual = rec.max_residual.max(residual);
    } else {
        rec.diagnostics.push(r.timings_s.diagnostics);
        rec.max_residual = rec.max_residual.max(r.max_constraint_residual_relative);
    }
    if f == drag.middle() {
        let unit = deformer.length_unit();
        let rows = (0..x.nrows()).map(|i| [0, 1, 2].map(|k| x[(i, k)] * unit));
        rec.middle = Some(rows.collect());
    }
    if unrefined {
        rec.buffer = Some(x);
    }
    Ok(())
}

/// Frame `f` of the basis: `evaluate` at the frame's transform into the
/// buffer kept across frames (the clock covers the evaluation alone; the
/// residual is measured after it).
fn basis_frame(
    basis: &HandleBasis,
    drag: &Drag,
    f: usize,
    rec: &mut Frames,
) -> Result<(), AnyError> {
    let m = drag.transform(f);
    let mut out = std::mem::take(&mut rec.positions);
    out.resize(basis.n_vertices(), [0.0; 3]);
    let start = Instant::now();
    basis.evaluate(std::slice::from_ref(&m), &mut out)?;
    let t = start.elapsed().as_secs_f64();
    rec.targets.push(0.0);
    rec.solve.push(t);
    rec.refine.push(0.0);
    rec.diagnostics.push(0.0);
    rec.frame.push(t);
    rec.max_residual = rec.max_residual.max(drag.residual(&m, &out));
    if f == drag.middle() {
        rec.middle = Some(out.clone());
    }
    rec.positions = out;
    Ok(())
}

/// The frames, round-robin over the configurations (frame f of every
/// configuration before frame f + 1 of any), so that the load of this
/// shared machine falls on all of them alike.
fn run_frames(ctx: &Context, drag: &Drag, configs: &[Config], slots: &mut [Slot]) {
    let bar = ctx.bar(drag.frames, &format!("{NAME}: frames"));
    for f in 0..drag.frames {
        for (c, slot) in configs.iter().zip(slots.iter_mut()) {
            let outcome = match (&slot.basis, slot.deformer.as_mut()) {
                (Some(b), _) => basis_frame(b, drag, f, &mut slot.rec),
                (None, Some(d)) => solve_frame(d, drag, f, c.frame_call, &mut slot.rec),
                (None, None) => continue,
            };
            if let Err(e) = outcome {
                slot.error = Some(e.to_string());
                (slot.deformer, slot.basis) = (None, None);
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    for slot in slots.iter_mut() {
        (slot.deformer, slot.basis) = (None, None);
    }
}

/// The Python rows: `drag_python.py` drags the same frames after the Rust
/// rows (in one process, each of its two rows frame after frame, as a
/// drag on that path runs), or
/// each row says why it was not measured. Returns a note naming the
/// Python when measured.
fn python_frames(
    case: &MeshCase,
    drag: &Drag,
    configs: &[Config],
    slots: &mut [Slot],
) -> Option<String> {
    let measured = python::measure(
        &case.mesh,
        &drag.constraints,
        &drag.transforms(),
        drag.middle() + 1,
    );
    for (c, slot) in configs.iter().zip(slots.iter_mut()) {
        if !c.frame_call.is_python() {
            continue;
        }
        match &measured {
            Ok(p) => slot.rec = python_record(p, c.frame_call == FrameCall::PythonBasis),
            Err(why) => slot.not_measured = Some(why.clone()),
        }
        slot.basis_build = match (&measured, c.frame_call) {
            (Ok(p), FrameCall::PythonBasis) => Some(p.measured.basis_build_s),
            _ => None,
        };
    }
    measured.ok().map(|p| {
        format!(
            "Python rows: Python {}, numpy {}, the package of this checkout in {}.",
            p.measured.python_version, p.measured.numpy_version, p.origin
        )
    })
}

/// The record of a Python row from the script's measurements.
fn python_record(p: &PythonRows, basis: bool) -> Frames {
    let m = &p.measured;
    let zeros = vec![0.0; m.basis_s.len()];
    if basis {
        Frames {
            targets: zeros.clone(),
            solve: m.basis_s.clone(),
            refine: zeros.clone(),
            diagnostics: zeros,
            frame: m.basis_s.clone(),
            max_residual: m.basis_residual,
            middle: Some(p.basis_middle.clone()),
            ..Frames::default()
        }
    } else {
        Frames {
            targets: zeros.clone(),
            solve: m.solve_phase_s.clone(),
            refine: m.refine_s.clone(),
            diagnostics: zeros,
            frame: m.solve_frame_s.clone(),
            max_residual: m.solve_residual,
            middle: Some(p.solve_middle.clone()),
            ..Frames::default()
        }
    }
}

/// Max vertex distance between two shapes (mesh units) over `diag`.
fn deviation(a: &[[f64; 3]], b: &[[f64; 3]], diag: f64) -> f64 {
    let worst = a
        .iter()
        .zip(b)
        .map(|(p, q)| (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt());
    worst.fold(0.0, f64::max) / diag
}

/// The statistics of a completed drag, into `row`.
fn summarise(row: &mut Row, rec: &Frames) {
    row.solve_p50_s = Some(median(&rec.solve));
    row.solve_p99_s = Some(percentile(&rec.solve, 0.99));
    row.solve_max_s = Some(percentile(&rec.solve, 1.0));
    row.frame_p50_s = Some(median(&rec.frame));
    row.frame_p99_s = Some(percentile(&rec.frame, 0.99));
    row.targets_p50_s = Some(median(&rec.targets));
    row.refine_p50_s = Some(median(&rec.refine));
    row.diagnostics_p50_s = Some(median(&rec.diagnostics));
    row.fps_p50 = row.frame_p50_s.map(|t| 1.0 / t);
    row.fps_p99 = row.frame_p99_s.map(|t| 1.0 / t);
    row.solve_fps_p50 = row.solve_p50_s.map(|t| 1.0 / t);
    row.max_constraint_residual_relative = Some(rec.max_residual);
}

/// One row per configuration; the mid-drag shapes compared with the first
/// configuration's.
fn rows(configs: &[Config], slots: &mut [Slot], diag: f64, notes: &mut Vec<String>) -> Vec<Row> {
    let mut rows: Vec<Row> = Vec::new();
    let mut reference: Option<Vec<[f64; 3]>> = None;
    for (c, slot) in configs.iter().zip(slots.iter_mut()) {
        let mut row = Row {
            label: c.label.clone(),
            method: c.choice.method.name(),
            qr_backend: (c.choice.method == Method::NullSpaceQr)
                .then(|| c.choice.qr.name().to_string()),
            spd_backend: c.choice.spd.name().to_string(),
            frame_call: c.frame_call.name(),
            precompute_s: slot.precompute,
            basis_build_s: slot.basis_build,
            frames: slot.rec.frame.len(),
            nnz_factor: slot.nnz_factor,
            status: "ok".into(),
            ..Row::default()
        };
        if let Some(why) = &slot.not_measured {
            row.status = format!("not measured: {}", short_error(why));
            rows.push(row);
            continue;
        }
        match &slot.error {
            None => {
                summarise(&mut row, &slot.rec);
                if let Some(mid) = slot.rec.middle.take() {
                    row.deviation_from_reference =
                        Some(reference.as_ref().map_or(0.0, |r| deviation(&mid, r, diag)));
                    reference.get_or_insert(mid);
                }
            }
            Some(e) => {
                notes.push(format!("{}: {e}", c.label));
                row.status = format!(
                    "failed after {} frames: {}",
                    slot.rec.frame.len(),
                    short_error(e)
                );
            }
        }
        rows.push(row);
    }
    rows
}

/// `drag_summary.csv`, `drag_frames.csv` and `drag_summary.json`.
fn write_data(
    ctx: &Context,
    dir: &Path,
    case: &MeshCase,
    drag: &Drag,
    rows: &[Row],
    slots: &[Slot],
) -> Result<(), AnyError> {
    ctx.write_rows(&dir.join("drag_summary"), rows)?;
    let frame_rows: Vec<FrameRow> = rows
        .iter()
        .zip(slots)
        .flat_map(|(r, s)| {
            let rec = &s.rec;
            (0..rec.frame.len()).map(move |f| FrameRow {
                label: r.label.clone(),
                frame: f + 1,
                targets_s: rec.targets[f],
                solve_s: rec.solve[f],
                refine_s: rec.refine[f],
                diagnostics_s: rec.diagnostics[f],
                frame_s: rec.frame[f],
            })
        })
        .collect();
    ctx.write_rows(&dir.join("drag_frames"), &frame_rows)?;
    ctx.write_json(
        &dir.join("drag_summary.json"),
        &serde_json::json!({
            "mesh": case.name,
            "source": case.source,
            "vertices": case.mesh.n_vertices(),
            "fixed": drag.fixed.len(),
            "handle": drag.handle.len(),
            "frames": drag.frames,
            "penalty_weight": PENALTY_RELATIVE_WEIGHT,
            "rows": rows,
        }),
    )
}

/// Figure: latency bars (solve p50, rest of the frame p50, p99 − p50).
fn latency_figure(
    dir: &Path,
    case: &MeshCase,
    frames: usize,
    rows: &[Row],
    notes: &mut Vec<String>,
) -> Result<(), AnyError> {
    let categories: Vec<Category> = rows
        .iter()
        .filter_map(|r| {
            let (s, f50, f99) = (r.solve_p50_s?, r.frame_p50_s?, r.frame_p99_s?);
            Some(Category {
                name: r.label.clone(),
                values: vec![
                    s * 1e3,
                    (f50 - s).max(0.0) * 1e3,
                    (f99 - f50).max(0.0) * 1e3,
                ],
            })
        })
        .collect();
    if categories.is_empty() {
        return Ok(());
    }
    let n_bars = categories.len() as u32;
    let spec = StackedBars {
        title: format!(
            "Per-frame latency over {frames} frames of a drag — {} ({} vertices)",
            case.name,
            case.mesh.n_vertices()
        ),
        value_label: "milliseconds".into(),
        segments: vec![
            "solve phase, p50".into(),
            "rest of the frame (targets, diagnostics), p50".into(),
            "frame p99 − frame p50".into(),
        ],
        categories,
        total_suffix: Some(" ms".into()),
        legend: LegendPosition::Auto,
    };
    let out = Output::new(dir.join("latency")).with_size(1000, 200 + 34 * n_bars);
    note_drawn(&plot::stacked_bars(&spec, &out)?, notes);
    Ok(())
}

/// Figure: the frame time of every frame for the first configuration of
/// each method; `false` when there is nothing to draw.
fn frames_figure(
    dir: &Path,
    case: &MeshCase,
    rows: &[Row],
    slots: &[Slot],
    notes: &mut Vec<String>,
) -> Result<bool, AnyError> {
    let mut series = Vec::new();
    for method in Method::ALL {
        if let Some((r, s)) = rows
            .iter()
            .zip(slots)
            .find(|(r, s)| r.method == method.name() && !s.rec.frame.is_empty())
        {
            let points = s.rec.frame.iter().enumerate();
            series.push(Series::new(
                r.label.clone(),
                points.map(|(f, &t)| ((f + 1) as f64, t * 1e3)).collect(),
            ));
        }
    }
    if series.is_empty() {
        return Ok(false);
    }
    let chart = LineChart {
        title: format!("Frame time along the drag — {}", case.name),
        x: Axis::linear("frame"),
        y: Axis::log10("frame time (ms): targets + solve + diagnostics"),
        series,
        reference_lines: vec![],
        legend: LegendPosition::Auto,
    };
    note_drawn(
        &plot::line_chart(&chart, &Output::new(dir.join("frame_times")))?,
        notes,
    );
    Ok(true)
}

/// Milliseconds with two decimals, or a dash.
fn ms(v: Option<f64>) -> String {
    v.map_or_else(|| "—".into(), |t| format!("{:.2}", t * 1e3))
}

/// The table of every configuration.
fn table(rows: &[Row]) -> String {
    let dash = || "—".to_string();
    let fmt = |v: Option<f64>, f: fn(f64) -> String| v.map_or_else(dash, f);
    let table_rows: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.label.clone(),
                fmt(r.precompute_s, fmt_time),
                fmt(r.basis_build_s, fmt_time),
                ms(r.solve_p50_s),
                ms(r.solve_p99_s),
                ms(r.refine_p50_s),
                ms(r.frame_p50_s),
                ms(r.frame_p99_s),
                fmt(r.fps_p50, |v| format!("{v:.0}")),
                fmt(r.fps_p99, |v| format!("{v:.0}")),
                fmt(r.solve_fps_p50, |v| format!("{v:.0}")),
                fmt(r.max_constraint_residual_relative, |v| format!("{v:.0e}")),
                fmt(r.deviation_from_reference, |v| format!("{v:.0e}")),
                r.status.clone(),
            ]
        })
        .collect();
    markdown_table(
        &[
            "configuration",
            "precompute",
            "basis build",
            "solve p50 (ms)",
            "solve p99 (ms)",
            "refine p50 (ms)",
            "frame p50 (ms)",
            "frame p99 (ms)",
            "fps (p50)",
            "fps (p99)",
            "fps, solve only (p50)",
            "residual",
            "deviation",
            "status",
        ],
        &table_rows,
    )
}

/// The configuration with the fastest frame (p50).
fn fastest(rows: &[Row]) -> Option<&Row> {
    rows.iter()
        .filter(|r| r.frame_p50_s.is_some())
        .min_by(|a, b| {
            let key = |r: &Row| r.frame_p50_s.unwrap_or(f64::INFINITY);
            key(a).total_cmp(&key(b))
        })
}

/// The section's first paragraph: the mesh, the scene and the method.
fn method_text(ctx: &Context, case: &MeshCase, drag: &Drag) -> String {
    format!(
        "Mesh: {} ({} vertices; {}). Scene: the paper's default (cotangent Laplacian, {} fixed vertices, a hard handle of {} vertices). \
         After one precompute per configuration and one warm-up solve, the handle is moved rigidly along a closed loop \
         (sideways by {:.0} % of the bounding-box diagonal × sin 2πt, along the long axis by the same × (1 − cos 2πt)/2) for {} frames: \
         frame f moves the handle group by the translation `M = [I | t_f]` of its rest targets (`transform_group(\"handle\", M)`), then solves. \
         All configurations are precomputed first and the frames run round-robin (frame f of every configuration before frame f + 1 of any), \
         so that the load of this shared machine falls on all of them alike. \
         Configurations: the library default first, then the library default with refinement off, whose frames call `solve_into` \
         (no correction and no diagnostics: the cost of a frame that skips refinement, and in \"deviation\" its error); \
         the library default's handle basis (`HandleBasis::new(deformer, [\"handle\"])` once after the warm-up solve, timed in \"basis build\"; each frame `HandleBasis::evaluate` at the same `M` into a buffer kept across frames: \
         its solve and frame columns are that evaluation, docs/handles.md); the same two frames through Python after the Rust frames, in one warm process of `experiments/drag_python.py` \
         (`Deformer.basis([\"handle\"]).evaluate({{\"handle\": M}}, out=buffer)`, and `transform_group(\"handle\", M)` + `solve()` with the default refinement, each path frame after frame as a drag on it runs: all basis frames, then all solve frames; \
         Python's frame includes the conversion to numpy); null-space QR on every SPD back end but faer-supernodal (what faer-auto selects at this size{}) and with every QR back end; \
         penalty, KKT and elimination on the default SPD back end only (their solve phase is that back end's; `scaling` compares the back ends). \
         Every other frame calls `Deformer::solve_matrix`: the solve phase, the refine phase of each method's default refinement (`auto` for the exact methods: \
         after the warm-up solve has measured the factor's rounding floor, a frame stops refining on the prediction of docs/refinement.md §6; `off` for penalty, \
         which still computes one correction for the forward-error estimate), then the solution diagnostics; an interactive caller that does not want the diagnostics calls `solve_into`. \
         **Solve** is the library's solve phase (`report.timings_s.solve`), **refine** its refine phase (`timings_s.refine`); **frame** is the wall time of the targets + `solve_matrix` (or `solve_into`) call; `solve_matrix`'s includes the \
         diagnostics the library computes after every such solve (constraint residuals, ‖AX − C‖). fps = 1 / latency. \
         Penalty weight w = {:.3e} (100 × median |L_ii|).\n",
        case.name,
        case.mesh.n_vertices(),
        case.source,
        drag.fixed.len(),
        drag.handle.len(),
        15.0,
        drag.frames,
        if ctx.has_user_meshes() {
            ""
        } else {
            "; faer-simplicial and nalgebra, 2–4× slower per solve, only in the run with --mesh-dir"
        },
        PENALTY_RELATIVE_WEIGHT
    )
}

/// The sentences computed from the rows: fastest, default, diagnostics.
fn findings(rows: &[Row]) -> String {
    let mut s = String::new();
    // The library default is the first configuration.
    if let (Some(b), Some(d)) = (fastest(rows), rows.first()) {
        let _ = writeln!(
            s,
            "\nFastest frame (p50): **{}** at {} ms ({:.0} fps). The library default ({}) runs at {} ms p50 / {} ms p99 per frame ({:.0} / {:.0} fps).",
            b.label,
            ms(b.frame_p50_s),
            b.fps_p50.unwrap_or(f64::NAN),
            d.label,
            ms(d.frame_p50_s),
            ms(d.frame_p99_s),
            d.fps_p50.unwrap_or(f64::NAN),
            d.fps_p99.unwrap_or(f64::NAN),
        );
    }
    if let Some(d) = rows.first()
        && let (Some(solve), Some(refine), Some(frame), Some(diag)) = (
            d.solve_p50_s,
            d.refine_p50_s,
            d.frame_p50_s,
            d.diagnostics_p50_s,
        )
    {
        let _ = writeln!(
            s,
            "The library default's frame p50 is {:.2}× its solve p50 ({:.2}× without the diagnostics, as `solve_into` runs it): refine p50 {} ms = {:.2}× the solve, diagnostics {} ms.",
            frame / solve,
            (frame - diag) / solve,
            ms(Some(refine)),
            refine / solve,
            ms(Some(diag)),
        );
    }
    if let (Some(d), Some(u)) = (
        rows.first(),
        rows.iter().find(|r| r.frame_call == "solve_into"),
    ) && let (Some(solve), Some(frame), Some(default_frame), Some(off_by)) = (
        u.solve_p50_s,
        u.frame_p50_s,
        d.frame_p50_s,
        u.deviation_from_reference,
    ) {
        let _ = writeln!(
            s,
            "Without refinement ({}): the frame p50 is {:.2}× its solve p50 and {:.2}× the default's frame, and the mid-drag shape is {:.1e} of the diagonal from the refined one (the default's refinement reaches the rounding floor: every correction repeats the solve's two triangular solves, so a refined frame costs at least two solves).",
            u.label,
            frame / solve,
            frame / default_frame,
            off_by,
        );
    }
    let diag_share: Vec<f64> = rows
        .iter()
        .filter(|r| r.frame_call == FrameCall::SolveMatrix.name())
        .filter_map(|r| Some(r.diagnostics_p50_s? / r.frame_p50_s?))
        .collect();
    if !diag_share.is_empty() {
        let _ = writeln!(
            s,
            "The per-solve diagnostics take {:.0}–{:.0} % of a frame (median {:.0} %): an interactive application would want to skip them.",
            100.0 * diag_share.iter().copied().fold(f64::INFINITY, f64::min),
            100.0 * diag_share.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            100.0 * median(&diag_share)
        );
    }
    s
}

/// The target of the handle basis (docs/handles.md §2: a frame reads the
/// basis once): its frame (p50) at most this
/// fraction of the library default's solve phase (p50)…
const BASIS_RATIO_LIMIT: f64 = 0.1;
/// …and its mid-drag shape within this of the refined one's, relative to
/// the bounding-box diagonal.
const BASIS_DEVIATION_LIMIT: f64 = 1e-10;

fn verdict(met: bool) -> &'static str {
    if met { "met" } else { "**missed**" }
}

/// The row of the frame call `call`, if measured.
fn row_of(rows: &[Row], call: FrameCall) -> Option<&Row> {
    rows.iter()
        .find(|r| r.frame_call == call.name() && r.frame_p50_s.is_some())
}

/// The sentence of one basis row: its build, its frame against the
/// default's solve phase and its deviation, with the targets.
fn basis_sentence(r: &Row, default_solve: f64) -> Option<String> {
    let (frame, dev) = (r.frame_p50_s?, r.deviation_from_reference?);
    let ratio = frame / default_solve;
    Some(format!(
        "{}: built once in {}; a frame p50 {} ms / p99 {} ms, **{ratio:.3}× the default's solve phase** (p50 {} ms; target ≤ {BASIS_RATIO_LIMIT}: {}), {dev:.1e} of the diagonal from the refined frame (target ≤ {BASIS_DEVIATION_LIMIT:.0e}: {}).",
        r.label,
        r.basis_build_s.map_or_else(|| "—".into(), fmt_time),
        ms(Some(frame)),
        ms(r.frame_p99_s),
        ms(Some(default_solve)),
        verdict(ratio <= BASIS_RATIO_LIMIT),
        verdict(dev <= BASIS_DEVIATION_LIMIT),
    ))
}

/// The handle basis against the solve, the Python rows, what was not
/// measured, and which path to use for what.
fn basis_findings(rows: &[Row]) -> String {
    let mut s = String::new();
    let Some(d) = rows.first() else {
        return s;
    };
    if let Some(solve) = d.solve_p50_s {
        for call in [FrameCall::Basis, FrameCall::PythonBasis] {
            if let Some(line) = row_of(rows, call).and_then(|r| basis_sentence(r, solve)) {
                let _ = writeln!(s, "{line}");
            }
        }
    }
    if let (Some(p), Some(frame)) = (row_of(rows, FrameCall::PythonSolve), d.frame_p50_s) {
        let _ = writeln!(
            s,
            "{}: a frame p50 {} ms / p99 {} ms, {:.2}× the Rust default's frame; {:.1e} of the diagonal from it.",
            p.label,
            ms(p.frame_p50_s),
            ms(p.frame_p99_s),
            p.frame_p50_s.unwrap_or(f64::NAN) / frame,
            p.deviation_from_reference.unwrap_or(f64::NAN),
        );
    }
    let missing: Vec<&Row> = rows
        .iter()
        .filter(|r| r.status.starts_with("not measured"))
        .collect();
    if let Some(first) = missing.first() {
        let labels: Vec<&str> = missing.iter().map(|r| r.label.as_str()).collect();
        let _ = writeln!(
            s,
            "**Not measured:** {} — {} (the Python rows need a Python with this checkout's package, found or created as the `python` section says).",
            labels.join("; "),
            first.status.trim_start_matches("not measured: ")
        );
    }
    let _ = writeln!(
        s,
        "Which path for what: a drag that moves handles by affine maps → the handle basis (`HandleBasis::evaluate`, Python's `Deformer.basis`; the refined solution for any transform of its groups without a solve); arbitrary edits of targets → `solve` (refinement `off` while dragging when the error of the refine-off row above is acceptable); the final shape → a refined solve (`auto`)."
    );
    s
}

/// The section, from the rows and notes.
fn section(
    ctx: &Context,
    case: &MeshCase,
    drag: &Drag,
    rows: &[Row],
    have_frames_figure: bool,
    notes: &[String],
) -> String {
    let mut s = method_text(ctx, case, drag);
    s.push_str(&ctx.regenerate(NAME));
    let _ = writeln!(
        s,
        "**Table.** One row per method and back end. Read the p50 columns for the typical frame and p99 for the hitches; \
         \"residual\" is the largest hard-constraint residual over all frames relative to the bounding-box diagonal (penalty: its approximation error), \
         \"deviation\" the largest distance of the mid-drag shape from the first row's, relative to the diagonal (all methods solve the same problem).\n"
    );
    s.push_str(&table(rows));
    s.push_str(&findings(rows));
    s.push_str(&basis_findings(rows));
    let _ = writeln!(
        s,
        "\n**Figure: latency.** One bar per configuration: the first segment is the solve phase (p50), the first two the whole frame (p50), \
         the end of the bar the frame's p99. Shorter is better; a long third segment means hitches.\n\n{}",
        link(NAME, "latency")
    );
    if have_frames_figure {
        let _ = writeln!(
            s,
            "\n**Figure: frame times.** Frame time of every frame for the first configuration of each method (log scale); \
             a flat line is a steady drag, spikes are hitches (on this shared 2-core machine, mostly other processes).\n\n{}",
            link(NAME, "frame_times")
        );
    }
    s.push_str(&ctx.closing(
        notes,
        &format!("Data: [`{NAME}/drag_summary.csv`]({NAME}/drag_summary.csv) (one row per configuration), [`{NAME}/drag_frames.csv`]({NAME}/drag_frames.csv) (every frame), [`{NAME}/drag_summary.json`]({NAME}/drag_summary.json)."),
    ));
    s
}

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let dir = ctx.dir(NAME)?;
    let case = ctx.fallback_mesh("bunny-35k-stanford.obj", 35_000, 10_000)?;
    let drag = Drag::new(ctx, &case.mesh)?;
    let configs = configs(PENALTY_RELATIVE_WEIGHT, ctx.has_user_meshes())?;
    let mut slots = precompute_all(&case.mesh, &drag, &configs);
    run_frames(ctx, &drag, &configs, &mut slots);
    let mut notes: Vec<String> = Vec::new();
    notes.extend(python_frames(&case, &drag, &configs, &mut slots));
    let rows = rows(&configs, &mut slots, case.mesh.bbox_diagonal(), &mut notes);
    write_data(ctx, &dir, &case, &drag, &rows, &slots)?;
    latency_figure(&dir, &case, drag.frames, &rows, &mut notes)?;
    let have_frames_figure = frames_figure(&dir, &case, &rows, &slots, &mut notes)?;
    let s = section(ctx, &case, &drag, &rows, have_frames_figure, &notes);
    ctx.write_section(NAME, &s)?;
    let best = fastest(&rows);
    let headline = match rows.first() {
        Some(d) if d.frame_p50_s.is_some() => format!(
            "{} on {} ({} vertices): frame p50 {} ms / p99 {} ms ({:.0} fps); fastest {} {} ms",
            d.label,
            case.name,
            case.mesh.n_vertices(),
            ms(d.frame_p50_s),
            ms(d.frame_p99_s),
            d.fps_p50.unwrap_or(f64::NAN),
            best.map(|b| b.label.clone()).unwrap_or_default(),
            ms(best.and_then(|b| b.frame_p50_s)),
        ),
        _ => "the default configuration failed".into(),
    };
    Ok(Summary::measured(headline))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn path_is_a_closed_loop_starting_at_rest() {
        for axis in 0..3 {
            let a = path(0.0, axis, 2.0);
            let b = path(1.0, axis, 2.0);
            for k in 0..3 {
                assert!(a[k].abs() < 1e-12);
                assert!(b[k].abs() < 1e-12);
            }
            // Halfway: along the axis by the full amplitude.
            let m = path(0.5, axis, 2.0);
            assert!((m[axis] - 2.0).abs() < 1e-12);
        }
    }

    #[test]
    fn the_handle_transform_translates_rest_targets_onto_the_path() {
        let offset = [0.1, -0.2, 0.3];
        let p = [1.0, 2.0, 3.0];
        let rest = [0, 1, 2].map(|k| p[k] + offset[k]);
        for axis in 0..3 {
            for t in [0.0, 0.3, 0.5, 0.9] {
                let d = path(t, axis, 2.0);
                let m = handle_transform(d, offset);
                for (r, row) in m.iter().enumerate() {
                    for (c, &v) in row[..3].iter().enumerate() {
                        assert_eq!(v, if r == c { 1.0 } else { 0.0 });
                    }
                    let moved: f64 = (0..3).map(|c| row[c] * rest[c]).sum::<f64>() + row[3];
                    assert!((moved - (p[r] + d[r])).abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn the_default_is_dragged_by_every_frame_call() {
        let c = configs(1.0, false).unwrap();
        for call in [
            FrameCall::SolveMatrix,
            FrameCall::UnrefinedSolveInto,
            FrameCall::Basis,
            FrameCall::PythonBasis,
            FrameCall::PythonSolve,
        ] {
            let same = c.iter().filter(|c| c.frame_call == call);
            assert!(same.clone().count() >= 1, "{}", call.name());
            // Every method's rows call `solve_matrix`; the other calls are
            // rows of the default (null-space) formulation only.
            if call != FrameCall::SolveMatrix {
                assert!(same.clone().all(|x| x.choice.method == Method::NullSpaceQr));
            }
        }
        assert_eq!(c[0].frame_call, FrameCall::SolveMatrix);
    }

    #[test]
    fn configs_cover_every_method() {
        let c = configs(1.0, true).unwrap();
        for m in Method::ALL {
            assert!(c.iter().any(|c| c.choice.method == m), "{m}");
        }
        assert_eq!(c[0].choice.method, Method::NullSpaceQr);
    }
}
