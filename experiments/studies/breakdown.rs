//! `precompute-breakdown`: the paper's Fig. 7 and 8 — the time of the
//! set-up and of each precompute phase (QR, preparation, normal matrix,
//! symbolic and numeric factorisation), hard + soft (the null-space QR
//! method) against soft only (penalty: every hard row a soft row of one
//! weight), per evaluation mesh and on every SPD back end of the build.
//!
//! Each bar is the run with the median precompute time of a few
//! repetitions from scratch (set-up included); hard + soft and soft only are
//! run alternately, so that their ratio is measured side by side.
//!
//! The module also holds the helpers the other timing experiments
//! (`relative`, `scaling`, `drag`) share: the back ends of the build, the
//! penalty weight, the phase list and the median run.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use lse_deform::backend::spd::SpdKind;
use lse_deform::constraints::ConstraintSet;
use lse_deform::report::Timings;
use lse_deform::scene::FixedAndHandle;
use lse_deform::{Mesh, Method, Report, formulation::Formulation, formulation::FormulationChoice};
use serde::Serialize;

use crate::harness::context::AnyError;
use crate::harness::context::{Context, MeshCase};
use crate::harness::plot::{self, Category, LegendPosition, Output, StackedBars};
use crate::harness::registry::{Experiment, Input, Summary};
use crate::harness::rows::{cell_f, cell_u, fmt_time, markdown_table, median};
use crate::harness::timing::{
    PENALTY_RELATIVE_WEIGHT, PHASE_COLUMNS, PHASES, Terms, link, median_index, note_drawn,
    phase_cells, phase_values, setup_and_precompute, short_error, spd_backends,
};

// ---------------------------------------------------------------------------
// The experiment.

pub const NAME: &str = "precompute-breakdown";

/// This study's entry in the list of experiments.
pub const EXPERIMENT: Experiment = Experiment {
    name: NAME,
    title: "Precompute breakdown (paper Fig. 7 and 8)",
    inputs: &[Input::Meshes, Input::SuiteSparse, Input::Mumps],
    run,
};

/// One row of the CSV: a (mesh, SPD back end, method) configuration.
#[derive(Debug, Clone, Serialize)]
struct Row {
    mesh: String,
    vertices: usize,
    method: &'static str,
    formulation: String,
    qr_backend: String,
    spd_backend: String,
    penalty_weight: Option<f64>,
    /// What was held equal across back ends.
    terms: Terms,
    /// The ordering the median run's factorisation used (its report's).
    ordering: Option<String>,
    /// The threads it ran on (its report's).
    threads: Option<usize>,
    repetitions: usize,
    /// The median run's phases.
    timings: Option<Timings>,
    /// Median over the repetitions of set-up + precompute.
    total_median_s: Option<f64>,
    /// Median of the precompute alone.
    precompute_median_s: Option<f64>,
    nnz_normal: Option<usize>,
    nnz_factor: Option<usize>,
    /// Max hard-constraint residual of one solve after the precompute
    /// (relative to the bounding-box diagonal); for penalty the residual of
    /// the former hard rows.
    constraint_residual_relative: Option<f64>,
    status: String,
}

/// The two formulations compared: null-space QR (positions hard, Laplacian
/// soft) and penalty (everything soft), on the SPD back end `spd_name`.
fn choices(spd_name: &str) -> Result<[FormulationChoice; 2], AnyError> {
    let spd: SpdKind = spd_name.parse()?;
    Ok([
        FormulationChoice {
            spd: spd.into(),
            ..FormulationChoice::new(Method::NullSpaceQr)
        },
        FormulationChoice {
            spd: spd.into(),
            weight: Some(PENALTY_RELATIVE_WEIGHT),
            ..FormulationChoice::new(Method::Penalty)
        },
    ])
}

/// The table's words for a formulation.
fn label(m: Method) -> &'static str {
    match m {
        Method::Penalty => "soft only",
        _ => "hard + soft",
    }
}

/// The runs of one formulation.
#[derive(Default)]
struct Runs {
    reports: Vec<Report>,
    error: Option<String>,
    residual: Option<f64>,
}

