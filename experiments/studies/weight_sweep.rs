//! Experiment `weight-sweep`: the weight question on a scene of one's own.
//!
//! For each mesh and scene (the paper's position-only scene, a mixed scene
//! with relative, on-edge and on-face constraints, and the user's `-c`
//! file on the `--mesh` files) and each relative penalty weight
//! `W = 10⁻² … 10¹²` (hard rows entering with `W·s`, see
//! [`lse_deform::formulation::Penalty`]):
//! - the error `‖X − X*‖/‖X*‖` of the penalty solution unrefined and with
//!   multiplier refinement ([`Refine::Auto`]), against `X*`: the sparse QR
//!   of the eliminated problem when every hard row is a position (its
//!   condition is never squared), else null-space QR refined;
//! - the exact methods (null-space QR, KKT), unrefined and refined, as one
//!   value each (horizontal lines);
//! - the hard-constraint residual (over the bounding-box diagonal) and the
//!   energy difference `(E(X) − E(X*))/E(X*)`;
//! - a factorisation that broke down, as the library's typed error;
//! - `κ₂` of the matrix factored (Lanczos, [`Deformer::estimate_condition`])
//!   and, for the normal-equation methods, two comparable numbers: `κ₂` of
//!   the least-squares matrix `K` whose normal matrix `M = KᵀK` is factored
//!   (`√κ₂(M)`), and `κ₂(K D)` with `D = diag(M)^{-1/2}` the column
//!   equilibration (`√κ₂(D M D)`, van der Sluis' near-optimal diagonal
//!   scaling). Equilibration absorbs a large weight on a position row (it
//!   only scales one column) but not on a coupled row (relative, edge,
//!   face), whose `w²BᵀB` couples columns.

use std::fmt::Write as _;
use std::ops::RangeInclusive;
use std::path::Path;
use std::time::Instant;

use faer::Mat;
use faer::sparse::{SparseColMat, Triplet};
use lse_deform::backend::spd::{FaerLlt, SpdBackend};
use lse_deform::condition::{self, InverseOperator, LowerSymmetricOperator};
use lse_deform::constraints::{ConstraintSet, read_constraints};
use lse_deform::error::Error;
use lse_deform::formulation::{Refine, max_hard_residual};
use lse_deform::problem::LseProblem;
use lse_deform::scene::{FixedAndHandle, MixedScene};
use lse_deform::{Deformer, LaplacianKind, Method, formulation::FormulationChoice};
use serde::Serialize;

use crate::harness::context::AnyError;
use crate::harness::context::{Context, MeshCase};
use crate::harness::measures::{energy_gap, failure_kind, qr_reference, sci};
use crate::harness::plot::{
    self, Axis, Failure, LegendPosition, LineChart, Output, ReferenceLine, Series,
};
use crate::harness::registry::{Experiment, Input, Summary};
use crate::harness::rows::{fmt_time, markdown_table};

/// The folder and command-line word of this experiment.
pub const NAME: &str = "weight-sweep";

/// This study's entry in the list of experiments.
pub const EXPERIMENT: Experiment = Experiment {
    name: NAME,
    title: "Penalty weight sweep",
    inputs: &[Input::Meshes, Input::Constraints],
    run,
};

/// Exponents of the relative weights: `10⁻² … 10¹²`.
const EXPONENTS: RangeInclusive<i32> = -2..=12;

/// The weight whose error the findings quote (a common choice in practice).
const QUOTED_WEIGHT: f64 = 1e4;

/// The meshes of `--mesh-dir` swept (those present); the first two of the
/// directory without any of them.
const DIR_MESHES: [&str; 2] = ["bunny-35k-stanford.obj", "armadillo-21k.obj"];

/// Sizes of the built-in mixed scene (see [`MixedScene`]).
const MIXED: (usize, usize, usize) = (300, 20, 20);

/// Errors below this are drawn at it (log axes; exact zeros included).
const FLOOR: f64 = 1e-17;

/// The Laplacian of every scene (the paper's).
const LAPLACIAN: LaplacianKind = LaplacianKind::Cotangent;

