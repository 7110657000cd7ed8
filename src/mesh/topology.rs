//! Mesh topology: edges, boundary loops, connected components, genus.
//!
//! Everything here is computed from one sort of the `3F` half-edges by their
//! undirected edge key (`O(F log F)`) plus union–find passes, so it runs in
//! well under a second on a million faces.
//!
//! Terminology (for a triangle mesh with `V` vertices, `E` unique edges and
//! `F` faces):
//! - a *boundary edge* is used by exactly one face, a *non-manifold edge* by
//!   more than two;
//! - the *fans* of a vertex are the groups of its incident faces connected
//!   through shared manifold edges around it; a vertex with more than one fan
//!   (e.g. two cones touching at their tips) is a *non-manifold vertex*;
//! - a *boundary loop* is a cycle of boundary edges, consecutive edges being
//!   linked at a vertex through the same fan (so two holes touching at a
//!   vertex count as two loops);
//! - the Euler characteristic is `χ = V − E + F`; for a connected, orientable
//!   2-manifold with `b` boundary loops the genus is `g = (2 − χ − b)/2`.

use super::{Mesh, MeshWarning};

/// Topological summary of a mesh.
///
/// Invariants: `n_boundary_edges + n_non_manifold_edges ≤ n_edges`;
/// `component_sizes.len() == n_components` and the sizes sum to
/// `n_vertices`; `genus` is `Some` only when the mesh is a consistently
/// oriented 2-manifold (no non-manifold edge or vertex).
#[derive(Debug, Clone, PartialEq)]
pub struct Topology {
    /// Number of vertices `V`.
    pub n_vertices: usize,
    /// Number of faces `F`.
    pub n_faces: usize,
    /// Number of unique (undirected) edges `E`.
    pub n_edges: usize,
    /// Number of edges with exactly one incident face.
    pub n_boundary_edges: usize,
    /// Number of boundary loops (0 for a closed mesh).
    pub n_boundary_loops: usize,
    /// Number of edges with more than two incident faces.
    pub n_non_manifold_edges: usize,
    /// Number of vertices with more than one fan of faces around them.
    pub n_non_manifold_vertices: usize,
    /// Number of connected components (of the vertex graph).
    pub n_components: usize,
    /// Vertex count of each component; components are numbered in order of
    /// their smallest vertex, as in [`vertex_components`].
    pub component_sizes: Vec<usize>,
    /// `true` if the faces' orientations agree: every edge with two faces is
    /// traversed in opposite directions by them, and every non-manifold edge
    /// is traversed equally often in each direction.
    pub consistently_oriented: bool,
    /// Euler characteristic `χ = V − E + F` of the whole mesh.
    pub euler_characteristic: i64,
    /// Total genus: the sum over components of `(2 − χ_c − b_c)/2`. `None`
    /// when undefined: a non-manifold edge or vertex, or inconsistent
    /// orientation (the formula is then not the genus).
    pub genus: Option<usize>,
}

/// One half-edge: undirected key `(lo, hi)` and its id `3·face + corner`
/// (the half-edge runs from corner `k` to corner `k+1` of its face).
#[derive(Clone, Copy, Default)]
struct HalfEdge {
    lo: usize,
    hi: usize,
    id: usize,
}

impl HalfEdge {
    fn face(&self) -> usize {
        self.id / 3
    }
    /// `true` if it runs from `lo` to `hi`.
    fn forward(&self, faces: &[[usize; 3]]) -> bool {
        faces[self.id / 3][self.id % 3] == self.lo
    }
}

/// All `3F` half-edges, sorted by `(lo, hi, id)`: a counting sort by `lo`
/// (`O(V + F)`), then a sort of each vertex's few half-edges by `hi`.
fn sorted_half_edges(mesh: &Mesh) -> Vec<HalfEdge> {
    let faces = mesh.faces();
    let mut start = vec![0usize; mesh.n_vertices() + 1];
    for face in faces {
        for k in 0..3 {
            start[face[k].min(face[(k + 1) % 3]) + 1] += 1;
        }
    }
    for v in 1..start.len() {
        start[v] += start[v - 1];
    }
    let mut fill = start.clone();
    let mut h = vec![HalfEdge::default(); 3 * faces.len()];
    for (f, face) in faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (face[k], face[(k + 1) % 3]);
            let lo = a.min(b);
            h[fill[lo]] = HalfEdge {
                lo,
                hi: a.max(b),
                id: 3 * f + k,
            };
            fill[lo] += 1;
        }
    }
    for w in start.windows(2) {
        h[w[0]..w[1]].sort_unstable_by_key(|e| (e.hi, e.id));
    }
    h
}

