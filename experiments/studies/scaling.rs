//! `scaling`: precompute and per-frame solve time against the vertex count,
//! per SPD back end — generated bumpy spheres from ~1k to ~655k vertices
//! and, with a mesh directory, the real models (up to the 537k-vertex
//! subdivided Igea) — on log–log axes with fitted power laws, and the
//! factor's nnz so that the solve can be read against it.
//!
//! Method: the null-space QR method with the library's default QR back end
//! on the paper's scene (20 % fixed, 2 % hard handle, cotangent Laplacian).
//! A back end whose predicted precompute on the next mesh exceeds a budget
//! is skipped from there on, and the section says so.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use lse_deform::mesh::generate::{self, GeneratedKind};
use lse_deform::report::Timings;
use lse_deform::scene::FixedAndHandle;
use lse_deform::{Deformer, LaplacianKind, formulation::NullSpaceQr};
use serde::Serialize;

use crate::harness::context::AnyError;
use crate::harness::context::{Context, MeshCase};
use crate::harness::plot::{self, LegendPosition, Output, ScatterFits, Series, fit_power_law};
use crate::harness::registry::{Experiment, Input, Summary};
use crate::harness::rows::{cell_f, cell_u, fmt_time, markdown_table, median};
use crate::harness::timing::{
    PHASE_COLUMNS, link, median_index, note_drawn, null_space_with_spd, phase_cells, short_error,
    spd_backends,
};

pub const NAME: &str = "scaling";

/// This study's entry in the list of experiments.
pub const EXPERIMENT: Experiment = Experiment {
    name: NAME,
    title: "Scaling with mesh size",
    inputs: &[Input::Meshes, Input::SuiteSparse, Input::Mumps],
    run,
};

/// Assumed growth exponent of the precompute for the budget prediction
/// (nested-dissection Cholesky of a surface mesh is `O(n^1.5)` at worst).
const PREDICTION_EXPONENT: f64 = 1.5;

/// One (mesh, back end) measurement.
#[derive(Debug, Clone, Serialize)]
struct Row {
    mesh: String,
    /// "generated" or "real".
    kind: &'static str,
    vertices: usize,
    spd_backend: String,
    qr_backend: String,
    repetitions: usize,
    setup_s: f64,
    timings: Option<Timings>,
    precompute_median_s: Option<f64>,
    solve_median_s: Option<f64>,
    solve_count: usize,
    nnz_a: Option<usize>,
    nnz_normal: Option<usize>,
    nnz_factor: Option<usize>,
    factor_bytes: Option<usize>,
    /// Solve time per factor entry (ns): constant if the solve is linear in
    /// nnz(L).
    solve_ns_per_factor_nnz: Option<f64>,
    constraint_residual_relative: Option<f64>,
    status: String,
}

/// The generated meshes: bumpy spheres closest to these vertex counts.
fn generated_targets(quick: bool) -> Vec<usize> {
    if quick {
        vec![1_000, 4_000, 16_000]
    } else {
        vec![1_000, 4_000, 16_000, 64_000, 256_000, 1_000_000]
    }
}

/// Budget of one predicted precompute (seconds): generous for the
/// library's default SPD back end (and CHOLMOD, the reference), so that
/// they reach the largest meshes; tight for the slow ones.
fn budget_for(ctx: &Context, spd_name: &str) -> f64 {
    let main = spd_name == NullSpaceQr::default().spd.name() || spd_name == "cholmod";
    match (ctx.quick, ctx.has_user_meshes(), main) {
        (true, _, _) => 5.0,
        (false, false, true) => 40.0,
        (false, false, false) => 8.0,
        (false, true, true) => 60.0,
        (false, true, false) => 15.0,
    }
}