/// One solve of one method at one weight, on one mesh and scene.
#[derive(Debug, Clone, Serialize)]
struct Row {
    mesh: String,
    vertices: usize,
    scene: String,
    hard_rows: usize,
    /// `nullspace-qr`, `penalty` or `kkt`.
    method: &'static str,
    /// With refinement ([`Refine::Auto`]): multiplier updates for penalty.
    refined: bool,
    /// The relative penalty weight (penalty only).
    weight: Option<f64>,
    /// The library error's kind, when the factorisation or solve failed.
    failure: Option<&'static str>,
    /// `"factor"` or `"solve"`: where it failed.
    failed_in: Option<&'static str>,
    /// `‖X − X*‖_F / ‖X*‖_F`.
    error: Option<f64>,
    /// `max_k ‖b_k X − d_k‖` over the bounding-box diagonal.
    residual: Option<f64>,
    /// `(E(X) − E(X*)) / E(X*)`.
    energy_gap: Option<f64>,
    /// `κ₂` of the matrix factored.
    kappa_factored: Option<f64>,
    /// `κ₂(K)`, `K` the least-squares matrix whose normal matrix is factored.
    kappa_least_squares: Option<f64>,
    /// `κ₂(K D)`, `D` the column equilibration.
    kappa_equilibrated: Option<f64>,
}

/// A scene: its name and constraints.
struct Scene {
    name: String,
    constraints: ConstraintSet,
}

/// The condition numbers of one factorisation.
#[derive(Clone, Copy, Default)]
struct Kappas {
    factored: Option<f64>,
    least_squares: Option<f64>,
    equilibrated: Option<f64>,
}

/// What every row of one mesh and scene shares.
struct Judge {
    mesh: String,
    vertices: usize,
    scene: String,
    hard_rows: usize,
    x_star: Mat<f64>,
    /// Problem units per bounding-box diagonal.
    residual_unit: f64,
}

