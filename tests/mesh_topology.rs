//! Topology, quality and generators, on hand-built meshes with hand-computed
//! values, and on the real test meshes against their README statistics.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use lse_deform::error::MeshError;
use lse_deform::mesh::generate::{self, GeneratedKind};
use lse_deform::mesh::quality::triangle_quality;
use lse_deform::mesh::topology::{edges, vertex_components, vertex_neighbors};
use lse_deform::mesh::{Mesh, MeshWarning, Quality, Topology, read_mesh};

// ---------------------------------------------------------------------------
// helpers

fn mesh(p: &[[f64; 3]], f: &[[usize; 3]]) -> Mesh {
    Mesh::new(p.to_vec(), f.to_vec()).unwrap()
}

fn tetrahedron() -> Mesh {
    mesh(
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ],
        &[[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    )
}

/// Torus with `n × m` quads (split in two), radii 2 and 0.7.
fn torus(n: usize, m: usize) -> Mesh {
    let mut p = Vec::new();
    for i in 0..n {
        let u = 2.0 * PI * i as f64 / n as f64;
        for j in 0..m {
            let v = 2.0 * PI * j as f64 / m as f64;
            let r = 2.0 + 0.7 * v.cos();
            p.push([r * u.cos(), r * u.sin(), 0.7 * v.sin()]);
        }
    }
    let id = |i: usize, j: usize| (i % n) * m + (j % m);
    let mut f = Vec::new();
    for i in 0..n {
        for j in 0..m {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            f.push([a, b, c]);
            f.push([a, c, d]);
        }
    }
    mesh(&p, &f)
}

/// Annulus with `rings` rings of `segments` quads between radii 1 and 2.
fn annulus(rings: usize, segments: usize) -> Mesh {
    let mut p = Vec::new();
    for k in 0..=rings {
        let r = 1.0 + k as f64 / rings as f64;
        for s in 0..segments {
            let t = 2.0 * PI * s as f64 / segments as f64;
            p.push([r * t.cos(), r * t.sin(), 0.0]);
        }
    }
    let id = |k: usize, s: usize| k * segments + s % segments;
    let mut f = Vec::new();
    for k in 0..rings {
        for s in 0..segments {
            let (a, b, c, d) = (id(k, s), id(k, s + 1), id(k + 1, s + 1), id(k + 1, s));
            f.push([a, b, c]);
            f.push([a, c, d]);
        }
    }
    mesh(&p, &f)
}

/// Signed volume `Σ det(a, b, c) / 6` (positive for outward orientation).
fn signed_volume(m: &Mesh) -> f64 {
    let p = m.positions();
    m.faces()
        .iter()
        .map(|&[a, b, c]| {
            let (a, b, c) = (p[a], p[b], p[c]);
            (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]))
                / 6.0
        })
        .sum()
}

