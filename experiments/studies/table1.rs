//! Experiment `table1`: the paper's Table 1 — does a formulation solve the
//! "fix the bottom, drag the top" scene on each evaluation mesh and
//! Laplacian, and how accurately?
//!
//! Meshes × {uniform, cotangent, intrinsic-Delaunay cotangent} ×
//! {soft only (penalty, w = [`TABLE_WEIGHT`]), soft + hard (the paper's
//! null-space QR), KKT, elimination}. For each: success or failure (the
//! library's typed error), `max‖BX − D‖` over the hard rows, the relative
//! gap of the Laplacian energy `(E − E*)/E*` with `E = ‖AX − C‖²` and `E*`
//! that of the reference solution `X*` on the same Laplacian (sparse QR of
//! the eliminated least-squares problem, see [`qr_reference`]), the relative
//! difference `‖X − X*‖/‖X*‖`, and an estimate of the condition number of
//! the matrix each method factors.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use faer::Mat;
use lse_deform::backend::spd::FaerLlt;
use lse_deform::condition::ConditionEstimate;
use lse_deform::formulation::{FORWARD_ERROR_WARNING, PenaltySweep, max_hard_residual};
use lse_deform::scene::FixedAndHandle;
use lse_deform::{
    Deformer, Error, LaplacianKind, Method, formulation::Formulation,
    formulation::FormulationChoice,
};
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use serde::Serialize;

use crate::harness::context::AnyError;
use crate::harness::context::{Context, MeshCase};
use crate::harness::measures::{
    LAPLACIANS, TABLE_WEIGHT, energy, energy_gap, failure_kind, qr_reference, relative_difference,
    sci,
};
use crate::harness::plot::{FONT, PALETTE, ensure_fonts};
use crate::harness::registry::{Experiment, Input, Summary};
use crate::harness::rows::{fmt_time, markdown_table};
use crate::harness::text::GoodText;

/// The folder and command-line word of this experiment.
pub const NAME: &str = "table1";

/// This study's entry in the list of experiments.
pub const EXPERIMENT: Experiment = Experiment {
    name: NAME,
    title: "Table 1 — stability of soft-only, hard + soft, KKT and elimination",
    inputs: &[Input::Meshes],
    run,
};

/// The columns of the table, in order: soft only (every hard row a
/// penalty row of weight [`TABLE_WEIGHT`]), soft + hard (the paper's
/// null-space QR), Lagrange multipliers (KKT), dropping the columns of the
/// fixed vertices (elimination).
pub const COLUMNS: [Method; 4] = [
    Method::Penalty,
    Method::NullSpaceQr,
    Method::Kkt,
    Method::Eliminate,
];

/// The formulation of a column: the library's defaults, penalty with
/// [`TABLE_WEIGHT`].
fn choice(m: Method) -> FormulationChoice {
    FormulationChoice {
        weight: (m == Method::Penalty).then_some(TABLE_WEIGHT),
        ..FormulationChoice::new(m)
    }
}

/// Column title.
pub fn title(m: Method) -> String {
    match m {
        Method::Penalty => format!("soft only (penalty, w = {})", sci(TABLE_WEIGHT)),
        Method::NullSpaceQr => "soft + hard (null-space QR, the paper)".into(),
        Method::Kkt => "KKT (LDLᵀ)".into(),
        Method::Eliminate => "elimination".into(),
    }
}

/// A method as its CLI word in CSV and JSON.
fn method_word<S: serde::Serializer>(m: &Method, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(m.name())
}

// ---------------------------------------------------------------------------
// One configuration.

/// The outcome of one method on one mesh and Laplacian.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// Mesh name.
    pub mesh: String,
    /// Vertices.
    pub vertices: usize,
    /// Laplacian name.
    pub laplacian: &'static str,
    /// Method.
    #[serde(serialize_with = "method_word")]
    pub method: Method,
    /// What `X*` (the exact solution of the gaps) is: `sparse-qr`
    /// ([`qr_reference`]) or `nullspace-qr`.
    pub reference: String,
    /// Penalty weight (penalty only).
    pub weight: Option<f64>,
    /// `true` if the library returned a solution.
    pub success: bool,
    /// Short failure kind, if any.
    pub failure: Option<String>,
    /// The full error message, if any.
    pub error: Option<String>,
    /// `max‖b_k X − d_k‖` (absolute), when a solution exists (for a
    /// rejected penalty solution: the rejected `X`).
    pub max_constraint_residual: Option<f64>,
    /// The same over the bounding-box diagonal.
    pub max_constraint_residual_relative: Option<f64>,
    /// `E = ‖AX − C‖²`.
    pub energy: Option<f64>,
    /// `(E − E*)/E*`.
    pub energy_gap: Option<f64>,
    /// `‖X − X*‖/‖X*‖`.
    pub x_error: Option<f64>,
    /// Condition estimate of the factored matrix.
    pub condition: Option<f64>,
    /// Whether the Lanczos estimate converged.
    pub condition_converged: Option<bool>,
    /// Lanczos steps of the estimate.
    pub condition_iterations: Option<usize>,
    /// The library's forward-error estimate of the solution (report).
    pub forward_error_estimate: Option<f64>,
    /// Precompute seconds (factorisation included).
    pub precompute_s: Option<f64>,
}