/// The meshes, generated first then real, each list small to large.
fn cases(ctx: &Context) -> Result<Vec<(MeshCase, &'static str)>, AnyError> {
    let mut cases: Vec<(MeshCase, &'static str)> = Vec::new();
    let mut seen = Vec::new();
    for target in generated_targets(ctx.quick) {
        let kind = GeneratedKind::BumpySphere;
        let size = generate::size_for_vertices(kind, target)?;
        if seen.contains(&size) {
            continue;
        }
        seen.push(size);
        let mesh = generate::generate(kind, size, ctx.seed)?;
        let case = MeshCase {
            name: format!("bumpy-sphere-{}", mesh.n_vertices()),
            source: format!(
                "generated {kind} ({size} subdivisions), {} vertices, seed {}",
                mesh.n_vertices(),
                ctx.seed
            ),
            mesh,
        };
        cases.push((case, "generated"));
    }
    if ctx.has_user_meshes() {
        // Every user mesh, small to large (the first three with --quick).
        let mut real = ctx.user_meshes()?;
        real.sort_by_key(|c| c.mesh.n_vertices());
        if ctx.quick {
            real.truncate(3);
        }
        cases.extend(real.into_iter().map(|c| (c, "real")));
    }
    Ok(cases)
}

/// The predicted precompute on `n` vertices from the history `h` of
/// (vertices, precompute) of one back end: `(prediction, n_prev, t_prev,
/// exponent)`. The reference point is the largest measured mesh not larger
/// than this one, else the smallest larger one — so that the prediction
/// shrinks with the mesh; the exponent is the back end's own growth between
/// its last two measurements if steeper than [`PREDICTION_EXPONENT`].
fn predict(h: &[(usize, f64)], n: usize) -> Option<(f64, usize, f64, f64)> {
    let &(n_prev, t_prev) = h
        .iter()
        .filter(|(m, _)| *m <= n)
        .max_by_key(|(m, _)| *m)
        .or_else(|| h.iter().min_by_key(|(m, _)| *m))?;
    let exponent = match h.len() {
        0 | 1 => PREDICTION_EXPONENT,
        l => {
            let ((n0, t0), (n1, t1)) = (h[l - 2], h[l - 1]);
            let slope = (t1 / t0).ln() / (n1 as f64 / n0 as f64).ln();
            if slope.is_finite() {
                slope.clamp(PREDICTION_EXPONENT, 3.0)
            } else {
                PREDICTION_EXPONENT
            }
        }
    };
    let predicted = t_prev * (n as f64 / n_prev as f64).powf(exponent);
    Some((predicted, n_prev, t_prev, exponent))
}

/// An empty row of one mesh and back end.
fn blank_row(case: &MeshCase, kind: &'static str, spd_name: &str, setup_s: f64) -> Row {
    Row {
        mesh: case.name.clone(),
        kind,
        vertices: case.mesh.n_vertices(),
        spd_backend: spd_name.into(),
        qr_backend: NullSpaceQr::default().qr.name().to_string(),
        repetitions: 0,
        setup_s,
        timings: None,
        precompute_median_s: None,
        solve_median_s: None,
        solve_count: 0,
        nnz_a: None,
        nnz_normal: None,
        nnz_factor: None,
        factor_bytes: None,
        solve_ns_per_factor_nnz: None,
        constraint_residual_relative: None,
        status: "ok".into(),
    }
}

/// Precompute (median of 3 below 2 s, else 1) and solves (11 below 100k
/// vertices, else 5) of one back end, into `row`.
fn measure_backend(
    ctx: &Context,
    deformer: &mut Deformer,
    spd_name: &str,
    row: &mut Row,
) -> Result<(), AnyError> {
    let formulation = null_space_with_spd(spd_name)?;
    let mut reports = Vec::new();
    let mut reps = if ctx.quick { 1 } else { 3 };
    let mut rep = 0;
    while rep < reps {
        deformer.refactor_with(&formulation, &lse_deform::resources::Resources::default())?;
        let t = deformer.report().timings_s.precompute();
        reports.push(deformer.report().clone());
        if t > 2.0 {
            reps = 1;
        }
        rep += 1;
    }
    let pre: Vec<f64> = reports.iter().map(|r| r.timings_s.precompute()).collect();
    let chosen = &reports[median_index(&pre)];
    row.repetitions = reports.len();
    row.timings = Some(chosen.timings_s.clone());
    row.precompute_median_s = Some(median(&pre));
    row.nnz_normal = chosen.nnz.normal;
    row.nnz_factor = chosen.nnz.factor;
    row.factor_bytes = chosen.nnz.factor_bytes;
    // Solves on the last factorisation.
    let count = if row.vertices < 100_000 { 11 } else { 5 };
    let mut times = Vec::new();
    for _ in 0..count {
        deformer.solve_matrix()?;
        times.push(deformer.report().timings_s.solve);
    }
    let solve = median(&times);
    row.solve_median_s = Some(solve);
    row.solve_count = times.len();
    row.nnz_a = Some(deformer.report().nnz.a);
    row.constraint_residual_relative = Some(deformer.report().max_constraint_residual_relative);
    if let Some(nnz) = row.nnz_factor.filter(|&v| v > 0) {
        row.solve_ns_per_factor_nnz = Some(solve / nnz as f64 * 1e9);
    }
    Ok(())
}

/// Last measured (vertices, precompute) per back end and mesh kind
/// (generated, real), for the budget prediction.
type History = Vec<[Vec<(usize, f64)>; 2]>;

/// Every back end on one mesh: a row each, skips and failures as notes.
fn measure_case(
    ctx: &Context,
    (case, kind): &(MeshCase, &'static str),
    history: &mut History,
    rows: &mut Vec<Row>,
    notes: &mut Vec<String>,
) -> Result<(), AnyError> {
    let mesh = &case.mesh;
    let n = mesh.n_vertices();
    let kind_index = usize::from(*kind == "real");
    let constraints = FixedAndHandle::paper_default(mesh).constraints(mesh)?;
    let t = Instant::now();
    let mut deformer = Deformer::new(
        mesh.clone(),
        LaplacianKind::Cotangent,
        constraints,
        &lse_deform::SolveOptions::default(),
    )?;
    let setup_s = t.elapsed().as_secs_f64();
    for (bi, &spd_name) in spd_backends().iter().enumerate() {
        let mut row = blank_row(case, kind, spd_name, setup_s);
        let h = if history[bi][kind_index].is_empty() {
            &history[bi][0]
        } else {
            &history[bi][kind_index]
        };
        let budget = budget_for(ctx, spd_name);
        if let Some((predicted, n_prev, t_prev, exponent)) = predict(h, n)
            && predicted > budget
        {
            row.status = format!(
                "skipped: predicted precompute {} > budget {}",
                fmt_time(predicted),
                fmt_time(budget)
            );
            notes.push(format!(
                "{spd_name} on {} ({n} vertices): {} (from {} at {n_prev} vertices, n^{exponent:.2})",
                case.name,
                row.status,
                fmt_time(t_prev)
            ));
            rows.push(row);
            continue;
        }
        match measure_backend(ctx, &mut deformer, spd_name, &mut row) {
            Ok(()) => history[bi][kind_index].extend(row.precompute_median_s.map(|t| (n, t))),
            Err(e) => {
                notes.push(format!("{spd_name} on {}: {e}", case.name));
                row.status = format!("failed: {}", short_error(&e.to_string()));
            }
        }
        rows.push(row);
    }
    Ok(())
}

/// `scaling.csv` (timings flattened) and `scaling.json`.
fn write_data(ctx: &Context, dir: &Path, rows: &[Row]) -> Result<(), AnyError> {
    let header = [
        &[
            "mesh",
            "kind",
            "vertices",
            "spd_backend",
            "qr_backend",
            "repetitions",
            "setup_s",
        ][..],
        &PHASE_COLUMNS,
        &[
            "precompute_median_s",
            "solve_median_s",
            "solve_count",
            "nnz_a",
            "nnz_normal",
            "nnz_factor",
            "factor_bytes",
            "solve_ns_per_factor_nnz",
            "constraint_residual_relative",
            "status",
        ],
    ]
    .concat();
    let csv_rows: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            let t = r.timings.as_ref();
            let mut cells = vec![
                r.mesh.clone(),
                r.kind.into(),
                r.vertices.to_string(),
                r.spd_backend.clone(),
                r.qr_backend.clone(),
                r.repetitions.to_string(),
                format!("{:.6e}", r.setup_s),
            ];
            cells.extend(phase_cells(t));
            cells.extend([
                cell_f(r.precompute_median_s),
                cell_f(r.solve_median_s),
                r.solve_count.to_string(),
                cell_u(r.nnz_a),
                cell_u(r.nnz_normal),
                cell_u(r.nnz_factor),
                cell_u(r.factor_bytes),
                cell_f(r.solve_ns_per_factor_nnz),
                cell_f(r.constraint_residual_relative),
                r.status.clone(),
            ]);
            cells
        })
        .collect();
    ctx.write_csv(&dir.join("scaling.csv"), &header, &csv_rows)?;
    let budget = budget_for(ctx, &NullSpaceQr::default().spd.name());
    let budget_other = budget_for(ctx, "nalgebra");
    ctx.write_json(
        &dir.join("scaling.json"),
        &serde_json::json!({ "budget_s": budget, "budget_other_s": budget_other, "rows": rows }),
    )
}

