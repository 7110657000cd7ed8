//! `lse-deform scene MESH -o CONSTRAINTS`: a constraints file that fixes
//! the bottom of a mesh and drags a handle at its top (with optional extra
//! constraint kinds, a duplicate and a conflict).

use std::path::PathBuf;

use clap::Args;
use lse_deform::Error;
use lse_deform::scene::{AxisDirection, FixedAndHandle, MixedScene, ParseAxisError};

use super::files::check_distinct;
use super::{check_outputs, load};

/// Arguments of `scene`.
#[derive(Args)]
pub struct SceneArgs {
    /// Input mesh.
    mesh: PathBuf,
    /// Fraction of vertices fixed at the bottom.
    #[arg(long, default_value_t = 0.2)]
    fixed: f64,
    /// Fraction of vertices in the handle at the top.
    #[arg(long, default_value_t = 0.02)]
    handle: f64,
    /// Axis from bottom to top: x, y or z, or -x, -y, -z for the other way
    /// (the fixed region at the largest coordinates). Default: the longest
    /// extent, ascending — on a y-up model whose longest extent is not y
    /// (the Stanford Bunny: x) that fixes one end, not the feet; give
    /// --axis y for those.
    #[arg(long, allow_hyphen_values = true)]
    axis: Option<String>,
    /// Handle displacement "dx,dy,dz" (default: 15% of the bounding-box
    /// diagonal, perpendicular to the axis).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    offset: Option<[f64; 3]>,
    /// Make the handle soft with this weight (default: hard).
    #[arg(long)]
    handle_weight: Option<f64>,
    /// Add this many relative constraints (a spanning tree of a patch in the
    /// middle, keeping its shape).
    #[arg(long, default_value_t = 0)]
    relative: usize,
    /// Add this many on-edge constraints (edge midpoints moved).
    #[arg(long, default_value_t = 0)]
    edges: usize,
    /// Add this many on-face constraints (face centroids moved).
    #[arg(long, default_value_t = 0)]
    faces: usize,
    /// Append a duplicate of the first fixed constraint (redundant).
    #[arg(long)]
    duplicate: bool,
    /// Append a constraint contradicting the second fixed one (conflicting).
    #[arg(long)]
    conflict: bool,
    /// Output constraints file.
    #[arg(long, short = 'o')]
    output: PathBuf,
}

fn parse_vec3(s: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("expected three comma-separated numbers, got '{s}'"));
    }
    let mut v = [0.0; 3];
    for (o, p) in v.iter_mut().zip(parts) {
        *o = p.trim().parse::<f64>().map_err(|e| format!("'{p}': {e}"))?;
        if !o.is_finite() {
            return Err(format!("'{p}' is not finite"));
        }
    }
    Ok(v)
}

/// Runs `scene`.
pub(crate) fn scene(a: SceneArgs) -> Result<(), Error> {
    check_distinct(
        &[("the input mesh", a.mesh.as_path())],
        &[("-o", a.output.as_path())],
    )?;
    check_outputs(None, Some(&a.output))?;
    let mesh = load(&a.mesh, lse_deform::limits::MemoryBudget::default())?;
    let mut s = FixedAndHandle::paper_default(&mesh);
    if let Some(axis) = &a.axis {
        let dir: AxisDirection = axis.parse().map_err(|e: ParseAxisError| {
            lse_deform::error::ProblemError::InvalidArgument {
                message: format!("--axis {e}"),
            }
        })?;
        s.axis = dir.axis;
        s.descending = dir.descending;
        s.offset = FixedAndHandle::default_offset(&mesh, s.axis);
    }
    if let Some(o) = a.offset {
        s.offset = o;
    }
    s.fixed_fraction = a.fixed;
    s.handle_fraction = a.handle;
    s.handle_weight = a.handle_weight;
    let mixed = MixedScene {
        base: s.clone(),
        relative: a.relative,
        edges: a.edges,
        faces: a.faces,
        duplicate: a.duplicate,
        conflict: a.conflict,
    };
    let set = mixed.constraints(&mesh)?;
    lse_deform::atomic::write_bytes(&a.output, set.to_json().as_bytes())
        .map_err(|e| Error::io(&a.output, e))?;
    let (fixed, handle) = s.regions(&mesh)?;
    let mut extra = String::new();
    for (count, what) in [
        (a.relative, "relative"),
        (a.edges, "on-edge"),
        (a.faces, "on-face"),
        (usize::from(a.duplicate), "duplicate"),
        (usize::from(a.conflict), "conflicting"),
    ] {
        if count > 0 {
            extra.push_str(&format!(" + {count} {what}"));
        }
    }
    eprintln!(
        "{} constraints: {} fixed + {} handle vertices{extra} (axis {}{}, offset {:?}) -> {}",
        set.len(),
        fixed.len(),
        handle.len(),
        if s.descending { "-" } else { "" },
        s.axis.name(),
        s.offset,
        a.output.display()
    );
    Ok(())
}