impl Judge {
    fn row(
        &self,
        problem: &LseProblem,
        (method, refined, weight): (Method, bool, Option<f64>),
        x: Result<&Mat<f64>, (&Error, &'static str)>,
        k: Kappas,
    ) -> Row {
        let (x, failure, failed_in) = match x {
            Ok(x) => (Some(x), None, None),
            Err((e, phase)) => (None, Some(failure_kind(e)), Some(phase)),
        };
        let star = self.x_star.norm_l2().max(f64::MIN_POSITIVE);
        Row {
            mesh: self.mesh.clone(),
            vertices: self.vertices,
            scene: self.scene.clone(),
            hard_rows: self.hard_rows,
            method: method.name(),
            refined,
            weight,
            failure,
            failed_in,
            error: x.map(|x| (x - &self.x_star).norm_l2() / star),
            residual: x.map(|x| max_hard_residual(problem, x) * self.residual_unit),
            energy_gap: x.map(|x| energy_gap(problem, x, &self.x_star)),
            kappa_factored: k.factored,
            kappa_least_squares: k.least_squares,
            kappa_equilibrated: k.equilibrated,
        }
    }
}

/// `κ₂(D M D)`, `D = diag(M)^{-1/2}`, of a full symmetric `M` by Lanczos
/// with its own Cholesky factor; `None` when a diagonal entry is not
/// positive (KKT) or the factorisation fails.
fn equilibrated_condition(full: &SparseColMat<usize, f64>) -> Option<f64> {
    let n = full.ncols();
    let (cols, rows, vals) = (
        full.symbolic().col_ptr(),
        full.symbolic().row_idx(),
        full.val(),
    );
    let entries = |j: usize| (cols[j]..cols[j + 1]).map(move |p| (rows[p], vals[p]));
    let diag: Vec<f64> = (0..n)
        .map(|j| entries(j).find(|&(i, _)| i == j).map_or(0.0, |(_, v)| v))
        .collect();
    if diag.iter().any(|&d| d.is_nan() || d <= 0.0) {
        return None;
    }
    let s: Vec<f64> = diag.iter().map(|d| 1.0 / d.sqrt()).collect();
    let triplets: Vec<Triplet<usize, usize, f64>> = (0..n)
        .flat_map(|j| entries(j).map(move |(i, v)| (i, j, v)))
        .filter(|&(i, j, _)| i >= j)
        .map(|(i, j, v)| Triplet::new(i, j, v * s[i] * s[j]))
        .collect();
    let lower = SparseColMat::try_new_from_triplets(n, n, &triplets).ok()?;
    let symbolic = FaerLlt::auto().analyze(lower.symbolic()).ok()?;
    let mut factor = symbolic.factorize(lower.as_ref()).ok()?;
    let mut matrix = LowerSymmetricOperator::new(lower.as_ref());
    let mut inverse = InverseOperator::new(n, |rhs| {
        factor.solve_in_place(rhs)?;
        Ok(())
    });
    condition::estimate(&mut matrix, &mut inverse, "D M D")
        .ok()
        .map(|c| c.value.sqrt())
}

/// The condition numbers of the deformer's current factorisation.
fn kappas(d: &mut Deformer, normal: bool) -> Kappas {
    let factored = d.solver_mut().estimate_condition().ok().map(|c| c.value);
    let equilibrated = if normal {
        d.solver()
            .prepared()
            .factored_matrix()
            .and_then(|m| equilibrated_condition(&m))
    } else {
        None
    };
    Kappas {
        factored,
        least_squares: factored.filter(|_| normal).map(f64::sqrt),
        equilibrated,
    }
}

/// `choice` factored once, solved unrefined and refined: two rows.
fn method_rows(d: &mut Deformer, judge: &Judge, choice: FormulationChoice) -> Vec<Row> {
    let key = |refined| (choice.method, refined, choice.weight);
    let factored = choice
        .build()
        .map_err(Error::from)
        .and_then(|f| d.refactor_with(&*f, &lse_deform::resources::Resources::default()));
    if let Err(e) = factored {
        let failed = |refined| {
            judge.row(
                d.problem(),
                key(refined),
                Err((&e, "factor")),
                Kappas::default(),
            )
        };
        return vec![failed(false), failed(true)];
    }
    let k = kappas(d, choice.method != Method::Kkt);
    [false, true]
        .into_iter()
        .map(|refined| {
            d.solver_mut().set_refine(Some(if refined {
                Refine::Auto
            } else {
                Refine::EstimateOnly
            }));
            let x = d.solve_matrix();
            let x = x.as_ref().map_err(|e| (e, "solve"));
            judge.row(d.problem(), key(refined), x, k)
        })
        .collect()
}

/// Every row of one mesh and scene.
fn sweep_scene(case: &MeshCase, scene: Scene, quick: bool) -> Result<Vec<Row>, AnyError> {
    let hard_rows = scene.constraints.n_hard();
    let mut d = Deformer::new(
        case.mesh.clone(),
        LAPLACIAN,
        scene.constraints,
        &lse_deform::SolveOptions::default(),
    )?;
    let x_star = match qr_reference(d.problem())? {
        Some(x) => x,
        None => {
            d.refactor_with(
                &*FormulationChoice::new(Method::NullSpaceQr).build()?,
                &lse_deform::resources::Resources::default(),
            )?;
            d.solver_mut().set_refine(Some(Refine::Auto));
            d.solve_matrix()?
        }
    };
    let judge = Judge {
        mesh: case.name.clone(),
        vertices: case.mesh.n_vertices(),
        scene: scene.name,
        hard_rows,
        x_star,
        residual_unit: d.length_unit() / case.mesh.bbox_diagonal(),
    };
    let mut rows = Vec::new();
    for method in [Method::NullSpaceQr, Method::Kkt] {
        rows.extend(method_rows(&mut d, &judge, FormulationChoice::new(method)));
    }
    for e in EXPONENTS.filter(|e| !quick || e % 2 == 0) {
        let choice = FormulationChoice {
            weight: Some(10f64.powi(e)),
            ..FormulationChoice::new(Method::Penalty)
        };
        rows.extend(method_rows(&mut d, &judge, choice));
    }
    Ok(rows)
}

/// The built-in scenes on `case`, and the user's (`-c`) when `user`.
fn scenes(ctx: &Context, case: &MeshCase, user: bool) -> Result<Vec<Scene>, AnyError> {
    let base = FixedAndHandle::paper_default(&case.mesh);
    let (relative, edges, faces) = MIXED;
    let mixed = MixedScene {
        base: base.clone(),
        relative,
        edges,
        faces,
        duplicate: false,
        conflict: false,
    };
    let mut out = vec![
        Scene {
            name: "position".into(),
            constraints: base.constraints(&case.mesh)?,
        },
        Scene {
            name: "mixed".into(),
            constraints: mixed.constraints(&case.mesh)?,
        },
    ];
    if let (true, Some(path)) = (user, &ctx.constraints) {
        out.push(Scene {
            name: path.file_stem().map_or_else(
                || "constraints".into(),
                |n| n.to_string_lossy().into_owned(),
            ),
            constraints: read_constraints(path, case.mesh.n_vertices())?,
        });
    }
    Ok(out)
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "constraints".into())
}