/// `(x, y)` of the rows of one kind (all with `None`) and back end.
fn points(
    rows: &[Row],
    kind: Option<&str>,
    spd_name: &str,
    x: fn(&Row) -> Option<f64>,
    y: fn(&Row) -> Option<f64>,
) -> Vec<(f64, f64)> {
    rows.iter()
        .filter(|r| kind.is_none_or(|k| r.kind == k) && r.spd_backend == spd_name)
        .filter_map(|r| Some((x(r)?, y(r)?)))
        .filter(|&(a, b)| a > 0.0 && b > 0.0)
        .collect()
}

fn vertices(r: &Row) -> Option<f64> {
    Some(r.vertices as f64)
}
fn precompute(r: &Row) -> Option<f64> {
    r.precompute_median_s
}
fn solve(r: &Row) -> Option<f64> {
    r.solve_median_s
}
fn factor_nnz(r: &Row) -> Option<f64> {
    r.nnz_factor.map(|v| v as f64)
}

/// The mesh kinds present: "generated", and "real" with user meshes.
fn kinds(rows: &[Row]) -> Vec<&'static str> {
    if rows.iter().any(|r| r.kind == "real") {
        vec!["generated", "real"]
    } else {
        vec!["generated"]
    }
}

/// The fitted-slopes table and the headline's slopes.
fn slopes(rows: &[Row]) -> (Vec<Vec<String>>, Vec<String>) {
    let fit_cell = |pts: &[(f64, f64)]| match fit_power_law(pts) {
        Ok(f) => format!("{:.2} (R² {:.3}, {} pts)", f.slope, f.r_squared, f.n),
        Err(_) => "—".into(),
    };
    let mut slope_rows = Vec::new();
    let mut headline = Vec::new();
    for kind in kinds(rows) {
        for spd_name in spd_backends() {
            let p = points(rows, Some(kind), spd_name, vertices, precompute);
            let s = points(rows, Some(kind), spd_name, vertices, solve);
            let z = points(rows, Some(kind), spd_name, factor_nnz, solve);
            let nz = points(rows, Some(kind), spd_name, vertices, factor_nnz);
            let largest = rows
                .iter()
                .filter(|r| {
                    r.kind == kind && r.spd_backend == spd_name && r.precompute_median_s.is_some()
                })
                .max_by_key(|r| r.vertices)
                .map_or_else(
                    || "—".into(),
                    |r| {
                        format!(
                            "{} vertices: precompute {}, solve {}",
                            r.vertices,
                            fmt_time(r.precompute_median_s.unwrap_or(f64::NAN)),
                            fmt_time(r.solve_median_s.unwrap_or(f64::NAN))
                        )
                    },
                );
            if kind == "generated"
                && let (Ok(fp), Ok(fs)) = (fit_power_law(&p), fit_power_law(&s))
            {
                headline.push(format!("{spd_name} {:.2}/{:.2}", fp.slope, fs.slope));
            }
            let cells = [fit_cell(&p), fit_cell(&s), fit_cell(&nz), fit_cell(&z)];
            let mut row = vec![kind.to_string(), spd_name.to_string()];
            row.extend(cells);
            row.push(largest);
            slope_rows.push(row);
        }
    }
    (slope_rows, headline)
}

