//! Laplacian values checked against hand computations.

use faer::sparse::SparseColMat;
use lse_deform::Mesh;
use lse_deform::laplacian::{self, LaplacianKind, mixed_voronoi_areas};

fn dense(l: &SparseColMat<usize, f64>) -> faer::Mat<f64> {
    l.to_dense()
}

/// Unit square split along the diagonal 0–2:
/// 3---2
/// | / |
/// 0---1
fn square() -> Mesh {
    Mesh::new(
        vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap()
}

#[test]
fn square_by_hand() {
    // Angles: 90° at 1 (in 012) and at 3 (in 023), 45° elsewhere. Edge 0–2 is
    // opposite the two right angles: cot 90° = 0, so w_02 = 0. Each boundary
    // edge is opposite one 45° angle: ½ cot 45° = ½.
    let sym = dense(&laplacian::laplacian(&square(), LaplacianKind::CotangentSymmetric).unwrap());
    let expected = [
        [1.0, -0.5, 0.0, -0.5],
        [-0.5, 1.0, -0.5, 0.0],
        [0.0, -0.5, 1.0, -0.5],
        [-0.5, 0.0, -0.5, 1.0],
    ];
    for i in 0..4 {
        for j in 0..4 {
            assert!((sym[(i, j)] - expected[i][j]).abs() < 1e-15, "({i},{j})");
        }
    }
    // Mixed Voronoi areas: both triangles are right triangles (not obtuse),
    // Meyer's formula gives 1/8 to each 45° corner and 1/4 to the right
    // corner; every vertex collects 1/4.
    let area = mixed_voronoi_areas(&square());
    for a in &area {
        assert!((a - 0.25).abs() < 1e-15, "{area:?}");
    }
    // Cotangent Laplacian = symmetric / area: row 0 is [4, -2, 0, -2].
    let cot = dense(&laplacian::laplacian(&square(), LaplacianKind::Cotangent).unwrap());
    for i in 0..4 {
        for j in 0..4 {
            assert!((cot[(i, j)] - 4.0 * expected[i][j]).abs() < 1e-14);
        }
    }
    // Uniform: every vertex of the square has 2 or 3 neighbours.
    let uni = dense(&laplacian::laplacian(&square(), LaplacianKind::Uniform).unwrap());
    assert_eq!(uni[(0, 0)], 1.0);
    assert!((uni[(0, 1)] + 1.0 / 3.0).abs() < 1e-15); // vertex 0: neighbours 1, 2, 3
    assert!((uni[(1, 0)] + 0.5).abs() < 1e-15); // vertex 1: neighbours 0, 2
    assert_eq!(uni[(1, 3)], 0.0);
}

#[test]
fn obtuse_triangle_areas() {
    // Triangle with an obtuse angle at vertex 2: (0,0), (4,0), (2,0.5).
    // Area = 1; Meyer gives ½ to the obtuse corner and ¼ to the others.
    let mesh = Mesh::new(
        vec![[0., 0., 0.], [4., 0., 0.], [2., 0.5, 0.]],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let area = mixed_voronoi_areas(&mesh);
    assert!((area[0] - 0.25).abs() < 1e-15);
    assert!((area[1] - 0.25).abs() < 1e-15);
    assert!((area[2] - 0.5).abs() < 1e-15);
    // cot of the angle at 2: u = (-2,-0.5), v = (2,-0.5): u·v = -3.75,
    // |u×v| = 2, cot = -1.875. Edge 0–1 weight ½·cot = -0.9375 (negative).
    let sym = dense(&laplacian::laplacian(&mesh, LaplacianKind::CotangentSymmetric).unwrap());
    assert!((sym[(0, 1)] - 0.9375).abs() < 1e-14);
}

#[test]
fn regular_grid_has_the_five_point_stencil() {
    // On a grid of right isoceles triangles, an interior vertex has weight 1
    // (½(cot 45° + cot 45°)) to its four axis neighbours and 0 (½(cot 90° +
    // cot 90°)) to its two diagonal neighbours: the 5-point stencil.
    let n = 6;
    let mut p = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            p.push([i as f64, j as f64, 0.0]);
        }
    }
    let id = |i: usize, j: usize| j * (n + 1) + i;
    let mut f = Vec::new();
    for j in 0..n {
        for i in 0..n {
            f.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            f.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    let mesh = Mesh::new(p, f).unwrap();
    let sym = dense(&laplacian::laplacian(&mesh, LaplacianKind::CotangentSymmetric).unwrap());
    let c = id(3, 3);
    assert!((sym[(c, c)] - 4.0).abs() < 1e-14);
    for nb in [id(2, 3), id(4, 3), id(3, 2), id(3, 4)] {
        assert!((sym[(c, nb)] + 1.0).abs() < 1e-14);
    }
    for diag in [id(2, 2), id(4, 4)] {
        assert!(sym[(c, diag)].abs() < 1e-14);
    }
    // Interior mixed area of a unit grid vertex is 1 (six triangles, Voronoi
    // parts summing to one cell), so the cotangent Laplacian equals it there.
    let area = mixed_voronoi_areas(&mesh);
    assert!((area[c] - 1.0).abs() < 1e-14);
}

#[test]
fn rows_sum_to_zero_and_flat_interior_delta_vanishes() {
    for seed in 0..5 {
        let mut mesh = lse_deform::testing::random_surface(7, 5, seed);
        for kind in LaplacianKind::ALL {
            let l = dense(&laplacian::laplacian(&mesh, kind).unwrap());
            let scale = (0..l.nrows()).map(|i| l[(i, i)].abs()).fold(0.0, f64::max);
            for i in 0..l.nrows() {
                let s: f64 = (0..l.ncols()).map(|j| l[(i, j)]).sum();
                assert!(s.abs() < 1e-12 * scale, "{kind} row {i} sums to {s}");
            }
        }
        // Flatten it: the cotangent Laplacian of a planar mesh vanishes at
        // interior vertices (mean curvature 0, and the x, y coordinates are
        // linear functions, which the cotangent Laplacian reproduces).
        let flat: Vec<[f64; 3]> = mesh.positions().iter().map(|p| [p[0], p[1], 0.0]).collect();
        mesh = mesh.with_positions(flat).unwrap();
        let l = laplacian::laplacian(&mesh, LaplacianKind::Cotangent).unwrap();
        let delta = laplacian::apply(&l, mesh.positions());
        let (nx, ny) = (7, 5);
        for j in 1..ny {
            for i in 1..nx {
                let v = j * (nx + 1) + i;
                for c in 0..3 {
                    assert!(delta[(v, c)].abs() < 1e-10, "δ[{v}] = {:?}", delta.row(v));
                }
            }
        }
        // The uniform Laplacian does not have this property on an irregular
        // grid: at least one interior δ is clearly nonzero.
        let lu = laplacian::laplacian(&mesh, LaplacianKind::Uniform).unwrap();
        let du = laplacian::apply(&lu, mesh.positions());
        let max_u = (0..du.nrows())
            .map(|v| du[(v, 0)].abs())
            .fold(0.0, f64::max);
        assert!(max_u > 1e-3);
    }
}

#[test]
fn intrinsic_delaunay_refuses_non_manifold_edges() {
    // Three triangles on the edge 0-1.
    let mesh = Mesh::new(
        vec![
            [0., 0., 0.],
            [1., 0., 0.],
            [0.5, 1., 0.],
            [0.5, -1., 0.],
            [0.5, 0., 1.],
        ],
        vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
    )
    .unwrap();
    let err = laplacian::laplacian(&mesh, LaplacianKind::IntrinsicDelaunay).unwrap_err();
    assert!(
        matches!(
            err,
            lse_deform::error::MeshError::NotManifold { edge: [0, 1], .. }
        ),
        "{err}"
    );
}