/// A solved method: `X` (or why not) and its condition estimate.
struct Outcome {
    x: Option<Mat<f64>>,
    error: Option<Error>,
    condition: Option<ConditionEstimate>,
    forward_error_estimate: Option<f64>,
    precompute_s: Option<f64>,
}

/// Precomputes, estimates the condition number and solves.
fn run_formulation(deformer: &mut Deformer, formulation: &dyn Formulation) -> Outcome {
    let mut out = Outcome {
        x: None,
        error: None,
        condition: None,
        forward_error_estimate: None,
        precompute_s: None,
    };
    if let Err(e) =
        deformer.refactor_with(formulation, &lse_deform::resources::Resources::default())
    {
        out.error = Some(e);
        return out;
    }
    out.precompute_s = Some(deformer.report().timings_s.precompute());
    out.condition = deformer.solver_mut().estimate_condition().ok().cloned();
    match deformer.solve_matrix() {
        Ok(x) => {
            out.x = Some(x);
            out.forward_error_estimate = deformer.report().forward_error_estimate;
        }
        Err(e) => out.error = Some(e),
    }
    out
}

/// The penalty column: the library's `Penalty` (which returns every
/// finite solution, with a warning when its forward-error estimate against
/// the constrained solution exceeds [`FORWARD_ERROR_WARNING`]); if it
/// fails, the solution from [`PenaltySweep`] so that its accuracy is shown.
fn run_penalty(deformer: &mut Deformer, penalty: &dyn Formulation, weight: f64) -> Outcome {
    let mut out = run_formulation(deformer, penalty);
    if out.x.is_none()
        && let Ok(sweep) = PenaltySweep::new(deformer.problem(), &FaerLlt::auto())
        && let Ok(s) = sweep.solve(deformer.problem(), weight)
    {
        out.x = Some(s.x);
    }
    out
}

/// Runs the four methods on one mesh and Laplacian.
fn run_case(case: &MeshCase, kind: LaplacianKind) -> Result<Vec<Row>, AnyError> {
    let scene = FixedAndHandle::paper_default(&case.mesh);
    let constraints = scene.constraints(&case.mesh)?;
    let mut deformer = Deformer::new(
        case.mesh.clone(),
        kind,
        constraints,
        &lse_deform::SolveOptions::default(),
    )?;
    let diag = case.mesh.bbox_diagonal();

    let mut outcomes = Vec::new();
    for method in COLUMNS {
        let formulation = choice(method).build()?;
        let outcome = match method {
            Method::Penalty => run_penalty(&mut deformer, formulation.as_ref(), TABLE_WEIGHT),
            _ => run_formulation(&mut deformer, formulation.as_ref()),
        };
        outcomes.push((method, outcome));
    }
    let problem = deformer.problem();
    // X*: the sparse-QR solution (condition not squared); the null-space
    // solution only if the scene has non-position hard rows.
    let (exact, reference) = match qr_reference(problem)? {
        Some(x) => (Some(x), "sparse-qr"),
        None => (
            outcomes
                .iter()
                .find(|(m, o)| *m == Method::NullSpaceQr && o.error.is_none())
                .and_then(|(_, o)| o.x.clone()),
            "nullspace-qr",
        ),
    };
    let mut rows = Vec::new();
    for (method, o) in outcomes {
        let residual = o.x.as_ref().map(|x| max_hard_residual(problem, x));
        let (gap, x_error) = match (&o.x, &exact) {
            (Some(x), Some(xs)) => (
                Some(energy_gap(problem, x, xs)),
                Some(relative_difference(x, xs)),
            ),
            _ => (None, None),
        };
        rows.push(Row {
            mesh: case.name.clone(),
            vertices: case.mesh.n_vertices(),
            laplacian: kind.name(),
            method,
            reference: reference.into(),
            weight: (method == Method::Penalty).then_some(TABLE_WEIGHT),
            success: o.error.is_none() && o.x.is_some(),
            failure: o.error.as_ref().map(|e| failure_kind(e).to_string()),
            error: o.error.as_ref().map(|e| e.to_string()),
            max_constraint_residual: residual,
            max_constraint_residual_relative: residual.map(|r| r / diag),
            energy: o.x.as_ref().map(|x| energy(problem, x)),
            energy_gap: gap,
            x_error,
            condition: o.condition.as_ref().map(|c| c.value),
            condition_converged: o.condition.as_ref().map(|c| c.converged),
            condition_iterations: o.condition.as_ref().map(|c| c.iterations),
            forward_error_estimate: o.forward_error_estimate,
            precompute_s: o.precompute_s,
        });
    }
    Ok(rows)
}