/// Set-up time (the same for every back end) per generated mesh.
fn setup_points(rows: &[Row]) -> Vec<(f64, f64)> {
    let mut v: Vec<(f64, f64)> = Vec::new();
    for r in rows.iter().filter(|r| r.kind == "generated") {
        if !v.iter().any(|p| p.0 == r.vertices as f64) {
            v.push((r.vertices as f64, r.setup_s));
        }
    }
    v
}

/// A drawn figure: stem, title, how to read it.
type Figure = (String, String, String);

/// One log–log scatter with fits; no figure (a note) without data.
fn scatter(
    dir: &Path,
    (stem, title, how): (String, String, &str),
    (x_label, y_label): (&str, &str),
    series: Vec<Series>,
    notes: &mut Vec<String>,
) -> Result<Option<Figure>, AnyError> {
    let series: Vec<Series> = series
        .into_iter()
        .filter(|s| !s.points.is_empty())
        .collect();
    if series.is_empty() {
        notes.push(format!("figure {stem}: no data"));
        return Ok(None);
    }
    let spec = ScatterFits {
        title: title.clone(),
        x_label: x_label.into(),
        y_label: y_label.into(),
        series,
        legend: LegendPosition::UpperLeft,
    };
    let drawn = plot::scatter_loglog_with_fits(&spec, &Output::new(dir.join(&stem)))?;
    note_drawn(&drawn, notes);
    Ok(Some((stem, title, how.to_string())))
}

