//! `lse-deform export-system MESH -c CONSTRAINTS -o DIR`: the matrices of
//! a mesh problem as Matrix Market files, with meta.json.

use std::path::PathBuf;

use clap::Args;
use lse_deform::export::{export_meta, export_problem};
use lse_deform::{Deformer, Error, LaplacianKind, mesh};

use super::{MethodArgs, constraints_for, load};

/// Arguments of `export-system`.
#[derive(Args)]
pub struct ExportArgs {
    /// Input mesh.
    mesh: PathBuf,
    /// Constraints file (JSON).
    #[arg(long, short = 'c')]
    constraints: PathBuf,
    /// Laplacian weights.
    #[arg(long, default_value = "cotan")]
    laplacian: LaplacianKind,
    #[command(flatten)]
    method: MethodArgs,
    /// Output directory.
    #[arg(long, short = 'o')]
    output: PathBuf,
}

/// Runs `export-system`.
pub fn export_system(a: ExportArgs) -> Result<(), Error> {
    // Fail fast: the directory (created now, as the export would) must take
    // files before the mesh is read and the system factored.
    std::fs::create_dir_all(&a.output).map_err(|e| Error::io(&a.output, e))?;
    mesh::check_writable(&a.output.join("A.mtx"))?;
    let budget = a.method.budget();
    let mesh = load(&a.mesh, budget)?;
    let constraints = constraints_for(&a.constraints, &mesh, false, budget)?;
    let options = a.method.options()?;
    let mut deformer = Deformer::new(mesh, a.laplacian, constraints)?;
    deformer.precompute_with(&options)?;
    let files = export_problem(&a.output, deformer.problem(), deformer.prepared())?;
    let meta = export_meta(&a.output, deformer.problem(), deformer.report())?;
    eprintln!(
        "wrote {}, {}, {}, {}, {}{}",
        files.a.display(),
        files.c.display(),
        files.b.display(),
        files.d.display(),
        meta.display(),
        files
            .factored
            .map(|f| format!(
                " and {} (the matrix {} factors)",
                f.display(),
                options.formulation.method
            ))
            .unwrap_or_default()
    );
    Ok(())
}
