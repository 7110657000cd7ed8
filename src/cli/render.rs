//! `lse-deform render MESH [DEFORMED] -o OUT.png`: a picture of a user's
//! own result. The deformed surface is drawn opaque with the original as a
//! translucent ghost, or coloured by a displacement or difference map with
//! a legend; constrained vertices get a colour per constraint group; the
//! camera puts the motion in the image plane ([`auto_camera`]) unless
//! `--up`, `--azimuth` or `--elevation` say otherwise.

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};
use lse_deform::mesh::{self, Mesh};
use lse_deform::render::{
    ColourScale, Ghost, Image, LEGEND_HEIGHT, Legend, RenderError, RenderMesh, Style, View,
    auto_camera, distances, render, render_with_ghost,
};

/// Arguments of `render`.
#[derive(Args)]
pub struct RenderArgs {
    /// The original mesh (.obj, .ply or .off; .gz after it allowed).
    mesh: PathBuf,
    /// A deformation of it (same vertices, in the same order): drawn
    /// opaque, with the original as a translucent ghost.
    deformed: Option<PathBuf>,
    /// Output PNG.
    #[arg(long, short = 'o')]
    output: PathBuf,
    /// Surface colour: shaded (grey), displacement (|DEFORMED − MESH|) or
    /// difference (|DEFORMED − AGAINST|, with --against), with a legend.
    #[arg(long, value_enum, default_value = "shaded")]
    color: ColourMode,
    /// A second deformation of MESH, for --color difference (e.g. penalty
    /// against the exact null-space solution).
    #[arg(long)]
    against: Option<PathBuf>,
    /// A constraints file: its vertices drawn in one colour per "group".
    #[arg(long)]
    constraints: Option<PathBuf>,
    /// World up axis: x, y or z (default: y, or chosen from the motion).
    #[arg(long, value_enum)]
    up: Option<Axis>,
    /// Camera azimuth around the up axis, degrees (default: automatic).
    #[arg(long, allow_hyphen_values = true)]
    azimuth: Option<f64>,
    /// Camera elevation, degrees in (−90, 90) (default: 15).
    #[arg(long, allow_hyphen_values = true)]
    elevation: Option<f64>,
    /// Image size WIDTHxHEIGHT in pixels (legend included).
    #[arg(long, default_value = "1000x800", value_parser = parse_size)]
    size: (u32, u32),
    /// Do not draw the original as a ghost.
    #[arg(long)]
    no_ghost: bool,
}

/// What colours the surface.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ColourMode {
    /// Grey, shaded.
    Shaded,
    /// Distance of each vertex from its original position.
    Displacement,
    /// Distance of each vertex from its position in --against.
    Difference,
}

/// A world axis.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Axis {
    /// x.
    X,
    /// y.
    Y,
    /// z.
    Z,
}

/// Why `render` failed: bad input (exit code 2).
#[derive(Debug, thiserror::Error)]
enum RenderCommandError {
    /// A file that cannot be read or is not a valid mesh or constraints
    /// file.
    #[error(transparent)]
    Input(#[from] lse_deform::Error),
    /// A render parameter or the output.
    #[error(transparent)]
    Render(#[from] RenderError),
    /// Arguments that do not go together.
    #[error("{0}")]
    Usage(String),
}

/// Colour of the ghost (a light blue-grey) and its opacity.
const GHOST: ([u8; 3], f64) = ([150, 170, 215], 0.35);

/// Colours of constraint groups, in order of first appearance (cycled).
const GROUP_COLOURS: [[u8; 3]; 6] = [
    [215, 35, 30],
    [230, 0, 160],
    [255, 130, 0],
    [30, 60, 200],
    [120, 60, 20],
    [0, 150, 60],
];

/// Runs `render` and reports an error like the other commands (one line,
/// causes with `--verbose`, exit code 2).
pub(crate) fn main(args: RenderArgs, verbose: bool) -> u8 {
    match run(&args) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            let mut source = std::error::Error::source(&e);
            while let (true, Some(s)) = (verbose, source) {
                eprintln!("  caused by: {s}");
                source = s.source();
            }
            2
        }
    }
}