/// `z` component of `(b − a) × (c − a)` for every face.
fn signed_areas_z(m: &Mesh) -> Vec<f64> {
    let p = m.positions();
    m.faces()
        .iter()
        .map(|&[a, b, c]| {
            let (a, b, c) = (p[a], p[b], p[c]);
            (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        })
        .collect()
}

fn assert_close(a: f64, b: f64, tol: f64) {
    assert!((a - b).abs() <= tol, "{a} vs {b} (tolerance {tol})");
}

// ---------------------------------------------------------------------------
// topology on hand-built meshes

#[test]
fn single_triangle() {
    let m = mesh(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        &[[0, 1, 2]],
    );
    let t = Topology::of(&m);
    assert_eq!(
        (
            t.n_vertices,
            t.n_faces,
            t.n_edges,
            t.n_boundary_edges,
            t.n_boundary_loops
        ),
        (3, 1, 3, 3, 1)
    );
    assert_eq!(t.euler_characteristic, 1);
    assert_eq!(t.genus, Some(0));
    assert!(t.consistently_oriented && t.is_manifold() && !t.is_closed());

    // Right isosceles: angles 90, 45, 45; aspect ratio (√2 / (1/√2))·√3/2 = √3.
    let q = Quality::of(&m);
    assert_close(q.min_angle_deg, 45.0, 1e-12);
    assert_close(q.max_angle_deg, 90.0, 1e-12);
    assert_close(q.max_aspect_ratio, 3f64.sqrt(), 1e-12);
    assert_close(q.edge_length_ratio, 2f64.sqrt(), 1e-12);
    assert_eq!(q.percent_below_10_deg, 0.0);
    assert_eq!(q.count_below_1_deg, 0);
    let tq = triangle_quality([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    assert_close(tq.angles_deg[0], 90.0, 1e-12);
    assert_close(tq.angles_deg[1], 45.0, 1e-12);
    assert_close(tq.angles_deg[2], 45.0, 1e-12);
}

#[test]
fn quality_of_equilateral_and_sliver_triangles() {
    let h = 3f64.sqrt() / 2.0;
    let eq = triangle_quality([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, h, 0.0]);
    assert_close(eq.aspect_ratio, 1.0, 1e-12);
    for a in eq.angles_deg {
        assert_close(a, 60.0, 1e-12);
    }
    // Isosceles sliver with base angles 0.5°: apex 179°; longest edge 1,
    // height y = tan(0.5°)/2, so AR = 1 / (2·(y/2)/1)·… = √3 / (2y).
    let y = 0.5 * 0.5f64.to_radians().tan();
    let m = mesh(
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, y, 0.0],
            [0.5, -h, 0.0],
        ],
        &[[0, 3, 1], [0, 1, 2]],
    );
    let q = Quality::of(&m);
    assert_close(q.min_angle_deg, 0.5, 1e-9);
    assert_eq!(q.min_angle_face, 1);
    assert_close(q.max_angle_deg, 179.0, 1e-9);
    assert_eq!(q.max_angle_face, 1);
    assert_close(q.max_aspect_ratio, 3f64.sqrt() / (2.0 * y), 1e-9);
    assert_eq!(q.max_aspect_ratio_face, 1);
    assert_eq!(q.percent_below_10_deg, 50.0);
    assert_eq!(q.count_below_1_deg, 1);
    // Shortest edge: the sliver's sides, sqrt(0.25 + y²).
    assert_close(q.edge_length_ratio, 1.0 / (0.25 + y * y).sqrt(), 1e-12);
}

#[test]
fn tetrahedron_is_closed_genus_zero() {
    let m = tetrahedron();
    let t = Topology::of(&m);
    assert_eq!(
        (t.n_edges, t.n_boundary_edges, t.n_boundary_loops),
        (6, 0, 0)
    );
    assert_eq!(t.euler_characteristic, 2);
    assert_eq!(t.genus, Some(0));
    assert!(t.is_closed() && t.consistently_oriented);
    assert_eq!(t.component_sizes, vec![4]);
    assert!(signed_volume(&m) > 0.0);
    assert_eq!(
        edges(&m),
        vec![[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    );
    assert!(m.warnings().is_empty());
}

#[test]
fn flipped_face_breaks_orientation_and_genus() {
    let m = mesh(
        tetrahedron().positions(),
        &[[0, 1, 2], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    );
    let t = Topology::of(&m);
    assert!(!t.consistently_oriented);
    assert_eq!(t.genus, None);
    assert_eq!(t.euler_characteristic, 2);
}

#[test]
fn torus_has_genus_one() {
    let m = torus(8, 6);
    let t = Topology::of(&m);
    assert_eq!((t.n_vertices, t.n_edges, t.n_faces), (48, 144, 96));
    assert_eq!(t.euler_characteristic, 0);
    assert_eq!(t.genus, Some(1));
    assert!(t.is_closed() && t.is_manifold() && t.consistently_oriented);
}

#[test]
fn annulus_has_two_loops_and_genus_zero() {
    let t = Topology::of(&annulus(2, 12));
    assert_eq!(t.n_boundary_edges, 24);
    assert_eq!(t.n_boundary_loops, 2);
    assert_eq!(t.euler_characteristic, 0);
    assert_eq!(t.genus, Some(0));
}

#[test]
fn components_and_genus_sum() {
    // A torus and a tetrahedron side by side, and a lone triangle.
    let a = torus(6, 5);
    let b = tetrahedron();
    let mut p = a.positions().to_vec();
    let mut f = a.faces().to_vec();
    let off = p.len();
    p.extend(b.positions().iter().map(|q| [q[0] + 10.0, q[1], q[2]]));
    f.extend(
        b.faces()
            .iter()
            .map(|t| [t[0] + off, t[1] + off, t[2] + off]),
    );
    let off = p.len();
    p.extend([[20.0, 0.0, 0.0], [21.0, 0.0, 0.0], [20.0, 1.0, 0.0]]);
    f.push([off, off + 1, off + 2]);
    let m = mesh(&p, &f);
    let t = Topology::of(&m);
    assert_eq!(t.n_components, 3);
    assert_eq!(t.component_sizes, vec![30, 4, 3]);
    assert_eq!(t.euler_characteristic, 2 + 1);
    assert_eq!(t.n_boundary_loops, 1);
    assert_eq!(t.genus, Some(1));
    let (comp, n) = vertex_components(m.n_vertices(), m.faces());
    assert_eq!(n, 3);
    assert_eq!((comp[0], comp[30], comp[34]), (0, 1, 2));
}

#[test]
fn non_manifold_edge_is_reported() {
    let m = mesh(
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 1.0, 0.0],
            [0.5, -1.0, 0.0],
            [0.5, 0.0, 1.0],
        ],
        &[[0, 1, 2], [1, 0, 3], [0, 1, 4]],
    );
    let t = Topology::of(&m);
    assert_eq!(t.n_non_manifold_edges, 1);
    assert_eq!(t.n_boundary_edges, 6);
    assert_eq!(t.genus, None);
    assert!(!t.is_manifold());
    let w = m.warnings();
    assert_eq!(
        w,
        vec![MeshWarning::NonManifoldEdge {
            edge: [0, 1],
            faces: 3,
            total: 1
        }]
    );
    assert!(w[0].to_string().contains("edge (0, 1) used by 3 faces"));
}

#[test]
fn bowtie_vertex_is_non_manifold_with_two_loops() {
    let m = mesh(
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.5, 0.0],
            [1.0, -0.5, 0.0],
            [-1.0, 0.5, 0.0],
            [-1.0, -0.5, 0.0],
        ],
        &[[0, 2, 1], [0, 3, 4]],
    );
    let t = Topology::of(&m);
    assert_eq!(t.n_non_manifold_vertices, 1);
    assert_eq!(t.n_non_manifold_edges, 0);
    assert_eq!(t.n_boundary_loops, 2);
    assert_eq!(t.n_components, 1);
    assert_eq!(t.genus, None);
}