// ---------------------------------------------------------------------------
// Output.

fn opt(v: Option<f64>) -> String {
    v.map(|v| format!("{v:e}")).unwrap_or_default()
}

fn write_csv(ctx: &Context, path: &Path, rows: &[Row]) -> Result<(), AnyError> {
    let header = [
        "mesh",
        "vertices",
        "laplacian",
        "method",
        "weight",
        "success",
        "failure",
        "max_constraint_residual",
        "max_constraint_residual_relative",
        "energy",
        "energy_gap_relative",
        "reference",
        "x_error_relative",
        "condition_estimate",
        "condition_converged",
        "condition_iterations",
        "forward_error_estimate",
        "precompute_s",
        "error",
    ];
    let body: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.mesh.clone(),
                r.vertices.to_string(),
                r.laplacian.to_string(),
                r.method.name().to_string(),
                opt(r.weight),
                r.success.to_string(),
                r.failure.clone().unwrap_or_default(),
                opt(r.max_constraint_residual),
                opt(r.max_constraint_residual_relative),
                opt(r.energy),
                opt(r.energy_gap),
                r.reference.clone(),
                opt(r.x_error),
                opt(r.condition),
                r.condition_converged
                    .map(|b| b.to_string())
                    .unwrap_or_default(),
                r.condition_iterations
                    .map(|n| n.to_string())
                    .unwrap_or_default(),
                opt(r.forward_error_estimate),
                r.precompute_s
                    .map(|s| format!("{s:.4}"))
                    .unwrap_or_default(),
                r.error.clone().unwrap_or_default(),
            ]
        })
        .collect();
    ctx.write_csv(path, &header, &body)
}

/// One cell of the Table-1-like table.
fn cell(r: &Row) -> String {
    let mark = if r.success { "○" } else { "×" };
    let mut s = mark.to_string();
    if let Some(f) = &r.failure {
        let _ = write!(s, " {f}");
    }
    if let Some(res) = r.max_constraint_residual_relative {
        let _ = write!(s, "<br>res {}", sci(res));
    }
    if let Some(g) = r.energy_gap {
        let _ = write!(s, "<br>ΔE {}", sci(g));
    }
    if let Some(e) = r.x_error {
        let _ = write!(s, "<br>ΔX {}", sci(e));
    }
    s
}

/// `κ` cell.
fn kappa_cell(r: &Row) -> String {
    match (r.condition, r.condition_converged) {
        (Some(k), Some(true)) => sci(k),
        (Some(k), _) => format!("≥{} (not converged)", sci(k)),
        _ => "–".into(),
    }
}

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let started = Instant::now();
    let dir = ctx.dir(NAME)?;
    let meshes = ctx.evaluation_meshes()?;
    let bar = ctx.bar(meshes.len() * LAPLACIANS.len(), NAME);
    let mut rows = Vec::new();
    for case in &meshes {
        for kind in LAPLACIANS {
            bar.set_message(format!("table1: {} / {}", case.name, kind.name()));
            match run_case(case, kind) {
                Ok(r) => rows.extend(r),
                Err(e) => {
                    // Set-up failed (e.g. intrinsic Delaunay on a non-manifold
                    // mesh): one failed row per method, said in the table.
                    for method in COLUMNS {
                        rows.push(Row {
                            mesh: case.name.clone(),
                            vertices: case.mesh.n_vertices(),
                            laplacian: kind.name(),
                            method,
                            reference: String::new(),
                            weight: (method == Method::Penalty).then_some(TABLE_WEIGHT),
                            success: false,
                            failure: Some("set-up failed".into()),
                            error: Some(e.to_string()),
                            max_constraint_residual: None,
                            max_constraint_residual_relative: None,
                            energy: None,
                            energy_gap: None,
                            x_error: None,
                            condition: None,
                            condition_converged: None,
                            condition_iterations: None,
                            forward_error_estimate: None,
                            precompute_s: None,
                        });
                    }
                }
            }
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    write_csv(ctx, &dir.join("table1.csv"), &rows)?;
    ctx.write_json(&dir.join("table1.json"), &rows)?;
    draw_figure(&rows, &dir.join("table1"))?;

    let seconds = started.elapsed().as_secs_f64();
    let section = section_markdown(ctx, &meshes, &rows, seconds);
    ctx.write_section(NAME, &section)?;

    let failed: Vec<String> = rows
        .iter()
        .filter(|r| !r.success)
        .map(|r| format!("{}/{}/{}", r.mesh, r.laplacian, r.method.name()))
        .collect();
    Ok(Summary::measured(if failed.is_empty() {
        format!(
            "all {} configurations solved (penalty at w = {})",
            rows.len(),
            sci(TABLE_WEIGHT)
        )
    } else {
        format!(
            "{} of {} configurations failed: {}",
            failed.len(),
            rows.len(),
            failed.join(", ")
        )
    }))
}

fn find<'a>(rows: &'a [Row], mesh: &str, lap: &str, method: Method) -> Option<&'a Row> {
    rows.iter()
        .find(|r| r.mesh == mesh && r.laplacian == lap && r.method == method)
}