/// `WIDTHxHEIGHT` (or `×`) as two positive integers.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("'{s}' is not WIDTHxHEIGHT (two positive integers, e.g. 1000x800)");
    let (w, h) = s.split_once(['x', 'X', '×']).ok_or_else(bad)?;
    let w: u32 = w.trim().parse().map_err(|_| bad())?;
    let h: u32 = h.trim().parse().map_err(|_| bad())?;
    if w == 0 || h == 0 {
        return Err(bad());
    }
    Ok((w, h))
}

fn run(a: &RenderArgs) -> Result<(), RenderCommandError> {
    check_arguments(a)?;
    let inputs = [
        ("the input mesh", Some(&a.mesh)),
        ("the deformed mesh", a.deformed.as_ref()),
        ("the mesh given with --against", a.against.as_ref()),
        (
            "the constraints file given with --constraints",
            a.constraints.as_ref(),
        ),
    ];
    let inputs: Vec<_> = inputs
        .into_iter()
        .filter_map(|(what, p)| p.map(|p| (what, p.as_path())))
        .collect();
    super::files::check_distinct(&inputs, &[("-o", a.output.as_path())])?;
    super::notes(mesh::check_writable(&a.output)?);
    let original = super::load(&a.mesh, lse_deform::limits::MemoryBudget::default())?;
    let deformed = a
        .deformed
        .as_deref()
        .map(|p| load_like(p, &original))
        .transpose()?;
    let against = a
        .against
        .as_deref()
        .map(|p| load_like(p, &original))
        .transpose()?;
    let shown = deformed.as_ref().unwrap_or(&original);
    let groups = match &a.constraints {
        Some(path) => constraint_groups(path, &original)?,
        None => Vec::new(),
    };
    let scale = colour_values(a, &original, shown, against.as_ref())?;
    let mut colours = match &scale {
        Some((scale, values, _)) => scale.colours(values),
        None => vec![Style::default().base; original.n_vertices()],
    };
    for (i, (_, vertices)) in groups.iter().enumerate() {
        for &v in vertices {
            colours[v] = GROUP_COLOURS[i % GROUP_COLOURS.len()];
        }
    }
    let ghost = deformed.is_some() && !a.no_ghost;
    let legend = legend(scale.map(|(s, _, label)| (s, label)), &groups, ghost);
    let view = framing(a, &original, shown, against.as_ref(), legend.is_empty())?;
    let surface = RenderMesh::new(shown.positions(), shown.faces()).colours(&colours);
    let style = Style::default();
    let image = if ghost {
        let ghost = Ghost {
            mesh: RenderMesh::from_mesh(&original),
            colour: GHOST.0,
            opacity: GHOST.1,
        };
        render_with_ghost(&surface, &ghost, &view, &style)?
    } else {
        render(&surface, &view, &style)?
    };
    let mut canvas = Image::filled(a.size.0, a.size.1, style.background);
    canvas.pixels[..image.pixels.len()].copy_from_slice(&image.pixels);
    if !legend.is_empty() {
        legend.draw(&mut canvas)?;
    }
    canvas.save_png(&a.output)?;
    Ok(())
}

/// Combinations the options cannot express.
fn check_arguments(a: &RenderArgs) -> Result<(), RenderCommandError> {
    let usage = |m: &str| Err(RenderCommandError::Usage(m.to_string()));
    match (a.color, &a.deformed, &a.against) {
        (ColourMode::Displacement, None, _) => {
            usage("--color displacement needs a DEFORMED mesh after MESH")
        }
        (ColourMode::Difference, None, _) | (ColourMode::Difference, _, None) => {
            usage("--color difference needs a DEFORMED mesh and --against OTHER")
        }
        (ColourMode::Difference, ..) => Ok(()),
        (_, _, Some(_)) => usage("--against is only used with --color difference"),
        _ => Ok(()),
    }
}

/// Reads a mesh that must have the vertices of `original`.
fn load_like(path: &Path, original: &Mesh) -> Result<Mesh, RenderCommandError> {
    let mesh = super::load(path, lse_deform::limits::MemoryBudget::default())?;
    if mesh.n_vertices() != original.n_vertices() {
        return Err(RenderError::VertexCount {
            what: path.display().to_string(),
            got: mesh.n_vertices(),
            n: original.n_vertices(),
        }
        .into());
    }
    Ok(mesh)
}