#[test]
fn neighbors_in_csr_form() {
    // grid(2, 1): rows 0 1 2 / 3 4 5, diagonals 0-4 and 1-5.
    let m = generate::grid(2, 1).unwrap();
    let (offsets, neighbors) = vertex_neighbors(&m);
    assert_eq!(offsets, vec![0, 3, 7, 9, 11, 15, 18]);
    assert_eq!(
        neighbors,
        vec![1, 3, 4, 0, 2, 4, 5, 1, 5, 0, 4, 0, 1, 3, 5, 1, 2, 4]
    );
    assert_eq!(neighbors.len(), 2 * edges(&m).len());
}

// ---------------------------------------------------------------------------
// generators

#[test]
fn icospheres() {
    for k in 0..=4u32 {
        let m = generate::icosphere(k).unwrap();
        let p4 = 4usize.pow(k);
        assert_eq!(m.n_vertices(), 10 * p4 + 2);
        assert_eq!(m.n_faces(), 20 * p4);
        let t = Topology::of(&m);
        assert!(t.is_closed() && t.is_manifold() && t.consistently_oriented);
        assert_eq!(t.euler_characteristic, 2);
        assert_eq!(t.genus, Some(0));
        assert_eq!(t.n_components, 1);
        for p in m.positions() {
            assert_close((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt(), 1.0, 1e-12);
        }
        assert!(signed_volume(&m) > 0.0, "outward orientation");
    }
    // Inscribed polyhedron: volume just below 4π/3.
    let v = signed_volume(&generate::icosphere(4).unwrap());
    assert!(v < 4.0 * PI / 3.0 && v > 0.99 * 4.0 * PI / 3.0, "{v}");
    assert!(matches!(
        generate::icosphere(12),
        Err(MeshError::BadParameter {
            name: "subdivisions",
            ..
        })
    ));
}

#[test]
fn bumpy_spheres() {
    let m = generate::bumpy_sphere(3, 0.2, 5).unwrap();
    assert_eq!(m.n_vertices(), 642);
    let t = Topology::of(&m);
    assert_eq!(t.genus, Some(0));
    assert!(t.is_closed() && t.consistently_oriented);
    let radii: Vec<f64> = m
        .positions()
        .iter()
        .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
        .collect();
    assert!(
        radii
            .iter()
            .all(|&r| (0.8 - 1e-12..=1.2 + 1e-12).contains(&r))
    );
    let spread =
        radii.iter().cloned().fold(0.0, f64::max) - radii.iter().cloned().fold(9.0, f64::min);
    assert!(spread > 0.05, "bumps are visible: {spread}");
    assert!(signed_volume(&m) > 0.0);
    // Deterministic; the seed changes the bumps.
    assert_eq!(m, generate::bumpy_sphere(3, 0.2, 5).unwrap());
    assert_eq!(
        generate::bumpy_sphere_seeded(2, 0.2, 5, 9).unwrap(),
        generate::bumpy_sphere_seeded(2, 0.2, 5, 9).unwrap()
    );
    assert_ne!(
        generate::bumpy_sphere_seeded(2, 0.2, 5, 9).unwrap(),
        generate::bumpy_sphere_seeded(2, 0.2, 5, 10).unwrap()
    );
    assert!(matches!(
        generate::bumpy_sphere(2, 1.0, 5),
        Err(MeshError::BadParameter {
            name: "amplitude",
            ..
        })
    ));
    assert!(matches!(
        generate::bumpy_sphere(2, 0.1, 0),
        Err(MeshError::BadParameter { name: "bumps", .. })
    ));
}

#[test]
fn grids() {
    let m = generate::grid(3, 2).unwrap();
    assert_eq!((m.n_vertices(), m.n_faces()), (12, 12));
    assert_eq!(m.positions()[2 * 4 + 1], [1.0 / 3.0, 1.0, 0.0]);
    let t = Topology::of(&m);
    assert_eq!((t.n_boundary_edges, t.n_boundary_loops), (10, 1));
    assert_eq!(t.euler_characteristic, 1);
    assert_eq!(t.genus, Some(0));
    assert!(signed_areas_z(&m).iter().all(|&a| a > 0.0));
    // Same diagonal everywhere: (i, j)–(i+1, j+1).
    for f in m.faces() {
        assert!(f.contains(&(f[0] + 5)), "{f:?}");
    }
    assert!(matches!(
        generate::grid(0, 3),
        Err(MeshError::BadParameter { .. })
    ));
    assert!(matches!(
        generate::grid(usize::MAX, 2),
        Err(MeshError::BadParameter { .. })
    ));
}

#[test]
fn unsymmetric_grids() {
    for n in 1..=5usize {
        let m = generate::unsymmetric_grid(n).unwrap();
        assert_eq!(m.n_vertices(), n * (n + 1) + (2 * n + 1).pow(2));
        assert_eq!(m.n_faces(), 10 * n * n + n);
        let t = Topology::of(&m);
        assert_eq!(t.n_boundary_edges, 9 * n);
        assert_eq!(t.n_boundary_loops, 1);
        assert_eq!(t.genus, Some(0));
        assert!(t.consistently_oriented);
        assert!(signed_areas_z(&m).iter().all(|&a| a > 0.0));
        assert_eq!(m.bounding_box(), ([0.0, 0.0, 0.0], [1.0, 1.0, 0.0]));
        // The domain is symmetric, the mesh is not.
        let left = m.positions().iter().filter(|p| p[0] < 0.5).count();
        let right = m.positions().iter().filter(|p| p[0] > 0.5).count();
        assert_eq!((left, right), (n * (n + 1), 2 * n * (2 * n + 1)));
        // Total area 1.
        let area: f64 = signed_areas_z(&m).iter().sum::<f64>() / 2.0;
        assert_close(area, 1.0, 1e-12);
    }
    assert!(generate::unsymmetric_grid(0).is_err());
}

#[test]
fn sliver_mesh_has_real_slivers() {
    let m = generate::sliver_mesh(30, 7).unwrap();
    assert_eq!(m.n_vertices(), 31 * 31 + 90);
    assert_eq!(m.n_faces(), 2 * 900 + 2 * 90);
    let q = Quality::of(&m);
    assert!(q.min_angle_deg < 1.0, "{}", q.min_angle_deg);
    assert!(q.count_below_1_deg > 50, "{}", q.count_below_1_deg);
    assert!(q.max_aspect_ratio > 100.0, "{}", q.max_aspect_ratio);
    assert!(q.max_angle_deg > 178.0, "{}", q.max_angle_deg);
    let t = Topology::of(&m);
    assert_eq!(t.n_boundary_loops, 1);
    assert_eq!(t.genus, Some(0));
    assert!(t.consistently_oriented);
    // A curved height field.
    let (lo, hi) = m.bounding_box();
    assert!(hi[2] - lo[2] > 0.1);
    assert!(signed_areas_z(&m).iter().all(|&a| a > 0.0));
    assert_eq!(m, generate::sliver_mesh(30, 7).unwrap());
    assert_ne!(m, generate::sliver_mesh(30, 8).unwrap());
    assert!(generate::sliver_mesh(1, 0).is_err());
}

#[test]
fn kinds_by_name_and_size_selection() {
    for kind in GeneratedKind::ALL {
        let parsed: GeneratedKind = kind.to_string().parse().unwrap();
        assert_eq!(parsed, kind);
        let m = generate::generate(kind.name().parse().unwrap(), 2, 1).unwrap();
        assert_eq!(Some(m.n_vertices()), kind.vertex_count(2));
        // The chosen size is the closest.
        for target in [0usize, 10, 1000, 5000, 123_456] {
            let s = generate::size_for_vertices(kind, target).unwrap();
            let d = |s: usize| kind.vertex_count(s).unwrap().abs_diff(target);
            assert!(s >= kind.min_size());
            if s > kind.min_size() {
                assert!(d(s) <= d(s - 1), "{kind} {target}");
            }
            assert!(d(s) <= d(s + 1), "{kind} {target}");
        }
    }
    assert_eq!(
        "Bumpy_Sphere".parse::<GeneratedKind>().unwrap(),
        GeneratedKind::BumpySphere
    );
    match "cube".parse::<GeneratedKind>() {
        Err(e) => {
            assert_eq!(e.word, "cube");
            assert!(e.to_string().contains("unsymmetric-grid"), "{e}")
        }
        other => panic!("{other:?}"),
    }
    let m = generate::with_about_vertices(GeneratedKind::Icosphere, 1000, 0).unwrap();
    assert_eq!(m.n_vertices(), 642);
    let m = generate::with_about_vertices(GeneratedKind::Grid, 1000, 0).unwrap();
    assert_eq!(m.n_vertices(), 1024);
    assert!(generate::with_about_vertices(GeneratedKind::Grid, 10_000_000_000, 0).is_err());
}

#[test]
fn million_vertex_grid_has_the_right_topology() {
    // Speed is measured in benches/, not asserted here.
    let m = generate::with_about_vertices(GeneratedKind::Grid, 1_000_000, 0).unwrap();
    assert_eq!(m.n_vertices(), 1_000_000);
    assert_eq!(m.n_faces(), 2 * 999 * 999);
    let topo = Topology::of(&m);
    assert_eq!(topo.n_boundary_loops, 1);
    assert_eq!(topo.genus, Some(0));
}

// ---------------------------------------------------------------------------
// real meshes against the README table

/// `LSE_MESH_DIR`, else `../shared/meshes` next to the repository, if it is
/// a directory.
fn mesh_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("LSE_MESH_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes"));
    dir.is_dir().then_some(dir)
}