/// The findings paragraph, computed from the rows.
fn findings(rows: &[Row]) -> String {
    let mut s = String::from("\n**Findings.**\n\n");
    exact_findings(&mut s, rows);
    let pen: Vec<&Row> = rows
        .iter()
        .filter(|r| r.method == Method::Penalty)
        .collect();
    penalty_findings(&mut s, rows, &pen);
    accuracy_findings(&mut s, rows, &pen);
    s
}

/// The findings on the exact methods: how many configurations they solved,
/// their largest constraint residual, and which failed.
fn exact_findings(s: &mut String, rows: &[Row]) {
    let fmax = |it: &mut dyn Iterator<Item = f64>| it.fold(0.0f64, f64::max);
    let exact = [Method::NullSpaceQr, Method::Kkt, Method::Eliminate];
    let exact_failed: Vec<&Row> = rows
        .iter()
        .filter(|r| exact.contains(&r.method) && !r.success)
        .collect();
    let exact_res = fmax(
        &mut rows
            .iter()
            .filter(|r| exact.contains(&r.method))
            .filter_map(|r| r.max_constraint_residual_relative),
    );
    let _ = writeln!(
        s,
        "- The three exact methods solved {} of {} configurations; their largest constraint residual is {} of the diagonal \
         (null-space QR and elimination: exactly 0 for these position constraints; KKT: rounding).",
        rows.iter()
            .filter(|r| exact.contains(&r.method) && r.success)
            .count(),
        rows.iter().filter(|r| exact.contains(&r.method)).count(),
        sci(exact_res)
    );
    if !exact_failed.is_empty() {
        let _ = writeln!(
            s,
            "- Exact methods that failed: {}.",
            exact_failed
                .iter()
                .map(|r| format!(
                    "{}/{}/{} ({})",
                    r.mesh,
                    r.laplacian,
                    r.method.name(),
                    r.failure.clone().unwrap_or_default()
                ))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
}

/// The findings on penalty: factorisation breakdowns and the solutions
/// returned with a forward-error warning.
fn penalty_findings(s: &mut String, rows: &[Row], pen: &[&Row]) {
    let breakdowns = rows
        .iter()
        .filter(|r| {
            matches!(
                r.failure.as_deref(),
                Some("not positive definite") | Some("Cholesky breakdown")
            )
        })
        .count();
    let warned: Vec<&Row> = pen
        .iter()
        .copied()
        .filter(|r| {
            r.success
                && r.forward_error_estimate
                    .is_some_and(|e| e > FORWARD_ERROR_WARNING)
        })
        .collect();
    let _ = writeln!(
        s,
        "- Penalty at relative weight w = {}: {} factorisation breakdowns in {} configurations — faer's sparse Cholesky does not fail where the paper's \
         TAUCS did. The library returns {} of them with a warning because its forward-error estimate against the constrained solution exceeds {} \
         (`--strict` would refuse them): {}.",
        sci(TABLE_WEIGHT),
        breakdowns,
        pen.len(),
        warned.len(),
        sci(FORWARD_ERROR_WARNING),
        if warned.is_empty() {
            "none".to_string()
        } else {
            warned
                .iter()
                .map(|r| {
                    let ns = find(rows, &r.mesh, r.laplacian, Method::NullSpaceQr);
                    format!(
                        "{}/{} (estimate {}, its real ‖X − X*‖/‖X*‖ = {}, null-space QR's = {}, κ of the reduced matrix {})",
                        r.mesh,
                        r.laplacian,
                        r.forward_error_estimate.map(sci).unwrap_or_else(|| "–".into()),
                        r.x_error.map(sci).unwrap_or_else(|| "–".into()),
                        ns.and_then(|n| n.x_error).map(sci).unwrap_or_else(|| "–".into()),
                        ns.and_then(|n| n.condition).map(sci).unwrap_or_else(|| "–".into()),
                    )
                })
                .collect::<Vec<_>>()
                .join("; ")
        }
    );
}

/// The findings on accuracy: penalty's worst constraint violation and the
/// null-space solution's worst agreement with the QR reference.
fn accuracy_findings(s: &mut String, rows: &[Row], pen: &[&Row]) {
    let worst_pen = pen
        .iter()
        .filter(|r| r.success)
        .filter_map(|r| r.max_constraint_residual_relative.map(|v| (v, *r)))
        .max_by(|a, b| a.0.total_cmp(&b.0));
    if let Some((v, r)) = worst_pen {
        let _ = writeln!(
            s,
            "- Penalty solutions violate the constraints by up to {} of the diagonal ({}/{}, ‖X − X*‖/‖X*‖ = {}): \
             the accuracy that a weight buys depends on the mesh and Laplacian; the weight sweep section shows where it is lost.",
            sci(v),
            r.mesh,
            r.laplacian,
            r.x_error.map(sci).unwrap_or_else(|| "–".into())
        );
    }
    let worst_ns = rows
        .iter()
        .filter(|r| r.method == Method::NullSpaceQr)
        .filter_map(|r| r.x_error.map(|v| (v, r)))
        .max_by(|a, b| a.0.total_cmp(&b.0));
    if let Some((v, r)) = worst_ns {
        let _ = writeln!(
            s,
            "- All four methods factor a normal matrix (condition squared); refined with the same factor (the library's default for the exact methods), \
             the null-space solution agrees with the QR reference to {3} correct digits at worst (‖X − X*‖/‖X*‖ = {4}, on {1}/{2}, κ of the reduced matrix {0}), \
             where the reference itself is not refined — the section Accuracy measures both against an independent refined reference.",
            r.condition.map(sci).unwrap_or_else(|| "–".into()),
            r.mesh,
            r.laplacian,
            (-v.log10()).floor().max(0.0),
            sci(v)
        );
    }
}

fn section_markdown(ctx: &Context, meshes: &[MeshCase], rows: &[Row], seconds: f64) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Scene: `FixedAndHandle::paper_default` — the lowest 20 % of the vertices along the longest axis fixed, \
         the 2 % nearest the top vertex moved by 15 % of the bounding-box diagonal, all hard. \
         Meshes: {}.\n",
        meshes
            .iter()
            .map(|m| format!(
                "{} ({} vertices; {})",
                m.name,
                m.mesh.n_vertices(),
                m.source
            ))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        s,
        "**Table 1.** ○ = the library returned a solution, × = it returned a typed error (named). \
         `res` = max‖b_k X − d_k‖ over the hard rows divided by the bounding-box diagonal; \
         `ΔE` = (E − E*)/E*, E = ‖AX − C‖² and E* that of the reference solution X* on the same Laplacian — \
         the fixed vertices substituted and the remaining least-squares problem min‖A_U X_U − C′‖ solved by sparse QR \
         (faer), which, unlike all four methods, never forms a normal matrix and so does not square the condition number \
         (negative: the solution violates the constraints and so undercuts the constrained minimum). \
         Every method runs with the library's default refinement (auto for the exact formulations, off for penalty).\n"
    );
    let header: Vec<String> = std::iter::once("mesh".to_string())
        .chain(std::iter::once("Laplacian".to_string()))
        .chain(COLUMNS.iter().map(|&m| title(m)))
        .collect();
    let header_refs: Vec<&str> = header.iter().map(|s| s.as_str()).collect();
    let mut table = Vec::new();
    let mut kappa_table = Vec::new();
    for m in meshes {
        for kind in LAPLACIANS {
            let mut row = vec![m.name.clone(), kind.name().to_string()];
            let mut krow = vec![m.name.clone(), kind.name().to_string()];
            for method in COLUMNS {
                match find(rows, &m.name, kind.name(), method) {
                    Some(r) => {
                        row.push(cell(r));
                        krow.push(kappa_cell(r));
                    }
                    None => {
                        row.push("–".into());
                        krow.push("–".into());
                    }
                }
            }
            table.push(row);
            kappa_table.push(krow);
        }
    }
    s.push_str(&markdown_table(&header_refs, &table));
    s.push_str(&findings(rows));
    let _ = writeln!(
        s,
        "\n**Condition estimates** of the matrix each method factors (Lanczos on the matrix and on its inverse; \
         penalty: AᵀA + w²BᵀB; null-space: (AQ2)ᵀ(AQ2); KKT: the scaled indefinite [AᵀA sBᵀ; sB 0]; \
         elimination: A_UᵀA_U — for position constraints the same matrix as the null-space one).\n"
    );
    s.push_str(&markdown_table(&header_refs, &kappa_table));
    let _ = writeln!(
        s,
        "\n![Table 1 as a figure](table1/table1.png)\n\n\
         How to read the figure: one column of markers per mesh and Laplacian, one marker shape per method; \
         top: constraint residual over the diagonal, bottom: |ΔE| (relative energy gap), both on log axes. \
         Markers at the bottom edge are exact zeros or failures (× = no solution).\n"
    );
    let _ = writeln!(
        s,
        "Data: [`table1/table1.csv`](table1/table1.csv) (also JSON with the full error messages). \
         Regenerate: `cargo run --release --bin experiments -- table1{}` ({} on {}).",
        if ctx.has_user_meshes() {
            " --mesh-dir ../shared/meshes"
        } else {
            " [--mesh-dir ../shared/meshes]"
        },
        fmt_time(seconds),
        ctx.machine.cpu
    );
    s
}

