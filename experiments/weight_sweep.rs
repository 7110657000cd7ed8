//! Experiment `weight-sweep`: the penalty ("soft only") formulation for the
//! relative weights `w = 10⁻⁴ … 10¹²` on the Table 1 scene, per mesh and Laplacian,
//! against the null-space method (the paper's) as reference lines.
//!
//! Per weight: the condition estimate of `AᵀA + w²BᵀB`, the constraint
//! residual `max‖b_k X − d_k‖`, the relative energy gap and the relative
//! difference `‖X − X*‖/‖X*‖` to the reference solution `X*` (sparse QR of
//! the eliminated problem, see [`crate::table1::qr_reference`]), the
//! penalty solve's own forward-error estimate (flagged `> 1e-2`) and whether
//! the factorisation failed. The symbolic analysis is done once per mesh and
//! Laplacian ([`PenaltySweep`]).

use std::fmt::Write as _;
use std::time::Instant;

use faer::Mat;
use lse_deform::backend::spd::{FaerLlt, SpdBackend};
use lse_deform::condition::{self, ConditionEstimate, InverseOperator, LowerSymmetricOperator};
use lse_deform::formulation::PENALTY_FORWARD_ERROR_LIMIT;
use lse_deform::problem::LseProblem;
use lse_deform::scene::FixedAndHandle;
use lse_deform::{Deformer, NullSpaceQr, PenaltySweep};

use crate::context::{Context, MeshCase, fmt_time, markdown_table};
use crate::plot::{self, Axis, Failure, LegendPosition, LineChart, Output, ReferenceLine, Series};
use crate::table1::{
    LAPLACIANS, energy_gap, failure_kind, max_hard_residual, qr_reference, relative_difference, sci,
};
use crate::{AnyError, Summary};

/// Exponents of the relative weights: `10⁻⁴ … 10¹²`. The weight is relative
/// (hard rows enter with `w·s`, `s = PenaltySweep::weight_unit` the power of
/// two nearest A's largest column norm), so this range shows approximation
/// error, the optimum, loss of accuracy and, if any, breakdown.
const EXPONENTS: std::ops::RangeInclusive<i32> = -4..=12;

/// The largest weight of the sweep.
const W_MAX: f64 = 1e12;

/// Above this many vertices the condition is estimated at even exponents
/// only (each estimate costs a second factorisation and tens of solves).
const CONDITION_EVERY_WEIGHT_UP_TO: usize = 20_000;

/// One weight of one mesh and Laplacian.
struct Point {
    mesh: String,
    vertices: usize,
    laplacian: &'static str,
    weight: f64,
    failure: Option<String>,
    residual: Option<f64>,
    residual_relative: Option<f64>,
    energy_gap: Option<f64>,
    x_error: Option<f64>,
    backward_error: Option<f64>,
    forward_error_estimate: Option<f64>,
    accepted: Option<bool>,
    condition: Option<ConditionEstimate>,
}

/// The null-space method's values on one mesh and Laplacian.
struct Reference {
    mesh: String,
    laplacian: &'static str,
    residual_relative: f64,
    energy_gap: f64,
    x_error: f64,
    condition: Option<f64>,
}

/// Condition estimate of `AᵀA + w²BᵀB` with its own factorisation.
fn penalty_condition(
    sweep: &PenaltySweep,
    symbolic: &dyn lse_deform::backend::spd::SpdSymbolic,
    w: f64,
) -> Option<ConditionEstimate> {
    let lower = sweep.normal_matrix(w).ok()?;
    let mut factor = symbolic.factorize(lower.as_ref()).ok()?;
    let mut matrix = LowerSymmetricOperator::new(lower.as_ref());
    let mut inverse = InverseOperator::new(lower.ncols(), |rhs| {
        factor.solve_in_place(rhs);
        Ok(())
    });
    condition::estimate(&mut matrix, &mut inverse, "AᵀA + w²BᵀB").ok()
}

