//! `lse-deform export-system MESH -c CONSTRAINTS -o DIR`: the matrices of
//! a mesh problem as Matrix Market files, with meta.json.

use std::path::PathBuf;

use clap::Args;
use lse_deform::export::{META_FILE, create_output_dir, export_meta, export_problem};
use lse_deform::options::DeformOptions;
use lse_deform::{Deformer, Error, LaplacianKind, mesh};

use super::files::{check_distinct, mesh_and_constraints};
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
    #[arg(long, default_value_t = DeformOptions::default().laplacian)]
    laplacian: LaplacianKind,
    #[command(flatten)]
    method: MethodArgs,
    /// Output directory.
    #[arg(long, short = 'o')]
    output: PathBuf,
}

/// Runs `export-system`.
pub(crate) fn export_system(a: ExportArgs) -> Result<(), Error> {
    // Fail fast: no file of the export may be an input, and the directory
    // (created now, as the export would) must take files, before the mesh
    // is read and the system factored.
    let names = [
        "A.mtx",
        "C.mtx",
        "B.mtx",
        "D.mtx",
        "factored.mtx",
        META_FILE,
    ];
    let paths = names.map(|n| a.output.join(n));
    let outputs: Vec<_> = paths.iter().map(|p| ("-o", p.as_path())).collect();
    let mut inputs = mesh_and_constraints(&a.mesh, &a.constraints).to_vec();
    inputs.extend(a.method.held.inputs());
    check_distinct(&inputs, &outputs)?;
    create_output_dir(&a.output)?;
    super::notes(mesh::check_writable(&paths[0])?);
    let budget = a.method.budget();
    let mesh = load(&a.mesh, budget)?;
    let constraints = constraints_for(&a.constraints, &mesh, false, budget)?;
    let options = a.method.options()?.solve;
    let deformer = Deformer::new(mesh, a.laplacian, constraints, &options)?;
    // Staged: a failed write leaves no file of this export, and the files
    // of an earlier one as they were.
    let (files, meta) = super::staged(|| {
        let files = export_problem(
            &a.output,
            deformer.problem(),
            Some(deformer.solver().prepared()),
        )?;
        let meta = export_meta(&a.output, deformer.problem(), deformer.report())?;
        Ok((files, meta))
    })?;
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