/// Groups of equal undirected key in a sorted half-edge list, as index ranges.
fn edge_groups(h: &[HalfEdge]) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
    let mut start = 0;
    std::iter::from_fn(move || {
        if start >= h.len() {
            return None;
        }
        let key = (h[start].lo, h[start].hi);
        let mut end = start + 1;
        while end < h.len() && (h[end].lo, h[end].hi) == key {
            end += 1;
        }
        let r = start..end;
        start = end;
        Some(r)
    })
}

/// The corner (`3f + k`) of `e`'s face at its vertex `lo` (`at_lo`) or
/// `hi`: the half-edge runs from corner `k` to `k + 1`, so its tail is
/// corner `k`.
fn corner_id(faces: &[[usize; 3]], e: &HalfEdge, at_lo: bool) -> usize {
    if at_lo == e.forward(faces) {
        e.id
    } else {
        3 * e.face() + (e.id + 1) % 3
    }
}

/// What one pass over the edges finds: the counts, the boundary
/// half-edges, whether the faces agree in orientation (each interior edge
/// used once in each direction; a non-manifold one as often each way), and
/// the fans: corners at the same vertex joined across manifold edges.
struct EdgeScan {
    fans: UnionFind,
    n_edges: usize,
    n_boundary_edges: usize,
    n_non_manifold_edges: usize,
    consistently_oriented: bool,
    boundary: Vec<HalfEdge>,
}

impl EdgeScan {
    /// Scans the half-edges `h` (sorted by edge) of `faces`.
    fn of(h: &[HalfEdge], faces: &[[usize; 3]]) -> EdgeScan {
        let mut scan = EdgeScan {
            fans: UnionFind::new(3 * faces.len()),
            n_edges: 0,
            n_boundary_edges: 0,
            n_non_manifold_edges: 0,
            consistently_oriented: true,
            boundary: Vec::new(),
        };
        for r in edge_groups(h) {
            scan.n_edges += 1;
            let g = &h[r];
            match g.len() {
                1 => {
                    scan.n_boundary_edges += 1;
                    scan.boundary.push(g[0]);
                }
                2 => {
                    if g[0].forward(faces) == g[1].forward(faces) {
                        scan.consistently_oriented = false;
                    }
                    for at_lo in [true, false] {
                        scan.fans.union(
                            corner_id(faces, &g[0], at_lo),
                            corner_id(faces, &g[1], at_lo),
                        );
                    }
                }
                _ => {
                    scan.n_non_manifold_edges += 1;
                    let fwd = g.iter().filter(|e| e.forward(faces)).count();
                    if 2 * fwd != g.len() {
                        scan.consistently_oriented = false;
                    }
                }
            }
        }
        scan
    }
}

/// Vertices (of `n`) with more than one fan of corners: non-manifold.
fn non_manifold_vertices(fans: &mut UnionFind, faces: &[[usize; 3]], n: usize) -> usize {
    let mut fan_count = vec![0usize; n];
    for (f, face) in faces.iter().enumerate() {
        for (k, &v) in face.iter().enumerate() {
            if fans.find(3 * f + k) == 3 * f + k {
                fan_count[v] += 1;
            }
        }
    }
    fan_count.iter().filter(|&&c| c > 1).count()
}

/// Boundary loops: boundary edges linked at a vertex when they lie in the
/// same fan there. Returns their number and the number per component
/// (`comp`: each vertex's component).
fn boundary_loops(
    boundary: &[HalfEdge],
    fans: &mut UnionFind,
    faces: &[[usize; 3]],
    comp: &[usize],
    n_components: usize,
) -> (usize, Vec<i64>) {
    let mut loops = UnionFind::new(boundary.len());
    let mut slot = vec![usize::MAX; 3 * faces.len()];
    for (i, e) in boundary.iter().enumerate() {
        for at_lo in [true, false] {
            let root = fans.find(corner_id(faces, e, at_lo));
            if slot[root] == usize::MAX {
                slot[root] = i;
            } else {
                loops.union(i, slot[root]);
            }
        }
    }
    let mut loops_per_comp = vec![0i64; n_components];
    let mut n_boundary_loops = 0;
    for i in 0..boundary.len() {
        if loops.find(i) == i {
            n_boundary_loops += 1;
            loops_per_comp[comp[boundary[i].lo]] += 1;
        }
    }
    (n_boundary_loops, loops_per_comp)
}

/// `χ = V − E + F` of each component (`comp`: each vertex's component;
/// `h`: the half-edges sorted by edge).
fn euler_per_component(
    comp: &[usize],
    n_components: usize,
    h: &[HalfEdge],
    faces: &[[usize; 3]],
) -> Vec<i64> {
    let mut chi = vec![0i64; n_components];
    for &c in comp {
        chi[c] += 1;
    }
    for r in edge_groups(h) {
        chi[comp[h[r.start].lo]] -= 1;
    }
    for face in faces {
        chi[comp[face[0]]] += 1;
    }
    chi
}