/// Up to `reps_wanted` set-ups and precomputes from scratch of both
/// formulations, alternately so that their ratio is measured side by side
/// (slow configurations get at most 3); one solve after the first.
fn measure_pair(
    mesh: &Mesh,
    constraints: &ConstraintSet,
    formulations: &[Box<dyn Formulation>; 2],
    reps_wanted: usize,
    terms: Terms,
) -> [Runs; 2] {
    let resources = terms.resources();
    let mut runs = [Runs::default(), Runs::default()];
    let mut reps = reps_wanted;
    let mut rep = 0;
    while rep < reps {
        for (r, f) in runs.iter_mut().zip(formulations) {
            if r.error.is_some() {
                continue;
            }
            let t = Instant::now();
            match setup_and_precompute(mesh, constraints, f.as_ref(), &resources) {
                Ok(mut d) => {
                    r.reports.push(d.report().clone());
                    // One solve: the constraints really hold (or, for
                    // penalty, how far off they are).
                    if rep == 0 {
                        match d.solve_matrix() {
                            Ok(_) => r.residual = Some(d.report().max_constraint_residual_relative),
                            Err(e) => r.error = Some(format!("solve failed: {e}")),
                        }
                    }
                }
                Err(e) => r.error = Some(e.to_string()),
            }
            if rep == 0 && t.elapsed().as_secs_f64() > 3.0 {
                reps = reps.min(3);
            }
        }
        rep += 1;
    }
    runs
}

/// The row of one formulation's runs (the median total's phases).
fn row_of(
    case: &MeshCase,
    (spd_name, terms): (&str, Terms),
    choice: &FormulationChoice,
    f: &dyn Formulation,
    runs: &Runs,
    notes: &mut Vec<String>,
) -> Row {
    let totals: Vec<f64> = runs
        .reports
        .iter()
        .map(|r| r.timings_s.setup + r.timings_s.precompute())
        .collect();
    let pre: Vec<f64> = runs
        .reports
        .iter()
        .map(|r| r.timings_s.precompute())
        .collect();
    let chosen = (!runs.reports.is_empty()).then(|| &runs.reports[median_index(&totals)]);
    let method = label(choice.method);
    let status = match &runs.error {
        Some(e) => {
            notes.push(format!(
                "{} / {method} / {spd_name} / {}: {e}",
                case.name,
                terms.word()
            ));
            format!("failed: {}", short_error(e))
        }
        None => "ok".into(),
    };
    Row {
        mesh: case.name.clone(),
        vertices: case.mesh.n_vertices(),
        method,
        formulation: f.name(),
        qr_backend: match choice.method {
            Method::NullSpaceQr => choice.qr.name().to_string(),
            _ => "—".into(),
        },
        spd_backend: spd_name.into(),
        penalty_weight: choice.weight,
        terms,
        ordering: chosen.and_then(|r| r.ordering.clone()),
        threads: chosen.and_then(|r| r.threads),
        repetitions: runs.reports.len(),
        timings: chosen.map(|r| r.timings_s.clone()),
        total_median_s: (!totals.is_empty()).then(|| median(&totals)),
        precompute_median_s: (!pre.is_empty()).then(|| median(&pre)),
        nnz_normal: chosen.and_then(|r| r.nnz.normal),
        nnz_factor: chosen.and_then(|r| r.nnz.factor),
        constraint_residual_relative: runs.residual,
        status,
    }
}

/// Both formulations on every SPD back end, on one mesh.
/// Meshes above this many vertices are measured on the fast SPD back ends
/// only (faer-auto, faer-supernodal, CHOLMOD).
const LARGE_VERTICES: usize = 100_000;

fn measure_case(
    ctx: &Context,
    case: &MeshCase,
    rows: &mut Vec<Row>,
    notes: &mut Vec<String>,
) -> Result<(), AnyError> {
    let constraints = FixedAndHandle::paper_default(&case.mesh).constraints(&case.mesh)?;
    let large = case.mesh.n_vertices() > LARGE_VERTICES;
    let slow = |s: &str| matches!(s, "faer-simplicial" | "nalgebra");
    if large {
        notes.push(format!(
            "{}: faer-simplicial and nalgebra left out (above {LARGE_VERTICES} vertices their numeric factorisation takes minutes per repetition; `scaling` shows how they grow)",
            case.name
        ));
    }
    for terms in Terms::ALL {
        for spd_name in spd_backends().into_iter().filter(|s| !(large && slow(s))) {
            let choices = choices(spd_name)?;
            let formulations = [choices[0].build()?, choices[1].build()?];
            let reps = if ctx.quick { 1 } else { 5 };
            let runs = measure_pair(&case.mesh, &constraints, &formulations, reps, terms);
            for ((c, f), r) in choices.iter().zip(&formulations).zip(&runs) {
                rows.push(row_of(case, (spd_name, terms), c, f.as_ref(), r, notes));
            }
        }
    }
    Ok(())
}

