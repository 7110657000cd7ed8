//! `arap`: as-rigid-as-possible deformation.
//!
//! (a) A generated tube bent by 90° and twisted by 90°: the linear
//! (gradient-domain) solution against ARAP, renders and the ARAP energy of
//! both, and how much the middle cross-section shrinks.
//! (b) Energy against iteration and against time, ours and libigl's
//! `arap_solve` (through `experiments/arap_libigl.py` and the Python of
//! [`environment::python_with_libigl`]; without one that part is left
//! out and the section says why) on the paper's position-only scene, from
//! libigl's initial guess (rest pose, constrained vertices at their
//! targets); then `experiments/arap_float_check.py`: libigl's loop
//! re-implemented with its rotations fitted in double and in single
//! precision, against ours and libigl at the same checkpoints.
//! (c) ARAP with 300 hard relative and 20 on-edge constraints on top of
//! the same scene: every hard constraint's residual and the energy at
//! every iteration.

use std::ffi::OsStr;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use faer::Mat;
use lse_deform::arap::{ArapDeformer, ArapEnergy, ArapInit, ArapTriangles};
use lse_deform::constraints::{Constraint, ConstraintKind, ConstraintSet};
use lse_deform::formulation::NullSpaceQr;
use lse_deform::mesh::{Mesh, generate};
use lse_deform::scene::{FixedAndHandle, MixedScene};
use serde::{Deserialize, Serialize};

use crate::harness::context::AnyError;
use crate::harness::context::{Context, MeshCase};
use crate::harness::environment::{self, Python};
use crate::harness::plot::{self, Axis, LegendPosition, LineChart, Output, Series};
use crate::harness::registry::{Experiment, Input, Summary};
use crate::harness::rows::{fmt_time, markdown_table};
use lse_deform::render::{self, Camera, Layout, Panel, RenderMesh, Style};

pub const NAME: &str = "arap";

/// This study's entry in the list of experiments.
pub const EXPERIMENT: Experiment = Experiment {
    name: NAME,
    title: "As-rigid-as-possible deformation (ARAP)",
    inputs: &[Input::OneMesh, Input::Python],
    run,
};

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let dir = ctx.dir(NAME)?;
    let bend = bend_and_twist(ctx, &dir)?;
    let case = scene_mesh(ctx)?;
    let peer = versus_libigl(ctx, &dir, &case)?;
    let exact = exact_constraints(ctx, &dir, &case)?;
    let init = initial_guesses(ctx, &dir, &case)?;
    let mut md = section(ctx, &bend, &peer, &exact, &case);
    initial_guess_text(&mut md, &init);
    ctx.write_section(NAME, &md)?;
    ctx.write_page(NAME, EXPERIMENT.title, &md)?;
    Ok(Summary::measured(format!(
        "tube bend+twist: ARAP energy {:.3e} vs linear {:.3e}; 300 relative + 20 on-edge: max residual {:.1e} × diagonal, energy {}",
        bend.arap_energy,
        bend.linear_energy,
        exact.max_residual_over_diagonal,
        if exact.monotone {
            "monotone"
        } else {
            "NOT monotone"
        }
    )))
}

// ---------------------------------------------------------------- (a)

/// A tube of radius `r` along z from 0 to `length`: `around` vertices per
/// ring, `along + 1` rings, open ends.
fn tube(around: usize, along: usize, r: f64, length: f64) -> Result<Mesh, AnyError> {
    let mut positions = Vec::with_capacity(around * (along + 1));
    for j in 0..=along {
        for i in 0..around {
            let a = std::f64::consts::TAU * i as f64 / around as f64;
            positions.push([r * a.cos(), r * a.sin(), length * j as f64 / along as f64]);
        }
    }
    let mut faces = Vec::with_capacity(2 * around * along);
    for j in 0..along {
        for i in 0..around {
            let (a, b) = (j * around + i, j * around + (i + 1) % around);
            let (c, d) = (a + around, b + around);
            faces.push([a, b, d]);
            faces.push([a, d, c]);
        }
    }
    Ok(Mesh::new(positions, faces)?)
}

