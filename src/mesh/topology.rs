//! Mesh topology: edges, boundary loops, connected components, genus.

use super::{Mesh, MeshWarning};

/// Topological summary of a mesh.
#[derive(Debug, Clone)]
pub struct Topology {}

/// The non-manifold-edge warning of a mesh, if it has any such edge.
pub(crate) fn non_manifold_warning(mesh: &Mesh) -> Option<MeshWarning> {
    let _ = mesh;
    None
}

/// Connected components of the vertex graph: `(component of each vertex,
/// number of components)`, components numbered in order of their smallest
/// vertex.
pub fn vertex_components(n_vertices: usize, faces: &[[usize; 3]]) -> (Vec<usize>, usize) {
    let mut parent: Vec<usize> = (0..n_vertices).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for f in faces {
        for k in 0..3 {
            let (a, b) = (find(&mut parent, f[k]), find(&mut parent, f[(k + 1) % 3]));
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut id = vec![usize::MAX; n_vertices];
    let mut comp = vec![0; n_vertices];
    let mut count = 0;
    for v in 0..n_vertices {
        let r = find(&mut parent, v);
        if id[r] == usize::MAX {
            id[r] = count;
            count += 1;
        }
        comp[v] = id[r];
    }
    (comp, count)
}