/// Every figure: precompute and solve against n per kind, solve against
/// nnz(L).
fn figures(dir: &Path, rows: &[Row], notes: &mut Vec<String>) -> Result<Vec<Figure>, AnyError> {
    let backends = spd_backends();
    let per_backend =
        |kind: Option<&str>, x: fn(&Row) -> Option<f64>, y: fn(&Row) -> Option<f64>| {
            backends
                .iter()
                .map(|&b| Series::new(b, points(rows, kind, b, x, y)))
                .collect::<Vec<_>>()
        };
    let mut out = Vec::new();
    for kind in kinds(rows) {
        let (prefix, what) = if kind == "real" {
            ("real_", "real models")
        } else {
            ("", "generated bumpy spheres")
        };
        let mut series = per_backend(Some(kind), vertices, precompute);
        if kind == "generated" {
            series.push(Series::new("set-up (L, A, B)", setup_points(rows)));
        }
        out.extend(scatter(
            dir,
            (format!("{prefix}precompute_vs_vertices"), format!("Precompute time against mesh size — {what}"),
             "Each series is one SPD back end (null-space QR, default QR back end); the legend gives the fitted slope of log t against log n: 1 is linear, 1.5 the nested-dissection bound for surface meshes."),
            ("vertices", "precompute time (s)"),
            series,
            notes,
        )?);
        out.extend(scatter(
            dir,
            (format!("{prefix}solve_vs_vertices"), format!("Per-frame solve time against mesh size — {what}"),
             "The solve phase (R1ᵀy = D, right-hand side, two triangular solves, X = Q[y; z]) per back end; a slope a little above 1 is the factor's growth (n log n fill)."),
            ("vertices", "solve time (s), median"),
            per_backend(Some(kind), vertices, solve),
            notes,
        )?);
    }
    out.extend(scatter(
        dir,
        ("solve_vs_factor_nnz".into(), "Per-frame solve time against the factor's nnz — all meshes".into(),
         "x is the number of entries of the factor L (lower triangle); a slope of 1 means the solve is linear in nnz(L), i.e. bounded by reading the factor twice."),
        ("nnz of the Cholesky factor L", "solve time (s), median"),
        per_backend(None, factor_nnz, solve),
        notes,
    )?);
    Ok(out)
}

/// The table of every measurement.
fn detail_table(rows: &[Row]) -> String {
    let dash = || "—".to_string();
    let detail: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.mesh.clone(),
                r.vertices.to_string(),
                r.spd_backend.clone(),
                fmt_time(r.setup_s),
                r.precompute_median_s.map_or_else(dash, fmt_time),
                r.timings.as_ref().map_or_else(dash, |t| {
                    format!("{} / {}", fmt_time(t.symbolic), fmt_time(t.numeric))
                }),
                r.solve_median_s.map_or_else(dash, fmt_time),
                r.nnz_factor
                    .map_or_else(dash, |v| format!("{:.2}M", v as f64 / 1e6)),
                r.factor_bytes
                    .map_or_else(dash, |v| format!("{:.0}", v as f64 / 1048576.0)),
                r.solve_ns_per_factor_nnz
                    .map_or_else(dash, |v| format!("{v:.2}")),
                r.status.clone(),
            ]
        })
        .collect();
    markdown_table(
        &[
            "mesh",
            "vertices",
            "SPD",
            "set-up",
            "precompute",
            "sym / num",
            "solve",
            "nnz(L)",
            "MB",
            "ns/nnz",
            "status",
        ],
        &detail,
    )
}

