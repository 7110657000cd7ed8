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
use std::time::Instant;

use std::sync::Arc;

use lse_deform::backend::qr::{QrBackend, QrKind};
use lse_deform::backend::spd::{SpdBackend, SpdKind};
use lse_deform::constraints::ConstraintSet;
use lse_deform::report::Timings;
use lse_deform::scene::FixedAndHandle;
use lse_deform::{Deformer, Formulation, LaplacianKind, Mesh, NullSpaceQr, Penalty, Report};
use serde::Serialize;

use crate::context::{Context, MeshCase, fmt_time, markdown_table, median};
use crate::plot::{self, Category, Drawn, LegendPosition, Orientation, Output, StackedBars};
use crate::{AnyError, Summary};

// ---------------------------------------------------------------------------
// Shared helpers of the timing experiments.

/// The phases of the paper's Fig. 8 (plus set-up), bottom of a stack first.
/// Every stacked-bar figure of the timing experiments passes this list, so a
/// phase keeps its colour across figures.
pub(crate) const PHASES: [&str; 6] = [
    "set-up",
    "QR",
    "preparation",
    "normal matrix",
    "symbolic",
    "numeric",
];

/// The values of [`PHASES`] of a report's timings (seconds).
pub(crate) fn phase_values(t: &Timings) -> Vec<f64> {
    vec![
        t.setup,
        t.qr,
        t.preparation,
        t.normal_matrix,
        t.symbolic,
        t.numeric,
    ]
}

/// [`phase_values`] without the set-up (the precompute phases only; zero in
/// the set-up slot so that colours still match [`PHASES`]).
pub(crate) fn precompute_phase_values(t: &Timings) -> Vec<f64> {
    let mut v = phase_values(t);
    v[0] = 0.0;
    v
}

/// The SPD back ends of this build (CHOLMOD only with `--features
/// suitesparse`), in the library's order.
pub(crate) fn spd_backends() -> Vec<&'static str> {
    SpdKind::available()
        .into_iter()
        .map(SpdKind::name)
        .collect()
}

/// The SPD back end called `name` (one of [`spd_backends`]).
pub(crate) fn spd_backend(name: &str) -> Result<Arc<dyn SpdBackend>, AnyError> {
    Ok(name.parse::<SpdKind>()?.backend()?)
}

/// The QR back ends of this build (SPQR only with `--features suitesparse`).
pub(crate) fn qr_backends() -> Vec<&'static str> {
    QrKind::available().into_iter().map(QrKind::name).collect()
}

/// The QR back end called `name` (one of [`qr_backends`]).
pub(crate) fn qr_backend(name: &str) -> Result<Arc<dyn QrBackend>, AnyError> {
    Ok(name.parse::<QrKind>()?.backend()?)
}

/// The null-space method with the library's default QR back end and the
/// SPD back end `spd` (the default QR is whatever `NullSpaceQr::default()`
/// uses, so a change of the default is picked up).
pub(crate) fn null_space_with_spd(spd_name: &str) -> Result<NullSpaceQr, AnyError> {
    Ok(NullSpaceQr {
        spd: spd_backend(spd_name)?,
        ..NullSpaceQr::default()
    })
}

/// The penalty weight of the timing experiments: relative, so that a
/// former hard row outweighs the heaviest Laplacian column by this factor on
/// every mesh (the library's penalty weight is relative to `A`'s largest
/// column norm, see `lse_deform::formulation::Penalty`).
pub(crate) const PENALTY_RELATIVE_WEIGHT: f64 = 100.0;

/// The index of the run with the median total of `totals` (the lower
/// median for an even count).
pub(crate) fn median_index(totals: &[f64]) -> usize {
    let mut order: Vec<usize> = (0..totals.len()).collect();
    order.sort_by(|&a, &b| totals[a].total_cmp(&totals[b]));
    order[(order.len().saturating_sub(1)) / 2]
}