/// The meshes, each with whether the user's constraints belong to it:
/// the `--mesh` files (with `-c`), else [`DIR_MESHES`] of `--mesh-dir`,
/// else two generated meshes.
fn meshes(ctx: &Context) -> Result<Vec<(MeshCase, bool)>, AnyError> {
    let mut out = Vec::new();
    for p in &ctx.mesh_paths {
        if let Some(case) = ctx.real_mesh(&file_name(p))? {
            out.push((case, true));
        }
    }
    if out.is_empty() && ctx.has_user_meshes() {
        for name in DIR_MESHES {
            if let Some(case) = ctx.real_mesh(name)? {
                out.push((case, false));
            }
        }
        if out.is_empty() {
            let all = ctx.user_meshes()?;
            out.extend(all.into_iter().take(2).map(|c| (c, false)));
        }
    }
    if out.is_empty() {
        let all = ctx.generated_evaluation_meshes()?;
        out.extend(all.into_iter().take(2).map(|c| (c, false)));
    }
    Ok(out)
}

/// What the rows of one mesh and scene say.
struct Finding {
    mesh: String,
    scene: String,
    hard_rows: usize,
    /// Best unrefined penalty: (W, error).
    best: Option<(f64, f64)>,
    at_quoted: Option<f64>,
    /// Error at the largest W whose solve succeeded.
    at_top: Option<(f64, f64)>,
    first_breakdown: Option<f64>,
    best_refined: Option<(f64, f64)>,
    exact: Vec<(String, Option<f64>)>,
    /// Equilibrated κ₂ at the smallest and largest W with a value.
    equilibrated: Option<((f64, f64), (f64, f64))>,
}

impl Finding {
    fn of(rows: &[&Row]) -> Finding {
        let penalty = |refined: bool| {
            rows.iter()
                .filter(move |r| r.method == Method::Penalty.name() && r.refined == refined)
        };
        let with_error = |refined| {
            penalty(refined)
                .filter_map(|r| Some((r.weight?, r.error?)))
                .collect::<Vec<_>>()
        };
        let min = |v: Vec<(f64, f64)>| v.into_iter().min_by(|a, b| a.1.total_cmp(&b.1));
        let eq: Vec<(f64, f64)> = penalty(false)
            .filter_map(|r| Some((r.weight?, r.kappa_equilibrated?)))
            .collect();
        Finding {
            mesh: rows[0].mesh.clone(),
            scene: rows[0].scene.clone(),
            hard_rows: rows[0].hard_rows,
            best: min(with_error(false)),
            at_quoted: with_error(false)
                .iter()
                .find(|(w, _)| *w == QUOTED_WEIGHT)
                .map(|p| p.1),
            at_top: with_error(false).last().copied(),
            first_breakdown: penalty(false)
                .find(|r| r.failed_in == Some("factor"))
                .and_then(|r| r.weight),
            best_refined: min(with_error(true)),
            exact: rows
                .iter()
                .filter(|r| r.method != Method::Penalty.name())
                .map(|r| (exact_label(r), r.error))
                .collect(),
            equilibrated: eq.first().copied().zip(eq.last().copied()),
        }
    }