// ---------------------------------------------------------------------------
// The figure: a categorical dot plot on log axes, drawn with plotters.

/// Values of one panel: per category (mesh/Laplacian) and method, the value
/// (`None` = failure or no value).
struct Panel {
    y_label: String,
    values: Vec<Vec<Option<f64>>>,
    /// Floor (drawn at the bottom edge) for zeros.
    floor: f64,
}

fn draw_figure(rows: &[Row], stem: &Path) -> Result<(), AnyError> {
    let mut categories: Vec<(String, String)> = Vec::new();
    for r in rows {
        let key = (r.mesh.clone(), r.laplacian.to_string());
        if !categories.contains(&key) {
            categories.push(key);
        }
    }
    let collect = |f: &dyn Fn(&Row) -> Option<f64>| -> Vec<Vec<Option<f64>>> {
        categories
            .iter()
            .map(|(m, l)| {
                COLUMNS
                    .iter()
                    .map(|&method| find(rows, m, l, method).and_then(f))
                    .collect()
            })
            .collect()
    };
    let panels = [
        Panel {
            y_label: "max‖BX − D‖ / diagonal".into(),
            values: collect(&|r: &Row| r.max_constraint_residual_relative.filter(|_| true)),
            floor: 1e-18,
        },
        Panel {
            y_label: "|E − E*| / E*".into(),
            values: collect(&|r: &Row| r.energy_gap.map(f64::abs)),
            floor: 1e-18,
        },
    ];
    let success: Vec<Vec<bool>> = categories
        .iter()
        .map(|(m, l)| {
            COLUMNS
                .iter()
                .map(|&method| find(rows, m, l, method).is_some_and(|r| r.success))
                .collect()
        })
        .collect();
    let labels: Vec<String> = categories
        .iter()
        .map(|(m, l)| format!("{m} / {l}"))
        .collect();
    let width = (260 + 70 * labels.len() as u32).max(1180);
    let label_h = labels
        .iter()
        .map(|l| crate::harness::text::text_width(l, 14.0).unwrap_or(8.0 * l.len() as f64))
        .fold(100.0, f64::max) as u32
        + 24;
    let size = (width, 830 + label_h);
    ensure_fonts()?;
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    {
        let root = GoodText::new(BitMapBackend::new(&png, size)).into_drawing_area();
        draw_dot_plot(&root, &labels, &panels, &success, label_h)?;
        root.present()?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        draw_dot_plot(&root, &labels, &panels, &success, label_h)?;
        root.present()?;
    }
    Ok(())
}

