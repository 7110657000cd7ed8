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
//! - Rows where rank detection is hard, built from their meaning:
//!   [`constructed_mixes`] (meshes, including [`sliver_meshes`], up to a
//!   few hundred vertices: rows either side of the rank tolerance, nearly
//!   parallel edges, edge parameters within `1e-12` of 0 or 1) and
//!   [`constructed_lses`] (general problems, rows scaled by `10^±8`), with
//!   the kept, redundant and conflicting sets and the sources of each
//!   dependent row, as a [`Mixture`] allows.
//! - The oracles: [`dense_reference`], the dense KKT solution by faer's
//!   full-pivoting LU (independent of every sparse path), its accurate
//!   counterpart [`accurate_reference`] (to a unit in the last place on
//!   ill-conditioned problems), and [`relative_difference`].
//!
//! A test a downstream crate can copy (`lse-deform = { version = "0.1",
//! features = ["proptest"] }` in its `[dev-dependencies]`), with its own
//! solver in place of `LseSolver`:
//!
//! ```
//! use lse_deform::testing::{constraint_mixes, dense_reference, relative_difference};
//! use lse_deform::{ConstraintSet, Deformer, LaplacianKind, SolveOptions};
//! use proptest::prelude::*;
//!
//! proptest!(ProptestConfig::with_cases(8), |(mix in constraint_mixes())| {
//!     let set = ConstraintSet::from_vec(mix.constraints.clone()).unwrap();
//!     let options = SolveOptions::default();
//!     let mut d = Deformer::new(mix.mesh.clone(), LaplacianKind::Cotangent, set, &options).unwrap();
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

/// The conformance kit: one call per seam runs, against any back end, the
/// properties every built-in back end passes (docs/backends.md §8).
pub mod conformance;

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
    let (a, c) = random_a_and_c(&mut rng, n, k);
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
        let Some((row, mut d)) =
            two_row_combination(&mut rng, &rows, &d_rows, &independent_rows, n)
        else {
            continue;
        };
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
    let (b, d) = assemble_b_d(&rows, &d_rows, n, k);
    let problem = LseProblem::from_parts(a.as_ref(), c.as_ref(), b.as_ref(), d.as_ref()).unwrap();
    RandomLse {
        problem,
        independent_rows,
        redundant,
        conflicting,
    }
}

/// The random `A` (`l × n`, `l = 3n/2`: a diagonal in `[1, 2)` plus `3n`
/// entries in `[−1, 1)` at random places, duplicates summed) and `C`
/// (`l × k`, entries in `[−1, 1)`) of [`random_lse`] and
/// [`constructed_lse`], drawn in that order from `rng`.
fn random_a_and_c(
    rng: &mut ChaCha8Rng,
    n: usize,
    k: usize,
) -> (SparseColMat<usize, f64>, Mat<f64>) {
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
    (a, c)
}

/// `B` (`rows.len() × n`, duplicate entries summed) and `D` (`k` columns)
/// from sparse rows and their right-hand sides.
fn assemble_b_d(
    rows: &[Vec<(usize, f64)>],
    d_rows: &[Vec<f64>],
    n: usize,
    k: usize,
) -> (SparseColMat<usize, f64>, Mat<f64>) {
    let m = rows.len();
    let b: Vec<Triplet<usize, usize, f64>> = rows
        .iter()
        .enumerate()
        .flat_map(|(i, r)| r.iter().map(move |&(j, v)| Triplet::new(i, j, v)))
        .collect();
    let b = SparseColMat::<usize, f64>::try_new_from_triplets(m, n, &b).unwrap();
    let d = Mat::from_fn(m, k, |i, c| d_rows[i][c]);
    (b, d)
}

/// A sparse row of `B` and its right-hand side.
type RowAndRhs = (Vec<(usize, f64)>, Vec<f64>);

/// `s · row p + t · row q` for two rows drawn from `independent_rows`,
/// `s ∈ [0.5, 2)`, `t ∈ [−2, −0.5)`, with the same combination of their
/// right-hand sides; `None` when the rows cancel exactly (`p = q`, `s = −t`).
fn two_row_combination(
    rng: &mut ChaCha8Rng,
    rows: &[Vec<(usize, f64)>],
    d_rows: &[Vec<f64>],
    independent_rows: &[usize],
    n: usize,
) -> Option<RowAndRhs> {
    let pick = |rng: &mut ChaCha8Rng| independent_rows[rng.random_range(0..independent_rows.len())];
    let (p, q) = (pick(rng), pick(rng));
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
        return None;
    }
    let k = d_rows[p].len();
    let d: Vec<f64> = (0..k)
        .map(|c| s * d_rows[p][c] + t * d_rows[q][c])
        .collect();
    Some((row, d))
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
pub(crate) fn sliver_meshes() -> impl Strategy<Value = Mesh> {
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

// ---------------------------------------------------------------------------
// Hard rows built from their meaning: every dependence (and every near
// dependence) is an explicit linear combination the generator chose, so the
// expected kept, redundant and conflicting sets — and which earlier
// constraints each dependent one combines — come from the construction,
// not from the library's assembly or rank detection.

/// Relative remainders (after projecting out the earlier kept rows, over
/// the row's norm) that the near-tolerance rows of [`constructed_mixes`]
/// and [`constructed_lses`] are built with below the rank tolerance
/// `η = 1e-10`: `0.1 η` and further down (within `1e-12` of 0 or 1 for an
/// edge parameter). These rows must be skipped by every QR back end.
pub const SKIPPED_REMAINDERS: [f64; 3] = [1e-11, 1e-12, 1e-14];

/// Relative remainders above the rank tolerance: `10 η` (ill-conditioned:
/// a kept row of remainder `ρ` amplifies rounding by `1/ρ` into the
/// solution) and a nearly parallel row at `1e-6`. These rows must be kept.
/// The factor 10 on either side of `η` is where the back ends are
/// documented to agree: sparse Givens tests one arriving entry at a time
/// and can differ from the dense test by `√k` for a remainder spread over
/// `k ≤ 3` entries here (`src/backend/qr/sparse_givens.rs`).
pub const KEPT_REMAINDERS: [f64; 2] = [1e-9, 1e-6];

/// A kept row whose share `|α_s| ‖b_s‖` of a dependent row `Σ α_s b_s` is
/// at most this times the dependent row's norm is not counted among its
/// sources (an edge parameter within `1e-12` of 0 or 1 puts a share that
/// small on one end).
pub const SOURCE_SHARE: f64 = 1e-9;

/// Which rows a constructed case ([`constructed_mix`], [`constructed_lse`])
/// may hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mixture {
    /// Independent rows only, each well separated from dependence (what
    /// KKT accepts); for general problems, no row scaling.
    Independent,
    /// Independent rows and dependent ones, exact or within
    /// [`SKIPPED_REMAINDERS`] of dependence: every kept row is well
    /// separated from the tolerance.
    Separated,
    /// Everything: also kept rows at [`KEPT_REMAINDERS`] and (meshes) kept
    /// rows with an entry below the tolerance.
    Everything,
}