    /// "V-shaped" when the error at the largest working weight is over 100×
    /// the best, else "flat".
    fn shape(&self) -> &'static str {
        match (self.best, self.at_top) {
            (Some((_, best)), Some((_, top))) if top > 100.0 * best.max(FLOOR) => "V-shaped",
            (Some(_), Some(_)) => "flat",
            _ => "no solution",
        }
    }

    fn table_row(&self) -> Vec<String> {
        let pair = |p: Option<(f64, f64)>| {
            p.map_or("–".into(), |(w, e)| {
                format!("{} at W = {}", sci(e), sci(w))
            })
        };
        let exact: Vec<String> = self
            .exact
            .iter()
            .map(|(l, e)| format!("{l} {}", e.map_or("failed".into(), sci)))
            .collect();
        vec![
            self.mesh.clone(),
            format!("{} ({} hard rows)", self.scene, self.hard_rows),
            self.shape().into(),
            pair(self.best),
            self.at_quoted.map_or("–".into(), sci),
            self.first_breakdown.map_or("none".into(), sci),
            pair(self.best_refined),
            exact.join("; "),
            self.equilibrated
                .map_or("–".into(), |((w0, k0), (w1, k1))| {
                    format!(
                        "{} (W = {}) → {} (W = {})",
                        sci(k0),
                        sci(w0),
                        sci(k1),
                        sci(w1)
                    )
                }),
        ]
    }
}

fn exact_label(r: &Row) -> String {
    format!("{}{}", r.method, if r.refined { " refined" } else { "" })
}

/// Groups rows by (mesh, scene), in order of appearance.
fn groups(rows: &[Row]) -> Vec<Vec<&Row>> {
    let mut out: Vec<Vec<&Row>> = Vec::new();
    for r in rows {
        match out
            .iter_mut()
            .find(|g| g[0].mesh == r.mesh && g[0].scene == r.scene)
        {
            Some(g) => g.push(r),
            None => out.push(vec![r]),
        }
    }
    out
}

/// One penalty series of `rows`: `value` against W, failures marked.
fn penalty_series(
    rows: &[&Row],
    name: &str,
    refined: bool,
    value: fn(&Row) -> Option<f64>,
) -> Series {
    let mine: Vec<&&Row> = rows
        .iter()
        .filter(|r| r.method == Method::Penalty.name() && r.refined == refined)
        .collect();
    let points = mine
        .iter()
        .filter_map(|r| Some((r.weight?, value(r)?.max(FLOOR))))
        .collect();
    let failures = mine
        .iter()
        .filter(|r| r.failure.is_some())
        .filter_map(|r| {
            Some(Failure {
                x: r.weight?,
                y: None,
            })
        })
        .collect();
    Series::new(name, points).with_failures(failures)
}