fn sweep_case(
    case: &MeshCase,
    kind: lse_deform::LaplacianKind,
    points: &mut Vec<Point>,
    references: &mut Vec<Reference>,
) -> Result<(), AnyError> {
    let scene = FixedAndHandle::paper_default(&case.mesh);
    let constraints = scene.constraints(&case.mesh)?;
    let mut deformer = Deformer::new(case.mesh.clone(), kind, constraints)?;
    let diag = case.mesh.bbox_diagonal();
    deformer.precompute(&NullSpaceQr::default())?;
    let x_ns = deformer.solve_matrix()?;
    let kappa_ns = deformer.estimate_condition().ok().map(|c| c.value);
    let problem: &LseProblem = deformer.problem();
    let x_star: Mat<f64> = match qr_reference(problem)? {
        Some(x) => x,
        None => x_ns.clone(),
    };
    references.push(Reference {
        mesh: case.name.clone(),
        laplacian: kind.name(),
        residual_relative: max_hard_residual(problem, &x_ns) / diag,
        energy_gap: energy_gap(problem, &x_ns, &x_star),
        x_error: relative_difference(&x_ns, &x_star),
        condition: kappa_ns,
    });
    let sweep = PenaltySweep::new(problem, &FaerLlt::auto())?;
    let pattern = sweep.normal_matrix(1.0)?;
    let symbolic = FaerLlt::auto().analyze(pattern.symbolic())?;
    for e in EXPONENTS {
        let w = 10f64.powi(e);
        let want_condition = case.mesh.n_vertices() <= CONDITION_EVERY_WEIGHT_UP_TO || e % 2 == 0;
        let mut p = Point {
            mesh: case.name.clone(),
            vertices: case.mesh.n_vertices(),
            laplacian: kind.name(),
            weight: w,
            failure: None,
            residual: None,
            residual_relative: None,
            energy_gap: None,
            x_error: None,
            backward_error: None,
            forward_error_estimate: None,
            accepted: None,
            condition: None,
        };
        match sweep.solve(problem, w) {
            Ok(s) => {
                p.residual = Some(s.max_constraint_residual);
                p.residual_relative = Some(s.max_constraint_residual / diag);
                p.energy_gap = Some(energy_gap(problem, &s.x, &x_star));
                p.x_error = Some(relative_difference(&s.x, &x_star));
                p.backward_error = Some(s.backward_error);
                p.forward_error_estimate = Some(s.forward_error_estimate);
                p.accepted = Some(s.forward_error_estimate <= PENALTY_FORWARD_ERROR_LIMIT);
                if want_condition {
                    p.condition = penalty_condition(&sweep, symbolic.as_ref(), w);
                }
            }
            Err(err) => p.failure = Some(failure_kind(&err).to_string()),
        }
        points.push(p);
    }
    Ok(())
}