/// The three mixtures, one in six independent-only.
pub(crate) fn mixtures() -> impl Strategy<Value = Mixture> {
    prop_oneof![
        1 => Just(Mixture::Independent),
        2 => Just(Mixture::Separated),
        3 => Just(Mixture::Everything),
    ]
}

/// Constraints on a mesh whose kept, redundant and conflicting sets are
/// known by construction ([`constructed_mixes`]).
#[derive(Debug, Clone)]
pub struct ConstructedMix {
    /// The mesh.
    pub mesh: Mesh,
    /// Hard constraints in priority order, then soft ones.
    pub constraints: Vec<Constraint>,
    /// The hard constraints that are independent of the earlier kept ones
    /// (by more than [`KEPT_REMAINDERS`]`[0]` relative), increasing.
    pub kept: Vec<usize>,
    /// Dependent (to within [`SKIPPED_REMAINDERS`]) with consistent targets.
    pub redundant: Vec<usize>,
    /// Dependent with a target moved by 5 % of the bounding-box diagonal.
    pub conflicting: Vec<usize>,
    /// For each dependent constraint, the kept ones it is a combination of
    /// (those with a share above [`SOURCE_SHARE`]), increasing.
    pub sources: Vec<(usize, Vec<usize>)>,
    /// Kept constraints with a remainder of `10 η … 1e-6`: independent,
    /// ill-conditioned.
    pub near_tolerance: Vec<usize>,
    /// Kept constraints with a coefficient below the rank tolerance `η`
    /// times their norm (an edge parameter within `1e-12` of 0 or 1):
    /// sparse Givens drops such an entry when it arrives at an empty row
    /// of `R` (Heath's test).
    pub tiny_entries: Vec<usize>,
    /// Whether every hard constraint is a position (what elimination
    /// accepts).
    pub positions_only: bool,
}

/// Builds a [`ConstructedMix`]: vertices join a forest whose edges are the
/// kept position rows (to a virtual ground) and relative rows, so that the
/// dependence of a later position, relative, edge or face row on them is a
/// path sum; kept edge and face rows with a fresh vertex of their own, and
/// the near-tolerance rows, mark their vertices as outside the forest.
struct MixBuilder<'a> {
    p: &'a [[f64; 3]],
    mixture: Mixture,
    rng: ChaCha8Rng,
    scale: f64,
    /// Vertices no row touches yet (candidates for a fresh pivot), shuffled.
    fresh: Vec<usize>,
    touched: Vec<bool>,
    /// Forest adjacency over vertices and the ground `n`: (neighbour,
    /// constraint, σ) with `e_x = σ row + e_neighbour` (`e_ground = 0`).
    adj: Vec<Vec<(usize, usize, f64)>>,
    /// A vertex whose unit vector is touched by a kept row outside the
    /// forest: never used in a dependent construction.
    tainted: Vec<bool>,
    /// The value each forest vertex has under the kept rows (up to one
    /// offset per tree not connected to the ground).
    value: Vec<[f64; 3]>,
    out: ConstructedMix,
    rows: Vec<Vec<(usize, f64)>>,
}