/// The error and κ figures of one mesh and scene; returns their stems.
fn draw(dir: &Path, rows: &[&Row]) -> Result<[String; 2], AnyError> {
    let (mesh, scene) = (&rows[0].mesh, &rows[0].scene);
    let exact = |what: &str, value: fn(&Row) -> Option<f64>, refined: Option<bool>| {
        rows.iter()
            .filter(|r| {
                r.method != Method::Penalty.name() && refined.is_none_or(|f| r.refined == f)
            })
            .filter_map(|r| {
                let v = value(r)?;
                let shown = if v == 0.0 {
                    "0: X* itself".into()
                } else {
                    sci(v)
                };
                Some(ReferenceLine {
                    y: v.max(FLOOR),
                    label: format!("{what}{} ({shown})", exact_label(r)),
                })
            })
            .collect::<Vec<_>>()
    };
    let error = LineChart {
        title: format!("{mesh}, {scene} scene: error against the refined exact solution"),
        x: Axis::log10("relative penalty weight W"),
        y: Axis::log10("‖X − X*‖ / ‖X*‖"),
        series: vec![
            penalty_series(rows, "penalty", false, |r| r.error),
            penalty_series(rows, "penalty + multiplier refinement", true, |r| r.error),
        ],
        reference_lines: exact("", |r| r.error, None),
        legend: LegendPosition::Auto,
    };
    let kappa = LineChart {
        title: format!("{mesh}, {scene} scene: condition numbers"),
        x: Axis::log10("relative penalty weight W"),
        y: Axis::log10("κ₂"),
        series: vec![
            penalty_series(rows, "κ₂([A; W s B])", false, |r| r.kappa_least_squares),
            penalty_series(rows, "κ₂([A; W s B] D), equilibrated", false, |r| {
                r.kappa_equilibrated
            }),
        ],
        reference_lines: [
            exact("κ₂(AQ₂), ", |r| r.kappa_least_squares, Some(false)),
            exact("κ₂(AQ₂ D), ", |r| r.kappa_equilibrated, Some(false)),
        ]
        .concat(),
        legend: LegendPosition::Auto,
    };
    let stems = [
        format!("{mesh}_{scene}_error"),
        format!("{mesh}_{scene}_kappa"),
    ];
    plot::line_chart(&error, &Output::new(dir.join(&stems[0])))?;
    plot::line_chart(&kappa, &Output::new(dir.join(&stems[1])))?;
    Ok(stems)
}

/// The section's findings paragraph, from the findings.
fn findings_text(findings: &[Finding]) -> String {
    let mut s = String::from("**Findings** (computed from the rows).");
    for f in findings {
        let _ = write!(s, " {} / {}: {}", f.mesh, f.scene, f.shape());
        if let Some((w, e)) = f.best {
            let _ = write!(
                s,
                ", best unrefined penalty error {} at W = {}",
                sci(e),
                sci(w)
            );
        }
        if let Some(e) = f.at_quoted {
            let _ = write!(s, ", {} at W = {}", sci(e), sci(QUOTED_WEIGHT));
        }
        match f.first_breakdown {
            Some(w) => {
                let _ = write!(s, ", factorisation breaks down from W = {}", sci(w));
            }
            None => s.push_str(", no breakdown"),
        }
        if let Some(((_, k0), (w1, k1))) = f.equilibrated {
            let _ = write!(
                s,
                "; equilibrated κ₂ {} → {} at W = {}",
                sci(k0),
                sci(k1),
                sci(w1)
            );
        }
        s.push('.');
    }
    s
}

