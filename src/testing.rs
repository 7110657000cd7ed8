//! Strategies and an oracle for property-based tests (cargo feature
//! `proptest`): what this crate's own tests use, exported so that another
//! crate can check its solver against ours — or ours against its own.
//!
//! - Meshes: [`random_surface`] (a jittered, curved height field),
//!   [`meshes`], [`scaled_meshes`] (coordinates times `10^e`, `e ∈ [−6, 6]`)
//!   and [`sliver_meshes`] (near-degenerate triangles).
//! - Constraints with a known answer: [`independent_constraints`] (rank =
//!   count), [`dependent_constraints`] (consistent combinations of earlier
//!   rows: exactly these are redundant; perturb their targets and exactly
//!   these conflict), [`with_soft`], and the strategy [`constraint_mixes`]
//!   that packs them into a [`ConstraintMix`] with the expected rank,
//!   redundant and conflicting indices.
//! - General problems: [`random_lse`] / [`random_lses`], a sparse LSE with
//!   known independent, redundant and conflicting rows of `B`.
//! - The oracle: [`dense_reference`], the dense KKT solution by faer's
//!   full-pivoting LU (independent of every sparse path), and
//!   [`relative_difference`].
//!
//! A test a downstream crate can copy (`lse-deform = { version = "0.1",
//! features = ["proptest"] }` in its `[dev-dependencies]`), with its own
//! solver in place of `LseSolver`:
//!
//! ```
//! use lse_deform::testing::{constraint_mixes, dense_reference, relative_difference};
//! use lse_deform::{ConstraintSet, Deformer, LaplacianKind, NullSpaceQr};
//! use proptest::prelude::*;
//!
//! proptest!(ProptestConfig::with_cases(8), |(mix in constraint_mixes())| {
//!     let set = ConstraintSet::from_vec(mix.constraints.clone()).unwrap();
//!     let mut d = Deformer::new(mix.mesh.clone(), LaplacianKind::Cotangent, set).unwrap();
//!     d.precompute(&NullSpaceQr::default()).unwrap();
//!     let x = d.solve_matrix().unwrap();
//!     // Rank and dependent constraints as constructed.
//!     prop_assert_eq!(d.report().rank, Some(mix.rank));
//!     prop_assert_eq!(&d.report().redundant, &mix.redundant);
//!     let conflicting: Vec<usize> = d.report().conflicting.iter().map(|c| c.index).collect();
//!     prop_assert_eq!(conflicting, mix.conflicting.clone());
//!     // The solution of the kept rows equals the dense oracle's.
//!     let kept: Vec<usize> = (0..mix.rank).collect();
//!     let reference = dense_reference(d.problem(), &kept);
//!     prop_assert!(relative_difference(&x, &reference) < 1e-8);
//! });
//! ```

use faer::Mat;
use faer::prelude::Solve;
use faer::sparse::{SparseColMat, Triplet};
use proptest::prelude::*;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::constraints::{Constraint, ConstraintKind};
use crate::laplacian::LaplacianKind;
use crate::mesh::{Mesh, generate};
use crate::problem::LseProblem;

/// Edge and barycentric parameters the generators draw from.
pub const T_VALUES: [f64; 5] = [0.2, 0.35, 0.5, 0.65, 0.8];

/// Every Laplacian kind.
pub fn laplacian_kinds() -> impl Strategy<Value = LaplacianKind> {
    prop::sample::select(LaplacianKind::ALL.to_vec())
}

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
    Mesh::new(p, f).expect("random_surface builds a valid mesh (jitter below a third of a cell)")
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

/// `p` plus a uniform offset in `[−amount, amount)³`.
pub fn jitter(rng: &mut ChaCha8Rng, p: [f64; 3], amount: f64) -> [f64; 3] {
    [
        p[0] + rng.random_range(-amount..amount),
        p[1] + rng.random_range(-amount..amount),
        p[2] + rng.random_range(-amount..amount),
    ]
}

