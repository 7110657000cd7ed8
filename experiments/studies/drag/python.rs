//! The Python rows of `drag`: `experiments/drag_python.py` drags the same
//! frames through the Python door, once by the handle basis
//! (`Deformer.basis(["handle"]).evaluate({"handle": M})`) and once by
//! `transform_group("handle", M)` + `solve()` (the default refinement),
//! in one warm Python process of [`environment::python_with_package`]
//! (this checkout's package). The frames are handed over as the handle's
//! transforms, so that every row of the section drags the same targets;
//! the script's mid-drag shapes come back for the deviation. Without a
//! Python the rows say what was not measured and why.

use std::ffi::OsStr;
use std::path::Path;

use lse_deform::ConstraintSet;
use lse_deform::deform::Affine;
use lse_deform::mesh::{Mesh, write_mesh};
use serde::Deserialize;

use crate::harness::context::AnyError;
use crate::harness::environment::{self, Python};

/// What the script prints.
#[derive(Debug, Clone, Deserialize)]
pub struct Measured {
    pub python_version: String,
    pub numpy_version: String,
    /// Seconds of `Deformer.basis(["handle"])`.
    pub basis_build_s: f64,
    /// Per frame: `basis.evaluate` into a buffer kept across frames.
    pub basis_s: Vec<f64>,
    /// Per frame: `transform_group` + `solve`, wall clock.
    pub solve_frame_s: Vec<f64>,
    /// Per frame: the report's `timings_s.solve` and `timings_s.refine`.
    pub solve_phase_s: Vec<f64>,
    pub refine_s: Vec<f64>,
    /// Max over frames of the hard-constraint residual over the diagonal.
    pub basis_residual: f64,
    pub solve_residual: f64,
}

/// The script's measurements, the mid-drag shapes of its two rows (mesh
/// units) and where its Python came from.
pub struct PythonRows {
    pub measured: Measured,
    pub basis_middle: Vec<[f64; 3]>,
    pub solve_middle: Vec<[f64; 3]>,
    pub origin: String,
}

/// Runs the script on `mesh` and `constraints` with the handle transforms
/// `frames`, keeping frame `middle` (1-based); `Err` says why not.
pub fn measure(
    mesh: &Mesh,
    constraints: &ConstraintSet,
    frames: &[Affine],
    middle: usize,
) -> Result<PythonRows, String> {
    let python = environment::python_with_package()?;
    let io = std::env::temp_dir().join(format!("lse-drag-python-{}", std::process::id()));
    let outcome = std::fs::create_dir_all(&io)
        .map_err(|e| format!("a temporary directory: {e}"))
        .and_then(|()| run_script(&python, &io, mesh, constraints, frames, middle));
    let _ = std::fs::remove_dir_all(&io);
    outcome
}

/// Writes the inputs into `io`, runs the script and reads its answers.
fn run_script(
    python: &Python,
    io: &Path,
    mesh: &Mesh,
    constraints: &ConstraintSet,
    frames: &[Affine],
    middle: usize,
) -> Result<PythonRows, String> {
    let inputs = || -> Result<(), AnyError> {
        write_mesh(mesh, &io.join("mesh.obj"))?;
        std::fs::write(io.join("scene.json"), constraints.to_json())?;
        let bytes: Vec<u8> = frames
            .iter()
            .flat_map(|m| m.iter().flatten().flat_map(|v| v.to_ne_bytes()))
            .collect();
        std::fs::write(io.join("frames.bin"), bytes)?;
        Ok(())
    };
    inputs().map_err(|e| format!("writing the script's inputs: {e}"))?;
    let middle = middle.to_string();
    let paths = [
        io.join("mesh.obj"),
        io.join("scene.json"),
        io.join("frames.bin"),
    ];
    let mut args: Vec<&OsStr> = paths.iter().map(|p| p.as_os_str()).collect();
    args.extend([OsStr::new(&middle), io.as_os_str()]);
    let stdout = python.script("drag_python.py", &args)?;
    let measured: Measured = serde_json::from_slice(&stdout)
        .map_err(|e| format!("drag_python.py printed no measurement: {e}"))?;
    let n = mesh.n_vertices();
    Ok(PythonRows {
        measured,
        basis_middle: read_positions(&io.join("basis_middle.bin"), n)?,
        solve_middle: read_positions(&io.join("solve_middle.bin"), n)?,
        origin: python.origin.clone(),
    })
}

/// `n` positions written by numpy's `tofile` (float64, native order).
fn read_positions(path: &Path, n: usize) -> Result<Vec<[f64; 3]>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if bytes.len() != n * 24 {
        return Err(format!(
            "drag_python.py wrote {} bytes of positions, expected {}",
            bytes.len(),
            n * 24
        ));
    }
    Ok(bytes
        .chunks_exact(24)
        .map(|p| {
            let v = |k: usize| f64::from_ne_bytes(p[8 * k..8 * k + 8].try_into().unwrap_or([0; 8]));
            [v(0), v(1), v(2)]
        })
        .collect())
}