/// The bottom rings (`end` of them) fixed; the top `end` rings moved
/// rigidly to where a bend by 90° about x (the tube's axis as a quarter
/// circle of length `length`, tangent ending along +y) and a twist by 90°
/// about the axis put them.
fn bend_constraints(
    mesh: &Mesh,
    around: usize,
    end: usize,
    length: f64,
) -> Result<ConstraintSet, AnyError> {
    let p = mesh.positions();
    let n = p.len();
    let radius = length / std::f64::consts::FRAC_PI_2;
    let mut cs = ConstraintSet::new();
    for (v, &q) in p.iter().enumerate().take(end * around) {
        cs.push(Constraint::hard(ConstraintKind::Position {
            vertex: v,
            target: q,
        }))?;
    }
    for (v, &q) in p.iter().enumerate().skip(n - end * around) {
        // Offset from the top centre (q₀, q₁, dz); twist: rotated by 90°
        // about z to (−q₁, q₀, dz); bend: the frame rotated by −90° about x
        // ((x, y, z) → (x, z, −y)), the top centre moved to (0, R, R).
        let dz = q[2] - length;
        let target = [-q[1], radius + dz, radius - q[0]];
        cs.push(Constraint::hard(ConstraintKind::Position {
            vertex: v,
            target,
        }))?;
    }
    Ok(cs)
}

/// Mean distance of ring `j`'s vertices from their centroid.
fn ring_radius(x: &[[f64; 3]], around: usize, j: usize) -> f64 {
    let ring = &x[j * around..(j + 1) * around];
    let c = [0, 1, 2].map(|k| ring.iter().map(|p| p[k]).sum::<f64>() / around as f64);
    ring.iter()
        .map(|p| ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt())
        .sum::<f64>()
        / around as f64
}

/// What (a) measured.
#[derive(Debug, Clone, Serialize)]
struct Bend {
    vertices: usize,
    iterations: usize,
    linear_energy: f64,
    arap_energy: f64,
    energies: Vec<f64>,
    /// Middle ring's mean radius over the rest radius.
    linear_mid_radius: f64,
    arap_mid_radius: f64,
    time_per_iteration_s: f64,
    render: String,
}

fn bend_and_twist(ctx: &Context, dir: &Path) -> Result<Bend, AnyError> {
    let (around, along, r, length) = if ctx.quick {
        (16, 40, 0.1, 1.0)
    } else {
        (32, 120, 0.1, 1.0)
    };
    let iterations = if ctx.quick { 30 } else { 3000 };
    let mesh = tube(around, along, r, length)?;
    let cs = bend_constraints(&mesh, around, (along / 20).max(1), length)?;
    let mut arap = ArapDeformer::with_formulation(
        mesh.clone(),
        cs,
        ArapEnergy::SpokesAndRims,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )?;
    arap.initialize(ArapInit::Linear)?;
    let linear = arap.positions();
    let linear_energy = arap.energy();
    let report = arap.run(iterations, 0.0)?;
    let deformed = arap.positions();
    let render = "bend_twist.png".to_string();
    render_bend(&mesh, &linear, &deformed, &dir.join(&render))?;
    Ok(Bend {
        vertices: mesh.n_vertices(),
        iterations,
        linear_energy,
        arap_energy: arap.energy(),
        energies: report.energies.clone(),
        linear_mid_radius: ring_radius(&linear, around, along / 2) / r,
        arap_mid_radius: ring_radius(&deformed, around, along / 2) / r,
        time_per_iteration_s: report.time_per_iteration_s,
        render,
    })
}

fn render_bend(
    mesh: &Mesh,
    linear: &[[f64; 3]],
    arap: &[[f64; 3]],
    path: &Path,
) -> Result<(), AnyError> {
    let panels = [
        Panel {
            mesh: RenderMesh::from_mesh(mesh),
            caption: "(a) rest".into(),
        },
        Panel {
            mesh: RenderMesh::new(linear, mesh.faces()),
            caption: "(b) linear (Laplacian editing)".into(),
        },
        Panel {
            mesh: RenderMesh::new(arap, mesh.faces()),
            caption: "(c) ARAP, spokes-and-rims".into(),
        },
    ];
    let layout = Layout {
        panel_width: 480,
        panel_height: 480,
        camera: Camera::from_direction([1.0, -0.35, 0.25], 2)?,
        title: Some(
            "Tube bent by 90° and twisted by 90° (5 % of the rings at each end constrained)".into(),
        ),
        ..Layout::default()
    };
    render::render_side_by_side(&panels, &layout, &Style::default(), path)?;
    Ok(())
}