impl MixBuilder<'_> {
    fn ground(&self) -> usize {
        self.p.len()
    }

    fn take_fresh(&mut self) -> Option<usize> {
        while let Some(v) = self.fresh.pop() {
            if !self.touched[v] {
                self.touched[v] = true;
                return Some(v);
            }
        }
        None
    }

    /// A vertex other than `not`, touched or not (the "other" vertices of a
    /// row with a fresh pivot).
    fn any_vertex(&mut self, not: &[usize]) -> usize {
        loop {
            let v = self.rng.random_range(0..self.p.len());
            if !not.contains(&v) {
                return v;
            }
        }
    }

    fn in_forest(&self, v: usize) -> bool {
        !self.adj[v].is_empty()
    }

    /// The forest path from `a` to `b`: `e_a − e_b = Σ σ row` as
    /// (constraint, σ), or `None` if they are not connected.
    fn path(&self, a: usize, b: usize) -> Option<Vec<(usize, f64)>> {
        let n = self.adj.len();
        let mut prev: Vec<Option<(usize, usize, f64)>> = vec![None; n];
        let mut seen = vec![false; n];
        let mut queue = std::collections::VecDeque::from([a]);
        seen[a] = true;
        while let Some(x) = queue.pop_front() {
            if x == b {
                let mut out = Vec::new();
                let mut y = b;
                while let Some((from, c, sigma)) = prev[y] {
                    out.push((c, sigma));
                    y = from;
                }
                return Some(out);
            }
            for &(y, c, sigma) in &self.adj[x] {
                if !seen[y] {
                    seen[y] = true;
                    prev[y] = Some((x, c, sigma));
                    queue.push_back(y);
                }
            }
        }
        None
    }

    fn push(&mut self, kind: ConstraintKind) -> usize {
        let i = self.out.constraints.len();
        // A fresh pivot must be untouched by every earlier row, whatever
        // its role there.
        for &v in kind.vertices() {
            self.touched[v] = true;
        }
        self.rows.push(kind.row().entries().to_vec());
        self.out.constraints.push(Constraint::hard(kind));
        i
    }

    fn link(&mut self, x: usize, y: usize, c: usize) {
        self.adj[x].push((y, c, 1.0));
        self.adj[y].push((x, c, -1.0));
    }

    fn norm(&self, c: usize) -> f64 {
        self.rows[c].iter().map(|e| e.1 * e.1).sum::<f64>().sqrt()
    }

    fn target_near(&mut self, v: usize) -> [f64; 3] {
        jitter(&mut self.rng, self.p[v], 0.05 * self.scale)
    }

    /// Records a dependent constraint `index`, the combination
    /// `Σ coefficient · row` of kept constraints, with the consistent
    /// right-hand side `rhs` (moved for a conflict, chosen at random).
    fn dependent(&mut self, kind: ConstraintKind, combination: &[(usize, f64)]) {
        let mut kind = kind;
        let index = self.out.constraints.len();
        if self.rng.random_bool(0.5) {
            let r = kind.rhs();
            kind.set_rhs([r[0] + 0.05 * self.scale, r[1], r[2]]);
            self.out.conflicting.push(index);
        } else {
            self.out.redundant.push(index);
        }
        self.push(kind);
        let own = self.norm(index);
        let mut shares: Vec<(usize, f64)> = Vec::new();
        for &(c, a) in combination {
            match shares.iter_mut().find(|s| s.0 == c) {
                Some(s) => s.1 += a,
                None => shares.push((c, a)),
            }
        }
        let mut named: Vec<usize> = shares
            .into_iter()
            .filter(|&(c, a)| a.abs() * self.norm(c) > SOURCE_SHARE * own)
            .map(|(c, _)| c)
            .collect();
        named.sort_unstable();
        self.out.sources.push((index, named));
    }

    fn kept(&mut self, kind: ConstraintKind) -> usize {
        let i = self.push(kind);
        self.out.kept.push(i);
        let norm = self.norm(i);
        if self.rows[i].iter().any(|e| e.1.abs() <= 1e-10 * norm) {
            self.out.tiny_entries.push(i);
        }
        i
    }

    /// `Σ w_v e_v` over grounded vertices as path sums to the ground.
    fn grounded_combination(&self, terms: &[(usize, f64)]) -> Vec<(usize, f64)> {
        let g = self.ground();
        let mut out = Vec::new();
        for &(v, w) in terms {
            for (c, sigma) in self.path(v, g).expect("grounded") {
                out.push((c, w * sigma));
            }
        }
        out
    }

    fn value_of(&self, terms: &[(usize, f64)]) -> [f64; 3] {
        std::array::from_fn(|k| terms.iter().map(|&(v, w)| w * self.value[v][k]).sum())
    }

    /// The untainted vertices connected to the ground, increasing.
    fn grounded_vertices(&self) -> Vec<usize> {
        let mut seen = vec![false; self.adj.len()];
        let mut stack = vec![self.ground()];
        seen[self.ground()] = true;
        while let Some(x) = stack.pop() {
            for &(y, _, _) in &self.adj[x] {
                if !seen[y] {
                    seen[y] = true;
                    stack.push(y);
                }
            }
        }
        (0..self.p.len())
            .filter(|&v| seen[v] && !self.tainted[v])
            .collect()
    }

    /// One independent row on a fresh pivot: position, relative, edge (the
    /// fresh end weighted `t ≥ 0.2`, or `1 − τ` with `τ ≤ 1e-12`) or face.
    fn independent(&mut self, positions_only: bool) -> bool {
        let Some(f) = self.take_fresh() else {
            return false;
        };
        let kind = if positions_only {
            0
        } else {
            self.rng.random_range(0..5)
        };
        match kind {
            0 => {
                let target = self.target_near(f);
                let c = self.kept(ConstraintKind::Position { vertex: f, target });
                let g = self.ground();
                self.link(f, g, c);
                self.value[f] = target;
            }
            1 => {
                let u = self.any_vertex(&[f]);
                let vector = [0, 1, 2].map(|k| self.p[f][k] - self.p[u][k]);
                let vector = jitter(&mut self.rng, vector, 0.02 * self.scale);
                let c = self.kept(ConstraintKind::Relative {
                    vertices: [f, u],
                    vector,
                });
                if self.tainted[u] {
                    self.tainted[f] = true;
                } else {
                    if !self.in_forest(u) {
                        self.value[u] = self.p[u];
                    }
                    self.touched[u] = true;
                    self.link(f, u, c);
                    self.value[f] = [0, 1, 2].map(|k| self.value[u][k] + vector[k]);
                }
            }
            2 | 3 => {
                let u = self.any_vertex(&[f]);
                let heavy = if self.mixture == Mixture::Everything && self.rng.random_bool(0.3) {
                    1.0 - 10f64.powi(-self.rng.random_range(12..=15))
                } else {
                    T_VALUES[self.rng.random_range(0..5)]
                };
                let target = self.target_near(f);
                // The fresh vertex's coefficient is `heavy` either way.
                let (vertices, t) = if kind == 2 {
                    ([f, u], heavy)
                } else {
                    ([u, f], 1.0 - heavy)
                };
                self.kept(ConstraintKind::Edge {
                    vertices,
                    t,
                    target,
                });
                self.tainted[f] = true;
            }
            _ => {
                let u = self.any_vertex(&[f]);
                let w = self.any_vertex(&[f, u]);
                let s = T_VALUES[self.rng.random_range(0..5)];
                let target = self.target_near(f);
                self.kept(ConstraintKind::Face {
                    vertices: [f, u, w],
                    barycentric: [s, 0.25 * (1.0 - s)],
                    target,
                });
                self.tainted[f] = true;
            }
        }
        true
    }

    /// One row that depends on the kept ones exactly (a duplicate, or a
    /// position, relative, edge or face built from forest paths): a recipe
    /// drawn (always a plain duplicate when `positions_only`), then built by
    /// [`MixBuilder::duplicate`], [`MixBuilder::forest_relative`] or
    /// [`MixBuilder::grounded_row`]. `false` when the recipe finds nothing
    /// to build on.
    fn exact_dependent(&mut self, positions_only: bool) -> bool {
        let recipe = if positions_only {
            0
        } else {
            self.rng.random_range(0..6)
        };
        let kept = self.out.kept.clone();
        let grounded = self.grounded_vertices();
        match recipe {
            0 | 1 => self.duplicate(&kept, recipe == 1),
            2 => self.forest_relative(),
            _ => self.grounded_row(recipe, &grounded),
        }
    }

    /// A duplicate of a kept constraint; with `reverse`, a relative one is
    /// reversed with its vector negated (the same row up to sign).
    fn duplicate(&mut self, kept: &[usize], reverse: bool) -> bool {
        let Some(&c) = kept.get(self.rng.random_range(0..kept.len().max(1))) else {
            return false;
        };
        let (kind, sign) = match self.out.constraints[c].kind.clone() {
            ConstraintKind::Relative { vertices, vector } if reverse => (
                ConstraintKind::Relative {
                    vertices: [vertices[1], vertices[0]],
                    vector: vector.map(|v| -v),
                },
                -1.0,
            ),
            other => (other, 1.0),
        };
        self.dependent(kind, &[(c, sign)]);
        true
    }

    /// A relative constraint between two distinct vertices of one
    /// untainted forest tree, combining the rows along their path.
    fn forest_relative(&mut self) -> bool {
        let trees: Vec<usize> = (0..self.p.len())
            .filter(|&v| self.in_forest(v) && !self.tainted[v])
            .collect();
        if trees.len() < 2 {
            return false;
        }
        let a = trees[self.rng.random_range(0..trees.len())];
        let b = trees[self.rng.random_range(0..trees.len())];
        let Some(path) = (a != b).then(|| self.path(a, b)).flatten() else {
            return false;
        };
        let vector = self.value_of(&[(a, 1.0), (b, -1.0)]);
        self.dependent(
            ConstraintKind::Relative {
                vertices: [a, b],
                vector,
            },
            &path,
        );
        true
    }

    /// A row on `grounded` vertices (their values fixed by kept rows):
    /// recipe 3 a position, 4 an edge (`t` from [`T_VALUES`] or within
    /// `1e-12` of 0 or 1), otherwise a face (`s = 0.2`, `t` from
    /// [`T_VALUES`]).
    fn grounded_row(&mut self, recipe: usize, grounded: &[usize]) -> bool {
        match recipe {
            3 => {
                let Some(&a) = grounded.get(self.rng.random_range(0..grounded.len().max(1))) else {
                    return false;
                };
                let combination = self.grounded_combination(&[(a, 1.0)]);
                let target = self.value[a];
                self.dependent(ConstraintKind::Position { vertex: a, target }, &combination);
            }
            4 => {
                if grounded.len() < 2 {
                    return false;
                }
                let a = grounded[self.rng.random_range(0..grounded.len())];
                let b = grounded[self.rng.random_range(0..grounded.len())];
                if a == b {
                    return false;
                }
                let t = match self.rng.random_range(0..4) {
                    0 => 10f64.powi(-self.rng.random_range(12..=15)),
                    1 => 1.0 - 10f64.powi(-self.rng.random_range(12..=15)),
                    _ => T_VALUES[self.rng.random_range(0..5)],
                };
                let terms = [(a, t), (b, 1.0 - t)];
                let combination = self.grounded_combination(&terms);
                let target = self.value_of(&terms);
                let vertices = [a, b];
                self.dependent(
                    ConstraintKind::Edge {
                        vertices,
                        t,
                        target,
                    },
                    &combination,
                );
            }
            _ => {
                if grounded.len() < 3 {
                    return false;
                }
                let mut pick = grounded.to_vec();
                pick.shuffle(&mut self.rng);
                let (a, b, c) = (pick[0], pick[1], pick[2]);
                let (s, t) = (0.2, T_VALUES[self.rng.random_range(0..5)]);
                let terms = [(a, s), (b, t), (c, 1.0 - s - t)];
                let combination = self.grounded_combination(&terms);
                let target = self.value_of(&terms);
                let (vertices, barycentric) = ([a, b, c], [s, t]);
                let kind = ConstraintKind::Face {
                    vertices,
                    barycentric,
                    target,
                };
                self.dependent(kind, &combination);
            }
        }
        true
    }

    /// A row whose remainder is `ρ` relative, on one side of the tolerance
    /// or the other: an edge from a grounded vertex to a fresh one weighted
    /// `ρ`, a face on two grounded vertices and a fresh one weighted `ρ`,
    /// or the second of two nearly parallel edges on two fresh vertices.
    fn near_dependent(&mut self, remainder: f64) -> bool {
        let grounded = self.grounded_vertices();
        let recipe = self.rng.random_range(0..3);
        let skipped = remainder < 1e-10;
        match recipe {
            0 | 1 if grounded.len() >= 2 => {
                let Some(f) = self.take_fresh() else {
                    return false;
                };
                self.tainted[f] = true;
                let a = grounded[self.rng.random_range(0..grounded.len())];
                let q = self.target_near(f);
                let (kind, terms) = if recipe == 0 {
                    // `t p_a + (1 − t) p_f`, `1 − t = ρ`: an edge parameter
                    // within ρ of 1 (or, written the other way round, of 0).
                    let t = 1.0 - remainder;
                    let rho = 1.0 - t;
                    let target: [f64; 3] =
                        std::array::from_fn(|k| t * self.value[a][k] + rho * q[k]);
                    let kind = if self.rng.random_bool(0.5) {
                        ConstraintKind::Edge {
                            vertices: [a, f],
                            t,
                            target,
                        }
                    } else {
                        ConstraintKind::Edge {
                            vertices: [f, a],
                            t: rho,
                            target,
                        }
                    };
                    (kind, vec![(a, t)])
                } else {
                    let b = loop {
                        let b = grounded[self.rng.random_range(0..grounded.len())];
                        if b != a {
                            break b;
                        }
                    };
                    // `s p_a + t p_b + ρ p_f` with `s = ½`, `t = ½ − ρ'`,
                    // scaled so that the relative remainder is `ρ`.
                    let rho = remainder * 0.5f64.sqrt();
                    let (s, t) = (0.5, 0.5 - rho);
                    let w = 1.0 - s - t;
                    let target: [f64; 3] = std::array::from_fn(|k| {
                        s * self.value[a][k] + t * self.value[b][k] + w * q[k]
                    });
                    (
                        ConstraintKind::Face {
                            vertices: [a, b, f],
                            barycentric: [s, t],
                            target,
                        },
                        vec![(a, s), (b, t)],
                    )
                };
                if skipped {
                    let combination = self.grounded_combination(&terms);
                    self.dependent(kind, &combination);
                } else {
                    let c = self.kept(kind);
                    self.out.near_tolerance.push(c);
                }
            }
            _ => {
                let (Some(a), Some(b)) = (self.take_fresh(), self.take_fresh()) else {
                    return false;
                };
                self.tainted[a] = true;
                self.tainted[b] = true;
                let (qa, qb) = (self.target_near(a), self.target_near(b));
                let first = self.kept(ConstraintKind::Edge {
                    vertices: [a, b],
                    t: 0.5,
                    target: std::array::from_fn(|k| 0.5 * qa[k] + 0.5 * qb[k]),
                });
                // (½ + δ, ½ − δ): the remainder is √2 δ over a norm of
                // about 1/√2, i.e. 2δ relative.
                let t = 0.5 + 0.5 * remainder;
                let target = std::array::from_fn(|k| t * qa[k] + (1.0 - t) * qb[k]);
                let kind = ConstraintKind::Edge {
                    vertices: [a, b],
                    t,
                    target,
                };
                if skipped {
                    self.dependent(kind, &[(first, 1.0)]);
                } else {
                    let c = self.kept(kind);
                    self.out.near_tolerance.push(c);
                }
            }
        }
        true
    }
}

