//! Helpers shared by the integration tests: small random meshes and a dense
//! reference solver computed independently of the library's sparse path.
#![allow(dead_code)]

use faer::Mat;
use faer::prelude::Solve;
use lse_deform::Mesh;
use lse_deform::problem::LseProblem;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A height field over a jittered `nx × ny` grid: a valid, curved,
/// irregular mesh with a boundary. Jitter stays below a third of a cell so
/// that no triangle flips.
pub fn random_surface(nx: usize, ny: usize, seed: u64) -> Mesh {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (hx, hy) = (1.0 / nx as f64, 1.0 / ny as f64);
    let mut p = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            let mut x = i as f64 * hx;
            let mut y = j as f64 * hy;
            if i > 0 && i < nx {
                x += rng.random_range(-0.3..0.3) * hx;
            }
            if j > 0 && j < ny {
                y += rng.random_range(-0.3..0.3) * hy;
            }
            let z = 0.2 * (3.0 * x).sin() * (2.0 * y).cos() + rng.random_range(-0.02..0.02);
            p.push([x, y, z]);
        }
    }
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    let mut f = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            if rng.random_bool(0.5) {
                f.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                f.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            } else {
                f.push([id(i, j), id(i + 1, j), id(i, j + 1)]);
                f.push([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
    }
    Mesh::new(p, f).expect("random_surface builds a valid mesh")
}

/// Dense reference for `min ‖AX − C‖ s.t. B_kept X = D_kept`: solves the KKT
/// system `[AᵀA Bᵀ; B 0] [X; Λ] = [AᵀC; D]` with faer's dense full-pivoting
/// LU. `rows` selects the rows of `B` to enforce (they must be independent).
pub fn dense_reference(problem: &LseProblem, rows: &[usize]) -> Mat<f64> {
    let n = problem.n();
    let a = problem.a().to_dense();
    let b = problem.b().to_dense();
    let m = rows.len();
    let mut k = Mat::<f64>::zeros(n + m, n + m);
    let ata = a.transpose() * &a;
    k.as_mut().submatrix_mut(0, 0, n, n).copy_from(&ata);
    for (r, &i) in rows.iter().enumerate() {
        for j in 0..n {
            k[(n + r, j)] = b[(i, j)];
            k[(j, n + r)] = b[(i, j)];
        }
    }
    let k_rhs = problem.n_rhs();
    let mut rhs = Mat::<f64>::zeros(n + m, k_rhs);
    let atc = a.transpose() * problem.c();
    rhs.as_mut().submatrix_mut(0, 0, n, k_rhs).copy_from(&atc);
    for (r, &i) in rows.iter().enumerate() {
        for c in 0..k_rhs {
            rhs[(n + r, c)] = problem.d()[(i, c)];
        }
    }
    let sol = k.full_piv_lu().solve(&rhs);
    sol.submatrix(0, 0, n, k_rhs).to_owned()
}

/// `max |x − y| / max |y|`.
pub fn relative_difference(x: &Mat<f64>, y: &Mat<f64>) -> f64 {
    let mut num = 0.0f64;
    let mut den = 0.0f64;
    for i in 0..x.nrows() {
        for c in 0..x.ncols() {
            num = num.max((x[(i, c)] - y[(i, c)]).abs());
            den = den.max(y[(i, c)].abs());
        }
    }
    num / den
}