/// Whether `CI` is set (to anything but empty, 0, false or no): there a
/// test that cannot run fails instead of passing without checking anything.
fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| !matches!(v.trim(), "" | "0" | "false" | "no"))
}

/// `value` equals `printed` (a README number, possibly with thousands
/// separators) to the printed precision: within half a unit of its last
/// digit.
fn matches_printed(value: f64, printed: &str) -> bool {
    let s = printed.replace(',', "");
    let decimals = s.split_once('.').map_or(0, |(_, d)| d.len());
    let expected: f64 = s.parse().unwrap();
    (value - expected).abs() <= 0.5 * 10f64.powi(-(decimals as i32)) + 1e-9
}

/// One README row: file, V, F, boundary edges, loops, genus, min∠, max∠,
/// max AR, %<10°, n<1°, Lmax/Lmin (copied from
/// ../shared/meshes/README.md).
type Row = (
    &'static str,
    usize,
    usize,
    usize,
    usize,
    usize,
    &'static str,
    &'static str,
    &'static str,
    &'static str,
    usize,
    &'static str,
);

const README_ROWS: &[Row] = &[
    (
        "bunny-3k.obj",
        3485,
        6966,
        0,
        0,
        0,
        "2.74",
        "172.1",
        "25.4",
        "0.34",
        0,
        "24",
    ),
    (
        "bunny-35k-stanford.obj",
        34834,
        69451,
        223,
        5,
        0,
        "0.48",
        "177.6",
        "128",
        "0.03",
        1,
        "28",
    ),
    (
        "bunny-35k-watertight.obj",
        34834,
        69664,
        0,
        0,
        0,
        "0.0017",
        "179.99",
        "38,772",
        "0.15",
        16,
        "166",
    ),
    (
        "camelhead-11k-open.obj",
        11381,
        22704,
        56,
        1,
        0,
        "0.55",
        "177.3",
        "89.7",
        "5.1",
        73,
        "541",
    ),
    (
        "demosthenes-8k-open.obj",
        8394,
        16719,
        67,
        1,
        0,
        "17.2",
        "127.8",
        "3.7",
        "0",
        0,
        "4.5",
    ),
    (
        "fandisk-6k.obj",
        6475,
        12946,
        0,
        0,
        0,
        "17.0",
        "128.2",
        "4.0",
        "0",
        0,
        "9.5",
    ),
    (
        "rocker-arm-10k.obj",
        10044,
        20088,
        0,
        0,
        1,
        "2.56",
        "164.1",
        "20.6",
        "0.12",
        0,
        "176",
    ),
    (
        "max-planck-5k-decimated.obj",
        5272,
        10540,
        0,
        0,
        0,
        "0.12",
        "179.7",
        "627",
        "3.2",
        5,
        "167",
    ),
];