/// A [`ConstructedMix`] on `mesh`: `count` hard rows (fewer if the fresh
/// vertices run out) — independent ones with a fresh pivot, exact
/// dependent ones from forest paths, and (unless `positions_only`) near-
/// tolerance ones with remainders from [`SKIPPED_REMAINDERS`] and
/// [`KEPT_REMAINDERS`], as `mixture` allows — then `n_soft` soft
/// positions.
pub(crate) fn constructed_mix(
    mesh: Mesh,
    count: usize,
    n_soft: usize,
    positions_only: bool,
    mixture: Mixture,
    seed: u64,
) -> ConstructedMix {
    let p = mesh.positions().to_vec();
    let n = p.len();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut fresh: Vec<usize> = (0..n).collect();
    fresh.shuffle(&mut rng);
    let scale = mesh.bbox_diagonal();
    let mut b = MixBuilder {
        p: &p,
        mixture,
        rng,
        scale,
        fresh,
        touched: vec![false; n],
        adj: vec![Vec::new(); n + 1],
        tainted: vec![false; n + 1],
        value: vec![[0.0; 3]; n],
        out: ConstructedMix {
            mesh: mesh.clone(),
            constraints: Vec::new(),
            kept: Vec::new(),
            redundant: Vec::new(),
            conflicting: Vec::new(),
            sources: Vec::new(),
            near_tolerance: Vec::new(),
            tiny_entries: Vec::new(),
            positions_only,
        },
        rows: Vec::new(),
    };
    // A position first: every mesh here is connected, and one position
    // pins it.
    b.independent(true);
    let mut attempts = 0;
    while b.out.constraints.len() < count && attempts < 20 * count {
        attempts += 1;
        let roll = match mixture {
            Mixture::Independent => 0,
            Mixture::Separated => b.rng.random_range(0..9),
            Mixture::Everything => b.rng.random_range(0..10),
        };
        let _ = match roll {
            0..=3 => b.independent(positions_only),
            4..=6 => b.exact_dependent(positions_only),
            _ if positions_only => b.exact_dependent(true),
            7 | 8 => {
                let r = SKIPPED_REMAINDERS[b.rng.random_range(0..SKIPPED_REMAINDERS.len())];
                b.near_dependent(r)
            }
            _ => {
                let r = KEPT_REMAINDERS[b.rng.random_range(0..KEPT_REMAINDERS.len())];
                b.near_dependent(r)
            }
        };
    }
    let mut rng = b.rng.clone();
    let mut out = b.out;
    out.constraints = with_soft(&mesh, &mut rng, out.constraints, n_soft);
    out
}

