//! Experiment `renders`: images of the original and deformed meshes with the
//! constrained regions coloured (the paper's red areas), for the Table 1
//! scene on each evaluation mesh, the conflict scene (Fig. 6) and a scene
//! with relative constraints preserving a feature region (Fig. 9/11).
//! Written to `results/renders/`.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use lse_deform::constraints::ConstraintKind;
use lse_deform::mesh::Mesh;
use lse_deform::scene::{FixedAndHandle, MixedScene};
use lse_deform::{Deformer, LaplacianKind, formulation::NullSpaceQr};

use crate::harness::conflict_scene as conflicts;
use crate::harness::context::AnyError;
use crate::harness::context::Context;
use crate::harness::registry::{Experiment, Input, Summary};
use crate::harness::rows::fmt_time;
use lse_deform::render::{
    self, Camera, ColourScale, Ghost, Image, LEGEND_HEIGHT, Legend, RenderMesh, Style, View,
};

/// The folder and command-line word of this experiment.
pub const NAME: &str = "renders";

/// This study's entry in the list of experiments.
pub const EXPERIMENT: Experiment = Experiment {
    name: NAME,
    title: "Renders",
    inputs: &[Input::Meshes],
    run,
};

const RED: [u8; 3] = [215, 35, 30];
const BLUE: [u8; 3] = [40, 90, 210];
const GREY: [u8; 3] = [200, 200, 196];
const WHITE: [u8; 3] = [255, 255, 255];
/// The original as a translucent ghost: colour and opacity.
const GHOST: ([u8; 3], f64) = ([150, 170, 215], 0.35);
/// Side of each panel's render, pixels (plus the legend strip).
const SIDE: u32 = 560;

/// Null-space QR positions for `constraints` on `mesh`.
fn deform(
    mesh: &Mesh,
    kind: LaplacianKind,
    constraints: lse_deform::ConstraintSet,
) -> Result<Vec<[f64; 3]>, AnyError> {
    let mut d = Deformer::with_formulation(
        mesh.clone(),
        kind,
        constraints,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )?;
    Ok(d.solve()?.positions)
}

/// Per-vertex colours: `base`, `red` vertices red, `blue` vertices blue.
fn colours(base: Vec<[u8; 3]>, red: &[usize], blue: &[usize]) -> Vec<[u8; 3]> {
    let mut c = base;
    for &v in red {
        c[v] = RED;
    }
    for &v in blue {
        c[v] = BLUE;
    }
    c
}

/// The camera that puts the motion from `original` to `moved` in the
/// image plane, framing every position set in `sets` in one view.
fn shared_view(
    original: &[[f64; 3]],
    moved: &[[f64; 3]],
    sets: &[&[[f64; 3]]],
) -> Result<View, AnyError> {
    let camera = render::auto_camera(original, moved, None)?;
    Ok(View::fit(&camera, sets, SIDE, SIDE, 0.06)?)
}

/// One panel: `mesh` in `view`, over the translucent `ghost` positions if
/// any, with `legend` in a strip underneath.
fn panel(
    mesh: RenderMesh<'_>,
    ghost: Option<&[[f64; 3]]>,
    legend: &Legend,
    view: &View,
) -> Result<Image, AnyError> {
    let style = Style::default();
    let image = match ghost {
        Some(g) => render::render_with_ghost(
            &mesh,
            &Ghost {
                mesh: RenderMesh::new(g, mesh.faces),
                colour: GHOST.0,
                opacity: GHOST.1,
            },
            view,
            &style,
        )?,
        None => render::render(&mesh, view, &style)?,
    };
    let mut canvas = Image::filled(view.width, view.height + LEGEND_HEIGHT, style.background);
    canvas.pixels[..image.pixels.len()].copy_from_slice(&image.pixels);
    if !legend.is_empty() {
        legend.draw(&mut canvas)?;
    }
    Ok(canvas)
}

/// A legend of named colours, with the ghost's.
fn swatches(names: &[(&str, [u8; 3])]) -> Legend {
    let mut swatches: Vec<(String, [u8; 3])> =
        names.iter().map(|(n, c)| (n.to_string(), *c)).collect();
    swatches.push(("original (ghost)".into(), GHOST.0));
    Legend {
        scale: None,
        swatches,
    }
}