/// `breakdown.csv` (timings flattened) and `breakdown.json`.
fn write_data(ctx: &Context, dir: &Path, rows: &[Row]) -> Result<(), AnyError> {
    let header = [
        &[
            "mesh",
            "vertices",
            "method",
            "formulation",
            "qr_backend",
            "spd_backend",
            "penalty_weight",
            "terms",
            "ordering",
            "threads",
            "repetitions",
            "setup_s",
        ][..],
        &PHASE_COLUMNS,
        &[
            "precompute_s",
            "precompute_median_s",
            "total_median_s",
            "nnz_normal",
            "nnz_factor",
            "constraint_residual_relative",
            "status",
        ],
    ]
    .concat();
    let csv_rows: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            let t = r.timings.as_ref();
            let f = |g: fn(&Timings) -> f64| cell_f(t.map(g));
            let mut cells = vec![
                r.mesh.clone(),
                r.vertices.to_string(),
                r.method.into(),
                r.formulation.clone(),
                r.qr_backend.clone(),
                r.spd_backend.clone(),
                cell_f(r.penalty_weight),
                r.terms.word().into(),
                r.ordering.clone().unwrap_or_default(),
                cell_u(r.threads),
                r.repetitions.to_string(),
                f(|t| t.setup),
            ];
            cells.extend(phase_cells(t));
            cells.extend([
                f(|t| t.precompute()),
                cell_f(r.precompute_median_s),
                cell_f(r.total_median_s),
                cell_u(r.nnz_normal),
                cell_u(r.nnz_factor),
                cell_f(r.constraint_residual_relative),
                r.status.clone(),
            ]);
            cells
        })
        .collect();
    ctx.write_csv(&dir.join("breakdown.csv"), &header, &csv_rows)?;
    ctx.write_json(&dir.join("breakdown.json"), &rows)
}

/// One figure per SPD back end, bars = mesh × method: (back end, stem).
fn figures(
    dir: &Path,
    rows: &[Row],
    notes: &mut Vec<String>,
) -> Result<Vec<(&'static str, String)>, AnyError> {
    let mut figures = Vec::new();
    for spd_name in spd_backends() {
        let categories: Vec<Category> = rows
            .iter()
            .filter(|r| r.spd_backend == spd_name && r.terms == Terms::Own)
            .filter_map(|r| {
                r.timings.as_ref().map(|t| Category {
                    name: format!("{} / {}", r.mesh, r.method),
                    values: phase_values(t),
                })
            })
            .collect();
        if categories.is_empty() {
            notes.push(format!("no bar could be drawn for {spd_name}"));
            continue;
        }
        let n_bars = categories.len() as u32;
        let spec = StackedBars {
            title: format!("Set-up and precompute by phase — SPD back end {spd_name}"),
            value_label: "time (s), median run".into(),
            segments: PHASES.iter().map(|s| s.to_string()).collect(),
            categories,
            total_suffix: Some(" s".into()),
            legend: LegendPosition::Auto,
        };
        let stem = format!("breakdown_{spd_name}");
        let out = Output::new(dir.join(&stem)).with_size(960, 200 + 44 * n_bars);
        note_drawn(&plot::stacked_bars(&spec, &out)?, notes);
        figures.push((spd_name, stem));
    }
    Ok(figures)
}

/// A total cell: the time, flagged when the solve failed.
fn total_cell(r: Option<&Row>) -> String {
    match r {
        Some(r) if r.total_median_s.is_some() => {
            let mut c = fmt_time(r.total_median_s.unwrap_or(f64::NAN));
            if r.status != "ok" {
                c.push_str(" (solve failed)");
            }
            c
        }
        Some(r) => r.status.clone(),
        None => "—".into(),
    }
}

/// The table's row of one mesh and back end, and its ratio.
fn ratio_row(
    case_label: String,
    spd_name: &str,
    h: Option<&Row>,
    s: Option<&Row>,
) -> (Vec<String>, Option<f64>) {
    let dash = || "—".to_string();
    let pre = |r: Option<&Row>| {
        r.and_then(|r| r.precompute_median_s)
            .map_or_else(dash, fmt_time)
    };
    let nnz = |r: Option<&Row>| {
        r.and_then(|r| r.nnz_factor)
            .map_or_else(dash, |v| format!("{:.2}M", v as f64 / 1e6))
    };
    let res = |r: Option<&Row>| {
        r.and_then(|r| r.constraint_residual_relative)
            .map_or_else(dash, |v| format!("{v:.1e}"))
    };
    let ratio = match (
        h.and_then(|r| r.total_median_s),
        s.and_then(|r| r.total_median_s),
    ) {
        (Some(a), Some(b)) if b > 0.0 => Some(a / b),
        _ => None,
    };
    let cells = vec![
        case_label,
        spd_name.to_string(),
        held_cell(h),
        pre(h),
        total_cell(h),
        pre(s),
        total_cell(s),
        ratio.map_or_else(dash, |r| format!("{r:.2}")),
        format!("{} / {}", nnz(h), nnz(s)),
        format!("{} / {}", res(h), res(s)),
    ];
    (cells, ratio)
}