/// Meshes for [`constructed_mixes`]: random surfaces from 4 × 4 up to
/// 16 × 16 cells (25–289 vertices) and sliver meshes ([`sliver_meshes`],
/// about 100–400 vertices).
pub(crate) fn constructed_meshes() -> impl Strategy<Value = Mesh> {
    prop_oneof![
        3 => (any::<u64>(), 4usize..9, 4usize..9).prop_map(|(s, nx, ny)| random_surface(nx, ny, s)),
        1 => (any::<u64>(), 9usize..17, 9usize..17).prop_map(|(s, nx, ny)| random_surface(nx, ny, s)),
        2 => sliver_meshes(),
    ]
}

/// [`ConstructedMix`]es on [`constructed_meshes`]: 4–40 hard rows of every
/// kind (a quarter of the cases positions only, which elimination
/// accepts), any [`Mixture`], 0–3 soft positions.
pub fn constructed_mixes() -> impl Strategy<Value = ConstructedMix> {
    (
        constructed_meshes(),
        any::<u64>(),
        4usize..41,
        0usize..4,
        prop::bool::weighted(0.25),
        mixtures(),
    )
        .prop_map(|(mesh, seed, count, n_soft, positions_only, mixture)| {
            constructed_mix(mesh, count, n_soft, positions_only, mixture, seed)
        })
}

/// A general problem whose kept, redundant and conflicting rows of `B` are
/// known by construction ([`constructed_lse`]).
#[derive(Debug, Clone)]
pub struct ConstructedLse {
    /// The problem.
    pub problem: LseProblem,
    /// Rows of `B` independent of the earlier kept ones.
    pub kept: Vec<usize>,
    /// Dependent rows with consistent `D`.
    pub redundant: Vec<usize>,
    /// Dependent rows whose `D` misses by 5 % of the row's norm (a distance
    /// of 0.05 in `X`'s units).
    pub conflicting: Vec<usize>,
    /// For each dependent row, the kept rows it combines, increasing.
    pub sources: Vec<(usize, Vec<usize>)>,
    /// Kept rows with a remainder of `10 η … 1e-6` (nearly dependent).
    pub near_tolerance: Vec<usize>,
    /// The power of ten each row of `B` (and of `D`) was scaled by.
    pub row_scales: Vec<i32>,
}

/// An independent row of [`constructed_lse`] before scaling: its index,
/// entries and right-hand side.
type BasisRow = (usize, Vec<(usize, f64)>, Vec<f64>);