/// A colour-bar legend for `scale`, labelled `what` and the maximum as a
/// percentage of `diagonal`.
fn bar(scale: ColourScale, what: &str, diagonal: f64) -> Legend {
    Legend {
        scale: Some((
            scale,
            format!(
                "{what} (max {:.2} % of the diagonal)",
                100.0 * scale.max / diagonal
            ),
        )),
        swatches: Vec::new(),
    }
}

fn file_name(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// A figure written: file name and caption.
type Figure = (String, String);

/// Table 1 scene on one mesh: cotangent and uniform solutions over the
/// original's ghost, and where they differ.
fn table1_figure(name: &str, mesh: &Mesh, dir: &Path) -> Result<Figure, AnyError> {
    let scene = FixedAndHandle::paper_default(mesh);
    let (fixed, handle) = scene.regions(mesh)?;
    let constrained: Vec<usize> = fixed.iter().chain(&handle).copied().collect();
    let cot = deform(mesh, LaplacianKind::Cotangent, scene.constraints(mesh)?)?;
    let uni = deform(mesh, LaplacianKind::Uniform, scene.constraints(mesh)?)?;
    let p = mesh.positions();
    let view = shared_view(p, &cot, &[p, &cot, &uni])?;
    let grey = colours(vec![GREY; p.len()], &constrained, &[]);
    let legend = swatches(&[("fixed and handle", RED)]);
    let diff = render::distances(&cot, &uni, "uniform")?;
    let scale = ColourScale::from_zero(&diff)?;
    let images = vec![
        (
            panel(
                RenderMesh::new(&cot, mesh.faces()).colours(&grey),
                Some(p),
                &legend,
                &view,
            )?,
            "(a) cotangent, over the original (ghost)".to_string(),
        ),
        (
            panel(
                RenderMesh::new(&uni, mesh.faces()).colours(&grey),
                Some(p),
                &legend,
                &view,
            )?,
            "(b) uniform, over the original (ghost)".to_string(),
        ),
        (
            panel(
                RenderMesh::new(&cot, mesh.faces()).colours(&scale.colours(&diff)),
                None,
                &bar(scale, "|cotangent − uniform|", mesh.bbox_diagonal()),
                &view,
            )?,
            "(c) where they differ, on (a)".to_string(),
        ),
    ];
    let file = format!("table1_{}.png", file_name(name));
    let title = format!(
        "Table 1 scene on {name} ({} vertices): 20 % fixed, 2 % handle moved by 15 % of the diagonal (null-space QR)",
        mesh.n_vertices()
    );
    render::compose(&images, Some(&title), WHITE, &dir.join(&file))?;
    let caption = format!(
        "Table 1 scene on {name}: the cotangent (a) and uniform (b) solutions over the original (blue ghost), camera across the handle's motion; (c) the distance between the two solutions (largest {:.2} % of the diagonal).",
        100.0 * scale.max / mesh.bbox_diagonal()
    );
    Ok((file, caption))
}

/// Conflict scene (Fig. 6): the null-space QR solution over the ghost, and
/// how far each soft compromise lies from it.
fn conflicts_figure(ctx: &Context, dir: &Path) -> Result<Figure, AnyError> {
    let (cname, cmesh) = conflicts::conflict_mesh(ctx)?;
    let sc = conflicts::scene(&cmesh, 5)?;
    let solved = conflicts::solve_all(&cmesh, &sc)?;
    let ok: Vec<(&str, &Vec<[f64; 3]>)> = solved
        .iter()
        .filter_map(|s| s.result.as_ref().ok().map(|(x, _)| (s.label.as_str(), x)))
        .collect();
    let (exact_label, exact) = *ok.last().ok_or("no method solved the conflict scene")?;
    let p = cmesh.positions();
    let constrained: Vec<usize> = sc.fixed.iter().chain(&sc.handle).copied().collect();
    let colour = colours(vec![GREY; p.len()], &constrained, &sc.conflicted);
    let mut sets: Vec<&[[f64; 3]]> = vec![p];
    sets.extend(ok.iter().map(|(_, x)| x.as_slice()));
    let view = shared_view(p, exact, &sets)?;
    let legend = swatches(&[("fixed and handle", RED), ("conflicting", BLUE)]);
    let mut images = vec![(
        panel(
            RenderMesh::new(exact, cmesh.faces()).colours(&colour),
            Some(p),
            &legend,
            &view,
        )?,
        format!("(a) {exact_label}"),
    )];
    let soft = &ok[..ok.len() - 1];
    let diffs: Vec<Vec<f64>> = soft
        .iter()
        .map(|(_, x)| render::distances(exact, x, "soft solution"))
        .collect::<Result<_, _>>()?;
    let scale = ColourScale::from_zero(&diffs.concat())?;
    let diagonal = cmesh.bbox_diagonal();
    for (k, ((label, x), d)) in soft.iter().zip(&diffs).enumerate() {
        let legend = bar(scale, "distance from (a)", diagonal);
        let shades = scale.colours(d);
        let mesh = RenderMesh::new(x, cmesh.faces()).colours(&shades);
        images.push((
            panel(mesh, None, &legend, &view)?,
            format!("({}) {label}", ["b", "c", "d"][k.min(2)]),
        ));
    }
    let file = "conflicts.png".to_string();
    let title = format!(
        "Conflicting constraints on {cname}: detect-and-remove (a) against the soft compromises (failed methods omitted)"
    );
    render::compose(&images, Some(&title), WHITE, &dir.join(&file))?;
    let caption = format!(
        "Conflict scene (paper Fig. 6; the handle moved by {:.0} % of the diagonal): (a) the null-space QR solution over the original (ghost), red constrained, blue the vertices of the later, contradicting constraints it drops; the other panels colour each soft solution by its distance from (a) (one scale, up to {:.1} % of the diagonal): the compromise moves the handle and the region around it away from where the exact constraints put them.",
        100.0 * sc.base.offset.iter().map(|v| v * v).sum::<f64>().sqrt() / diagonal,
        100.0 * scale.max / diagonal
    );
    Ok((file, caption))
}

/// A camera with the up axis of `camera` looking at `patch` from the
/// direction of its centroid seen from the mesh centre, slightly from
/// above (`camera` itself if that direction is degenerate).
fn toward_patch(mesh: &Mesh, patch: &[usize], camera: Camera) -> Camera {
    let (lo, hi) = mesh.bounding_box();
    let p = mesh.positions();
    let up = camera.up_axis;
    let mut toward = [0.0; 3];
    for k in 0..3 {
        let c = patch.iter().map(|&v| p[v][k]).sum::<f64>() / patch.len().max(1) as f64;
        toward[k] = c - 0.5 * (lo[k] + hi[k]);
    }
    toward[up] = 0.0;
    let len = toward.iter().map(|v| v * v).sum::<f64>().sqrt();
    toward[up] = 0.35 * len;
    Camera::from_direction(toward, up).unwrap_or(camera)
}

/// Relative constraints (Fig. 9/11): with and without a feature patch,
/// both over the ghost, and what the relative constraints change.
fn relative_figure(ctx: &Context, dir: &Path) -> Result<Figure, AnyError> {
    let (cname, cmesh) = conflicts::conflict_mesh(ctx)?;
    let n = cmesh.n_vertices();
    let base = FixedAndHandle::paper_default(&cmesh);
    let relative = (n / 12).clamp(50, 400);
    let mixed = MixedScene {
        base: base.clone(),
        relative,
        edges: 0,
        faces: 0,
        duplicate: false,
        conflict: false,
    };
    let constraints = mixed.constraints(&cmesh)?;
    let mut patch: Vec<usize> = constraints
        .as_slice()
        .iter()
        .filter_map(|c| match c.kind {
            ConstraintKind::Relative { vertices, .. } => Some(vertices),
            _ => None,
        })
        .flatten()
        .collect();
    patch.sort_unstable();
    patch.dedup();
    let (fixed, handle) = base.regions(&cmesh)?;
    let constrained: Vec<usize> = fixed.iter().chain(&handle).copied().collect();
    let colour = colours(vec![GREY; n], &constrained, &patch);
    let without = deform(&cmesh, LaplacianKind::Cotangent, base.constraints(&cmesh)?)?;
    let with = deform(&cmesh, LaplacianKind::Cotangent, constraints)?;
    let p = cmesh.positions();
    let camera = toward_patch(&cmesh, &patch, render::auto_camera(p, &without, None)?);
    let view = View::fit(&camera, &[p, &without, &with], SIDE, SIDE, 0.06)?;
    let legend = swatches(&[("fixed and handle", RED), ("relative patch", BLUE)]);
    let diff = render::distances(&without, &with, "with relative constraints")?;
    let scale = ColourScale::from_zero(&diff)?;
    let faces = cmesh.faces();
    let images = vec![
        (
            panel(
                RenderMesh::new(&without, faces).colours(&colour),
                Some(p),
                &legend,
                &view,
            )?,
            "(a) fixed + handle only".to_string(),
        ),
        (
            panel(
                RenderMesh::new(&with, faces).colours(&colour),
                Some(p),
                &legend,
                &view,
            )?,
            format!("(b) + {relative} relative constraints (hard)"),
        ),
        (
            panel(
                RenderMesh::new(&with, faces).colours(&scale.colours(&diff)),
                None,
                &bar(scale, "|(b) − (a)|", cmesh.bbox_diagonal()),
                &view,
            )?,
            "(c) what the relative constraints change".to_string(),
        ),
    ];
    let file = "relative.png".to_string();
    let title = format!(
        "Relative constraints on {cname}: the blue patch keeps its edge vectors (it may only translate)"
    );
    render::compose(&images, Some(&title), WHITE, &dir.join(&file))?;
    let caption = format!(
        "Relative-constraint scene (paper Fig. 9/11): a breadth-first patch of {} vertices (blue) keeps its edge vectors exactly while the handle is dragged; (a) and (b) over the original (ghost), (c) the distance between them (largest {:.2} % of the diagonal).",
        patch.len(),
        100.0 * scale.max / cmesh.bbox_diagonal()
    );
    Ok((file, caption))
}

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let started = Instant::now();
    let dir = ctx.dir(NAME)?;
    // The first three evaluation meshes (with a mesh directory: Bunny,
    // Armadillo, Dragon).
    let mut meshes = ctx.evaluation_meshes()?;
    meshes.truncate(3);
    let bar = ctx.bar(meshes.len() + 2, NAME);
    let mut images = Vec::new();
    for case in &meshes {
        bar.set_message(format!("renders: table1 {}", case.name));
        images.push(table1_figure(&case.name, &case.mesh, &dir)?);
        bar.inc(1);
    }
    bar.set_message("renders: conflicts");
    images.push(conflicts_figure(ctx, &dir)?);
    bar.inc(1);
    bar.set_message("renders: relative constraints");
    images.push(relative_figure(ctx, &dir)?);
    bar.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    write_section(ctx, &images, seconds)?;
    Ok(Summary::measured(format!(
        "{} images in {}",
        images.len(),
        dir_display(&dir)
    )))
}