/// The ordering and threads of a row (`own (amd), 1 thread`).
fn held_cell(r: Option<&Row>) -> String {
    match r {
        Some(r) => format!(
            "{}, {} thread{}",
            r.ordering.as_deref().unwrap_or("—"),
            r.threads.map_or("—".into(), |t| t.to_string()),
            if r.threads == Some(1) { "" } else { "s" }
        ),
        None => "—".into(),
    }
}

/// Seconds of one phase of a row's median run.
fn phase_cell(r: Option<&Row>, phase: fn(&Timings) -> f64) -> String {
    r.and_then(|r| r.timings.as_ref())
        .map_or_else(|| "—".into(), |t| fmt_time(phase(t)))
}

/// The equal-terms table: per mesh and back end, the hard + soft
/// precompute on the back end's own ordering and threads next to one AMD
/// permutation and one thread.
fn equal_terms_table(meshes: &[MeshCase], rows: &[Row]) -> Vec<Vec<String>> {
    let find = |mesh: &str, spd_name: &str, terms: Terms| {
        rows.iter().find(|r| {
            r.mesh == mesh
                && r.spd_backend == spd_name
                && r.method == label(Method::NullSpaceQr)
                && r.terms == terms
        })
    };
    let nnz = |r: Option<&Row>| {
        r.and_then(|r| r.nnz_factor)
            .map_or_else(|| "—".into(), |v| format!("{:.2}M", v as f64 / 1e6))
    };
    let pre = |r: Option<&Row>| {
        r.and_then(|r| r.precompute_median_s)
            .map_or_else(|| "—".into(), fmt_time)
    };
    let mut table = Vec::new();
    for case in meshes {
        for spd_name in spd_backends() {
            let own = find(&case.name, spd_name, Terms::Own);
            let held = find(&case.name, spd_name, Terms::AmdOneThread);
            if own.is_none() && held.is_none() {
                continue;
            }
            table.push(vec![
                format!("{} ({})", case.name, case.mesh.n_vertices()),
                spd_name.to_string(),
                held_cell(own),
                nnz(own),
                phase_cell(own, |t| t.symbolic),
                phase_cell(own, |t| t.numeric),
                pre(own),
                held_cell(held),
                nnz(held),
                phase_cell(held, |t| t.ordering),
                phase_cell(held, |t| t.symbolic),
                phase_cell(held, |t| t.numeric),
                pre(held),
            ]);
        }
    }
    table
}

/// Hard + soft over soft only, per mesh and back end: table rows, ratios.
fn ratio_table(meshes: &[MeshCase], rows: &[Row]) -> (Vec<Vec<String>>, Vec<f64>) {
    let find = |mesh: &str, spd_name: &str, m: Method| {
        rows.iter().find(|r| {
            r.mesh == mesh
                && r.spd_backend == spd_name
                && r.method == label(m)
                && r.terms == Terms::Own
        })
    };
    let mut table = Vec::new();
    let mut ratios = Vec::new();
    for case in meshes {
        for spd_name in spd_backends() {
            let (cells, ratio) = ratio_row(
                format!("{} ({})", case.name, case.mesh.n_vertices()),
                spd_name,
                find(&case.name, spd_name, Method::NullSpaceQr),
                find(&case.name, spd_name, Method::Penalty),
            );
            table.push(cells);
            ratios.extend(ratio);
        }
    }
    (table, ratios)
}

/// The range and median of the ratios, as "a to b (median c)".
fn ratio_range(ratios: &[f64]) -> (f64, f64, f64) {
    (
        ratios.iter().copied().fold(f64::INFINITY, f64::min),
        ratios.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        median(ratios),
    )
}