/// A [`ConstructedLse`] with `n` unknowns, `rows` rows of `B` and `k`
/// right-hand sides. `A` is [`random_lse`]'s (a nonzero diagonal on top,
/// full column rank). Each row of `B` is, before a scaling by `10^e`
/// (`e ∈ {−8, 0, 8}`):
/// - independent: a pivot column no earlier row touches (coefficient
///   ±[0.5, 1.5]) and up to two entries on earlier pivots or on columns that
///   are never pivots;
/// - dependent: `Σ α_i v_i` over one to three earlier independent rows
///   (`α_i ∈ ±[0.5, 2]`), plus, for a near dependence, `ρ ‖v‖ u` with `u` a
///   unit vector on one to three columns no other row touches (so the
///   remainder is exactly `ρ` relative): skipped for `ρ` in
///   [`SKIPPED_REMAINDERS`] or 0, kept for `ρ` in [`KEPT_REMAINDERS`].
pub(crate) fn constructed_lse(
    n: usize,
    rows: usize,
    k: usize,
    mixture: Mixture,
    seed: u64,
) -> ConstructedLse {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (a, c) = random_a_and_c(&mut rng, n, k);
    let mut columns: Vec<usize> = (0..n).collect();
    columns.shuffle(&mut rng);
    // A third of the columns are pivots, a third perturbation columns (each
    // used by one row only), a third fillers.
    let third = n / 3;
    let mut pivots = columns[..third].iter().copied();
    let mut spare = columns[third..2 * third].iter().copied();
    let fillers = columns[2 * third..].to_vec();
    // Unscaled rows and right-hand sides of the independent rows that later
    // rows may combine.
    let mut basis: Vec<BasisRow> = Vec::new();
    let mut used_pivots: Vec<usize> = Vec::new();
    let mut b_rows: Vec<Vec<(usize, f64)>> = Vec::new();
    let mut d_rows: Vec<Vec<f64>> = Vec::new();
    let (mut kept_rows, mut redundant, mut conflicting) = (Vec::new(), Vec::new(), Vec::new());
    let (mut sources, mut near_tolerance, mut row_scales) = (Vec::new(), Vec::new(), Vec::new());
    let norm = row_norm;
    while b_rows.len() < rows {
        let index = b_rows.len();
        let dependent = mixture != Mixture::Independent && basis.len() >= 2 && rng.random_bool(0.5);
        let (mut v, mut d): (Vec<(usize, f64)>, Vec<f64>);
        let mut remainder = 0.0;
        let mut combination: Vec<(usize, f64)> = Vec::new();
        if !dependent {
            let Some(pivot) = pivots.next() else { break };
            (v, d) = pivot_row(&mut rng, pivot, &used_pivots, &fillers, k);
            used_pivots.push(pivot);
        } else {
            (v, d) = basis_combination(&mut rng, &basis, k, &mut combination);
            if norm(&v) < 0.1 {
                continue;
            }
            let choices = if mixture == Mixture::Everything { 6 } else { 4 };
            remainder = match rng.random_range(0..choices) {
                0 | 1 => 0.0,
                2 | 3 => SKIPPED_REMAINDERS[rng.random_range(0..SKIPPED_REMAINDERS.len())],
                _ => KEPT_REMAINDERS[rng.random_range(0..KEPT_REMAINDERS.len())],
            };
            if remainder > 0.0 && !perturb(&mut rng, remainder, &mut spare, &mut v, &mut d) {
                break;
            }
        }
        let kept = !dependent || remainder >= KEPT_REMAINDERS[0];
        if dependent && !kept && rng.random_bool(0.5) {
            d[0] += 0.05 * norm(&v);
            conflicting.push(index);
        } else if dependent && !kept {
            redundant.push(index);
        }
        if kept {
            kept_rows.push(index);
            if dependent {
                near_tolerance.push(index);
            } else {
                basis.push((index, v.clone(), d.clone()));
            }
        } else {
            let mut named: Vec<usize> = combination
                .iter()
                .filter(|&&(row, alpha)| {
                    let own = basis.iter().find(|b| b.0 == row).map(|b| norm(&b.1));
                    alpha.abs() * own.unwrap_or(0.0) > SOURCE_SHARE * norm(&v)
                })
                .map(|&(row, _)| row)
                .collect();
            named.sort_unstable();
            sources.push((index, named));
        }
        let e = match rng.random_range(0..4) {
            _ if mixture == Mixture::Independent => 0,
            0 => 8,
            1 => -8,
            _ => 0,
        };
        let s = 10f64.powi(e);
        row_scales.push(e);
        b_rows.push(v.iter().map(|&(j, x)| (j, s * x)).collect());
        d_rows.push(d.iter().map(|x| s * x).collect());
    }
    let (b, d) = assemble_b_d(&b_rows, &d_rows, n, k);
    ConstructedLse {
        problem: LseProblem::from_parts(a.as_ref(), c.as_ref(), b.as_ref(), d.as_ref()).unwrap(),
        kept: kept_rows,
        redundant,
        conflicting,
        sources,
        near_tolerance,
        row_scales,
    }
}

/// `±` a draw from `[lo, hi)`, the sign a fair coin (drawn second).
fn signed(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    let v = rng.random_range(lo..hi);
    if rng.random_bool(0.5) { v } else { -v }
}

/// The Euclidean norm of a sparse row.
fn row_norm(v: &[(usize, f64)]) -> f64 {
    v.iter().map(|e| e.1 * e.1).sum::<f64>().sqrt()
}

/// An independent row of [`constructed_lse`]: `±[0.5, 1.5)` on its fresh
/// `pivot`, and up to two more such entries on earlier pivots or fillers;
/// a right-hand side of `k` entries in `[−1, 1)`.
fn pivot_row(
    rng: &mut ChaCha8Rng,
    pivot: usize,
    used_pivots: &[usize],
    fillers: &[usize],
    k: usize,
) -> (Vec<(usize, f64)>, Vec<f64>) {
    let mut v = vec![(pivot, signed(rng, 0.5, 1.5))];
    let extra = rng.random_range(0..3);
    for _ in 0..extra {
        let j = if !used_pivots.is_empty() && rng.random_bool(0.5) {
            used_pivots[rng.random_range(0..used_pivots.len())]
        } else {
            fillers[rng.random_range(0..fillers.len())]
        };
        if v.iter().all(|e| e.0 != j) {
            v.push((j, signed(rng, 0.5, 1.5)));
        }
    }
    let d = (0..k).map(|_| rng.random_range(-1.0..1.0)).collect();
    (v, d)
}

/// A combination of 1–3 distinct rows of `basis` with coefficients
/// `±[0.5, 2)`, right-hand sides combined alike; exact zeros dropped. The
/// `(row, coefficient)` pairs are appended to `combination`.
fn basis_combination(
    rng: &mut ChaCha8Rng,
    basis: &[BasisRow],
    k: usize,
    combination: &mut Vec<(usize, f64)>,
) -> (Vec<(usize, f64)>, Vec<f64>) {
    let terms = rng.random_range(1..=3.min(basis.len()));
    let mut picks: Vec<usize> = (0..basis.len()).collect();
    picks.shuffle(rng);
    let mut dense: std::collections::BTreeMap<usize, f64> = Default::default();
    let mut d = vec![0.0; k];
    for &i in &picks[..terms] {
        let alpha = signed(rng, 0.5, 2.0);
        let (row, entries, rhs) = &basis[i];
        for &(j, x) in entries {
            *dense.entry(j).or_default() += alpha * x;
        }
        for (dc, r) in d.iter_mut().zip(rhs) {
            *dc += alpha * r;
        }
        combination.push((*row, alpha));
    }
    (dense.into_iter().filter(|e| e.1 != 0.0).collect(), d)
}