/// The constrained vertices by group name (`"constrained"` for constraints
/// without a group), groups in order of first appearance.
fn constraint_groups(
    path: &Path,
    mesh: &Mesh,
) -> Result<Vec<(String, Vec<usize>)>, RenderCommandError> {
    let set = super::constraints_for(
        path,
        mesh,
        false,
        lse_deform::limits::MemoryBudget::default(),
    )?;
    let mut groups: Vec<(String, Vec<usize>)> = Vec::new();
    for c in set.as_slice() {
        let name = c.group.as_deref().unwrap_or("constrained");
        let at = match groups.iter().position(|(g, _)| g == name) {
            Some(i) => i,
            None => {
                groups.push((name.to_string(), Vec::new()));
                groups.len() - 1
            }
        };
        groups[at].1.extend_from_slice(c.kind.vertices());
    }
    Ok(groups)
}

/// The colour scale, the per-vertex values and the legend label of the
/// colour mode (`None` for shaded).
fn colour_values(
    a: &RenderArgs,
    original: &Mesh,
    shown: &Mesh,
    against: Option<&Mesh>,
) -> Result<Option<(ColourScale, Vec<f64>, String)>, RenderCommandError> {
    let (reference, what) = match (a.color, against) {
        (ColourMode::Shaded, _) => return Ok(None),
        (ColourMode::Displacement, _) => (original, "displacement"),
        (ColourMode::Difference, Some(other)) => (other, "difference from --against"),
        (ColourMode::Difference, None) => return Ok(None),
    };
    let values = distances(reference.positions(), shown.positions(), "deformed mesh")?;
    let scale = ColourScale::from_zero(&values)?;
    let diagonal = original.bbox_diagonal();
    // In the mesh's units and as a fraction of its diagonal, in scientific
    // notation: a difference of 8.6e-12 must not read "0.00 %".
    let label = if diagonal > 0.0 {
        format!(
            "{what}: max {:.2e} mesh units = {:.2e} × bbox diagonal",
            scale.max,
            scale.max / diagonal
        )
    } else {
        format!("{what}: max {:.2e} mesh units", scale.max)
    };
    Ok(Some((scale, values, label)))
}

fn legend(
    scale: Option<(ColourScale, String)>,
    groups: &[(String, Vec<usize>)],
    ghost: bool,
) -> Legend {
    let mut swatches: Vec<(String, [u8; 3])> = groups
        .iter()
        .enumerate()
        .map(|(i, (name, _))| (name.clone(), GROUP_COLOURS[i % GROUP_COLOURS.len()]))
        .collect();
    if ghost {
        swatches.push(("original (ghost)".into(), GHOST.0));
    }
    Legend { scale, swatches }
}

/// The view: automatic camera unless overridden, framing every mesh drawn,
/// in the image above the legend strip.
fn framing(
    a: &RenderArgs,
    original: &Mesh,
    shown: &Mesh,
    against: Option<&Mesh>,
    no_legend: bool,
) -> Result<View, RenderCommandError> {
    let up = a.up.map(|axis| axis as usize);
    let mut camera = auto_camera(original.positions(), shown.positions(), up)?;
    if let Some(az) = a.azimuth {
        camera.azimuth_deg = az;
    }
    if let Some(el) = a.elevation {
        camera.elevation_deg = el;
    }
    let (w, h) = a.size;
    let strip = if no_legend { 0 } else { LEGEND_HEIGHT };
    if h < strip + 32 || (!no_legend && w < 200) {
        return Err(RenderError::Invalid {
            what: "size",
            message: format!(
                "{w}x{h} leaves no room for the mesh and the legend (at least 200x{})",
                strip + 32
            ),
        }
        .into());
    }
    let mut sets = vec![original.positions(), shown.positions()];
    sets.extend(against.map(|m| m.positions()));
    Ok(View::fit(&camera, &sets, w, h - strip, 0.06)?)
}