/// The section's first paragraph: what was measured and how.
fn method_text(ctx: &Context, rows: &[Row]) -> String {
    let default_spd = NullSpaceQr::default().spd.name().to_string();
    let mut sizes: Vec<String> = Vec::new();
    for r in rows.iter().filter(|r| r.kind == "generated") {
        let v = r.vertices.to_string();
        if !sizes.contains(&v) {
            sizes.push(v);
        }
    }
    format!(
        "Null-space QR (QR back end `{}`, the library default) on the paper's scene (20 % fixed, 2 % hard handle, cotangent Laplacian), \
         per SPD back end ({}), on generated bumpy spheres of {} vertices{}. \
         Precompute = QR + preparation + normal matrix + symbolic + numeric: median of 3 runs below 2 s, one run above; \
         solve = the library's solve phase for 3 right-hand sides (median of 11 solves below 100k vertices, 5 above). \
         A back end whose predicted precompute on the next mesh exceeds its budget — {} for the default SPD back end `{default_spd}` and CHOLMOD, {} for the others — is skipped from there on \
         (prediction t·(n'/n)^p, p = the back end's own slope between its last two meshes, at least {PREDICTION_EXPONENT}); the skips are listed under the table. \
         The next generated size after 655k vertices (2.6M) is beyond this machine's time budget.\n",
        NullSpaceQr::default().qr.name(),
        spd_backends().join(", "),
        sizes.join(", "),
        if kinds(rows).contains(&"real") {
            " and the real models listed below"
        } else {
            ""
        },
        fmt_time(budget_for(ctx, &default_spd)),
        fmt_time(budget_for(ctx, "nalgebra"))
    )
}

/// The section, from the rows, figures and notes.
fn section(ctx: &Context, rows: &[Row], figures: &[Figure], notes: &[String]) -> String {
    let mut s = method_text(ctx, rows);
    s.push_str(&ctx.regenerate(NAME));
    let _ = writeln!(
        s,
        "**Fitted slopes** of log time against log n (and of log solve time against log nnz(L)); R² and the number of points in brackets. \
         Read: precompute slope ≈ 1–1.5 is what sparse Cholesky of a surface mesh allows; solve-vs-nnz(L) slope ≈ 1 means the solve is linear in the factor.\n"
    );
    let header = [
        "meshes",
        "SPD back end",
        "precompute vs n",
        "solve vs n",
        "nnz(L) vs n",
        "solve vs nnz(L)",
        "largest measured",
    ];
    s.push_str(&markdown_table(&header, &slopes(rows).0));
    if let Ok(f) = fit_power_law(&setup_points(rows)) {
        let _ = writeln!(
            s,
            "\nSet-up (Laplacian, A, B; the same for every back end) on the generated meshes: slope {:.2} (R² {:.3}).",
            f.slope, f.r_squared
        );
    }
    for (stem, title, how) in figures {
        let _ = writeln!(s, "\n**Figure: {title}.** {how}\n\n{}", link(NAME, stem));
    }
    let _ = writeln!(
        s,
        "\n**Table: every measurement.** Times are medians; \"sym / num\" is the symbolic and numeric factorisation of the median run; \
         MB is the factor's memory (values and row indices); ns/nnz is the solve time per factor entry (3 right-hand sides, two triangular solves — constant if the solve is linear in nnz(L)).\n"
    );
    s.push_str(&detail_table(rows));
    s.push_str(&ctx.closing(
        notes,
        &format!("Data: [`{NAME}/scaling.csv`]({NAME}/scaling.csv), [`{NAME}/scaling.json`]({NAME}/scaling.json)."),
    ));
    s
}

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let dir = ctx.dir(NAME)?;
    let cases = cases(ctx)?;
    let mut rows: Vec<Row> = Vec::new();
    let mut notes: Vec<String> = Vec::new();
    let mut history: History = vec![[Vec::new(), Vec::new()]; spd_backends().len()];
    let bar = ctx.bar(cases.len(), NAME);
    for case in &cases {
        bar.set_message(format!(
            "{NAME}: {} ({} vertices)",
            case.0.name,
            case.0.mesh.n_vertices()
        ));
        measure_case(ctx, case, &mut history, &mut rows, &mut notes)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    write_data(ctx, &dir, &rows)?;
    let figures = figures(&dir, &rows, &mut notes)?;
    ctx.write_section(NAME, &section(ctx, &rows, &figures, &notes))?;
    let largest = rows.iter().map(|r| r.vertices).max().unwrap_or(0);
    Ok(Summary::measured(format!(
        "log–log slopes precompute/solve on generated meshes up to {largest} vertices: {}",
        slopes(&rows).1.join(", ")
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_sizes_span_three_orders_of_magnitude() {
        let targets = generated_targets(false);
        let counts: Vec<usize> = targets
            .iter()
            .map(|&t| {
                let s = generate::size_for_vertices(GeneratedKind::BumpySphere, t).unwrap();
                GeneratedKind::BumpySphere.vertex_count(s).unwrap()
            })
            .collect();
        assert!(counts[0] <= 1_000);
        assert!(*counts.last().unwrap() >= 500_000);
        assert!(counts.windows(2).all(|w| w[0] < w[1]));
    }
}