/// Moves `v` off the span of the rows it combines by `remainder · ‖v‖`:
/// 1–3 fresh perturbation columns from `spare`, a random unit direction
/// `u` on them (entries `±[0.5, 1)`, normalised), and the right-hand side
/// made consistent at random values of those unknowns. `false` when
/// `spare` runs out.
fn perturb(
    rng: &mut ChaCha8Rng,
    remainder: f64,
    spare: &mut impl Iterator<Item = usize>,
    v: &mut Vec<(usize, f64)>,
    d: &mut [f64],
) -> bool {
    let width = rng.random_range(1..=3);
    let cols: Vec<usize> = spare.by_ref().take(width).collect();
    if cols.len() < width {
        return false;
    }
    let u: Vec<f64> = cols.iter().map(|_| signed(rng, 0.5, 1.0)).collect();
    let u_norm = u.iter().map(|x| x * x).sum::<f64>().sqrt();
    let size = remainder * row_norm(v);
    // The consistent right-hand side of the perturbed row at X = q on the
    // perturbation columns.
    for (&j, &uj) in cols.iter().zip(&u) {
        let coefficient = size * uj / u_norm;
        v.push((j, coefficient));
        for dc in d.iter_mut() {
            *dc += coefficient * rng.random_range(-1.0..1.0);
        }
    }
    true
}

/// [`ConstructedLse`]s: 24–300 unknowns, up to a sixth as many rows of
/// `B` (3–50), 1–4 right-hand sides, any [`Mixture`].
pub fn constructed_lses() -> impl Strategy<Value = ConstructedLse> {
    (any::<u64>(), 24usize..301, 1usize..5, mixtures())
        .prop_flat_map(|(seed, n, k, mixture)| {
            (
                Just(seed),
                Just(n),
                3usize..(n / 6).max(4),
                Just(k),
                Just(mixture),
            )
        })
        .prop_map(|(seed, n, rows, k, mixture)| constructed_lse(n, rows, k, mixture, seed))
}

/// `(s, e)` with `s + e = a + b` exactly.
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// `Σ x_i y_i` as if computed in twice the working precision and rounded
/// once (Ogita, Rump & Oishi's Dot2, with the products split exactly by a
/// fused multiply–add).
fn dot2(terms: impl Iterator<Item = (f64, f64)>) -> f64 {
    let (mut s, mut c) = (0.0, 0.0);
    for (x, y) in terms {
        let p = x * y;
        let ep = x.mul_add(y, -p);
        let (t, es) = two_sum(s, p);
        s = t;
        c += es + ep;
    }
    s + c
}

/// A double-double number `hi + lo` (`|lo| ≤ ulp(hi)/2`): about 32
/// significant digits, for [`accurate_reference`].
#[derive(Debug, Clone, Copy, Default)]
struct Dd(f64, f64);

impl Dd {
    fn from(x: f64) -> Dd {
        Dd(x, 0.0)
    }

    fn renormalised(hi: f64, lo: f64) -> Dd {
        let s = hi + lo;
        Dd(s, lo - (s - hi))
    }

    fn add(self, o: Dd) -> Dd {
        let (s, e) = two_sum(self.0, o.0);
        let (t, f) = two_sum(self.1, o.1);
        let r = Dd::renormalised(s, e + t);
        Dd::renormalised(r.0, r.1 + f)
    }

    fn neg(self) -> Dd {
        Dd(-self.0, -self.1)
    }

    fn sub(self, o: Dd) -> Dd {
        self.add(o.neg())
    }

    fn mul(self, o: Dd) -> Dd {
        let p = self.0 * o.0;
        let e = self.0.mul_add(o.0, -p) + (self.0 * o.1 + self.1 * o.0);
        Dd::renormalised(p, e)
    }

    fn div(self, o: Dd) -> Dd {
        let q1 = self.0 / o.0;
        let r = self.sub(o.mul(Dd::from(q1)));
        let q2 = r.0 / o.0;
        let r = r.sub(o.mul(Dd::from(q2)));
        let q3 = r.0 / o.0;
        Dd::renormalised(q1, q2).add(Dd::from(q3))
    }

    fn sqrt(self) -> Dd {
        if self.0 <= 0.0 {
            return Dd::default();
        }
        let x = Dd::from(self.0.sqrt());
        let r = self.sub(x.mul(x));
        x.add(Dd::from(r.0 / (2.0 * x.0)))
    }
}

/// An orthonormal basis of the rows `rows` of `B` (which must be
/// independent), with the right-hand sides carried along: `W = T B_rows`,
/// `E = T D_rows` for the lower triangular `T` of Gram–Schmidt (twice, in
/// double-double arithmetic), rounded to `f64`. `W X = E` has the solutions
/// of `B_rows X = D_rows` however nearly dependent or badly scaled the rows
/// are, with a matrix of condition number one.
fn orthonormal_constraints(problem: &LseProblem, rows: &[usize]) -> (Mat<f64>, Mat<f64>) {
    let (n, k) = (problem.n(), problem.n_rhs());
    let b = problem.b().to_dense();
    let mut w: Vec<Vec<Dd>> = Vec::new();
    let mut e: Vec<Vec<Dd>> = Vec::new();
    for &row in rows {
        let mut v: Vec<Dd> = (0..n).map(|j| Dd::from(b[(row, j)])).collect();
        let mut d: Vec<Dd> = (0..k).map(|c| Dd::from(problem.d()[(row, c)])).collect();
        for _pass in 0..2 {
            for (wj, ej) in w.iter().zip(&e) {
                let mut dot = Dd::default();
                for (x, y) in v.iter().zip(wj) {
                    if x.0 != 0.0 && y.0 != 0.0 {
                        dot = dot.add(x.mul(*y));
                    }
                }
                if dot.0 == 0.0 {
                    continue;
                }
                for (x, y) in v.iter_mut().zip(wj) {
                    if y.0 != 0.0 {
                        *x = x.sub(dot.mul(*y));
                    }
                }
                for (x, y) in d.iter_mut().zip(ej) {
                    *x = x.sub(dot.mul(*y));
                }
            }
        }
        let mut norm2 = Dd::default();
        for x in &v {
            norm2 = norm2.add(x.mul(*x));
        }
        let norm = norm2.sqrt();
        w.push(v.iter().map(|x| x.div(norm)).collect());
        e.push(d.iter().map(|x| x.div(norm)).collect());
    }
    (
        Mat::from_fn(rows.len(), n, |i, j| w[i][j].0 + w[i][j].1),
        Mat::from_fn(rows.len(), k, |i, c| e[i][c].0 + e[i][c].1),
    )
}

