//! `drag`: an interactive drag — the handle of the paper's scene moved
//! along a smooth closed path for 300 frames; each frame sets the handle
//! constraints' targets ([`Deformer::set_target`]) and solves without
//! refactoring. Per method and back end: per-frame latency p50 / p99 of the
//! solve phase and of the whole frame (targets + solve + the library's
//! per-solve diagnostics), and the frames per second they imply.

use std::f64::consts::PI;
use std::fmt::Write as _;
use std::time::Instant;

use faer::Mat;
use lse_deform::scene::FixedAndHandle;
use lse_deform::{Deformer, Elimination, Formulation, Kkt, LaplacianKind, NullSpaceQr, Penalty};
use serde::Serialize;

use crate::breakdown::{
    PENALTY_RELATIVE_WEIGHT, link, note_drawn, qr_backend, qr_backends, short_error, spd_backend,
    spd_backends,
};
use crate::context::{Context, fmt_time, markdown_table, median, percentile};
use crate::plot::{
    self, Axis, Category, LegendPosition, LineChart, Orientation, Output, Series, StackedBars,
};
use crate::{AnyError, Summary};

pub const NAME: &str = "drag";

/// A method and back-end configuration of the drag.
struct Config {
    /// Label for tables and figures.
    label: String,
    method: &'static str,
    qr: Option<String>,
    spd: String,
    formulation: Box<dyn Formulation>,
}

/// The configurations, the library default (null-space QR with the default
/// QR and SPD back ends) first: null-space QR with the default QR back end
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
    let default = NullSpaceQr::default();
    let default_qr = default.qr.name().to_string();
    let default_spd = default.spd.name().to_string();
    let mut spds: Vec<&str> = vec![default_spd.as_str()];
    spds.extend(spd_backends().into_iter().filter(|&s| {
        s != default_spd
            && s != "faer-supernodal"
            && (slow_backends || !matches!(s, "faer-simplicial" | "nalgebra"))
    }));
    let mut out = Vec::new();
    for &s in &spds {
        out.push(Config {
            label: format!("null-space {default_qr} + {s}"),
            method: "nullspace-qr",
            qr: Some(default_qr.clone()),
            spd: s.into(),
            formulation: Box::new(NullSpaceQr {
                spd: spd_backend(s)?,
                ..default.clone()
            }),
        });
    }
    for q in qr_backends() {
        if q == default_qr {
            continue;
        }
        out.push(Config {
            label: format!("null-space {q} + {default_spd}"),
            method: "nullspace-qr",
            qr: Some(q.into()),
            spd: default_spd.clone(),
            formulation: Box::new(NullSpaceQr {
                qr: qr_backend(q)?,
                ..default.clone()
            }),
        });
    }
    out.push(Config {
        label: format!("penalty + {default_spd}"),
        method: "penalty",
        qr: None,
        spd: default_spd.clone(),
        formulation: Box::new(Penalty::with_backend(weight, spd_backend(&default_spd)?)),
    });
    out.push(Config {
        label: "KKT LDLᵀ faer-auto".into(),
        method: "kkt",
        qr: None,
        spd: "faer-auto".into(),
        formulation: Box::new(Kkt::default()),
    });
    out.push(Config {
        label: format!("elimination + {default_spd}"),
        method: "eliminate",
        qr: None,
        spd: default_spd.clone(),
        formulation: Box::new(Elimination::new(spd_backend(&default_spd)?)),
    });
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