/// The dot plot's chart of one panel: category index × log10 value.
type DotChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Draws the dot plot of Table 1 on `root`: the title, a legend of the
/// methods' markers, and one panel per measure with every category's
/// methods side by side.
fn draw_dot_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    labels: &[String],
    panels: &[Panel],
    success: &[Vec<bool>],
    label_h: u32,
) -> Result<(), AnyError>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let (w, h) = root.dim_in_pixel();
    let title_h = 44;
    let legend_h = 40;
    let (title_area, rest) = root.split_vertically(title_h);
    title_area.draw_text(
        &format!(
            "Table 1: constraint residual and energy gap per configuration (penalty w = {})",
            sci(TABLE_WEIGHT)
        ),
        &(FONT, 22.0)
            .into_font()
            .color(&BLACK)
            .pos(Pos::new(HPos::Center, VPos::Center)),
        ((w / 2) as i32, (title_h / 2) as i32),
    )?;
    let (legend_area, plots) = rest.split_vertically(legend_h);
    draw_dot_legend(&legend_area, legend_h as i32 / 2)?;
    let panel_h = (h - title_h - legend_h - label_h) / panels.len() as u32;
    for (p, panel) in panels.iter().enumerate() {
        let area = plots.margin(p as u32 * panel_h, 0, 0, 0);
        let is_last = p + 1 == panels.len();
        let area_h = panel_h + if is_last { label_h } else { 0 };
        let (area, _) = area.split_vertically(area_h);
        let dots = Dots {
            labels,
            panel,
            success,
            label_h: is_last.then_some(label_h),
        };
        dots.draw(root, &area)?;
    }
    Ok(())
}

