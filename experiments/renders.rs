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
use lse_deform::{Deformer, LaplacianKind, NullSpaceQr};

use crate::context::{Context, fmt_time};
use crate::render::{self, Camera, Layout, Panel, RenderMesh, Style};
use crate::{AnyError, Summary, conflicts};

const RED: [u8; 3] = [215, 35, 30];
const BLUE: [u8; 3] = [40, 90, 210];
const GREY: [u8; 3] = [200, 200, 196];

/// Null-space QR positions for `constraints` on `mesh`.
fn deform(
    mesh: &Mesh,
    kind: LaplacianKind,
    constraints: lse_deform::ConstraintSet,
) -> Result<Vec<[f64; 3]>, AnyError> {
    let mut d = Deformer::new(mesh.clone(), kind, constraints)?;
    d.precompute(&NullSpaceQr::default())?;
    Ok(d.solve()?.positions)
}

/// Per-vertex colours: grey, `red` vertices red, `blue` vertices blue.
fn colours(n: usize, red: &[usize], blue: &[usize]) -> Vec<[u8; 3]> {
    let mut c = vec![GREY; n];
    for &v in red {
        c[v] = RED;
    }
    for &v in blue {
        c[v] = BLUE;
    }
    c
}

fn layout(scene: &FixedAndHandle, title: String, panels: usize) -> Layout {
    let side = if panels > 3 { 480 } else { 560 };
    Layout {
        panel_width: side,
        panel_height: side,
        // The handle moves along axis (up + 1) % 3, seen sideways from here.
        camera: Camera::new(-70.0, 15.0).with_up_axis(scene.axis),
        title: Some(title),
        ..Layout::default()
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

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let started = Instant::now();
    let dir = ctx.dir("renders")?;
    let style = Style::default();
    let mut images: Vec<(String, String)> = Vec::new();

    // 1. Table 1 scene on each evaluation mesh (the first three with a mesh
    //    directory: Bunny, Armadillo, Dragon).
    let mut meshes = ctx.evaluation_meshes()?;
    meshes.truncate(3);
    let bar = ctx.bar(meshes.len() + 2, "renders");
    for case in &meshes {
        bar.set_message(format!("renders: table1 {}", case.name));
        let mesh = &case.mesh;
        let scene = FixedAndHandle::paper_default(mesh);
        let (fixed, handle) = scene.regions(mesh)?;
        let constrained: Vec<usize> = fixed.iter().chain(&handle).copied().collect();
        let cot = deform(mesh, LaplacianKind::Cotangent, scene.constraints(mesh)?)?;
        let uni = deform(mesh, LaplacianKind::Uniform, scene.constraints(mesh)?)?;
        let panels = [
            Panel {
                mesh: RenderMesh::from_mesh(mesh).highlight(&constrained),
                caption: "(a) original, constrained vertices red".into(),
            },
            Panel {
                mesh: RenderMesh::new(&cot, mesh.faces()).highlight(&constrained),
                caption: "(b) cotangent, null-space QR".into(),
            },
            Panel {
                mesh: RenderMesh::new(&uni, mesh.faces()).highlight(&constrained),
                caption: "(c) uniform, null-space QR".into(),
            },
        ];
        let name = format!("table1_{}.png", file_name(&case.name));
        render::render_side_by_side(
            &panels,
            &layout(
                &scene,
                format!(
                    "Table 1 scene on {} ({} vertices): 20 % fixed, 2 % handle moved by 15 % of the diagonal",
                    case.name,
                    mesh.n_vertices()
                ),
                3,
            ),
            &style,
            &dir.join(&name),
        )?;
        images.push((
            name,
            format!(
                "Table 1 scene on {}: original, cotangent and uniform Laplacian (null-space QR).",
                case.name
            ),
        ));
        bar.inc(1);
    }

    // 2. Conflict scene (Fig. 6).
    bar.set_message("renders: conflicts");
    let (cname, cmesh) = conflicts::conflict_mesh(ctx)?;
    let sc = conflicts::scene(&cmesh, 5)?;
    let solved = conflicts::solve_all(&cmesh, &sc)?;
    let n = cmesh.n_vertices();
    let constrained: Vec<usize> = sc.fixed.iter().chain(&sc.handle).copied().collect();
    let colour = colours(n, &constrained, &sc.conflicted);
    let mut panels = vec![Panel {
        mesh: RenderMesh::from_mesh(&cmesh).colours(&colour),
        caption: "(a) original; red constrained, blue conflicting".into(),
    }];
    let letters = ["b", "c", "d", "e"];
    let mut k = 0;
    for s in &solved {
        if let Ok((x, _)) = &s.result {
            panels.push(Panel {
                mesh: RenderMesh::new(x, cmesh.faces()).colours(&colour),
                caption: format!("({}) {}", letters[k.min(3)], s.label),
            });
            k += 1;
        }
    }
    let np = panels.len();
    let name = "conflicts.png".to_string();
    render::render_side_by_side(
        &panels,
        &layout(
            &sc.base,
            format!(
                "Conflicting constraints on {cname}: soft compromise vs detect-and-remove (failed methods omitted)"
            ),
            np,
        ),
        &style,
        &dir.join(&name),
    )?;
    images.push((
        name,
        "Conflict scene (paper Fig. 6): the blue vertices carry a second, contradicting constraint; the soft solves compromise, the null-space QR keeps the earlier constraints exactly.".into(),
    ));
    bar.inc(1);

    // 3. Relative constraints preserving a feature region (Fig. 9/11).
    bar.set_message("renders: relative constraints");
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
    let colour = colours(n, &constrained, &patch);
    let without = deform(&cmesh, LaplacianKind::Cotangent, base.constraints(&cmesh)?)?;
    let with = deform(&cmesh, LaplacianKind::Cotangent, constraints)?;
    let panels = [
        Panel {
            mesh: RenderMesh::from_mesh(&cmesh).colours(&colour),
            caption: "(a) original; blue: relative-constraint patch".into(),
        },
        Panel {
            mesh: RenderMesh::new(&without, cmesh.faces()).colours(&colour),
            caption: "(b) fixed + handle only".into(),
        },
        Panel {
            mesh: RenderMesh::new(&with, cmesh.faces()).colours(&colour),
            caption: format!("(c) + {relative} relative constraints (hard)"),
        },
    ];
    // Look at the patch: from the direction of its centroid, seen from
    // the mesh centre, slightly from above.
    let mut rel_layout = layout(
        &base,
        format!(
            "Relative constraints on {cname}: the blue patch keeps its shape (translated rigidly)"
        ),
        3,
    );
    let (lo, hi) = cmesh.bounding_box();
    let p = cmesh.positions();
    let mut dir_to = [0.0; 3];
    for k in 0..3 {
        let c = patch.iter().map(|&v| p[v][k]).sum::<f64>() / patch.len().max(1) as f64;
        dir_to[k] = c - 0.5 * (lo[k] + hi[k]);
    }
    dir_to[base.axis] = 0.0;
    let len = dir_to.iter().map(|v| v * v).sum::<f64>().sqrt();
    if len > 0.0 {
        dir_to[base.axis] = 0.35 * len;
        if let Ok(camera) = Camera::from_direction(dir_to, base.axis) {
            rel_layout.camera = camera;
        }
    }
    let name = "relative.png".to_string();
    render::render_side_by_side(&panels, &rel_layout, &style, &dir.join(&name))?;
    images.push((
        name,
        format!("Relative-constraint scene (paper Fig. 9/11): a breadth-first patch of {} vertices keeps its edge vectors exactly while the handle is dragged.", patch.len()),
    ));
    bar.inc(1);
    bar.finish_and_clear();

    let seconds = started.elapsed().as_secs_f64();
    write_section(ctx, &images, seconds)?;
    Ok(Summary {
        headline: format!("{} images in {}", images.len(), dir_display(&dir)),
    })
}

fn dir_display(dir: &Path) -> String {
    dir.display().to_string()
}

fn write_section(ctx: &Context, images: &[(String, String)], seconds: f64) -> Result<(), AnyError> {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Software-rendered (z-buffered, smooth shaded) images of the scenes of the other sections. In every image the panels share one \
         camera and framing, so displacements compare directly; red = constrained vertices (fixed region and handle, the paper's red \
         areas), blue = the vertices of the constraints the caption names.\n"
    );
    for (file, caption) in images {
        let _ = writeln!(s, "![{caption}](renders/{file})\n\n{caption}\n");
    }
    let _ = writeln!(
        s,
        "Regenerate: `cargo run --release --bin experiments -- renders{}` ({} on {}).",
        if ctx.has_user_meshes() {
            " --mesh-dir ../shared/meshes"
        } else {
            " [--mesh-dir ../shared/meshes]"
        },
        fmt_time(seconds),
        ctx.machine.cpu
    );
    ctx.write_section("renders", &s)
}