// ---------------------------------------------------------------- (b), (c)

/// The mesh of (b) and (c): the Bunny if given, else a generated bumpy
/// sphere.
fn scene_mesh(ctx: &Context) -> Result<MeshCase, AnyError> {
    if let Some(case) = ctx.real_mesh("bunny-35k-stanford.obj")? {
        return Ok(case);
    }
    let size = if ctx.quick { 3_000 } else { 20_000 };
    ctx.generated("bumpy-sphere", generate::GeneratedKind::BumpySphere, size)
}

fn matrix(x: &[[f64; 3]]) -> Mat<f64> {
    Mat::from_fn(x.len(), 3, |i, c| x[i][c])
}

fn max_gap(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0, f64::max)
}

/// One checkpoint of (b).
#[derive(Debug, Clone, Serialize)]
struct PeerRow {
    iterations: usize,
    ours_energy: f64,
    ours_elapsed_s: f64,
    libigl_energy: Option<f64>,
    libigl_elapsed_s: Option<f64>,
    max_difference_over_diagonal: Option<f64>,
}

/// One checkpoint of the float-rotation check (`arap_float_check.py`):
/// largest coordinate differences over the bounding-box diagonal.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct FloatRow {
    iterations: usize,
    ours_vs_libigl: f64,
    ours_vs_double_reimplementation: f64,
    single_reimplementation_vs_libigl: f64,
    double_vs_single_reimplementation: f64,
}

/// What (b) measured.
#[derive(Debug, Clone, Serialize)]
struct Peer {
    rows: Vec<PeerRow>,
    /// Ours: energy after every iteration and the cumulative seconds.
    ours: Vec<(f64, f64)>,
    float_check: Vec<FloatRow>,
    /// Why libigl (or the float check) was not run, if it was not.
    note: Option<String>,
    libigl_version: Option<String>,
    /// Where the Python came from.
    python: Option<String>,
}

fn write_raw(path: &Path, values: impl Iterator<Item = [u8; 8]>) -> Result<(), AnyError> {
    let bytes: Vec<u8> = values.flatten().collect();
    std::fs::write(path, bytes)?;
    Ok(())
}

/// The position-only problem for arap_libigl.py, as raw little-endian arrays.
fn write_problem(io: &Path, mesh: &Mesh, cs: &ConstraintSet) -> Result<(), AnyError> {
    std::fs::create_dir_all(io)?;
    write_raw(
        &io.join("V.f64"),
        mesh.positions().iter().flatten().map(|v| v.to_le_bytes()),
    )?;
    write_raw(
        &io.join("F.i64"),
        mesh.faces()
            .iter()
            .flatten()
            .map(|&v| (v as i64).to_le_bytes()),
    )?;
    let (mut b, mut bc) = (Vec::new(), Vec::new());
    for c in cs.as_slice() {
        if let ConstraintKind::Position { vertex, target } = c.kind {
            b.extend_from_slice(&(vertex as i32).to_le_bytes());
            bc.extend(target);
        }
    }
    std::fs::write(io.join("b.i32"), b)?;
    write_raw(&io.join("bc.f64"), bc.iter().map(|v| v.to_le_bytes()))?;
    Ok(())
}