/// The total genus of orientable manifold components from `χ = 2 − 2g − b`
/// (`b`: boundary loops): `None` when some component's `2 − χ − b` is
/// negative or odd (not a surface of that kind).
fn genus_of(chi: &[i64], loops_per_comp: &[i64]) -> Option<usize> {
    chi.iter()
        .zip(loops_per_comp)
        .try_fold(0usize, |acc, (&x, &b)| {
            let twice = 2 - x - b;
            if twice < 0 || twice % 2 != 0 {
                None
            } else {
                usize::try_from(twice / 2).ok().map(|g| acc + g)
            }
        })
}

/// Union–find with path halving; `union` keeps the smaller root, so every
/// root is the smallest element of its set.
pub(crate) struct UnionFind(Vec<usize>);

impl UnionFind {
    /// `n` singletons.
    pub(crate) fn new(n: usize) -> UnionFind {
        UnionFind((0..n).collect())
    }

    /// The root (smallest element) of `x`'s set.
    pub(crate) fn find(&mut self, mut x: usize) -> usize {
        while self.0[x] != x {
            self.0[x] = self.0[self.0[x]];
            x = self.0[x];
        }
        x
    }

    /// Merges the sets of `a` and `b`.
    pub(crate) fn union(&mut self, a: usize, b: usize) {
        let (a, b) = (self.find(a), self.find(b));
        if a != b {
            self.0[a.max(b)] = a.min(b);
        }
    }

    /// `(set of each element, number of sets)`, sets numbered in order of
    /// their smallest element.
    pub(crate) fn components(&mut self) -> (Vec<usize>, usize) {
        let n = self.0.len();
        let mut id = vec![usize::MAX; n];
        let mut comp = vec![0; n];
        let mut count = 0;
        for (v, c) in comp.iter_mut().enumerate() {
            let r = self.find(v);
            if id[r] == usize::MAX {
                id[r] = count;
                count += 1;
            }
            *c = id[r];
        }
        (comp, count)
    }
}

impl Topology {
    /// Computes the summary in `O(V + F log d)` (`d` the largest vertex
    /// degree).
    ///
    /// Phases: the edges ([`EdgeScan::of`], which also joins corner fans),
    /// the non-manifold vertices ([`non_manifold_vertices`]), the boundary
    /// loops ([`boundary_loops`]), the Euler characteristic per component
    /// ([`euler_per_component`]) and the genus ([`genus_of`]).
    pub fn of(mesh: &Mesh) -> Topology {
        let n = mesh.n_vertices();
        let faces = mesh.faces();
        let h = sorted_half_edges(mesh);
        let mut scan = EdgeScan::of(&h, faces);
        let n_non_manifold_vertices = non_manifold_vertices(&mut scan.fans, faces, n);
        let (comp, n_components) = vertex_components(n, faces);
        let mut component_sizes = vec![0usize; n_components];
        for &c in &comp {
            component_sizes[c] += 1;
        }
        let (n_boundary_loops, loops_per_comp) =
            boundary_loops(&scan.boundary, &mut scan.fans, faces, &comp, n_components);
        let chi = euler_per_component(&comp, n_components, &h, faces);
        let euler_characteristic = chi.iter().sum();
        let genus = if scan.n_non_manifold_edges == 0
            && n_non_manifold_vertices == 0
            && scan.consistently_oriented
        {
            genus_of(&chi, &loops_per_comp)
        } else {
            None
        };
        Topology {
            n_vertices: n,
            n_faces: faces.len(),
            n_edges: scan.n_edges,
            n_boundary_edges: scan.n_boundary_edges,
            n_boundary_loops,
            n_non_manifold_edges: scan.n_non_manifold_edges,
            n_non_manifold_vertices,
            n_components,
            component_sizes,
            consistently_oriented: scan.consistently_oriented,
            euler_characteristic,
            genus,
        }
    }

    /// `true` if the mesh has no boundary edge.
    pub fn is_closed(&self) -> bool {
        self.n_boundary_edges == 0
    }

    /// `true` if no edge has more than two faces and every vertex has a
    /// single fan of faces.
    pub fn is_manifold(&self) -> bool {
        self.n_non_manifold_edges == 0 && self.n_non_manifold_vertices == 0
    }
}

/// The unique undirected edges of a mesh, each as `[a, b]` with `a < b`,
/// sorted lexicographically.
pub fn edges(mesh: &Mesh) -> Vec<[usize; 2]> {
    let h = sorted_half_edges(mesh);
    edge_groups(&h)
        .map(|r| [h[r.start].lo, h[r.start].hi])
        .collect()
}