/// `count` independent hard constraints of all four kinds (each on a vertex
/// no earlier one uses, so the rows are triangular after a permutation);
/// the first three are positions. With `positions_only`, all are.
pub fn independent_constraints(
    mesh: &Mesh,
    rng: &mut ChaCha8Rng,
    count: usize,
    positions_only: bool,
) -> Vec<Constraint> {
    let n = mesh.n_vertices();
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(rng);
    let p = mesh.positions();
    // Each constraint has a nonzero coefficient at a vertex no earlier one
    // touches, so the rows are triangular after a column permutation.
    let mut touched: Vec<usize> = Vec::new();
    let mut fresh = order.into_iter();
    let mut out = Vec::new();
    for k in 0..count {
        let Some(v) = fresh.by_ref().find(|v| !touched.contains(v)) else {
            break;
        };
        let other = |rng: &mut ChaCha8Rng, not: &[usize]| loop {
            let u = rng.random_range(0..n);
            if !not.contains(&u) {
                break u;
            }
        };
        let kind = if k < 3 || positions_only {
            0
        } else {
            rng.random_range(0..4)
        };
        let c = match kind {
            0 => ConstraintKind::Position {
                vertex: v,
                target: jitter(rng, p[v], 0.2),
            },
            1 => {
                let u = other(rng, &[v]);
                ConstraintKind::Edge {
                    vertices: [v, u],
                    t: T_VALUES[rng.random_range(0..5)],
                    target: jitter(rng, p[v], 0.2),
                }
            }
            2 => {
                let u = other(rng, &[v]);
                let w = other(rng, &[v, u]);
                ConstraintKind::Face {
                    vertices: [u, v, w],
                    barycentric: [T_VALUES[rng.random_range(0..5)], 0.25],
                    target: jitter(rng, p[v], 0.2),
                }
            }
            _ => {
                let u = other(rng, &[v]);
                ConstraintKind::Relative {
                    vertices: [v, u],
                    vector: jitter(
                        rng,
                        [p[v][0] - p[u][0], p[v][1] - p[u][1], p[v][2] - p[u][2]],
                        0.1,
                    ),
                }
            }
        };
        touched.extend_from_slice(c.vertices());
        out.push(Constraint::hard(c));
    }
    out
}

/// `cs` followed by `n_soft` soft position constraints (weights in
/// `[0.5, 5)`, targets near their vertices).
pub fn with_soft(
    mesh: &Mesh,
    rng: &mut ChaCha8Rng,
    mut cs: Vec<Constraint>,
    n_soft: usize,
) -> Vec<Constraint> {
    let p = mesh.positions();
    for _ in 0..n_soft {
        let v = rng.random_range(0..mesh.n_vertices());
        cs.push(Constraint::soft(
            ConstraintKind::Position {
                vertex: v,
                target: jitter(rng, p[v], 0.2),
            },
            rng.random_range(0.5..5.0),
        ));
    }
    cs
}

/// Constraints that are linear combinations of `base` rows, with consistent
/// right-hand sides: duplicates, and edges, relatives and faces built from
/// base positions.
pub fn dependent_constraints(
    base: &[Constraint],
    rng: &mut ChaCha8Rng,
    count: usize,
) -> Vec<Constraint> {
    let positions: Vec<(usize, [f64; 3])> = base
        .iter()
        .filter_map(|c| match c.kind {
            ConstraintKind::Position { vertex, target } => Some((vertex, target)),
            _ => None,
        })
        .collect();
    let lerp = |a: [f64; 3], b: [f64; 3], t: f64| {
        [
            t * a[0] + (1.0 - t) * b[0],
            t * a[1] + (1.0 - t) * b[1],
            t * a[2] + (1.0 - t) * b[2],
        ]
    };
    let mut out = Vec::new();
    for _ in 0..count {
        let mut pick: Vec<(usize, [f64; 3])> = positions.clone();
        pick.shuffle(rng);
        let kind = match rng.random_range(0..4) {
            0 => base[rng.random_range(0..base.len())].kind.clone(),
            1 => {
                let t = T_VALUES[rng.random_range(0..5)];
                ConstraintKind::Edge {
                    vertices: [pick[0].0, pick[1].0],
                    t,
                    target: lerp(pick[0].1, pick[1].1, t),
                }
            }
            2 => ConstraintKind::Relative {
                vertices: [pick[0].0, pick[1].0],
                vector: [0, 1, 2].map(|c| pick[0].1[c] - pick[1].1[c]),
            },
            _ => {
                let (s, t) = (0.2, 0.3);
                let target = [0, 1, 2]
                    .map(|c| s * pick[0].1[c] + t * pick[1].1[c] + (1.0 - s - t) * pick[2].1[c]);
                ConstraintKind::Face {
                    vertices: [pick[0].0, pick[1].0, pick[2].0],
                    barycentric: [s, t],
                    target,
                }
            }
        };
        out.push(Constraint::hard(kind));
    }
    out
}