#[test]
fn real_meshes_match_the_readme_table() {
    let Some(dir) = mesh_dir() else {
        assert!(
            !in_ci(),
            "CI is set but there is no mesh directory (../shared/meshes or LSE_MESH_DIR): this test would check nothing"
        );
        eprintln!("skipped: no mesh directory (set LSE_MESH_DIR)");
        return;
    };
    for &(file, v, f, be, loops, genus, min_a, max_a, ar, pct, n1, lratio) in README_ROWS {
        let path = dir.join(file);
        if !path.is_file() {
            assert!(!in_ci(), "CI is set but {} is missing", path.display());
            eprintln!("skipped {file}: not found");
            continue;
        }
        let loaded = read_mesh(&path, lse_deform::limits::MemoryBudget::default())
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(loaded.notes.is_empty(), "{file}: {:?}", loaded.notes);
        let m = loaded.mesh;
        let t = Topology::of(&m);
        let q = Quality::of(&m);
        assert_eq!((m.n_vertices(), m.n_faces()), (v, f), "{file}");
        assert_eq!(
            (t.n_boundary_edges, t.n_boundary_loops),
            (be, loops),
            "{file}"
        );
        assert!(t.is_manifold() && t.consistently_oriented, "{file}");
        assert_eq!(t.n_components, 1, "{file}");
        assert_eq!(t.genus, Some(genus), "{file}");
        if be == 0 {
            assert!(signed_volume(&m) > 0.0, "{file}: outward normals");
        }
        for (name, value, printed) in [
            ("min angle", q.min_angle_deg, min_a),
            ("max angle", q.max_angle_deg, max_a),
            ("max aspect ratio", q.max_aspect_ratio, ar),
            ("% below 10°", q.percent_below_10_deg, pct),
            ("Lmax/Lmin", q.edge_length_ratio, lratio),
        ] {
            assert!(
                matches_printed(value, printed),
                "{file}: {name} = {value}, README says {printed}"
            );
        }
        assert_eq!(q.count_below_1_deg, n1, "{file}");
    }
}

/// The 1M-face derived mesh (gzip): about a second in the test profile, so
/// it is opt-in: `cargo test --test mesh_topology -- --ignored`.
#[test]
#[ignore]
fn igea_537k_gz_matches_the_readme_table() {
    let Some(dir) = mesh_dir() else { return };
    let m = read_mesh(
        &dir.join("igea-537k-subdiv.obj.gz"),
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap()
    .mesh;
    let t = Topology::of(&m);
    let q = Quality::of(&m);
    assert_eq!((m.n_vertices(), m.n_faces()), (537_374, 1_074_744));
    assert_eq!((t.n_boundary_edges, t.genus), (0, Some(0)));
    assert!(matches_printed(q.min_angle_deg, "1.02"));
    assert!(matches_printed(q.max_angle_deg, "176.7"));
    assert!(matches_printed(q.max_aspect_ratio, "70.7"));
    assert!(matches_printed(q.percent_below_10_deg, "0.11"));
    assert!(matches_printed(q.edge_length_ratio, "58"));
}