fn read_positions(path: &Path, n: usize) -> Result<Vec<[f64; 3]>, AnyError> {
    let bytes = std::fs::read(path)?;
    if bytes.len() != 24 * n {
        return Err(format!(
            "{}: {} bytes, expected {}",
            path.display(),
            bytes.len(),
            24 * n
        )
        .into());
    }
    let v: Vec<f64> = bytes
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect();
    Ok(v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// libigl at the checkpoints: positions and cumulative seconds, and its
/// version; `Err` with a note when it cannot run.
#[allow(clippy::type_complexity)]
fn run_libigl(
    python: &Python,
    io: &Path,
    n: usize,
    checkpoints: &[usize],
) -> Result<(Vec<(Vec<[f64; 3]>, f64)>, String), AnyError> {
    let trace: Vec<String> = checkpoints.iter().map(|k| k.to_string()).collect();
    let trace = trace.join(",");
    let args: [&OsStr; 5] = [
        io.as_os_str(),
        "--iterations".as_ref(),
        "".as_ref(),
        "--trace".as_ref(),
        trace.as_ref(),
    ];
    let stdout = python.script("arap_libigl.py", &args)?;
    let json: serde_json::Value = serde_json::from_slice(&stdout)?;
    let version = json["libigl_version"]
        .as_str()
        .unwrap_or("unknown")
        .to_string();
    let mut rows = Vec::new();
    for (k, t) in checkpoints
        .iter()
        .zip(json["trace"].as_array().ok_or("no trace")?)
    {
        let x = read_positions(&io.join(format!("libigl_trace_{k}.f64")), n)?;
        rows.push((x, t["elapsed_s"].as_f64().unwrap_or(f64::NAN)));
    }
    Ok((rows, version))
}

/// The float-rotation check's checkpoints (a subset of (b)'s).
fn float_checkpoints(ctx: &Context) -> Vec<usize> {
    if ctx.quick { vec![10] } else { vec![10, 100] }
}

/// Ours on the scene from the rest pose: (energy, cumulative seconds)
/// after every iteration up to the last checkpoint, and the positions at
/// each checkpoint.
#[allow(clippy::type_complexity)]
fn ours_from_rest(
    mesh: &Mesh,
    cs: &ConstraintSet,
    checkpoints: &[usize],
) -> Result<(Vec<(f64, f64)>, Vec<Vec<[f64; 3]>>), AnyError> {
    let last = *checkpoints.last().ok_or("no checkpoints")?;
    let mut arap = ArapDeformer::with_formulation(
        mesh.clone(),
        cs.clone(),
        ArapEnergy::SpokesAndRims,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )?;
    arap.initialize(ArapInit::Rest)?;
    let (mut ours, mut snapshots, mut elapsed) = (Vec::new(), Vec::new(), 0.0);
    for k in 1..=last {
        let t = Instant::now();
        arap.iterate(1)?;
        elapsed += t.elapsed().as_secs_f64();
        ours.push((arap.energy(), elapsed));
        if checkpoints.contains(&k) {
            snapshots.push(arap.positions());
        }
    }
    Ok((ours, snapshots))
}

/// libigl at the checkpoints and the float check, filled into `peer`;
/// `Err` with the reason when either cannot run.
fn libigl_part(
    peer: &mut Peer,
    python: &Python,
    io: &Path,
    mesh: &Mesh,
    cs: &ConstraintSet,
    snapshots: &[Vec<[f64; 3]>],
    float_at: &[usize],
) -> Result<(), AnyError> {
    write_problem(io, mesh, cs)?;
    let checkpoints: Vec<usize> = peer.rows.iter().map(|r| r.iterations).collect();
    let (libigl, version) = run_libigl(python, io, mesh.n_vertices(), &checkpoints)?;
    peer.libigl_version = Some(version);
    let triangles = ArapTriangles::new(mesh, ArapEnergy::SpokesAndRims);
    let diag = mesh.bbox_diagonal();
    for ((row, (x, t)), ours_x) in peer.rows.iter_mut().zip(&libigl).zip(snapshots) {
        row.libigl_energy = Some(triangles.energy_at(&matrix(x)));
        row.libigl_elapsed_s = Some(*t);
        row.max_difference_over_diagonal = Some(max_gap(x, ours_x) / diag);
    }
    for (&k, x) in checkpoints.iter().zip(snapshots) {
        if float_at.contains(&k) {
            write_raw(
                &io.join(format!("ours_{k}.f64")),
                x.iter().flatten().map(|v| v.to_le_bytes()),
            )?;
        }
    }
    peer.float_check = run_float_check(python, io, float_at)?;
    Ok(())
}

/// `arap_float_check.py` on the problem and trajectories in `io`.
fn run_float_check(python: &Python, io: &Path, at: &[usize]) -> Result<Vec<FloatRow>, AnyError> {
    let list: Vec<String> = at.iter().map(|k| k.to_string()).collect();
    let list = list.join(",");
    let args: [&OsStr; 3] = [io.as_os_str(), "--iterations".as_ref(), list.as_ref()];
    Ok(serde_json::from_slice(
        &python.script("arap_float_check.py", &args)?,
    )?)
}

fn versus_libigl(ctx: &Context, dir: &Path, case: &MeshCase) -> Result<Peer, AnyError> {
    let mesh = &case.mesh;
    let cs = FixedAndHandle::paper_default(mesh).constraints(mesh)?;
    let checkpoints: Vec<usize> = if ctx.quick {
        vec![1, 2, 5, 10]
    } else {
        vec![1, 2, 5, 10, 20, 50, 100]
    };
    let (ours, snapshots) = ours_from_rest(mesh, &cs, &checkpoints)?;
    let rows = checkpoints
        .iter()
        .map(|&k| PeerRow {
            iterations: k,
            ours_energy: ours[k - 1].0,
            ours_elapsed_s: ours[k - 1].1,
            libigl_energy: None,
            libigl_elapsed_s: None,
            max_difference_over_diagonal: None,
        })
        .collect();
    let mut peer = Peer {
        rows,
        ours,
        float_check: Vec::new(),
        note: None,
        libigl_version: None,
        python: None,
    };
    match environment::python_with_libigl() {
        Err(why) => peer.note = Some(format!("libigl and the float check not run: {why}")),
        Ok(python) => {
            peer.python = Some(python.origin.clone());
            let io = std::env::temp_dir().join(format!("lse-arap-libigl-{}", std::process::id()));
            let float_at = float_checkpoints(ctx);
            let result = libigl_part(&mut peer, &python, &io, mesh, &cs, &snapshots, &float_at);
            let _ = std::fs::remove_dir_all(&io);
            if let Err(e) = result {
                peer.note = Some(format!("libigl or the float check not run: {e}"));
            }
        }
    }
    ctx.write_json(&dir.join("versus_libigl.json"), &peer)?;
    if !peer.float_check.is_empty() {
        ctx.write_rows(&dir.join("float_check"), &peer.float_check)?;
    }
    plot_peer(&peer, dir)?;
    Ok(peer)
}

fn plot_peer(peer: &Peer, dir: &Path) -> Result<(), AnyError> {
    for (stem, by_time) in [("energy_by_iteration", false), ("energy_by_time", true)] {
        let ours: Vec<(f64, f64)> = peer
            .ours
            .iter()
            .enumerate()
            .map(|(k, &(e, t))| (if by_time { t } else { (k + 1) as f64 }, e))
            .collect();
        let mut series = vec![Series::new("ours (null-space QR, spokes-and-rims)", ours)];
        let libigl: Vec<(f64, f64)> = peer
            .rows
            .iter()
            .filter_map(|r| {
                let x = if by_time {
                    r.libigl_elapsed_s?
                } else {
                    r.iterations as f64
                };
                Some((x, r.libigl_energy?))
            })
            .collect();
        if !libigl.is_empty() {
            series.push(Series::new("libigl arap_solve", libigl));
        }
        let chart = LineChart {
            title: "ARAP energy, rest-pose initial guess, position constraints only".into(),
            x: if by_time {
                Axis::log10("seconds (cumulative)")
            } else {
                Axis::log10("iterations")
            },
            y: Axis::log10("ARAP energy"),
            series,
            legend: LegendPosition::UpperRight,
            ..LineChart::default()
        };
        plot::line_chart(&chart, &Output::new(dir.join(stem)))?;
    }
    Ok(())
}

/// What (c) measured.
#[derive(Debug, Clone, Serialize)]
struct Exact {
    relative: usize,
    on_edge: usize,
    hard: usize,
    iterations: usize,
    energies: Vec<f64>,
    residuals_over_diagonal: Vec<f64>,
    max_residual_over_diagonal: f64,
    /// Largest `(E_k − E_{k−1}) / E_{k−1}` (≤ 0 for a monotone run).
    largest_relative_increase: f64,
    monotone: bool,
}

fn exact_constraints(ctx: &Context, dir: &Path, case: &MeshCase) -> Result<Exact, AnyError> {
    let mesh = &case.mesh;
    let scene = MixedScene {
        base: FixedAndHandle::paper_default(mesh),
        relative: 300,
        edges: 20,
        faces: 0,
        duplicate: false,
        conflict: false,
    };
    let cs = scene.constraints(mesh)?;
    let count =
        |f: fn(&ConstraintKind) -> bool| cs.as_slice().iter().filter(|c| f(&c.kind)).count();
    let relative = count(|k| matches!(k, ConstraintKind::Relative { .. }));
    let on_edge = count(|k| matches!(k, ConstraintKind::Edge { .. }));
    let iterations = if ctx.quick { 20 } else { 100 };
    let mut arap = ArapDeformer::with_formulation(
        mesh.clone(),
        cs.clone(),
        ArapEnergy::SpokesAndRims,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )?;
    arap.initialize(ArapInit::Linear)?;
    let report = arap.run(iterations, 0.0)?;
    let diag = mesh.bbox_diagonal();
    let residuals: Vec<f64> = report
        .constraint_residuals
        .iter()
        .map(|r| r / diag)
        .collect();
    let mut energies = vec![report.initial_energy];
    energies.extend(&report.energies);
    let largest = energies
        .windows(2)
        .map(|e| (e[1] - e[0]) / e[0])
        .fold(f64::NEG_INFINITY, f64::max);
    let exact = Exact {
        relative,
        on_edge,
        hard: cs.len(),
        iterations,
        max_residual_over_diagonal: residuals.iter().copied().fold(0.0, f64::max),
        residuals_over_diagonal: residuals,
        // Rounding allowance: 1e-12 of the energy per iteration.
        monotone: largest <= 1e-12,
        largest_relative_increase: largest,
        energies,
    };
    ctx.write_json(&dir.join("exact_constraints.json"), &exact)?;
    plot_exact(&exact, dir)?;
    Ok(exact)
}

fn plot_exact(exact: &Exact, dir: &Path) -> Result<(), AnyError> {
    let energy: Vec<(f64, f64)> = exact
        .energies
        .iter()
        .enumerate()
        .map(|(k, &e)| (k as f64, e))
        .collect();
    let chart = LineChart {
        title: format!(
            "ARAP with {} relative + {} on-edge hard constraints: energy per iteration",
            exact.relative, exact.on_edge
        ),
        x: Axis::linear("iteration (0 = linear initial guess)"),
        y: Axis::log10("objective"),
        series: vec![Series::new("energy", energy)],
        legend: LegendPosition::Hidden,
        ..LineChart::default()
    };
    plot::line_chart(&chart, &Output::new(dir.join("exact_energy")))?;
    let residual: Vec<(f64, f64)> = exact
        .residuals_over_diagonal
        .iter()
        .enumerate()
        .map(|(k, &r)| ((k + 1) as f64, r.max(1e-18)))
        .collect();
    let chart = LineChart {
        title: "max hard-constraint residual / bounding-box diagonal (0 drawn at 1e-18)".into(),
        x: Axis::linear("iteration"),
        y: Axis::log10("max |b·X − d| / diagonal").with_range(1e-18, 1e-9),
        series: vec![Series::new("residual", residual)],
        legend: LegendPosition::Hidden,
        ..LineChart::default()
    };
    plot::line_chart(&chart, &Output::new(dir.join("exact_residual")))?;
    Ok(())
}

// ---------------------------------------------------------------- (d)

/// Which initial guess a row of (d) starts from.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum Init {
    Rest,
    Linear,
}

/// One row of (d): the energy after `iterations` from one initial guess.
#[derive(Debug, Clone, Serialize)]
struct InitRow {
    init: Init,
    iterations: usize,
    energy: f64,
}

/// The iteration counts of (d) (0: the initial guess itself).
const INIT_COUNTS: [usize; 6] = [0, 1, 5, 10, 20, 30];

/// (d): the paper's position-only scene from the rest pose and from the
/// linear solution, the energy at [`INIT_COUNTS`].
fn initial_guesses(ctx: &Context, dir: &Path, case: &MeshCase) -> Result<Vec<InitRow>, AnyError> {
    let mesh = &case.mesh;
    let cs = FixedAndHandle::paper_default(mesh).constraints(mesh)?;
    let last = if ctx.quick {
        5
    } else {
        INIT_COUNTS[INIT_COUNTS.len() - 1]
    };
    let mut rows = Vec::new();
    for (init, start) in [
        (Init::Rest, ArapInit::Rest),
        (Init::Linear, ArapInit::Linear),
    ] {
        let mut arap = ArapDeformer::with_formulation(
            mesh.clone(),
            cs.clone(),
            ArapEnergy::SpokesAndRims,
            &NullSpaceQr::default(),
            &lse_deform::resources::Resources::default(),
        )?;
        arap.initialize(start)?;
        for k in 0..=last {
            if k > 0 {
                arap.iterate(1)?;
            }
            if INIT_COUNTS.contains(&k) {
                rows.push(InitRow {
                    init,
                    iterations: k,
                    energy: arap.energy(),
                });
            }
        }
    }
    ctx.write_rows(&dir.join("initial_guess"), &rows)?;
    Ok(rows)
}

/// (d)'s table and finding, from its rows.
fn initial_guess_text(s: &mut String, rows: &[InitRow]) {
    let energies =
        |init: Init| -> Vec<&InitRow> { rows.iter().filter(|r| r.init == init).collect() };
    let (rest, linear) = (energies(Init::Rest), energies(Init::Linear));
    let _ = writeln!(
        s,
        "\n**(d) Initial guess.** The scene of (b) from the rest pose (constrained vertices at their targets) and from the linear solution: ARAP energy after k iterations.\n"
    );
    let header: Vec<String> = std::iter::once("init".to_string())
        .chain(rest.iter().map(|r| format!("k = {}", r.iterations)))
        .collect();
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    let table: Vec<Vec<String>> = [("rest", &rest), ("linear", &linear)]
        .iter()
        .map(|(name, rs)| {
            std::iter::once(name.to_string())
                .chain(rs.iter().map(|r| format!("{:.3e}", r.energy)))
                .collect()
        })
        .collect();
    s.push_str(&markdown_table(&header, &table));
    let lower = rest
        .iter()
        .zip(&linear)
        .filter(|(r, l)| l.energy < r.energy)
        .count();
    let _ = writeln!(
        s,
        "\nThe linear start is lower at {lower} of {} counts{}.",
        rest.len(),
        if lower == rest.len() {
            " (every one): hence `--arap-init linear` is the default"
        } else {
            ""
        }
    );
}

// ---------------------------------------------------------------- section

/// The float-rotation check's table and what it shows, from its rows.
fn float_check_text(s: &mut String, peer: &Peer) {
    if peer.float_check.is_empty() {
        let _ = writeln!(
            s,
            "**Float-rotation check**: not run (see the note above).\n"
        );
        return;
    }
    let _ = writeln!(
        s,
        "**Why ours and libigl drift apart** (`experiments/arap_float_check.py`): libigl's `arap_solve` fits its rotations with `polar_svd3x3`, a single-precision 3 × 3 SVD. The script re-implements libigl's loop step by step from libigl's own `cotmatrix_entries`, `cotmatrix` and `fit_rotations`, once with single-precision rotations (what `arap_solve` does) and once with double (max coordinate difference / diagonal):\n"
    );
    let rows: Vec<Vec<String>> = peer
        .float_check
        .iter()
        .map(|r| {
            vec![
                r.iterations.to_string(),
                format!("{:.1e}", r.ours_vs_libigl),
                format!("{:.1e}", r.ours_vs_double_reimplementation),
                format!("{:.1e}", r.single_reimplementation_vs_libigl),
                format!("{:.1e}", r.double_vs_single_reimplementation),
            ]
        })
        .collect();
    s.push_str(&markdown_table(
        &[
            "iterations",
            "ours vs libigl",
            "ours vs re-impl. (double rotations)",
            "re-impl. (float rotations) vs libigl",
            "re-impl. double vs float",
        ],
        &rows,
    ));
    let worst = |f: fn(&FloatRow) -> f64| peer.float_check.iter().map(f).fold(0.0, f64::max);
    let ours_double = worst(|r| r.ours_vs_double_reimplementation);
    let single_libigl = worst(|r| r.single_reimplementation_vs_libigl);
    let ours_libigl = worst(|r| r.ours_vs_libigl);
    let verdict = if ours_double < single_libigl.min(ours_libigl) {
        "ours is closer to libigl's algorithm with double-precision rotations than libigl is to its own float re-implementation: the gap to `arap_solve` is its single-precision rotation fit"
    } else {
        "ours is not closer to the double-precision re-implementation than libigl is to the float one: the float rotations do not explain the whole gap"
    };
    let _ = writeln!(
        s,
        "\nLargest differences: ours vs the double re-implementation {ours_double:.1e}, the float re-implementation vs libigl {single_libigl:.1e}, ours vs libigl {ours_libigl:.1e}: {verdict}.\n"
    );
}

fn opt(v: Option<f64>, f: impl Fn(f64) -> String) -> String {
    v.map(f).unwrap_or_else(|| "—".into())
}

fn section(ctx: &Context, bend: &Bend, peer: &Peer, exact: &Exact, case: &MeshCase) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "{}\n", ctx.machine.one_line());
    s.push_str(&ctx.regenerate(NAME));
    let _ = writeln!(
        s,
        "libigl runs in `$LSE_PYTHON` if set, else in the virtual environment `{}` (created with numpy, scipy and libigl if missing).\n",
        environment::VENV
    );
    bend_text(&mut s, bend);
    peer_text(&mut s, peer, case);
    exact_text(&mut s, exact);
    s
}

