//! `viz-demo`: one example of every plot kind and a side-by-side render of a
//! real deformation, and the rasteriser's timing on ~50k-face meshes. A
//! development aid for the plotting and rendering toolkit.

use std::path::Path;
use std::time::Instant;

use lse_deform::mesh::{Mesh, generate};
use lse_deform::scene::FixedAndHandle;
use lse_deform::{Deformer, LaplacianKind, Report, formulation::NullSpaceQr};

use crate::harness::context::AnyError;
use crate::harness::plot::{
    self, Axis, Category, Drawn, Failure, LegendPosition, LineChart, Output, ReferenceLine,
    ScatterFits, Series, StackedBars,
};
use lse_deform::render::{self, Camera, Layout, Panel, RenderMesh, Style, View};

/// The deformation of the demo: positions, report and the constrained
/// vertices (fixed and handle).
struct Deformed {
    /// Deformed positions.
    positions: Vec<[f64; 3]>,
    /// Report of the solve.
    report: Report,
}

/// Deforms `mesh` with the paper's default scene, the handle hard (`None`)
/// or soft with weight `w`.
fn deform(mesh: &Mesh, handle_weight: Option<f64>) -> Result<Deformed, AnyError> {
    let scene = FixedAndHandle {
        handle_weight,
        ..FixedAndHandle::paper_default(mesh)
    };
    let constraints = scene.constraints(mesh)?;
    let mut deformer = Deformer::with_formulation(
        mesh.clone(),
        LaplacianKind::Cotangent,
        constraints,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )?;
    let solution = deformer.solve()?;
    Ok(Deformed {
        positions: solution.positions,
        report: solution.report,
    })
}