/// An accurate reference for `min ‖AX − C‖ s.t. B_rows X = D_rows` (the
/// rows must be independent, however nearly): the constraint rows are
/// first replaced by an orthonormal basis of their span with the
/// right-hand sides carried along, in double-double arithmetic
/// ([`orthonormal_constraints`]), so that near dependence and row scaling
/// leave no trace in the conditioning; then the augmented system
/// `[I A 0; Aᵀ 0 Wᵀ; 0 W 0] [S; X; Λ] = [C; 0; E]` is factored by faer's
/// dense partial-pivoting LU and refined with residuals computed in twice
/// the working precision until a correction stops shrinking. The result is
/// the exact solution to about a unit in the last place of its largest
/// entries wherever `ε κ(A)` is well below one — unlike
/// [`dense_reference`], whose own error grows with the condition number of
/// the KKT matrix (the square of `A`'s, times that of `B`), this one
/// measures the true error of a solver on ill-conditioned problems.
/// Independent of every sparse path of the library; dense, so for problems
/// of up to about a thousand unknowns and rows.
pub fn accurate_reference(problem: &LseProblem, rows: &[usize]) -> Mat<f64> {
    let (n, l, m, k) = (
        problem.n(),
        problem.a().nrows(),
        rows.len(),
        problem.n_rhs(),
    );
    let size = l + n + m;
    let a = problem.a().to_dense();
    let (w, e) = orthonormal_constraints(problem, rows);
    let mut kmat = Mat::<f64>::zeros(size, size);
    for i in 0..l {
        kmat[(i, i)] = 1.0;
        for j in 0..n {
            kmat[(i, l + j)] = a[(i, j)];
            kmat[(l + j, i)] = a[(i, j)];
        }
    }
    let mut rhs = Mat::<f64>::zeros(size, k);
    for i in 0..l {
        for c in 0..k {
            rhs[(i, c)] = problem.c()[(i, c)];
        }
    }
    for r in 0..m {
        for j in 0..n {
            kmat[(l + n + r, l + j)] = w[(r, j)];
            kmat[(l + j, l + n + r)] = w[(r, j)];
        }
        for c in 0..k {
            rhs[(l + n + r, c)] = e[(r, c)];
        }
    }
    let nonzeros: Vec<Vec<(usize, f64)>> = (0..size)
        .map(|i| {
            (0..size)
                .filter(|&j| kmat[(i, j)] != 0.0)
                .map(|j| (j, kmat[(i, j)]))
                .collect()
        })
        .collect();
    let lu = kmat.partial_piv_lu();
    let mut v = lu.solve(&rhs);
    let mut last = f64::INFINITY;
    for _ in 0..40 {
        let residual = Mat::from_fn(size, k, |i, c| {
            dot2(
                std::iter::once((rhs[(i, c)], 1.0))
                    .chain(nonzeros[i].iter().map(|&(j, x)| (-x, v[(j, c)]))),
            )
        });
        let delta = lu.solve(&residual);
        let step = delta.norm_max();
        if step.is_nan() || step >= last {
            break;
        }
        v += &delta;
        last = step;
        if step <= f64::EPSILON * f64::EPSILON * v.norm_max() {
            break;
        }
    }
    v.submatrix(l, 0, n, k).to_owned()
}

#[cfg(test)]
mod helper_tests {
    use super::*;

    #[test]
    fn row_norm_and_b_d_assembly() {
        assert_eq!(row_norm(&[(0, 3.0), (5, -4.0)]), 5.0);
        let rows = vec![vec![(2, 1.0), (0, -1.0)], vec![(1, 0.5), (1, 0.25)]];
        let d_rows = vec![vec![1.0, 2.0], vec![3.0, 4.0]];
        let (b, d) = assemble_b_d(&rows, &d_rows, 3, 2);
        assert_eq!(b.to_dense(), faer::mat![[-1.0, 0.0, 1.0], [0.0, 0.75, 0.0]]);
        assert_eq!(d, faer::mat![[1.0, 2.0], [3.0, 4.0]]);
    }

    #[test]
    fn a_combination_of_one_row_with_itself_keeps_row_and_rhs_in_proportion() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let rows = vec![vec![(1, 2.0)]];
        let (row, d) = two_row_combination(&mut rng, &rows, &[vec![4.0]], &[0], 3).expect("s ≠ −t");
        assert_eq!(row.len(), 1);
        assert_eq!(row[0].0, 1);
        assert_eq!(d, [2.0 * row[0].1]);
    }

    #[test]
    fn pivot_rows_lead_with_their_pivot_and_use_fillers() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..20 {
            let (v, d) = pivot_row(&mut rng, 9, &[], &[4, 5], 2);
            assert_eq!(v[0].0, 9);
            assert!((0.5..1.5).contains(&v[0].1.abs()), "{v:?}");
            assert!(v[1..].iter().all(|e| e.0 == 4 || e.0 == 5), "{v:?}");
            assert!(d.len() == 2 && d.iter().all(|x| (-1.0..1.0).contains(x)));
        }
    }

    #[test]
    fn perturbation_adds_fresh_columns_of_the_asked_size() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut v = vec![(0, 3.0), (1, 4.0)];
        let mut d = vec![0.0];
        let mut spare = [7, 8, 9].into_iter();
        assert!(perturb(&mut rng, 0.1, &mut spare, &mut v, &mut d));
        let added = &v[2..];
        assert!(!added.is_empty() && added.iter().zip(7..).all(|(e, j)| e.0 == j));
        // ‖added‖ = 0.1 · ‖(3, 4)‖ = 0.5.
        assert!((row_norm(added) - 0.5).abs() < 1e-15, "{added:?}");
        let mut empty = std::iter::empty();
        assert!(!perturb(&mut rng, 0.1, &mut empty, &mut v, &mut d));
    }
}