/// Part (a) of the section: the bend and twist, linear against ARAP.
fn bend_text(s: &mut String, bend: &Bend) {
    let _ = writeln!(
        s,
        "**(a) Bend and twist.** A tube ({} vertices), bottom 5 % of the rings fixed, top 5 % moved rigidly: bent by 90° and twisted by 90°; {} ARAP iterations (spokes-and-rims) from the linear solution.\n",
        bend.vertices, bend.iterations
    );
    let rows = vec![
        vec![
            "linear (Laplacian editing)".into(),
            format!("{:.4e}", bend.linear_energy),
            format!("{:.3}", bend.linear_mid_radius),
        ],
        vec![
            "ARAP".into(),
            format!("{:.4e}", bend.arap_energy),
            format!("{:.3}", bend.arap_mid_radius),
        ],
    ];
    s.push_str(&markdown_table(
        &[
            "solution",
            "ARAP energy",
            "middle ring radius / rest radius",
        ],
        &rows,
    ));
    let _ = writeln!(s, "\n![bend and twist]({NAME}/{})\n", bend.render);
}

/// Part (b) of the section: ours against libigl's `arap_solve`, then the
/// float-rotation check.
fn peer_text(s: &mut String, peer: &Peer, case: &MeshCase) {
    let _ = writeln!(
        s,
        "**(b) Ours against libigl's `arap_solve`** on {} ({} vertices), the paper's position-only scene, rest-pose initial guess, spokes-and-rims.{}\n",
        case.name,
        case.mesh.n_vertices(),
        peer.libigl_version
            .as_ref()
            .map(|v| format!(" libigl {v}."))
            .unwrap_or_default()
    );
    if let Some(note) = &peer.note {
        let _ = writeln!(s, "**Not measured:** {note}.\n");
    }
    if let Some(python) = &peer.python {
        let _ = writeln!(s, "Python: {python}.\n");
    }
    let rows: Vec<Vec<String>> = peer
        .rows
        .iter()
        .map(|r| {
            vec![
                r.iterations.to_string(),
                format!("{:.6e}", r.ours_energy),
                opt(r.libigl_energy, |e| format!("{e:.6e}")),
                fmt_time(r.ours_elapsed_s),
                opt(r.libigl_elapsed_s, fmt_time),
                opt(r.max_difference_over_diagonal, |d| format!("{d:.1e}")),
            ]
        })
        .collect();
    s.push_str(&markdown_table(
        &[
            "iterations",
            "ours energy",
            "libigl energy",
            "ours elapsed",
            "libigl elapsed",
            "max \\|ours − libigl\\| / diagonal",
        ],
        &rows,
    ));
    let _ = writeln!(
        s,
        "\n![energy by iteration]({NAME}/energy_by_iteration.png) ![energy by time]({NAME}/energy_by_time.png)\n"
    );
    float_check_text(s, peer);
}

/// Part (c) of the section: exact general constraints.
fn exact_text(s: &mut String, exact: &Exact) {
    let _ = writeln!(
        s,
        "**(c) Exact general constraints.** {} relative and {} on-edge hard constraints on top of the scene ({} hard constraints), {} iterations from the linear solution: largest hard-constraint residual over all iterations {:.1e} × diagonal; largest relative energy increase {:.1e} ({}).\n",
        exact.relative,
        exact.on_edge,
        exact.hard,
        exact.iterations,
        exact.max_residual_over_diagonal,
        exact.largest_relative_increase,
        if exact.monotone {
            "monotone"
        } else {
            "not monotone"
        }
    );
    let _ = writeln!(
        s,
        "![energy]({NAME}/exact_energy.png) ![residual]({NAME}/exact_residual.png)"
    );
}