/// Largest distance of a handle vertex from its target.
fn handle_error(
    mesh: &Mesh,
    deformed: &[[f64; 3]],
    scene: &FixedAndHandle,
) -> Result<f64, AnyError> {
    let (_, handle) = scene.regions(mesh)?;
    let p = mesh.positions();
    Ok(handle
        .iter()
        .map(|&v| {
            (0..3)
                .map(|k| (deformed[v][k] - p[v][k] - scene.offset[k]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max))
}

/// Prints what a plot call wrote and skipped.
fn report_drawn(drawn: &Drawn) {
    for f in &drawn.files {
        println!("wrote {}", f.display());
    }
    for n in &drawn.notes {
        println!("  note: {n}");
    }
}

/// The `viz-demo` subcommand.
pub fn viz_demo(out: &Path) -> Result<(), AnyError> {
    std::fs::create_dir_all(out)?;
    let mesh = generate::bumpy_sphere(4, 0.15, 6)?;
    let scene = FixedAndHandle::paper_default(&mesh);
    let hard = deform(&mesh, None)?;
    demo_render(out, &mesh, &scene, &hard)?;
    demo_line_chart(out, &mesh, &scene, &hard)?;
    let (scaling_hard, scaling_soft) = demo_stacked_bars(out)?;
    demo_scatter(out, scaling_hard, scaling_soft)?;
    demo_render_timing(out)
}

/// Renders: original | hard handle | soft handle, one framing.
fn demo_render(
    out: &Path,
    mesh: &Mesh,
    scene: &FixedAndHandle,
    hard: &Deformed,
) -> Result<(), AnyError> {
    let (fixed, handle) = scene.regions(mesh)?;
    let constrained: Vec<usize> = fixed.iter().chain(&handle).copied().collect();
    let soft = deform(mesh, Some(1.0))?;
    // The handle moves along axis (up + 1) % 3, which a camera at azimuth
    // −70° sees mostly sideways.
    let camera = Camera::new(-70.0, 15.0).with_up_axis(scene.axis.index());
    let layout = Layout {
        camera,
        title: Some(format!(
            "Bumpy sphere ({} vertices): fixed bottom 20 %, handle 2 % dragged",
            mesh.n_vertices()
        )),
        ..Layout::default()
    };
    let panels = [
        Panel {
            mesh: RenderMesh::from_mesh(mesh).highlight(&constrained),
            caption: "(a) original, constrained vertices red".into(),
        },
        Panel {
            mesh: RenderMesh::new(&hard.positions, mesh.faces()).highlight(&constrained),
            caption: "(b) hard handle (null-space QR)".into(),
        },
        Panel {
            mesh: RenderMesh::new(&soft.positions, mesh.faces()).highlight(&constrained),
            caption: "(c) soft handle, w = 1".into(),
        },
    ];
    let path = out.join("render_bumpy_sphere.png");
    render::render_side_by_side(&panels, &layout, &Style::default(), &path)?;
    println!("wrote {}", path.display());
    Ok(())
}

/// Line chart: handle error against the soft weight, with the hard
/// handle's error as the reference.
fn demo_line_chart(
    out: &Path,
    mesh: &Mesh,
    scene: &FixedAndHandle,
    hard: &Deformed,
) -> Result<(), AnyError> {
    let weights: Vec<f64> = (-2..=8).map(|k| 10f64.powi(k)).collect();
    let mut points = Vec::new();
    let mut failures = Vec::new();
    for &w in &weights {
        match deform(mesh, Some(w)) {
            Ok(d) => points.push((w, handle_error(mesh, &d.positions, scene)?)),
            Err(e) => {
                println!("  soft handle w = {w:e} failed: {e}");
                failures.push(Failure { x: w, y: None });
            }
        }
    }
    let hard_error = handle_error(mesh, &hard.positions, scene)?;
    let line = LineChart {
        title: "Handle error of a soft handle against its weight".into(),
        x: Axis::log10("soft-constraint weight w"),
        y: Axis::log10("max handle distance from target"),
        series: vec![Series::new("soft handle (null-space QR)", points).with_failures(failures)],
        reference_lines: vec![ReferenceLine {
            y: hard_error,
            label: format!("hard handle ({hard_error:.1e})"),
        }],
        legend: LegendPosition::Auto,
    };
    report_drawn(&plot::line_chart(
        &line,
        &Output::new(out.join("demo_line_chart")),
    )?);
    Ok(())
}

/// Points of a plotted series.
type Points = Vec<(f64, f64)>;

/// Stacked bars: precompute breakdown, hard vs soft handle, two sizes;
/// returns the precompute times against vertex count (hard, soft) for the
/// scatter.
fn demo_stacked_bars(out: &Path) -> Result<(Points, Points), AnyError> {
    let segments = ["QR", "preparation", "normal matrix", "symbolic", "numeric"];
    let mut categories = Vec::new();
    let mut scaling_hard = Vec::new();
    let mut scaling_soft = Vec::new();
    for subdivisions in [2u32, 3, 4] {
        let m = generate::bumpy_sphere(subdivisions, 0.15, 6)?;
        for (kind, weight) in [("hard handle", None), ("soft handle", Some(1.0))] {
            let d = deform(&m, weight)?;
            let t = &d.report.timings_s;
            if subdivisions >= 3 {
                categories.push(Category {
                    name: format!("{} vertices / {kind}", m.n_vertices()),
                    values: vec![t.qr, t.preparation, t.normal_matrix, t.symbolic, t.numeric],
                });
            }
            let target = if weight.is_none() {
                &mut scaling_hard
            } else {
                &mut scaling_soft
            };
            target.push((m.n_vertices() as f64, t.precompute()));
        }
    }
    let bars = StackedBars {
        title: "Breakdown of precomputation time".into(),
        value_label: "time (s)".into(),
        segments: segments.iter().map(|s| s.to_string()).collect(),
        categories,
        total_suffix: Some(" s".into()),
        legend: LegendPosition::Auto,
    };
    report_drawn(&plot::stacked_bars(
        &bars,
        &Output::new(out.join("demo_stacked_bars")),
    )?);
    Ok((scaling_hard, scaling_soft))
}

/// Scatter with fits: precompute time against vertex count.
fn demo_scatter(out: &Path, scaling_hard: Points, scaling_soft: Points) -> Result<(), AnyError> {
    let scatter = ScatterFits {
        title: "Precomputation time against mesh size".into(),
        x_label: "vertices".into(),
        y_label: "precompute time (s)".into(),
        series: vec![
            Series::new("hard handle", scaling_hard),
            Series::new("soft handle", scaling_soft),
        ],
        legend: LegendPosition::Auto,
    };
    report_drawn(&plot::scatter_loglog_with_fits(
        &scatter,
        &Output::new(out.join("demo_scatter_fits")),
    )?);
    Ok(())
}

/// Rasteriser timing at 800 × 800: a 51,200-face grid seen at an angle
/// and an 81,920-face bumpy sphere.
fn demo_render_timing(out: &Path) -> Result<(), AnyError> {
    let timing_meshes = [
        (
            "grid",
            generate::grid(160, 160)?,
            Camera::new(20.0, 35.0).with_up_axis(1),
        ),
        (
            "sphere",
            generate::bumpy_sphere(6, 0.15, 6)?,
            Camera::default(),
        ),
    ];
    for (name, big, camera) in &timing_meshes {
        let view = View::fit(camera, &[big.positions()], 800, 800, 0.05)?;
        for supersample in [1, 2] {
            let style = Style {
                supersample,
                ..Style::default()
            };
            let t = Instant::now();
            let image = render::render(&RenderMesh::from_mesh(big), &view, &style)?;
            let elapsed = t.elapsed().as_secs_f64();
            println!(
                "render {name}: {} faces at 800×800, supersample {supersample}×{supersample}: {elapsed:.3} s",
                big.n_faces(),
            );
            let path = out.join(format!("render_timing_{name}_ss{supersample}.png"));
            image.save_png(&path)?;
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}