/// The legend of the dot plot: one marker per method, then "× = failed",
/// on the line `y` of `area`.
fn draw_dot_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    y: i32,
) -> Result<(), AnyError>
where
    DB::ErrorType: 'static,
{
    let font = (FONT, 15.0)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    let mut x = 90i32;
    for (k, method) in COLUMNS.iter().enumerate() {
        draw_marker(area, k, (x, y), PALETTE[k])?;
        let name = title(*method);
        area.draw_text(&name, &font, (x + 12, y))?;
        x += 24 + crate::harness::text::text_width(&name, 15.0).unwrap_or(200.0) as i32 + 30;
    }
    area.draw_text("× = failed", &font, (x, y))?;
    Ok(())
}

/// One panel of the dot plot, with what it needs to draw itself.
struct Dots<'a> {
    /// Category labels.
    labels: &'a [String],
    /// The values.
    panel: &'a Panel,
    /// Per category and method: whether the solve succeeded.
    success: &'a [Vec<bool>],
    /// Height of the category labels below the last panel (`None` above).
    label_h: Option<u32>,
}

impl Dots<'_> {
    /// The panel's y range (log10): a decade below the smallest positive
    /// value (at least down to the floor's decade) to half a decade above
    /// the largest; `−16 … 0` without positive values.
    fn range(&self) -> (f64, f64) {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for v in self.panel.values.iter().flatten().flatten() {
            if *v > 0.0 {
                lo = lo.min(v.log10());
                hi = hi.max(v.log10());
            }
        }
        if !lo.is_finite() {
            lo = -16.0;
            hi = 0.0;
        }
        let lo = (lo.floor() - 1.0).min(self.panel.floor.log10().max(lo.floor() - 1.0));
        (lo, hi.ceil() + 0.5)
    }

    /// Draws the panel's axes and dots into `area` (the category labels and
    /// markers on `root`, in its pixels).
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        area: &DrawingArea<DB, Shift>,
    ) -> Result<(), AnyError>
    where
        DB::ErrorType: 'static,
    {
        let n = self.labels.len();
        let (lo, hi) = self.range();
        let mut chart = ChartBuilder::on(area)
            .margin_left(10)
            .margin_right(20)
            .margin_top(8)
            .x_label_area_size(self.label_h.unwrap_or(0))
            .y_label_area_size(90)
            .build_cartesian_2d(-0.5f64..(n as f64 - 0.5), lo..hi)?;
        let mut mesh = chart.configure_mesh();
        mesh.y_desc(self.panel.y_label.as_str())
            .y_label_formatter(&|v| format!("1e{}", v.round() as i64))
            .y_labels(((hi - lo) as usize + 1).min(12))
            .x_labels(n)
            .disable_x_mesh()
            .axis_desc_style((FONT, 17.0))
            .label_style((FONT, 14.0));
        mesh.x_label_formatter(&|_| String::new());
        mesh.draw()?;
        if self.label_h.is_some() {
            self.draw_labels(root, &chart, lo)?;
        }
        self.draw_values(root, &chart, lo)
    }

    /// Category labels, drawn here (plotters ignores the anchor of rotated
    /// tick labels): reading upwards, ending just below the axis.
    fn draw_labels<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        chart: &DotChart<'_, DB>,
        lo: f64,
    ) -> Result<(), AnyError>
    where
        DB::ErrorType: 'static,
    {
        let font = (FONT, 14.0)
            .into_font()
            .transform(FontTransform::Rotate270)
            .color(&BLACK)
            .pos(Pos::new(HPos::Right, VPos::Center));
        for (i, label) in self.labels.iter().enumerate() {
            let (px, py) = chart.backend_coord(&(i as f64, lo));
            root.draw_text(label, &font, (px, py + 8))?;
        }
        Ok(())
    }

    /// Each category's methods side by side: a marker, or for a failure a
    /// cross (at the value of the rejected solution if there is one, else
    /// at the bottom edge).
    fn draw_values<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        chart: &DotChart<'_, DB>,
        lo: f64,
    ) -> Result<(), AnyError>
    where
        DB::ErrorType: 'static,
    {
        let spread = 0.15;
        for (i, per_method) in self.panel.values.iter().enumerate() {
            for (k, v) in per_method.iter().enumerate() {
                let xpos = i as f64 + (k as f64 - 1.5) * spread;
                let colour = PALETTE[k];
                let y = match v {
                    Some(v) if *v > 0.0 => v.log10(),
                    _ => lo,
                };
                let px = chart.backend_coord(&(xpos, y.max(lo)));
                if v.is_none() || !self.success[i][k] {
                    let r = 6;
                    for (a, b) in [((-r, -r), (r, r)), ((-r, r), (r, -r))] {
                        root.draw(&PathElement::new(
                            vec![(px.0 + a.0, px.1 + a.1), (px.0 + b.0, px.1 + b.1)],
                            colour.stroke_width(3),
                        ))?;
                    }
                } else {
                    draw_marker(root, k, px, colour)?;
                }
            }
        }
        Ok(())
    }
}