/// Summary of one configuration's drag.
#[derive(Debug, Clone, Serialize)]
struct Row {
    label: String,
    method: &'static str,
    qr_backend: Option<String>,
    spd_backend: String,
    precompute_s: Option<f64>,
    frames: usize,
    solve_p50_s: Option<f64>,
    solve_p99_s: Option<f64>,
    solve_max_s: Option<f64>,
    frame_p50_s: Option<f64>,
    frame_p99_s: Option<f64>,
    set_target_p50_s: Option<f64>,
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

/// Per-frame timings of one configuration.
#[derive(Debug, Clone, Default)]
struct Frames {
    set_target: Vec<f64>,
    solve: Vec<f64>,
    diagnostics: Vec<f64>,
    frame: Vec<f64>,
    max_residual: f64,
    middle: Option<Mat<f64>>,
}

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let dir = ctx.dir(NAME)?;
    let case = ctx.fallback_mesh("bunny-35k-stanford.obj", 35_000, 10_000)?;
    let frames = if ctx.quick { 60 } else { 300 };
    let mesh = &case.mesh;
    let scene = FixedAndHandle::paper_default(mesh);
    let (fixed, handle) = scene.regions(mesh)?;
    let constraints = scene.constraints(mesh)?;
    let amplitude = 0.15 * mesh.bbox_diagonal();
    let diag = mesh.bbox_diagonal();
    let original = mesh.positions().to_vec();
    let probe = Deformer::new(mesh.clone(), LaplacianKind::Cotangent, constraints.clone())?;
    let weight = PENALTY_RELATIVE_WEIGHT;
    drop(probe);
    let configs = configs(weight, ctx.has_user_meshes())?;