/// The vertex adjacency graph in compressed sparse row form `(offsets,
/// neighbors)`: the neighbors of vertex `v` are
/// `neighbors[offsets[v]..offsets[v + 1]]`, sorted ascending and without
/// duplicates. `offsets.len() == n_vertices + 1` and
/// `neighbors.len() == 2 · n_edges`.
pub fn vertex_neighbors(mesh: &Mesh) -> (Vec<usize>, Vec<usize>) {
    let e = edges(mesh);
    let n = mesh.n_vertices();
    let mut offsets = vec![0usize; n + 1];
    for &[a, b] in &e {
        offsets[a + 1] += 1;
        offsets[b + 1] += 1;
    }
    for v in 0..n {
        offsets[v + 1] += offsets[v];
    }
    let mut fill = offsets.clone();
    let mut neighbors = vec![0usize; 2 * e.len()];
    // Edges are sorted by (a, b): vertex v first receives its smaller
    // neighbors (from edges (u, v), in increasing u), then its larger ones
    // (from edges (v, w), in increasing w), so each list comes out sorted.
    for &[a, b] in &e {
        neighbors[fill[a]] = b;
        fill[a] += 1;
        neighbors[fill[b]] = a;
        fill[b] += 1;
    }
    (offsets, neighbors)
}

/// The non-manifold-edge warning of a mesh, if it has any such edge: the
/// first such edge in sorted order, its face count and the total count.
pub(crate) fn non_manifold_warning(mesh: &Mesh) -> Option<MeshWarning> {
    let h = sorted_half_edges(mesh);
    let mut first: Option<([usize; 2], usize)> = None;
    let mut total = 0;
    for r in edge_groups(&h) {
        if r.len() > 2 {
            total += 1;
            if first.is_none() {
                first = Some(([h[r.start].lo, h[r.start].hi], r.len()));
            }
        }
    }
    first.map(|(edge, faces)| MeshWarning::NonManifoldEdge { edge, faces, total })
}

/// Connected components of the vertex graph: `(component of each vertex,
/// number of components)`, components numbered in order of their smallest
/// vertex.
pub fn vertex_components(n_vertices: usize, faces: &[[usize; 3]]) -> (Vec<usize>, usize) {
    let mut sets = UnionFind::new(n_vertices);
    for f in faces {
        for k in 0..3 {
            sets.union(f[k], f[(k + 1) % 3]);
        }
    }
    sets.components()
}

#[cfg(test)]
mod phase_tests {
    use super::*;

    /// Two triangles sharing only vertex 0 (a bowtie), the second listed
    /// against the first's orientation at no shared edge.
    fn bowtie() -> Mesh {
        Mesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [-1.0, 0.0, 0.0],
                [0.0, -1.0, 0.0],
            ],
            vec![[0, 1, 2], [0, 3, 4]],
        )
        .unwrap()
    }

    #[test]
    fn genus_from_euler_characteristic_and_boundary_loops() {
        assert_eq!(genus_of(&[2], &[0]), Some(0)); // sphere
        assert_eq!(genus_of(&[0], &[0]), Some(1)); // torus
        assert_eq!(genus_of(&[1, -2], &[1, 0]), Some(2)); // disc + genus 2
        assert_eq!(genus_of(&[1], &[0]), None); // odd
        assert_eq!(genus_of(&[3], &[0]), None); // negative
    }

    #[test]
    fn edge_scan_counts_and_fans_of_a_bowtie() {
        let mesh = bowtie();
        let h = sorted_half_edges(&mesh);
        let mut scan = EdgeScan::of(&h, mesh.faces());
        assert_eq!(
            (
                scan.n_edges,
                scan.n_boundary_edges,
                scan.n_non_manifold_edges
            ),
            (6, 6, 0)
        );
        assert!(scan.consistently_oriented);
        // Vertex 0 has two fans (one per triangle): non-manifold.
        assert_eq!(non_manifold_vertices(&mut scan.fans, mesh.faces(), 5), 1);
        let comp = vec![0; 5];
        let (loops, per_comp) =
            boundary_loops(&scan.boundary, &mut scan.fans, mesh.faces(), &comp, 1);
        assert_eq!((loops, per_comp), (2, vec![2]));
        // V − E + F = 5 − 6 + 2.
        assert_eq!(euler_per_component(&comp, 1, &h, mesh.faces()), [1]);
    }

    #[test]
    fn a_flipped_neighbour_is_inconsistent_orientation() {
        let mesh = Mesh::new(
            vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]],
            vec![[0, 1, 2], [1, 2, 3]],
        )
        .unwrap();
        let h = sorted_half_edges(&mesh);
        let scan = EdgeScan::of(&h, mesh.faces());
        assert_eq!((scan.n_edges, scan.n_boundary_edges), (5, 4));
        assert!(!scan.consistently_oriented);
    }
}