/// Set-up (a fresh [`Deformer`]) and precompute of `formulation`; the
/// report carries both times.
pub(crate) fn setup_and_precompute(
    mesh: &Mesh,
    constraints: &ConstraintSet,
    formulation: &dyn Formulation,
) -> Result<Deformer, AnyError> {
    let mut deformer = Deformer::new(mesh.clone(), LaplacianKind::Cotangent, constraints.clone())?;
    deformer.precompute(formulation)?;
    Ok(deformer)
}

/// Prints the notes of a drawn figure (skipped points) on stderr.
pub(crate) fn note_drawn(drawn: &Drawn, notes: &mut Vec<String>) {
    for n in &drawn.notes {
        eprintln!("  plot note: {n}");
        notes.push(format!("plot: {n}"));
    }
}

/// The file name of `path` (for README links relative to `results/`).
pub(crate) fn link(dir: &str, stem: &str) -> String {
    format!("[![{stem}]({dir}/{stem}.png)]({dir}/{stem}.svg)")
}

/// Shortens an error message for a table cell.
pub(crate) fn short_error(e: &str) -> String {
    let one_line = e.replace('\n', " ").replace('|', "/");
    if one_line.chars().count() > 110 {
        format!("{}…", one_line.chars().take(110).collect::<String>())
    } else {
        one_line
    }
}

// ---------------------------------------------------------------------------
// The experiment.

pub const NAME: &str = "precompute-breakdown";

/// The two formulations compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Method {
    /// Null-space QR: positions hard, Laplacian soft.
    HardSoft,
    /// Penalty: everything soft.
    SoftOnly,
}