/// The section, from the tables, figures and notes.
fn section(
    ctx: &Context,
    (table, equal): (&[Vec<String>], &[Vec<String>]),
    ratios: &[f64],
    figures: &[(&str, String)],
    notes: &[String],
) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Set-up and precompute time of the paper's scene (`FixedAndHandle::paper_default`: lowest 20 % of the vertices fixed, a 2 % handle; cotangent Laplacian) \
         with the positions **hard** (null-space QR, QR back end `{}` = the library default) against **soft only** \
         (penalty: every hard row a soft row of relative weight w = {PENALTY_RELATIVE_WEIGHT}, i.e. w × the largest column norm of A, the paper's conversion), on every SPD back end of this build ({}). \
         Each entry is the median of up to {} repetitions from scratch, hard and soft run alternately so that the ratio is measured side by side; \
         the bars show the run with the median total.\n",
        FormulationChoice::new(Method::NullSpaceQr).qr.name(),
        spd_backends().join(", "),
        if ctx.quick { 1 } else { 5 }
    );
    s.push_str(&ctx.regenerate(NAME));
    let _ = writeln!(
        s,
        "**Table.** Precompute (QR + preparation + normal matrix + symbolic + numeric) and set-up + precompute per mesh and back end; ratio = hard + soft over soft only (set-up included, as in the paper's Fig. 7). \
         A ratio near 1 is the paper's claim (\"as fast as the method with only soft constraints\"); below 1, the hard constraints make the problem smaller (fixed vertices leave the system). \
         The last columns give the factor's nnz and the max residual of the constraints after one solve, relative to the bounding-box diagonal (hard: rounding; soft: the penalty's approximation).\n"
    );
    let header = [
        "mesh (vertices)",
        "SPD back end",
        "ordering, threads",
        "hard + soft precompute",
        "hard + soft total",
        "soft only precompute",
        "soft only total",
        "ratio (total)",
        "nnz(L) hard / soft",
        "residual hard / soft",
    ];
    s.push_str(&markdown_table(&header, table));
    if !ratios.is_empty() {
        let (lo, hi, med) = ratio_range(ratios);
        let _ = writeln!(
            s,
            "\nOver all meshes and back ends the ratio hard + soft / soft only ranges from {lo:.2} to {hi:.2} (median {med:.2})."
        );
    }
    let _ = writeln!(
        s,
        "\n**Table (equal terms).** Hard + soft on each back end's own ordering and threads, next to one AMD permutation of the matrix factored \
         (faer's AMD, computed once per precompute and given to the back end: faer's custom ordering, CHOLMOD's `cholmod_l_analyze_p`, MUMPS's `PERM_IN`, nalgebra's permuted matrix) and one thread \
         (docs/equal-terms.md). `ordering` is the time computing the held permutation, apart from the back end's symbolic phase; with the back end's own ordering it is inside `symbolic`. \
         nnz(L) counts the entries each back end stores (faer-supernodal and MUMPS include supernodal padding; faer-simplicial, nalgebra and CHOLMOD count the exact fill, equal under one permutation).\n"
    );
    let equal_header = [
        "mesh (vertices)",
        "SPD back end",
        "own: ordering, threads",
        "nnz(L)",
        "symbolic",
        "numeric",
        "precompute",
        "held: ordering, threads",
        "nnz(L)",
        "ordering",
        "symbolic",
        "numeric",
        "precompute",
    ];
    s.push_str(&markdown_table(&equal_header, equal));
    for (spd_name, stem) in figures {
        let _ = writeln!(
            s,
            "\n**Figure ({spd_name}).** One bar per mesh and method, stacked by phase (set-up first); the number at the end is the total. \
             Compare the two bars of a mesh: the paper's Fig. 7 (totals) and Fig. 8 (phases) in one.\n\n{}",
            link(NAME, stem)
        );
    }
    s.push_str(&ctx.closing(
        notes,
        &format!("Data: [`{NAME}/breakdown.csv`]({NAME}/breakdown.csv), [`{NAME}/breakdown.json`]({NAME}/breakdown.json)."),
    ));
    s
}

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let dir = ctx.dir(NAME)?;
    let meshes = ctx.evaluation_meshes()?;
    let mut rows: Vec<Row> = Vec::new();
    let mut notes: Vec<String> = Vec::new();
    let bar = ctx.bar(meshes.len(), NAME);
    for case in &meshes {
        bar.set_message(format!("{NAME}: {}", case.name));
        measure_case(ctx, case, &mut rows, &mut notes)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    write_data(ctx, &dir, &rows)?;
    let figures = figures(&dir, &rows, &mut notes)?;
    let (table, ratios) = ratio_table(&meshes, &rows);
    let equal = equal_terms_table(&meshes, &rows);
    ctx.write_section(
        NAME,
        &section(ctx, (&table, &equal), &ratios, &figures, &notes),
    )?;
    let headline = if ratios.is_empty() {
        "no ratio could be measured".to_string()
    } else {
        let (lo, hi, med) = ratio_range(&ratios);
        format!(
            "hard+soft / soft-only set-up+precompute: median ratio {med:.2} (range {lo:.2}–{hi:.2}) over {} mesh × back-end pairs",
            ratios.len()
        )
    };
    Ok(Summary::measured(headline))
}
