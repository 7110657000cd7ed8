//! The intrinsic triangulation against hand-made cases and the Laplacian
//! built on it: a file of its own, above `laplacian`, whose set-up it uses.

use super::IntrinsicTriangulation;
use crate::laplacian::{self, LaplacianKind};
use crate::mesh::Mesh;

fn dense(l: &faer::sparse::SparseColMat<usize, f64>) -> faer::Mat<f64> {
    l.to_dense()
}

#[test]
fn intrinsic_delaunay_flips_the_skinny_pair() {
    // a=(0,0), b=(2,0), c=(1,0.1), d=(1,-0.1): the triangles abc and bad
    // share ab, whose opposite angles (at c and d) are ~168.6° each, so ab is
    // not Delaunay. The flip gives the edge cd, of length 0.2.
    let pts = vec![[0., 0., 0.], [2., 0., 0.], [1., 0.1, 0.], [1., -0.1, 0.]];
    let skinny = Mesh::new(pts.clone(), vec![[0, 1, 2], [1, 0, 3]]).unwrap();
    let flipped = Mesh::new(pts, vec![[0, 3, 2], [1, 2, 3]]).unwrap();
    let tri = IntrinsicTriangulation::new(&skinny)
        .unwrap()
        .flip_to_delaunay()
        .unwrap();
    assert_eq!(tri.flips(), 1);
    let mut faces: Vec<[usize; 3]> = tri
        .faces()
        .into_iter()
        .map(|mut f| {
            f.sort_unstable();
            f
        })
        .collect();
    faces.sort_unstable();
    assert_eq!(faces, vec![[0, 2, 3], [1, 2, 3]]);
    let intrinsic =
        dense(&laplacian::laplacian(&skinny, LaplacianKind::IntrinsicDelaunay).unwrap());
    let reference = dense(&laplacian::laplacian(&flipped, LaplacianKind::Cotangent).unwrap());
    for i in 0..4 {
        for j in 0..4 {
            assert!(
                (intrinsic[(i, j)] - reference[(i, j)]).abs() < 1e-12 * reference[(i, i)].abs(),
                "({i},{j}): {} vs {}",
                intrinsic[(i, j)],
                reference[(i, j)]
            );
        }
    }
    // The original cotangent Laplacian has a negative weight on ab
    // (positive off-diagonal entry); the intrinsic one has none.
    let original = dense(&laplacian::laplacian(&skinny, LaplacianKind::Cotangent).unwrap());
    assert!(original[(0, 1)] > 0.0);
    for i in 0..4 {
        for j in 0..4 {
            if i != j {
                assert!(intrinsic[(i, j)] <= 0.0);
            }
        }
    }
}

#[test]
fn intrinsic_delaunay_weights_are_nonnegative_on_curved_meshes() {
    for seed in 0..4 {
        let mesh = crate::testing::random_surface(9, 7, seed);
        let tri = IntrinsicTriangulation::new(&mesh)
            .unwrap()
            .flip_to_delaunay()
            .unwrap();
        assert!(tri.min_cotan_sum() >= -1e-12);
        let l = dense(&laplacian::laplacian(&mesh, LaplacianKind::IntrinsicDelaunay).unwrap());
        for i in 0..l.nrows() {
            let mut sum = 0.0;
            for j in 0..l.ncols() {
                sum += l[(i, j)];
                if i != j {
                    assert!(
                        l[(i, j)] <= 1e-12 * l[(i, i)],
                        "negative weight at ({i},{j})"
                    );
                }
            }
            assert!(sum.abs() < 1e-10 * l[(i, i)]);
        }
    }
    // A regular grid of right isoceles triangles is already Delaunay (the
    // diagonals are cocircular, cot sum exactly 0): no flip, same matrix.
    let mut p = Vec::new();
    for j in 0..=4 {
        for i in 0..=4 {
            p.push([i as f64, j as f64, 0.0]);
        }
    }
    let id = |i: usize, j: usize| j * 5 + i;
    let mut f = Vec::new();
    for j in 0..4 {
        for i in 0..4 {
            f.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            f.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    let grid = Mesh::new(p, f).unwrap();
    let tri = IntrinsicTriangulation::new(&grid)
        .unwrap()
        .flip_to_delaunay()
        .unwrap();
    assert_eq!(tri.flips(), 0);
}
