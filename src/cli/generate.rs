//! `lse-deform generate KIND --vertices N -o OUT`: a generated mesh.

use std::path::PathBuf;

use clap::Args;
use lse_deform::mesh::generate::{self, GeneratedKind};
use lse_deform::{Error, mesh};

/// Arguments of `generate`.
#[derive(Args)]
pub struct GenerateArgs {
    /// icosphere, bumpy-sphere, grid, unsymmetric-grid or sliver.
    kind: GeneratedKind,
    /// Approximate number of vertices.
    #[arg(long, default_value_t = 10_000)]
    vertices: usize,
    /// Seed of the random parts (bumps, slivers).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output mesh (.obj, .ply or .off).
    #[arg(long, short = 'o')]
    output: PathBuf,
}

/// Runs `generate`: the mesh of the kind nearest the vertex count asked for.
pub(crate) fn generate(a: GenerateArgs) -> Result<(), Error> {
    let kind = a.kind;
    super::notes(mesh::check_mesh_output(&a.output)?);
    let size = generate::size_for_vertices(kind, a.vertices)?;
    let mesh = generate::generate(kind, size, a.seed)?;
    mesh::write_mesh(&mesh, &a.output)?;
    let n = mesh.n_vertices();
    let nearest = if n == a.vertices {
        String::new()
    } else {
        // The family's sizes next to the one chosen, so the user sees why N
        // was not hit exactly.
        let neighbours: Vec<String> = [size.checked_sub(1), size.checked_add(1)]
            .into_iter()
            .flatten()
            .filter(|&s| s >= kind.min_size())
            .filter_map(|s| kind.vertex_count(s))
            .map(|c| c.to_string())
            .collect();
        format!(
            " (the nearest {kind} to the {} vertices asked for; the neighbouring sizes have {})",
            a.vertices,
            neighbours.join(" and ")
        )
    };
    eprintln!(
        "{kind}: {n} vertices, {} faces{nearest} -> {}",
        mesh.n_faces(),
        a.output.display()
    );
    Ok(())
}
