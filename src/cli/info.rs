//! `lse-deform info MESH`: counts, topology and triangle quality.

use std::path::PathBuf;

use clap::Args;
use lse_deform::Error;
use lse_deform::mesh::{Quality, Topology};

use super::load;

/// Arguments of `info`.
#[derive(Args)]
pub struct InfoArgs {
    /// Input mesh.
    mesh: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// Runs `info`, as text or JSON.
pub(crate) fn info(a: InfoArgs) -> Result<(), Error> {
    let mesh = load(&a.mesh, lse_deform::limits::MemoryBudget::default())?;
    let topo = Topology::of(&mesh);
    let q = Quality::of(&mesh);
    let (lo, hi) = mesh.bounding_box();
    if a.json {
        let v = serde_json::json!({
            "vertices": mesh.n_vertices(),
            "faces": mesh.n_faces(),
            "edges": topo.n_edges,
            "boundary_edges": topo.n_boundary_edges,
            "boundary_loops": topo.n_boundary_loops,
            "non_manifold_edges": topo.n_non_manifold_edges,
            "components": topo.n_components,
            "consistently_oriented": topo.consistently_oriented,
            "euler_characteristic": topo.euler_characteristic,
            "genus": topo.genus,
            "bbox_min": lo,
            "bbox_max": hi,
            "bbox_diagonal": mesh.bbox_diagonal(),
            "min_angle_deg": q.min_angle_deg,
            "max_angle_deg": q.max_angle_deg,
            "max_aspect_ratio": q.max_aspect_ratio,
            "percent_min_angle_below_10deg": q.percent_below_10_deg,
            "faces_min_angle_below_1deg": q.count_below_1_deg,
            "edge_length_ratio": q.edge_length_ratio,
        });
        out!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return Ok(());
    }
    out!("vertices            {}", mesh.n_vertices());
    out!("faces               {}", mesh.n_faces());
    out!("edges               {}", topo.n_edges);
    out!(
        "boundary            {} edges in {} loops{}",
        topo.n_boundary_edges,
        topo.n_boundary_loops,
        if topo.n_boundary_edges == 0 {
            " (closed)"
        } else {
            ""
        }
    );
    out!("non-manifold edges  {}", topo.n_non_manifold_edges);
    out!("components          {}", topo.n_components);
    out!(
        "orientation         {}",
        if topo.consistently_oriented {
            "consistent"
        } else {
            "inconsistent"
        }
    );
    out!("Euler char.         {}", topo.euler_characteristic);
    out!(
        "genus               {}",
        topo.genus
            .map(|g| g.to_string())
            .unwrap_or_else(|| "undefined (non-manifold)".into())
    );
    out!(
        "bounding box        {lo:?} .. {hi:?} (diagonal {:.6})",
        mesh.bbox_diagonal()
    );
    out!(
        "angles              min {:.4} deg, max {:.4} deg",
        q.min_angle_deg,
        q.max_angle_deg
    );
    out!("worst aspect ratio  {:.2}", q.max_aspect_ratio);
    out!(
        "slivers             {:.2}% of faces with min angle < 10 deg, {} below 1 deg",
        q.percent_below_10_deg,
        q.count_below_1_deg
    );
    out!("edge length ratio   {:.1}", q.edge_length_ratio);
    Ok(())
}