fn draw_marker<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    k: usize,
    (x, y): (i32, i32),
    colour: RGBColor,
) -> Result<(), AnyError>
where
    DB::ErrorType: 'static,
{
    let r = 6;
    let style = colour.filled();
    match k % 4 {
        0 => area.draw(&Circle::new((x, y), r, style))?,
        1 => area.draw(&Rectangle::new([(x - r, y - r), (x + r, y + r)], style))?,
        2 => area.draw(&Polygon::new(
            vec![(x, y - r - 1), (x - r, y + r - 1), (x + r, y + r - 1)],
            style,
        ))?,
        _ => area.draw(&Polygon::new(
            vec![
                (x, y - r - 1),
                (x + r + 1, y),
                (x, y + r + 1),
                (x - r - 1, y),
            ],
            style,
        ))?,
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use lse_deform::mesh::generate;
    use lse_deform::{formulation::Kkt, formulation::NullSpaceQr};

    fn grid_problem() -> (Deformer, Mat<f64>) {
        let mesh = generate::grid(12, 12).unwrap();
        let scene = FixedAndHandle::paper_default(&mesh);
        let constraints = scene.constraints(&mesh).unwrap();
        let mut d = Deformer::with_formulation(
            mesh,
            LaplacianKind::Cotangent,
            constraints,
            &NullSpaceQr::default(),
            &lse_deform::resources::Resources::default(),
        )
        .unwrap();
        let x = d.solve_matrix().unwrap();
        (d, x)
    }

    #[test]
    fn energy_gap_matches_the_naive_difference() {
        let (d, xs) = grid_problem();
        let p = d.problem();
        // A perturbed X: the gap formula equals (E − E*)/E*.
        let x = Mat::<f64>::from_fn(xs.nrows(), 3, |i, c| {
            xs[(i, c)] + 1e-3 * ((i * 7 + c * 3) % 11) as f64
        });
        let naive = (energy(p, &x) - energy(p, &xs)) / energy(p, &xs);
        let gap = energy_gap(p, &x, &xs);
        assert!(
            (gap - naive).abs() <= 1e-9 * naive.abs(),
            "{gap} vs {naive}"
        );
        assert_eq!(energy_gap(p, &xs, &xs), 0.0);
    }

    #[test]
    fn exact_methods_have_no_gap_and_penalty_undercuts() {
        let (mut d, xs) = grid_problem();
        d.refactor_with(
            &Kkt::default(),
            &lse_deform::resources::Resources::default(),
        )
        .unwrap();
        let xk = d.solve_matrix().unwrap();
        let p = d.problem();
        assert!(energy_gap(p, &xk, &xs).abs() < 1e-10);
        assert!(max_hard_residual(p, &xk) < 1e-12);
        // A moderate penalty violates the constraints and lowers the energy,
        // the more so the smaller the weight.
        let sweep = PenaltySweep::new(p, &FaerLlt::auto()).unwrap();
        let g1 = energy_gap(p, &sweep.solve(p, 1e1).unwrap().x, &xs);
        let g2 = energy_gap(p, &sweep.solve(p, 1e2).unwrap().x, &xs);
        assert!(g1 < g2 && g2 < 0.0, "{g1} {g2}");
        assert!(relative_difference(&xs, &xs) == 0.0);
    }

    /// Independent value: with every target at its rest position the
    /// constrained minimiser is the rest mesh itself (`C = L·P`, so `X = P`
    /// gives `AX − C = 0` and meets `BX = D`), known without any solver.
    #[test]
    fn qr_reference_of_rest_targets_is_the_rest_mesh() {
        let mesh = generate::grid(12, 12).unwrap();
        let mut scene = FixedAndHandle::paper_default(&mesh);
        scene.offset = [0.0; 3];
        let constraints = scene.constraints(&mesh).unwrap();
        let d = Deformer::new(
            mesh.clone(),
            LaplacianKind::Cotangent,
            constraints,
            &lse_deform::SolveOptions::default(),
        )
        .unwrap();
        let unit = d.length_unit();
        let p = Mat::<f64>::from_fn(mesh.n_vertices(), 3, |i, c| mesh.positions()[i][c] / unit);
        let xq = qr_reference(d.problem()).unwrap().unwrap();
        assert!(
            relative_difference(&xq, &p) < 1e-12,
            "{}",
            relative_difference(&xq, &p)
        );
        assert!(max_hard_residual(d.problem(), &xq) == 0.0);
    }

    #[test]
    fn sci_formats_compactly() {
        assert_eq!(sci(1e8), "1e8");
        assert_eq!(sci(0.0), "0");
        assert_eq!(sci(-2.5e-12), "-2.5e-12");
    }
}