impl Method {
    fn label(self) -> &'static str {
        match self {
            Method::HardSoft => "hard + soft",
            Method::SoftOnly => "soft only",
        }
    }
}

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

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let dir = ctx.dir(NAME)?;
    let meshes = ctx.evaluation_meshes()?;
    let backends = spd_backends();
    let default_qr = NullSpaceQr::default().qr.name().to_string();
    let reps_wanted = if ctx.quick { 1 } else { 5 };
    let mut rows: Vec<Row> = Vec::new();
    let mut notes: Vec<String> = Vec::new();
    let bar = ctx.bar(meshes.len() * backends.len(), NAME);
    for case in &meshes {
        let MeshCase { name, mesh, .. } = case;
        let scene = FixedAndHandle::paper_default(mesh);
        let constraints = scene.constraints(mesh)?;
        // One set-up to find the penalty weight (relative to L).
        let probe = Deformer::new(mesh.clone(), LaplacianKind::Cotangent, constraints.clone())?;
        let weight = PENALTY_RELATIVE_WEIGHT;
        drop(probe);
        for &spd_name in &backends {
            bar.set_message(format!("{NAME}: {name} / {spd_name}"));
            let hard: Box<dyn Formulation> = Box::new(null_space_with_spd(spd_name)?);
            let soft: Box<dyn Formulation> =
                Box::new(Penalty::with_backend(weight, spd_backend(spd_name)?));
            let methods = [(Method::HardSoft, hard), (Method::SoftOnly, soft)];
            let mut reports: Vec<Vec<Report>> = vec![Vec::new(); 2];
            let mut errors: Vec<Option<String>> = vec![None; 2];
            let mut residuals: Vec<Option<f64>> = vec![None; 2];
            let mut reps = reps_wanted;
            let mut rep = 0;
            while rep < reps {
                for (i, (_, f)) in methods.iter().enumerate() {
                    if errors[i].is_some() {
                        continue;
                    }
                    let t = Instant::now();
                    match setup_and_precompute(mesh, &constraints, f.as_ref()) {
                        Ok(mut d) => {
                            reports[i].push(d.report().clone());
                            if rep == 0 {
                                // One solve: the constraints really hold (or,
                                // for penalty, how far off they are).
                                match d.solve_matrix() {
                                    Ok(_) => {
                                        residuals[i] =
                                            Some(d.report().max_constraint_residual_relative)
                                    }
                                    Err(e) => errors[i] = Some(format!("solve failed: {e}")),
                                }
                            }
                        }
                        Err(e) => errors[i] = Some(e.to_string()),
                    }
                    // Slow configurations get fewer repetitions.
                    if rep == 0 && t.elapsed().as_secs_f64() > 3.0 {
                        reps = reps.min(3);
                    }
                }
                rep += 1;
            }
            for (i, (method, f)) in methods.iter().enumerate() {
                let runs = &reports[i];
                let totals: Vec<f64> = runs
                    .iter()
                    .map(|r| r.timings_s.setup + r.timings_s.precompute())
                    .collect();
                let pre: Vec<f64> = runs.iter().map(|r| r.timings_s.precompute()).collect();
                let chosen = (!runs.is_empty()).then(|| &runs[median_index(&totals)]);
                let status = match &errors[i] {
                    Some(e) => {
                        notes.push(format!("{name} / {} / {spd_name}: {e}", method.label()));
                        format!("failed: {}", short_error(e))
                    }
                    None => "ok".into(),
                };
                rows.push(Row {
                    mesh: name.clone(),
                    vertices: mesh.n_vertices(),
                    method: method.label(),
                    formulation: f.name(),
                    qr_backend: if *method == Method::HardSoft {
                        default_qr.clone()
                    } else {
                        "—".into()
                    },
                    spd_backend: spd_name.into(),
                    penalty_weight: (*method == Method::SoftOnly).then_some(weight),
                    repetitions: runs.len(),
                    timings: chosen.map(|r| r.timings_s.clone()),
                    total_median_s: (!totals.is_empty()).then(|| median(&totals)),
                    precompute_median_s: (!pre.is_empty()).then(|| median(&pre)),
                    nnz_normal: chosen.and_then(|r| r.nnz.normal),
                    nnz_factor: chosen.and_then(|r| r.nnz.factor),
                    constraint_residual_relative: residuals[i],
                    status,
                });
            }
            bar.inc(1);
        }
    }
    bar.finish_and_clear();

    // Data.
    let header = [
        "mesh",
        "vertices",
        "method",
        "formulation",
        "qr_backend",
        "spd_backend",
        "penalty_weight",
        "repetitions",
        "setup_s",
        "qr_s",
        "preparation_s",
        "normal_matrix_s",
        "symbolic_s",
        "numeric_s",
        "precompute_s",
        "precompute_median_s",
        "total_median_s",
        "nnz_normal",
        "nnz_factor",
        "constraint_residual_relative",
        "status",
    ];
    let opt = |v: Option<f64>| v.map(|x| format!("{x:.6e}")).unwrap_or_default();
    let csv_rows: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            let t = r.timings.as_ref();
            let f = |g: fn(&Timings) -> f64| opt(t.map(g));
            vec![
                r.mesh.clone(),
                r.vertices.to_string(),
                r.method.into(),
                r.formulation.clone(),
                r.qr_backend.clone(),
                r.spd_backend.clone(),
                opt(r.penalty_weight),
                r.repetitions.to_string(),
                f(|t| t.setup),
                f(|t| t.qr),
                f(|t| t.preparation),
                f(|t| t.normal_matrix),
                f(|t| t.symbolic),
                f(|t| t.numeric),
                f(|t| t.precompute()),
                opt(r.precompute_median_s),
                opt(r.total_median_s),
                r.nnz_normal.map(|v| v.to_string()).unwrap_or_default(),
                r.nnz_factor.map(|v| v.to_string()).unwrap_or_default(),
                opt(r.constraint_residual_relative),
                r.status.clone(),
            ]
        })
        .collect();
    ctx.write_csv(&dir.join("breakdown.csv"), &header, &csv_rows)?;
    ctx.write_json(&dir.join("breakdown.json"), &rows)?;

    // Figures: one per SPD back end, bars = mesh × method.
    let mut figures = Vec::new();
    for &spd_name in &backends {
        let categories: Vec<Category> = rows
            .iter()
            .filter(|r| r.spd_backend == spd_name)
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
            orientation: Orientation::Horizontal,
            total_suffix: Some(" s".into()),
            legend: LegendPosition::Auto,
        };
        let stem = format!("breakdown_{spd_name}");
        let out = Output::new(dir.join(&stem)).with_size(960, 200 + 44 * n_bars);
        let drawn = plot::stacked_bars(&spec, &out)?;
        note_drawn(&drawn, &mut notes);
        figures.push((spd_name, stem));
    }

    // Ratio table: hard + soft over soft only, per mesh and back end.
    let find = |mesh: &str, spd_name: &str, m: Method| {
        rows.iter()
            .find(|r| r.mesh == mesh && r.spd_backend == spd_name && r.method == m.label())
    };
    let mut ratio_rows = Vec::new();
    let mut ratios = Vec::new();
    for case in &meshes {
        for &spd_name in &backends {
            let h = find(&case.name, spd_name, Method::HardSoft);
            let s = find(&case.name, spd_name, Method::SoftOnly);
            let cell = |r: Option<&Row>| match r {
                Some(r) if r.total_median_s.is_some() => {
                    let mut c = fmt_time(r.total_median_s.unwrap_or(f64::NAN));
                    if r.status != "ok" {
                        c.push_str(" (solve failed)");
                    }
                    c
                }
                Some(r) => r.status.clone(),
                None => "—".into(),
            };
            let pre = |r: Option<&Row>| {
                r.and_then(|r| r.precompute_median_s)
                    .map(fmt_time)
                    .unwrap_or_else(|| "—".into())
            };
            let ratio = match (
                h.and_then(|r| r.total_median_s),
                s.and_then(|r| r.total_median_s),
            ) {
                (Some(a), Some(b)) if b > 0.0 => {
                    ratios.push(a / b);
                    format!("{:.2}", a / b)
                }
                _ => "—".into(),
            };
            let nnz = |r: Option<&Row>| {
                r.and_then(|r| r.nnz_factor)
                    .map(|v| format!("{:.2}M", v as f64 / 1e6))
                    .unwrap_or_else(|| "—".into())
            };
            let res = |r: Option<&Row>| {
                r.and_then(|r| r.constraint_residual_relative)
                    .map(|v| format!("{v:.1e}"))
                    .unwrap_or_else(|| "—".into())
            };
            ratio_rows.push(vec![
                format!("{} ({})", case.name, case.mesh.n_vertices()),
                spd_name.to_string(),
                pre(h),
                cell(h),
                pre(s),
                cell(s),
                ratio,
                format!("{} / {}", nnz(h), nnz(s)),
                format!("{} / {}", res(h), res(s)),
            ]);
        }
    }

    // Section.
    let command = format!(
        "cargo run --release --features suitesparse --bin experiments -- {NAME}{}",
        if ctx.has_user_meshes() {
            " --mesh-dir ../shared/meshes"
        } else {
            ""
        }
    );
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Set-up and precompute time of the paper's scene (`FixedAndHandle::paper_default`: lowest 20 % of the vertices fixed, a 2 % handle; cotangent Laplacian) \
         with the positions **hard** (null-space QR, QR back end `{default_qr}` = the library default) against **soft only** \
         (penalty: every hard row a soft row of relative weight w = {PENALTY_RELATIVE_WEIGHT}, i.e. w × the largest column norm of A, the paper's conversion), on every SPD back end of this build ({}). \
         Each entry is the median of up to {reps_wanted} repetitions from scratch, hard and soft run alternately so that the ratio is measured side by side; \
         the bars show the run with the median total.\n",
        backends.join(", ")
    );
    let _ = writeln!(
        s,
        "Regenerate this section alone:\n\n```sh\n{command}\n```\n"
    );
    let _ = writeln!(
        s,
        "**Table.** Precompute (QR + preparation + normal matrix + symbolic + numeric) and set-up + precompute per mesh and back end; ratio = hard + soft over soft only (set-up included, as in the paper's Fig. 7). \
         A ratio near 1 is the paper's claim (\"as fast as the method with only soft constraints\"); below 1, the hard constraints make the problem smaller (fixed vertices leave the system). \
         The last columns give the factor's nnz and the max residual of the constraints after one solve, relative to the bounding-box diagonal (hard: rounding; soft: the penalty's approximation).\n"
    );
    s.push_str(&markdown_table(
        &[
            "mesh (vertices)",
            "SPD back end",
            "hard + soft precompute",
            "hard + soft total",
            "soft only precompute",
            "soft only total",
            "ratio (total)",
            "nnz(L) hard / soft",
            "residual hard / soft",
        ],
        &ratio_rows,
    ));
    if !ratios.is_empty() {
        let _ = writeln!(
            s,
            "\nOver all meshes and back ends the ratio hard + soft / soft only ranges from {:.2} to {:.2} (median {:.2}).",
            ratios.iter().copied().fold(f64::INFINITY, f64::min),
            ratios.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            median(&ratios)
        );
    }
    for (spd_name, stem) in &figures {
        let _ = writeln!(
            s,
            "\n**Figure ({spd_name}).** One bar per mesh and method, stacked by phase (set-up first); the number at the end is the total. \
             Compare the two bars of a mesh: the paper's Fig. 7 (totals) and Fig. 8 (phases) in one.\n\n{}",
            link(NAME, stem)
        );
    }
    if !notes.is_empty() {
        let _ = writeln!(s, "\n**What did not work / notes.**\n");
        for n in &notes {
            let _ = writeln!(s, "- {n}");
        }
    }
    let _ = writeln!(
        s,
        "\nData: [`{NAME}/breakdown.csv`]({NAME}/breakdown.csv), [`{NAME}/breakdown.json`]({NAME}/breakdown.json)."
    );
    let _ = writeln!(s, "\n_{}_", ctx.machine.one_line());
    ctx.write_section(NAME, &s)?;

    let headline = if ratios.is_empty() {
        "no ratio could be measured".to_string()
    } else {
        format!(
            "hard+soft / soft-only set-up+precompute: median ratio {:.2} (range {:.2}–{:.2}) over {} mesh × back-end pairs",
            median(&ratios),
            ratios.iter().copied().fold(f64::INFINITY, f64::min),
            ratios.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            ratios.len()
        )
    };
    Ok(Summary { headline })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_index_picks_the_middle_run() {
        assert_eq!(median_index(&[3.0, 1.0, 2.0]), 2);
        assert_eq!(median_index(&[5.0]), 0);
        // Lower median for an even count.
        assert_eq!(median_index(&[4.0, 1.0, 3.0, 2.0]), 3);
    }

    #[test]
    fn backends_of_the_build_are_listed() {
        let spds = spd_backends();
        assert!(spds.contains(&"faer-auto"));
        assert_eq!(spds.contains(&"cholmod"), cfg!(feature = "suitesparse"));
        let qrs = qr_backends();
        assert!(qrs.contains(&"dense-householder"));
        assert_eq!(qrs.contains(&"spqr"), cfg!(feature = "suitesparse"));
    }

    #[test]
    fn phases_sum_to_setup_plus_precompute() {
        let t = Timings {
            setup: 1.0,
            qr: 2.0,
            preparation: 3.0,
            normal_matrix: 4.0,
            symbolic: 5.0,
            numeric: 6.0,
            solve: 7.0,
            refine: 0.5,
            diagnostics: 8.0,
        };
        let v = phase_values(&t);
        assert_eq!(v.len(), PHASES.len());
        assert_eq!(v.iter().sum::<f64>(), t.setup + t.precompute());
        assert_eq!(precompute_phase_values(&t)[0], 0.0);
    }
}