/// The section: what was measured, the findings table, the figures.
fn section(ctx: &Context, findings: &[Finding], figures: &[[String; 2]], seconds: f64) -> String {
    let mut s = format!(
        "Penalty against the exact methods, per relative weight W = 10⁻² … 10¹² (hard rows entering as W·s, s the power of two nearest A's largest column norm), cotangent Laplacian. \
         Scenes: `position` is the paper's (20 % fixed, 2 % handle, every hard row one vertex); `mixed` adds {} relative, {} on-edge and {} on-face hard constraints (`MixedScene`, as `lse-deform scene --relative {} --edges {} --faces {}` writes). \
         X* is the sparse QR of the eliminated problem for position-only scenes, else null-space QR refined. \
         κ₂([A; W s B]) is √κ₂ of the normal matrix penalty factors; κ₂([A; W s B] D) the same with the columns equilibrated (D = diag(M)^-1/2), the Skeel-style scaled measure; the exact methods' values are those of AQ₂ (null-space) and, unscaled, of the KKT matrix.\n\n",
        MIXED.0, MIXED.1, MIXED.2, MIXED.0, MIXED.1, MIXED.2
    );
    let header = [
        "mesh",
        "scene",
        "penalty error curve",
        "best unrefined penalty",
        "error at W = 1e4",
        "first breakdown W",
        "best refined penalty",
        "exact methods' error",
        "equilibrated κ₂ (smallest → largest W)",
    ];
    let rows: Vec<Vec<String>> = findings.iter().map(Finding::table_row).collect();
    s.push_str(&markdown_table(&header, &rows));
    let _ = writeln!(s, "\n{}\n", findings_text(findings));
    for [error, kappa] in figures {
        let _ = writeln!(
            s,
            "![{error}]({NAME}/{error}.png) ![{kappa}]({NAME}/{kappa}.png)\n"
        );
    }
    let _ = writeln!(
        s,
        "How to read the figures: x is W; dashed horizontal lines are the exact methods; crosses on the bottom edge are weights whose factorisation or solve failed (the `failure` column names the library's error). \
         Data: [`{NAME}/weight_sweep.csv`]({NAME}/weight_sweep.csv) (and `.json`). \
         Regenerate: `cargo run --release --bin experiments -- {NAME}{} --out results` ({} on {}). \
         Sweep your own scene: `cargo run --release --bin experiments -- {NAME} --mesh MESH -c CONSTRAINTS.json`.",
        ctx.mesh_args(),
        fmt_time(seconds),
        ctx.machine.cpu
    );
    s
}

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let started = Instant::now();
    let dir = ctx.dir(NAME)?;
    let meshes = meshes(ctx)?;
    let mut rows = Vec::new();
    let mut setup_failures = Vec::new();
    for (case, user) in &meshes {
        for scene in scenes(ctx, case, *user)? {
            let label = format!("{} / {}", case.name, scene.name);
            eprintln!("{NAME}: {label}");
            match sweep_scene(case, scene, ctx.quick) {
                Ok(r) => rows.extend(r),
                Err(e) => setup_failures.push(format!("{label}: {e}")),
            }
        }
    }
    ctx.write_rows(&dir.join("weight_sweep"), &rows)?;
    let grouped = groups(&rows);
    let findings: Vec<Finding> = grouped.iter().map(|g| Finding::of(g)).collect();
    let figures = grouped
        .iter()
        .map(|g| draw(&dir, g))
        .collect::<Result<Vec<_>, _>>()?;
    let mut s = section(ctx, &findings, &figures, started.elapsed().as_secs_f64());
    if !setup_failures.is_empty() {
        let _ = writeln!(
            s,
            "\n\nSet-up failures (no sweep): {}.",
            setup_failures.join("; ")
        );
    }
    ctx.write_section(NAME, &format!("{}\n\n{s}\n", ctx.machine.one_line()))?;
    Ok(Summary::measured(findings_text(&findings)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The full symmetric 2 × 2 matrix `[a b; b a]`.
    fn two_by_two(a: f64, b: f64) -> SparseColMat<usize, f64> {
        let t = [(0, 0, a), (1, 0, b), (0, 1, b), (1, 1, a)].map(|(i, j, v)| Triplet::new(i, j, v));
        SparseColMat::try_new_from_triplets(2, 2, &t).unwrap()
    }

    #[test]
    fn equilibration_absorbs_a_weight_on_one_column_only() {
        // A position row of weight w on vertex 0: M = diag(1 + w², 1),
        // κ(M) = 1 + w², but D M D = I.
        let w2 = 1e8;
        let t = [(0, 0, 1.0 + w2), (1, 1, 1.0)].map(|(i, j, v)| Triplet::new(i, j, v));
        let position = SparseColMat::try_new_from_triplets(2, 2, &t).unwrap();
        let k = equilibrated_condition(&position).unwrap();
        assert!((k - 1.0).abs() < 1e-6, "{k}");
        // A relative row x₀ − x₁ of weight w: M = I + w² [1 −1; −1 1],
        // eigenvalues 1 and 1 + 2w²; D M D keeps the ratio (1 + 2w²)/1,
        // so √κ ≈ √2 w.
        let coupled = two_by_two(1.0 + w2, -w2);
        let k = equilibrated_condition(&coupled).unwrap();
        let expected = (1.0 + 2.0 * w2).sqrt();
        assert!((k / expected - 1.0).abs() < 1e-3, "{k} vs {expected}");
    }

    #[test]
    fn equilibration_refuses_an_indefinite_diagonal() {
        // A KKT matrix has zeros on its multiplier block.
        assert!(equilibrated_condition(&two_by_two(0.0, 1.0)).is_none());
    }
}