fn dir_display(dir: &Path) -> String {
    dir.display().to_string()
}

/// The mesh options of the committed renders.
const MESHES: &str = "--mesh ../shared/meshes/bunny-35k-stanford.obj --mesh ../shared/meshes/armadillo-43k.obj \
                      --mesh ../shared/meshes/dragon-50k.obj --mesh ../shared/meshes/bunny-3k.obj";

fn write_section(ctx: &Context, images: &[(String, String)], seconds: f64) -> Result<(), AnyError> {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Software-rendered (z-buffered, smooth shaded; `lse_deform::render`) images of the scenes of the other sections. In every \
         image the panels share one camera and framing, so displacements compare directly; the camera looks across the handle's \
         motion (`render::auto_camera`: along the axis the vertices moved least, y up). Red = constrained vertices (fixed region \
         and handle, the paper's red areas), blue = the vertices of the constraints the caption names, light blue = the original \
         surface as a translucent ghost; colour maps are viridis with their range in the legend.\n"
    );
    for (file, caption) in images {
        let _ = writeln!(s, "![{caption}](renders/{file})\n\n{caption}\n");
    }
    let _ = writeln!(
        s,
        "Regenerate: `cargo run --release --bin experiments -- renders {MESHES}` ({} on {}); the Table 1 figures are made for \
         the first three evaluation meshes given, the conflict and relative figures on bunny-3k (a generated bumpy sphere \
         without it). Without any mesh option everything runs on generated meshes.",
        fmt_time(seconds),
        ctx.machine.cpu
    );
    ctx.write_section(NAME, &s)
}