fn opt(v: Option<f64>) -> String {
    v.map(|v| format!("{v:e}")).unwrap_or_default()
}

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let started = Instant::now();
    let dir = ctx.dir("weight-sweep")?;
    let meshes = ctx.evaluation_meshes()?;
    let bar = ctx.bar(meshes.len() * LAPLACIANS.len(), "weight-sweep");
    let mut points = Vec::new();
    let mut references = Vec::new();
    let mut setup_failures = Vec::new();
    for case in &meshes {
        for kind in LAPLACIANS {
            bar.set_message(format!("weight-sweep: {} / {}", case.name, kind.name()));
            if let Err(e) = sweep_case(case, kind, &mut points, &mut references) {
                setup_failures.push(format!("{} / {}: {e}", case.name, kind.name()));
            }
            bar.inc(1);
        }
    }
    bar.finish_and_clear();

    let header = [
        "mesh",
        "vertices",
        "laplacian",
        "weight",
        "failure",
        "max_constraint_residual",
        "max_constraint_residual_relative",
        "energy_gap_relative",
        "x_error_relative",
        "backward_error",
        "forward_error_estimate",
        "accepted_by_penalty",
        "condition_estimate",
        "condition_converged",
    ];
    let mut rows: Vec<Vec<String>> = points
        .iter()
        .map(|p| {
            vec![
                p.mesh.clone(),
                p.vertices.to_string(),
                p.laplacian.to_string(),
                format!("{:e}", p.weight),
                p.failure.clone().unwrap_or_default(),
                opt(p.residual),
                opt(p.residual_relative),
                opt(p.energy_gap),
                opt(p.x_error),
                opt(p.backward_error),
                opt(p.forward_error_estimate),
                p.accepted.map(|b| b.to_string()).unwrap_or_default(),
                opt(p.condition.as_ref().map(|c| c.value)),
                p.condition
                    .as_ref()
                    .map(|c| c.converged.to_string())
                    .unwrap_or_default(),
            ]
        })
        .collect();
    // The null-space reference as rows with weight "nullspace-qr".
    for r in &references {
        rows.push(vec![
            r.mesh.clone(),
            String::new(),
            r.laplacian.to_string(),
            "nullspace-qr".into(),
            String::new(),
            String::new(),
            format!("{:e}", r.residual_relative),
            format!("{:e}", r.energy_gap),
            format!("{:e}", r.x_error),
            String::new(),
            String::new(),
            String::new(),
            opt(r.condition),
            String::new(),
        ]);
    }
    ctx.write_csv(&dir.join("weight_sweep.csv"), &header, &rows)?;

    // Figures: per Laplacian, three charts (condition, residual, X error),
    // one series per mesh, the null-space values as dashed lines.
    let mut figures = Vec::new();
    let floor = 1e-17;
    for kind in LAPLACIANS {
        let lap = kind.name();
        for (quantity, y_label, file) in [
            (0, "condition estimate of the factored matrix", "condition"),
            (1, "max‖b_k X − d_k‖ / diagonal", "residual"),
            (2, "‖X − X*‖ / ‖X*‖", "x_error"),
        ] {
            let mut series = Vec::new();
            let mut refs = Vec::new();
            for case in &meshes {
                let pts: Vec<&Point> = points
                    .iter()
                    .filter(|p| p.mesh == case.name && p.laplacian == lap)
                    .collect();
                if pts.is_empty() {
                    continue;
                }
                let value = |p: &Point| -> Option<f64> {
                    match quantity {
                        0 => p.condition.as_ref().map(|c| c.value),
                        1 => p.residual_relative.map(|v| v.max(floor)),
                        _ => p.x_error.map(|v| v.max(floor)),
                    }
                };
                let data: Vec<(f64, f64)> = pts
                    .iter()
                    .filter_map(|p| value(p).map(|v| (p.weight, v)))
                    .collect();
                let failures: Vec<Failure> = pts
                    .iter()
                    .filter(|p| p.failure.is_some())
                    .map(|p| Failure {
                        x: p.weight,
                        y: None,
                    })
                    .collect();
                if data.is_empty() && failures.is_empty() {
                    continue;
                }
                series.push(Series::new(case.name.clone(), data).with_failures(failures));
                if let Some(r) = references
                    .iter()
                    .find(|r| r.mesh == case.name && r.laplacian == lap)
                {
                    let y = match quantity {
                        0 => r.condition,
                        1 => Some(r.residual_relative.max(floor)),
                        _ => Some(r.x_error.max(floor)),
                    };
                    if let Some(y) = y {
                        refs.push(ReferenceLine {
                            y,
                            label: format!("null-space QR, {} ({})", case.name, sci(y)),
                        });
                    }
                }
            }
            if series.is_empty() {
                continue;
            }
            let chart = LineChart {
                title: format!("Penalty weight sweep, {lap} Laplacian: {y_label}"),
                x: Axis::log10("penalty weight w"),
                y: Axis::log10(y_label),
                series,
                reference_lines: refs,
                // The corner covering the least data (errors fall with w
                // but may rise again at large w: no corner is always free).
                legend: LegendPosition::Auto,
            };
            let stem = format!("weight_sweep_{lap}_{file}");
            plot::line_chart(&chart, &Output::new(dir.join(&stem)))?;
            figures.push((lap, file, stem));
        }
    }

    // Summary table: per mesh and Laplacian.
    let mut table = Vec::new();
    let mut headline_parts = Vec::new();
    for r in &references {
        let pts: Vec<&Point> = points
            .iter()
            .filter(|p| p.mesh == r.mesh && p.laplacian == r.laplacian)
            .collect();
        let best = pts
            .iter()
            .filter_map(|p| p.x_error.map(|e| (p.weight, e, p.residual_relative)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let first_good = pts
            .iter()
            .find(|p| p.x_error.is_some_and(|e| e <= 1e-6))
            .map(|p| sci(p.weight));
        let matches = pts
            .iter()
            .find(|p| p.x_error.is_some_and(|e| e <= 2.0 * r.x_error.max(1e-15)))
            .map(|p| sci(p.weight));
        let rejected: Vec<String> = pts
            .iter()
            .filter(|p| p.accepted == Some(false))
            .map(|p| sci(p.weight))
            .collect();
        let failed: Vec<String> = pts
            .iter()
            .filter(|p| p.failure.is_some())
            .map(|p| {
                format!(
                    "{} ({})",
                    sci(p.weight),
                    p.failure.clone().unwrap_or_default()
                )
            })
            .collect();
        let (bw, be, br) = best.unwrap_or((f64::NAN, f64::NAN, None));
        table.push(vec![
            r.mesh.clone(),
            r.laplacian.to_string(),
            r.condition.map(sci).unwrap_or_else(|| "–".into()),
            format!("{} / {}", sci(r.residual_relative), sci(r.x_error)),
            first_good.unwrap_or_else(|| "never".into()),
            matches.unwrap_or_else(|| "never".into()),
            format!(
                "{}: {} / {}",
                sci(bw),
                br.map(sci).unwrap_or_default(),
                sci(be)
            ),
            if rejected.is_empty() {
                "none".into()
            } else {
                rejected.join(", ")
            },
            if failed.is_empty() {
                "none".into()
            } else {
                failed.join(", ")
            },
        ]);
        if r.laplacian == "cotan" {
            headline_parts.push(format!(
                "{}: best penalty ‖ΔX‖ {} at w={} vs null-space {}",
                r.mesh,
                sci(be),
                sci(bw),
                sci(r.x_error)
            ));
        }
    }
    let seconds = started.elapsed().as_secs_f64();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "The Table 1 scene (20 % fixed, 2 % handle, all hard) solved as *soft only*: every hard row a penalty row of weight w, \
         `(AᵀA + w²BᵀB) X = AᵀC + w²BᵀD`, for relative weights w = 10⁻⁴ … 10¹² (the hard rows enter with w·s, s the power of two nearest A's largest column norm; one symbolic analysis per mesh and Laplacian, `PenaltySweep`). \
         X* is the reference solution of Table 1 (sparse QR of the eliminated problem, condition not squared). \
         Meshes: {}.\n",
        meshes
            .iter()
            .map(|m| format!("{} ({} vertices)", m.name, m.mesh.n_vertices()))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        s,
        "**Summary.** One row per mesh and Laplacian. κ(null-space) is the condition estimate of (AQ₂)ᵀ(AQ₂); \
         “first w with ‖ΔX‖ ≤ 1e-6” is the smallest weight whose solution is within 1e-6 (relative) of X*; \
         “≤ 2 × null-space's” the smallest weight from which the penalty is as accurate as the exact method (within a factor 2); \
         “best w” the weight with the smallest ‖X − X*‖/‖X*‖, with its residual/diagonal and that error; \
         “rejected” the weights whose forward-error estimate exceeds {} (the solve's own estimate of its error against the penalty system; the `Penalty` formulation returns such a solution with a warning, or refuses it with `--strict`); \
         “failed” factorisations that broke down.\n",
        sci(PENALTY_FORWARD_ERROR_LIMIT)
    );
    s.push_str(&markdown_table(
        &[
            "mesh",
            "Laplacian",
            "κ (null-space)",
            "null-space res / ‖ΔX‖",
            "first w with ‖ΔX‖ ≤ 1e-6",
            "first w with ‖ΔX‖ ≤ 2 × null-space's",
            "best w: res / ‖ΔX‖",
            "rejected weights",
            "failed weights",
        ],
        &table,
    ));
    let n_failed = points.iter().filter(|p| p.failure.is_some()).count();
    let n_rejected = points.iter().filter(|p| p.accepted == Some(false)).count();
    let worse_than_ns_at_top = references
        .iter()
        .filter(|r| {
            points.iter().any(|p| {
                p.mesh == r.mesh
                    && p.laplacian == r.laplacian
                    && p.weight == W_MAX
                    && p.x_error.is_some_and(|e| e > 10.0 * r.x_error.max(1e-15))
            })
        })
        .count();
    let matched = references
        .iter()
        .filter(|r| {
            points.iter().any(|p| {
                p.mesh == r.mesh
                    && p.laplacian == r.laplacian
                    && p.x_error.is_some_and(|e| e <= 2.0 * r.x_error.max(1e-15))
            })
        })
        .count();
    let accuracy = if matched == references.len() {
        format!(
            "Past a mesh-dependent weight the plain penalty solution is as accurate as the null-space one (within 2×) on every mesh/Laplacian pair; {worse_than_ns_at_top} of {} pairs end more than 10 × less accurate at w = {}.",
            references.len(),
            sci(W_MAX)
        )
    } else {
        format!(
            "The plain penalty solution comes within 2 × of the (refined) null-space accuracy at some weight on {matched} of {} mesh/Laplacian pairs (its best error is the “best w” column), and {worse_than_ns_at_top} of {} pairs end more than 10 × less accurate than null-space QR at w = {}: without multiplier updates no single weight is exact, and the section Accuracy shows the updates closing the gap.",
            references.len(),
            references.len(),
            sci(W_MAX)
        )
    };
    let _ = writeln!(
        s,
        "\n**Findings.** {n_failed} of {} factorisations failed{}; the solve's own forward-error check flags \
         {n_rejected} of the solutions (estimate > 1e-2, the “rejected weights” column). {accuracy} What the weight does decide is the constraint residual, which falls \
         like 1/w² until it reaches rounding level — only the null-space and elimination methods give exactly zero.",
        points.len(),
        if n_failed == 0 {
            " (faer's sparse Cholesky factors AᵀA + (ws)²BᵀB up to w = 1e12 on every mesh — \
             the breakdown the paper reports for TAUCS at large weights does not happen here)"
        } else {
            " (see the “failed weights” column)"
        },
    );
    if !setup_failures.is_empty() {
        let _ = writeln!(
            s,
            "\nSet-up failures (no sweep): {}.",
            setup_failures.join("; ")
        );
    }
    let _ = writeln!(s);
    for (lap, file, stem) in &figures {
        if *lap == "cotan" || *file == "x_error" {
            let _ = writeln!(s, "![{lap} {file}](weight-sweep/{stem}.png)\n");
        }
    }
    let _ = writeln!(
        s,
        "How to read the figures: x is the penalty weight, one line per mesh, dashed horizontal lines are the null-space method's \
         values on the same mesh (values below 1e-17, including exact zeros, are drawn at 1e-17); crosses on the bottom edge are \
         failed factorisations. The penalty's condition grows like w² while its residual falls like 1/w² until rounding takes over; \
         ‖X − X*‖ first falls with w and then levels off or rises once κ·ε does. Figures for the other Laplacians and quantities: {}.\n",
        figures
            .iter()
            .filter(|(lap, file, _)| *lap != "cotan" && *file != "x_error")
            .map(|(_, _, stem)| format!("[`{stem}.png`](weight-sweep/{stem}.png)"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        s,
        "Data: [`weight-sweep/weight_sweep.csv`](weight-sweep/weight_sweep.csv) (rows with weight `nullspace-qr` are the reference). \
         Regenerate: `cargo run --release --bin experiments -- weight-sweep{}` ({} on {}).",
        if ctx.has_user_meshes() {
            " --mesh-dir ../shared/meshes"
        } else {
            " [--mesh-dir ../shared/meshes]"
        },
        fmt_time(seconds),
        ctx.machine.cpu
    );
    ctx.write_section("weight-sweep", &s)?;
    Ok(Summary {
        headline: if headline_parts.is_empty() {
            format!("no sweep completed: {}", setup_failures.join("; "))
        } else {
            headline_parts.join("; ")
        },
    })
}