/// A random sparse LSE: `A` (l × n) with a nonzero diagonal on top (full
/// column rank), `B` with `independent` random rows followed by rows that
/// are combinations of two earlier rows — consistent ones at the indices
/// returned as `redundant`, inconsistent ones (D perturbed by 1) at
/// `conflicting`.
#[derive(Debug, Clone)]
pub struct RandomLse {
    /// The problem.
    pub problem: LseProblem,
    /// The rows of `B` that are kept (independent of earlier rows).
    pub independent_rows: Vec<usize>,
    /// Rows that are consistent combinations of kept rows.
    pub redundant: Vec<usize>,
    /// Rows that are combinations of kept rows with `D` off by 1.
    pub conflicting: Vec<usize>,
}

/// A [`RandomLse`] with `n` unknowns, `independent` random rows of three
/// entries (each with a pivot column no earlier row touches, so they are
/// independent by construction; fewer if `n` runs out of pivots), then `extra` dependent rows (alternately redundant and
/// conflicting), each followed by one more independent row; `k`
/// right-hand-side columns.
pub fn random_lse(n: usize, independent: usize, extra: usize, k: usize, seed: u64) -> RandomLse {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let l = n + n / 2;
    let mut a = Vec::new();
    for j in 0..n {
        a.push(Triplet::new(j, j, rng.random_range(1.0..2.0)));
    }
    for _ in 0..3 * n {
        a.push(Triplet::new(
            rng.random_range(0..l),
            rng.random_range(0..n),
            rng.random_range(-1.0..1.0),
        ));
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(l, n, &a).unwrap();
    let c = Mat::from_fn(l, k, |_, _| rng.random_range(-1.0..1.0));
    // Every independent row has a pivot column that no earlier row touches
    // (its other entries are on earlier pivots or on columns that are never
    // pivots), so the rows are independent in list order by construction.
    let mut columns: Vec<usize> = (0..n).collect();
    columns.shuffle(&mut rng);
    let n_pivots = (independent + extra).min(n.saturating_sub(2));
    let (pivots, never_pivots) = columns.split_at(n_pivots);
    let mut used_pivots: Vec<usize> = Vec::new();
    let mut independent_row = |rng: &mut ChaCha8Rng| -> Option<Vec<(usize, f64)>> {
        let pivot = *pivots.get(used_pivots.len())?;
        let mut row = vec![(pivot, rng.random_range(0.5..1.5))];
        let pool: Vec<usize> = used_pivots.iter().chain(never_pivots).copied().collect();
        while row.len() < 3.min(pool.len() + 1) {
            let j = pool[rng.random_range(0..pool.len())];
            if row.iter().all(|e| e.0 != j) {
                row.push((j, rng.random_range(0.5..1.5)));
            }
        }
        used_pivots.push(pivot);
        Some(row)
    };
    let mut rows: Vec<Vec<(usize, f64)>> = Vec::new();
    let mut d_rows: Vec<Vec<f64>> = Vec::new();
    for _ in 0..independent {
        let Some(row) = independent_row(&mut rng) else {
            break;
        };
        rows.push(row);
        d_rows.push((0..k).map(|_| rng.random_range(-1.0..1.0)).collect());
    }
    let independent = rows.len();
    let (mut redundant, mut conflicting, mut independent_rows) =
        (Vec::new(), Vec::new(), (0..independent).collect::<Vec<_>>());
    for e in 0..extra {
        // Combinations of kept rows only (a combination involving a
        // conflicting row would be inconsistent with the kept ones).
        let pick =
            |rng: &mut ChaCha8Rng| independent_rows[rng.random_range(0..independent_rows.len())];
        let (p, q) = (pick(&mut rng), pick(&mut rng));
        let (s, t) = (rng.random_range(0.5..2.0), rng.random_range(-2.0..-0.5));
        let mut dense = vec![0.0; n];
        for &(j, v) in &rows[p] {
            dense[j] += s * v;
        }
        for &(j, v) in &rows[q] {
            dense[j] += t * v;
        }
        let row: Vec<(usize, f64)> = dense
            .iter()
            .enumerate()
            .filter(|e| *e.1 != 0.0)
            .map(|(j, &v)| (j, v))
            .collect();
        if row.is_empty() {
            continue;
        }
        let mut d: Vec<f64> = (0..k)
            .map(|c| s * d_rows[p][c] + t * d_rows[q][c])
            .collect();
        if e % 2 == 1 {
            d[0] += 1.0;
            conflicting.push(rows.len());
        } else {
            redundant.push(rows.len());
        }
        rows.push(row);
        d_rows.push(d);
        // One more independent row after each dependent one, so that
        // dependent rows sit between independent ones.
        if let Some(row) = independent_row(&mut rng) {
            independent_rows.push(rows.len());
            rows.push(row);
            d_rows.push((0..k).map(|_| rng.random_range(-1.0..1.0)).collect());
        }
    }
    let m = rows.len();
    let b: Vec<Triplet<usize, usize, f64>> = rows
        .iter()
        .enumerate()
        .flat_map(|(i, r)| r.iter().map(move |&(j, v)| Triplet::new(i, j, v)))
        .collect();
    let b = SparseColMat::<usize, f64>::try_new_from_triplets(m, n, &b).unwrap();
    let d = Mat::from_fn(m, k, |i, c| d_rows[i][c]);
    let problem = LseProblem::from_parts(a.as_ref(), c.as_ref(), b.as_ref(), d.as_ref()).unwrap();
    RandomLse {
        problem,
        independent_rows,
        redundant,
        conflicting,
    }
}

/// Random surfaces of 4–8 × 4–8 cells ([`random_surface`]).
pub fn meshes() -> impl Strategy<Value = Mesh> {
    (any::<u64>(), 4usize..9, 4usize..9).prop_map(|(seed, nx, ny)| random_surface(nx, ny, seed))
}

/// [`meshes`] with coordinates multiplied by `10^e`, `e ∈ [−6, 6]`: a
/// solver's tolerances must follow the model's units.
pub fn scaled_meshes() -> impl Strategy<Value = Mesh> {
    (meshes(), -6i32..=6).prop_map(|(mesh, e)| {
        let s = 10f64.powi(e);
        let p: Vec<[f64; 3]> = mesh.positions().iter().map(|q| q.map(|v| v * s)).collect();
        Mesh::new(p, mesh.faces().to_vec()).expect("a scaled valid mesh is valid")
    })
}

/// Meshes with sliver triangles ([`generate::sliver_mesh`], about 100–400
/// vertices): bad angles, large cotangent weights.
pub fn sliver_meshes() -> impl Strategy<Value = Mesh> {
    (any::<u64>(), 10usize..20).prop_filter_map("sliver mesh parameters", |(seed, n)| {
        generate::sliver_mesh(n, seed).ok()
    })
}

/// A mesh with hard and soft constraints whose rank and dependent
/// constraints are known by construction.
#[derive(Debug, Clone)]
pub struct ConstraintMix {
    /// The mesh.
    pub mesh: Mesh,
    /// Independent hard constraints (indices `0..rank`), then dependent
    /// ones, then soft ones.
    pub constraints: Vec<Constraint>,
    /// The rank of the hard constraints.
    pub rank: usize,
    /// Indices of the dependent constraints whose targets are consistent.
    pub redundant: Vec<usize>,
    /// Indices of the dependent constraints whose targets were moved by 5 %
    /// of the bounding-box diagonal (along x).
    pub conflicting: Vec<usize>,
}

/// [`ConstraintMix`]es on [`meshes`]: 3–11 independent constraints of all
/// four kinds, 0–5 dependent ones (each redundant or conflicting at
/// random), 0–3 soft ones.
pub fn constraint_mixes() -> impl Strategy<Value = ConstraintMix> {
    (meshes(), any::<u64>(), 3usize..12, 0usize..6, 0usize..4).prop_map(
        |(mesh, seed, n_base, n_added, n_soft)| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let base = independent_constraints(&mesh, &mut rng, n_base, false);
            let rank = base.len();
            let scale = mesh.bbox_diagonal();
            let (mut redundant, mut conflicting) = (Vec::new(), Vec::new());
            let mut constraints = base.clone();
            for mut c in dependent_constraints(&base, &mut rng, n_added) {
                if rng.random_bool(0.5) {
                    let r = c.kind.rhs();
                    c.kind.set_rhs([r[0] + 0.05 * scale, r[1], r[2]]);
                    conflicting.push(constraints.len());
                } else {
                    redundant.push(constraints.len());
                }
                constraints.push(c);
            }
            let constraints = with_soft(&mesh, &mut rng, constraints, n_soft);
            ConstraintMix {
                mesh,
                constraints,
                rank,
                redundant,
                conflicting,
            }
        },
    )
}

/// [`random_lse`] problems: 20–40 unknowns, 2–9 independent rows, 0–5
/// dependent ones (each followed by one more independent row, so at most
/// 14 independent rows: fewer than the unknowns, as independence needs),
/// 1–5 right-hand-side columns.
pub fn random_lses() -> impl Strategy<Value = RandomLse> {
    (any::<u64>(), 20usize..40, 2usize..10, 0usize..6, 1usize..6)
        .prop_map(|(seed, n, independent, extra, k)| random_lse(n, independent, extra, k, seed))
}