    // One deformer per configuration, all precomputed first; then the
    // frames run round-robin over the configurations (frame f of every
    // configuration before frame f + 1 of any), so that the load of this
    // shared machine falls on all of them alike.
    let mut notes: Vec<String> = Vec::new();
    let mut recs: Vec<Frames> = vec![Frames::default(); configs.len()];
    let mut errors: Vec<Option<String>> = vec![None; configs.len()];
    let mut precomputes: Vec<Option<f64>> = vec![None; configs.len()];
    let mut nnz_factor: Vec<Option<usize>> = vec![None; configs.len()];
    let mut deformers: Vec<Option<Deformer>> = Vec::new();
    let bar = ctx.bar(configs.len(), &format!("{NAME}: precompute"));
    for (i, c) in configs.iter().enumerate() {
        bar.set_message(format!("{NAME}: precompute {}", c.label));
        let outcome = (|| -> Result<Deformer, AnyError> {
            let mut d = Deformer::new(mesh.clone(), LaplacianKind::Cotangent, constraints.clone())?;
            d.precompute(c.formulation.as_ref())?;
            precomputes[i] = Some(d.report().timings_s.precompute());
            nnz_factor[i] = d.report().nnz.factor;
            // Warm-up solve (not counted): caches, and penalty's one-off
            // accuracy check.
            d.solve_matrix()?;
            Ok(d)
        })();
        match outcome {
            Ok(d) => deformers.push(Some(d)),
            Err(e) => {
                errors[i] = Some(e.to_string());
                deformers.push(None);
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let bar = ctx.bar(frames, &format!("{NAME}: frames"));
    for f in 0..frames {
        let t = (f + 1) as f64 / frames as f64;
        let d = path(t, scene.axis, amplitude);
        for (i, slot) in deformers.iter_mut().enumerate() {
            let Some(deformer) = slot else { continue };
            let rec = &mut recs[i];
            let outcome = (|| -> Result<(), AnyError> {
                let start = Instant::now();
                for (j, &v) in handle.iter().enumerate() {
                    let p = original[v];
                    deformer
                        .set_target(fixed.len() + j, [p[0] + d[0], p[1] + d[1], p[2] + d[2]])?;
                }
                let set = start.elapsed().as_secs_f64();
                let x = deformer.solve_matrix()?;
                let frame = start.elapsed().as_secs_f64();
                let r = deformer.report();
                rec.set_target.push(set);
                rec.solve.push(r.timings_s.solve);
                rec.diagnostics.push(r.timings_s.diagnostics);
                rec.frame.push(frame);
                rec.max_residual = rec.max_residual.max(r.max_constraint_residual_relative);
                if f + 1 == frames / 2 {
                    rec.middle = Some(x);
                }
                Ok(())
            })();
            if let Err(e) = outcome {
                errors[i] = Some(e.to_string());
                *slot = None;
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    drop(deformers);

    let mut rows: Vec<Row> = Vec::new();
    let mut reference: Option<Mat<f64>> = None;
    for (i, c) in configs.iter().enumerate() {
        let rec = &mut recs[i];
        let mut row = Row {
            label: c.label.clone(),
            method: c.method,
            qr_backend: c.qr.clone(),
            spd_backend: c.spd.clone(),
            precompute_s: precomputes[i],
            frames: rec.frame.len(),
            solve_p50_s: None,
            solve_p99_s: None,
            solve_max_s: None,
            frame_p50_s: None,
            frame_p99_s: None,
            set_target_p50_s: None,
            diagnostics_p50_s: None,
            fps_p50: None,
            fps_p99: None,
            solve_fps_p50: None,
            nnz_factor: nnz_factor[i],
            max_constraint_residual_relative: None,
            deviation_from_reference: None,
            status: "ok".into(),
        };
        match &errors[i] {
            None => {
                row.solve_p50_s = Some(median(&rec.solve));
                row.solve_p99_s = Some(percentile(&rec.solve, 0.99));
                row.solve_max_s = Some(percentile(&rec.solve, 1.0));
                row.frame_p50_s = Some(median(&rec.frame));
                row.frame_p99_s = Some(percentile(&rec.frame, 0.99));
                row.set_target_p50_s = Some(median(&rec.set_target));
                row.diagnostics_p50_s = Some(median(&rec.diagnostics));
                row.fps_p50 = row.frame_p50_s.map(|t| 1.0 / t);
                row.fps_p99 = row.frame_p99_s.map(|t| 1.0 / t);
                row.solve_fps_p50 = row.solve_p50_s.map(|t| 1.0 / t);
                row.max_constraint_residual_relative = Some(rec.max_residual);
                if let Some(mid) = &rec.middle {
                    match &reference {
                        None => {
                            reference = Some(mid.clone());
                            row.deviation_from_reference = Some(0.0);
                        }
                        Some(r) => {
                            let mut worst = 0.0f64;
                            for i in 0..mid.nrows() {
                                let d2: f64 =
                                    (0..3).map(|k| (mid[(i, k)] - r[(i, k)]).powi(2)).sum();
                                worst = worst.max(d2.sqrt());
                            }
                            row.deviation_from_reference = Some(worst / diag);
                        }
                    }
                }
            }
            Some(e) => {
                notes.push(format!("{}: {e}", c.label));
                row.status = format!(
                    "failed after {} frames: {}",
                    rec.frame.len(),
                    short_error(e)
                );
            }
        }
        rec.middle = None;
        rows.push(row);
    }
    let all_frames = recs;

    // Data.
    let opt = |v: Option<f64>| v.map(|x| format!("{x:.6e}")).unwrap_or_default();
    let header = [
        "label",
        "method",
        "qr_backend",
        "spd_backend",
        "precompute_s",
        "frames",
        "solve_p50_s",
        "solve_p99_s",
        "solve_max_s",
        "frame_p50_s",
        "frame_p99_s",
        "set_target_p50_s",
        "diagnostics_p50_s",
        "fps_p50",
        "fps_p99",
        "solve_fps_p50",
        "nnz_factor",
        "max_constraint_residual_relative",
        "deviation_from_reference",
        "status",
    ];
    let csv_rows: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.label.clone(),
                r.method.into(),
                r.qr_backend.clone().unwrap_or_default(),
                r.spd_backend.clone(),
                opt(r.precompute_s),
                r.frames.to_string(),
                opt(r.solve_p50_s),
                opt(r.solve_p99_s),
                opt(r.solve_max_s),
                opt(r.frame_p50_s),
                opt(r.frame_p99_s),
                opt(r.set_target_p50_s),
                opt(r.diagnostics_p50_s),
                opt(r.fps_p50),
                opt(r.fps_p99),
                opt(r.solve_fps_p50),
                r.nnz_factor.map(|v| v.to_string()).unwrap_or_default(),
                opt(r.max_constraint_residual_relative),
                opt(r.deviation_from_reference),
                r.status.clone(),
            ]
        })
        .collect();
    ctx.write_csv(&dir.join("drag_summary.csv"), &header, &csv_rows)?;
    let mut frame_rows = Vec::new();
    for (r, rec) in rows.iter().zip(&all_frames) {
        for f in 0..rec.frame.len() {
            frame_rows.push(vec![
                r.label.clone(),
                (f + 1).to_string(),
                format!("{:.6e}", rec.set_target[f]),
                format!("{:.6e}", rec.solve[f]),
                format!("{:.6e}", rec.diagnostics[f]),
                format!("{:.6e}", rec.frame[f]),
            ]);
        }
    }
    ctx.write_csv(
        &dir.join("drag_frames.csv"),
        &[
            "label",
            "frame",
            "set_target_s",
            "solve_s",
            "diagnostics_s",
            "frame_s",
        ],
        &frame_rows,
    )?;
    ctx.write_json(
        &dir.join("drag_summary.json"),
        &serde_json::json!({
            "mesh": case.name,
            "source": case.source,
            "vertices": mesh.n_vertices(),
            "fixed": fixed.len(),
            "handle": handle.len(),
            "frames": frames,
            "penalty_weight": weight,
            "rows": rows,
        }),
    )?;

    // Figure: latency bars.
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
    if !categories.is_empty() {
        let n_bars = categories.len() as u32;
        let spec = StackedBars {
            title: format!(
                "Per-frame latency over {frames} frames of a drag — {} ({} vertices)",
                case.name,
                mesh.n_vertices()
            ),
            value_label: "milliseconds".into(),
            segments: vec![
                "solve phase, p50".into(),
                "rest of the frame (targets, diagnostics), p50".into(),
                "frame p99 − frame p50".into(),
            ],
            categories,
            orientation: Orientation::Horizontal,
            total_suffix: Some(" ms".into()),
            legend: LegendPosition::Auto,
        };
        let drawn = plot::stacked_bars(
            &spec,
            &Output::new(dir.join("latency")).with_size(1000, 200 + 34 * n_bars),
        )?;
        note_drawn(&drawn, &mut notes);
    }
    // Figure: latency per frame for the first configuration of each method.
    let mut series = Vec::new();
    for method in ["nullspace-qr", "penalty", "kkt", "eliminate"] {
        if let Some((r, rec)) = rows
            .iter()
            .zip(&all_frames)
            .find(|(r, rec)| r.method == method && !rec.frame.is_empty())
        {
            series.push(Series::new(
                r.label.clone(),
                rec.frame
                    .iter()
                    .enumerate()
                    .map(|(f, &t)| ((f + 1) as f64, t * 1e3))
                    .collect(),
            ));
        }
    }
    let mut have_frames_figure = false;
    if !series.is_empty() {
        let chart = LineChart {
            title: format!("Frame time along the drag — {}", case.name),
            x: Axis::linear("frame"),
            y: Axis::log10("frame time (ms): targets + solve + diagnostics"),
            series,
            reference_lines: vec![],
            legend: LegendPosition::Auto,
        };
        let drawn = plot::line_chart(&chart, &Output::new(dir.join("frame_times")))?;
        note_drawn(&drawn, &mut notes);
        have_frames_figure = true;
    }

    // Tables.
    let ms = |v: Option<f64>| {
        v.map(|t| format!("{:.2}", t * 1e3))
            .unwrap_or_else(|| "—".into())
    };
    let table_rows: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.label.clone(),
                r.precompute_s.map(fmt_time).unwrap_or_else(|| "—".into()),
                ms(r.solve_p50_s),
                ms(r.solve_p99_s),
                ms(r.frame_p50_s),
                ms(r.frame_p99_s),
                r.fps_p50
                    .map(|v| format!("{v:.0}"))
                    .unwrap_or_else(|| "—".into()),
                r.fps_p99
                    .map(|v| format!("{v:.0}"))
                    .unwrap_or_else(|| "—".into()),
                r.solve_fps_p50
                    .map(|v| format!("{v:.0}"))
                    .unwrap_or_else(|| "—".into()),
                r.max_constraint_residual_relative
                    .map(|v| format!("{v:.0e}"))
                    .unwrap_or_else(|| "—".into()),
                r.deviation_from_reference
                    .map(|v| format!("{v:.0e}"))
                    .unwrap_or_else(|| "—".into()),
                r.status.clone(),
            ]
        })
        .collect();
    let best = rows
        .iter()
        .filter(|r| r.frame_p50_s.is_some())
        .min_by(|a, b| {
            a.frame_p50_s
                .unwrap_or(f64::INFINITY)
                .total_cmp(&b.frame_p50_s.unwrap_or(f64::INFINITY))
        });
    // The library default is the first configuration.
    let default_row = rows.first();
    let diag_share: Vec<f64> = rows
        .iter()
        .filter_map(|r| Some(r.diagnostics_p50_s? / r.frame_p50_s?))
        .collect();

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
        "Mesh: {} ({} vertices; {}). Scene: the paper's default (cotangent Laplacian, {} fixed vertices, a hard handle of {} vertices). \
         After one precompute per configuration and one warm-up solve, the handle is moved rigidly along a closed loop \
         (sideways by {:.0} % of the bounding-box diagonal × sin 2πt, along the long axis by the same × (1 − cos 2πt)/2) for {frames} frames: \
         each frame calls `set_target` for every handle constraint, then `solve`. \
         All configurations are precomputed first and the frames run round-robin (frame f of every configuration before frame f + 1 of any), \
         so that the load of this shared machine falls on all of them alike. \
         Configurations: the library default first; null-space QR on every SPD back end but faer-supernodal (what faer-auto selects at this size{}) and with every QR back end; \
         penalty, KKT and elimination on the default SPD back end only (their solve phase is that back end's; `scaling` compares the back ends). \
         **Solve** is the library's solve phase (`report.timings_s.solve`); **frame** is the wall time of the targets + solve call, which includes the \
         diagnostics the library computes after every solve (constraint residuals, ‖AX − C‖). fps = 1 / latency. \
         Penalty weight w = {weight:.3e} (100 × median |L_ii|).\n",
        case.name,
        mesh.n_vertices(),
        case.source,
        fixed.len(),
        handle.len(),
        15.0,
        if ctx.has_user_meshes() {
            ""
        } else {
            "; faer-simplicial and nalgebra, 2–4× slower per solve, only in the run with --mesh-dir"
        }
    );
    let _ = writeln!(
        s,
        "Regenerate this section alone:\n\n```sh\n{command}\n```\n"
    );
    let _ = writeln!(
        s,
        "**Table.** One row per method and back end. Read the p50 columns for the typical frame and p99 for the hitches; \
         \"residual\" is the largest hard-constraint residual over all frames relative to the bounding-box diagonal (penalty: its approximation error), \
         \"deviation\" the largest distance of the mid-drag shape from the first row's, relative to the diagonal (all methods solve the same problem).\n"
    );
    s.push_str(&markdown_table(
        &[
            "configuration",
            "precompute",
            "solve p50 (ms)",
            "solve p99 (ms)",
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
    ));
    if let (Some(b), Some(d)) = (best, default_row) {
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
    if !diag_share.is_empty() {
        let _ = writeln!(
            s,
            "The per-solve diagnostics take {:.0}–{:.0} % of a frame (median {:.0} %): an interactive application would want to skip them.",
            100.0 * diag_share.iter().copied().fold(f64::INFINITY, f64::min),
            100.0 * diag_share.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            100.0 * median(&diag_share)
        );
    }
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
    if !notes.is_empty() {
        let _ = writeln!(s, "\n**What did not work / notes.**\n");
        for n in &notes {
            let _ = writeln!(s, "- {n}");
        }
    }
    let _ = writeln!(
        s,
        "\nData: [`{NAME}/drag_summary.csv`]({NAME}/drag_summary.csv) (one row per configuration), [`{NAME}/drag_frames.csv`]({NAME}/drag_frames.csv) (every frame), [`{NAME}/drag_summary.json`]({NAME}/drag_summary.json)."
    );
    let _ = writeln!(s, "\n_{}_", ctx.machine.one_line());
    ctx.write_section(NAME, &s)?;

    let headline = match default_row {
        Some(d) if d.frame_p50_s.is_some() => format!(
            "{} on {} ({} vertices): frame p50 {} ms / p99 {} ms ({:.0} fps); fastest {} {} ms",
            d.label,
            case.name,
            mesh.n_vertices(),
            ms(d.frame_p50_s),
            ms(d.frame_p99_s),
            d.fps_p50.unwrap_or(f64::NAN),
            best.map(|b| b.label.clone()).unwrap_or_default(),
            ms(best.and_then(|b| b.frame_p50_s)),
        ),
        _ => "the default configuration failed".into(),
    };
    Ok(Summary { headline })
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
    fn configs_cover_every_method() {
        let c = configs(1.0, true).unwrap();
        for m in ["nullspace-qr", "penalty", "kkt", "eliminate"] {
            assert!(c.iter().any(|c| c.method == m), "{m}");
        }
        assert_eq!(c[0].method, "nullspace-qr");
    }
}
