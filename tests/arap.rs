//! ARAP: agreement with an independent dense implementation (angles by
//! atan2, rotations by Horn's quaternion method, the global step by a dense
//! KKT solve), exact hard constraints and monotone energy at every
//! iteration over random meshes and constraint mixes, and no NaN on
//! sliver meshes.

use faer::Mat;
use faer::prelude::Solve;
use lse_deform::arap::{ArapDeformer, ArapEnergy, ArapInit};
use lse_deform::constraints::{Constraint, ConstraintKind, ConstraintSet};
use lse_deform::mesh::generate;
use lse_deform::testing::random_surface;
use lse_deform::{Mesh, formulation::NullSpaceQr};
use nalgebra::{Matrix3, Matrix4};
use proptest::prelude::*;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

type M3 = Matrix3<f64>;
/// A hard constraint row: its `(vertex, coefficient)` pairs and target.
type HardRow = (Vec<(usize, f64)>, [f64; 3]);

fn v3(p: [f64; 3]) -> nalgebra::Vector3<f64> {
    nalgebra::Vector3::new(p[0], p[1], p[2])
}

/// The rotation maximising `tr(Rᵀ M)` by Horn's (1987) quaternion method:
/// the eigenvector of the largest eigenvalue of a symmetric 4 × 4 matrix.
fn horn_rotation(m: &M3) -> M3 {
    let s = m.transpose(); // S_ab = Σ w p_a x_b
    let (sxx, sxy, sxz) = (s[(0, 0)], s[(0, 1)], s[(0, 2)]);
    let (syx, syy, syz) = (s[(1, 0)], s[(1, 1)], s[(1, 2)]);
    let (szx, szy, szz) = (s[(2, 0)], s[(2, 1)], s[(2, 2)]);
    #[rustfmt::skip]
    let n = Matrix4::new(
        sxx + syy + szz, syz - szy, szx - sxz, sxy - syx,
        syz - szy, sxx - syy - szz, sxy + syx, szx + sxz,
        szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy,
        sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz,
    );
    let eig = n.symmetric_eigen();
    let k = eig.eigenvalues.imax();
    let q = eig.eigenvectors.column(k);
    let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
    #[rustfmt::skip]
    let r = M3::new(
        1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w),
        2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w),
        2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y),
    );
    r
}

/// A dense ARAP written from the definition: per triangle and edge,
/// `c = ½ cot θ` (θ by atan2), owners per energy, `E = Σ c Σ_o ‖x_e − R_o p_e‖²`.
struct DenseArap {
    /// (i, j, c, owners): the edge from i to j with weight c.
    edges: Vec<(usize, usize, f64, Vec<usize>)>,
    rest: Vec<[f64; 3]>,
    hard: Vec<HardRow>,
}

impl DenseArap {
    fn new(mesh: &Mesh, energy: ArapEnergy, constraints: &ConstraintSet) -> DenseArap {
        let p = mesh.positions();
        let mut edges = Vec::new();
        for f in mesh.faces() {
            for k in 0..3 {
                let (o, i, j) = (f[k], f[(k + 1) % 3], f[(k + 2) % 3]);
                let (u, v) = (v3(p[i]) - v3(p[o]), v3(p[j]) - v3(p[o]));
                let angle = u.cross(&v).norm().atan2(u.dot(&v));
                let owners = match energy {
                    ArapEnergy::SpokesAndRims => vec![o, i, j],
                    ArapEnergy::Spokes => vec![i, j],
                };
                edges.push((i, j, 0.5 / angle.tan(), owners));
            }
        }
        let hard = constraints
            .as_slice()
            .iter()
            .filter(|c| c.weight.is_none())
            .map(|c| (c.kind.row().entries().to_vec(), c.kind.rhs()))
            .collect();
        DenseArap {
            edges,
            rest: p.to_vec(),
            hard,
        }
    }

    fn edge(&self, x: &[[f64; 3]], i: usize, j: usize) -> nalgebra::Vector3<f64> {
        v3(x[j]) - v3(x[i])
    }

    fn rotations(&self, x: &[[f64; 3]]) -> Vec<M3> {
        let mut m = vec![M3::zeros(); self.rest.len()];
        for (i, j, c, owners) in &self.edges {
            let outer = self.edge(x, *i, *j) * self.edge(&self.rest, *i, *j).transpose() * *c;
            for &o in owners {
                m[o] += outer;
            }
        }
        m.iter().map(horn_rotation).collect()
    }

    fn energy(&self, x: &[[f64; 3]], r: &[M3]) -> f64 {
        self.edges
            .iter()
            .map(|(i, j, c, owners)| {
                let (xe, pe) = (self.edge(x, *i, *j), self.edge(&self.rest, *i, *j));
                owners
                    .iter()
                    .map(|&o| c * (xe - r[o] * pe).norm_squared())
                    .sum::<f64>()
            })
            .sum()
    }

    /// `min_X E(X, R) s.t. the hard rows`, by a dense KKT solve.
    fn global(&self, r: &[M3]) -> Vec<[f64; 3]> {
        let n = self.rest.len();
        let m = self.hard.len();
        let mut k = Mat::<f64>::zeros(n + m, n + m);
        let mut rhs = Mat::<f64>::zeros(n + m, 3);
        for (i, j, c, owners) in &self.edges {
            let w = c * owners.len() as f64;
            for (a, b, s) in [(*i, *i, 1.0), (*j, *j, 1.0), (*i, *j, -1.0), (*j, *i, -1.0)] {
                k[(a, b)] += w * s;
            }
            let pe = self.edge(&self.rest, *i, *j);
            let v: nalgebra::Vector3<f64> = owners.iter().map(|&o| r[o] * pe).sum();
            for d in 0..3 {
                rhs[(*j, d)] += c * v[d];
                rhs[(*i, d)] -= c * v[d];
            }
        }
        for (row, (entries, target)) in self.hard.iter().enumerate() {
            for &(v, a) in entries {
                k[(n + row, v)] = a;
                k[(v, n + row)] = a;
            }
            for d in 0..3 {
                rhs[(n + row, d)] = target[d];
            }
        }
        let x = k.full_piv_lu().solve(&rhs);
        (0..n).map(|i| [x[(i, 0)], x[(i, 1)], x[(i, 2)]]).collect()
    }
}

fn rest_with_positions(mesh: &Mesh, constraints: &ConstraintSet) -> Vec<[f64; 3]> {
    let mut x = mesh.positions().to_vec();
    for c in constraints.as_slice() {
        if let (None, ConstraintKind::Position { vertex, target }) = (c.weight, &c.kind) {
            x[*vertex] = *target;
        }
    }
    x
}

/// The bottom row fixed, the top row lifted and pushed sideways, one edge
/// and one relative constraint: a bend.
fn bend_scene(mesh: &Mesh, nx: usize, ny: usize) -> ConstraintSet {
    let p = mesh.positions();
    let mut cs = ConstraintSet::new();
    for i in 0..=nx {
        cs.push(Constraint::hard(ConstraintKind::Position {
            vertex: i,
            target: p[i],
        }))
        .unwrap();
        let top = ny * (nx + 1) + i;
        let q = p[top];
        cs.push(Constraint::hard(ConstraintKind::Position {
            vertex: top,
            target: [q[0] + 0.3, q[1] - 0.4, q[2] + 0.6],
        }))
        .unwrap();
    }
    let mid = (ny / 2) * (nx + 1);
    cs.push(Constraint::hard(ConstraintKind::Edge {
        vertices: [mid + 1, mid + 2],
        t: 0.3,
        target: [0.2, 0.5, 0.4],
    }))
    .unwrap();
    cs.push(Constraint::hard(ConstraintKind::Relative {
        vertices: [mid + nx, mid],
        vector: [0.8, 0.1, 0.2],
    }))
    .unwrap();
    cs
}

#[test]
fn iterations_match_a_dense_implementation_from_the_definition() {
    let (nx, ny) = (5, 6);
    for energy in [ArapEnergy::SpokesAndRims, ArapEnergy::Spokes] {
        let mesh = random_surface(nx, ny, 11);
        let cs = bend_scene(&mesh, nx, ny);
        let dense = DenseArap::new(&mesh, energy, &cs);
        let mut arap = ArapDeformer::with_formulation(
            mesh.clone(),
            cs.clone(),
            energy,
            &NullSpaceQr::default(),
            &lse_deform::resources::Resources::default(),
        )
        .unwrap();
        arap.initialize(ArapInit::Rest).unwrap();
        let mut x = rest_with_positions(&mesh, &cs);
        let r0 = dense.rotations(&x);
        let e0 = dense.energy(&x, &r0);
        assert!(
            (arap.energy() - e0).abs() <= 1e-10 * e0,
            "{energy:?}: initial energy {} vs dense {e0}",
            arap.energy()
        );
        let scale = mesh.bbox_diagonal();
        for it in 1..=8 {
            let r = dense.rotations(&x);
            x = dense.global(&r);
            let e = dense.energy(&x, &dense.rotations(&x));
            arap.iterate(1).unwrap();
            let ours = arap.positions();
            let dx = ours
                .iter()
                .zip(&x)
                .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
                .fold(0.0, f64::max);
            assert!(
                dx <= 1e-9 * scale,
                "{energy:?} iteration {it}: positions differ by {dx:e}"
            );
            assert!(
                (arap.energy() - e).abs() <= 1e-9 * e,
                "{energy:?} iteration {it}: energy {} vs dense {e}",
                arap.energy()
            );
        }
    }
}

#[test]
fn linear_init_is_the_identity_rotation_global_step() {
    let (nx, ny) = (4, 5);
    let mesh = random_surface(nx, ny, 3);
    let cs = bend_scene(&mesh, nx, ny);
    let dense = DenseArap::new(&mesh, ArapEnergy::SpokesAndRims, &cs);
    let expected = dense.global(&vec![M3::identity(); mesh.n_vertices()]);
    let mut arap = ArapDeformer::with_formulation(
        mesh.clone(),
        cs,
        ArapEnergy::SpokesAndRims,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    arap.initialize(ArapInit::Linear).unwrap();
    for (a, b) in arap.positions().iter().zip(&expected) {
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() <= 1e-10 * mesh.bbox_diagonal());
        }
    }
}

/// Runs `iterations` and checks, at every iteration, every kept hard
/// constraint to `1e-10 ×` the diagonal and a non-increasing objective (to
/// rounding: `1e-10 ×` the initial objective plus `1e-13 ×` the current).
fn check_run(
    mesh: Mesh,
    cs: ConstraintSet,
    energy: ArapEnergy,
    iterations: usize,
) -> Result<(), TestCaseError> {
    let scale = mesh.bbox_diagonal();
    let mut arap = ArapDeformer::with_formulation(
        mesh,
        cs,
        energy,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    arap.initialize(ArapInit::Rest).unwrap();
    let report = arap.run(iterations, 0.0).unwrap();
    prop_assert!(arap.positions().iter().flatten().all(|v| v.is_finite()));
    for (k, r) in report.constraint_residuals.iter().enumerate() {
        prop_assert!(*r <= 1e-10 * scale, "iteration {}: residual {r:e}", k + 1);
    }
    let first = report.energies[0];
    for (k, e) in report.energies.windows(2).enumerate() {
        prop_assert!(e[0].is_finite() && e[1].is_finite());
        prop_assert!(
            e[1] <= e[0] + 1e-10 * first + 1e-13 * e[0].abs(),
            "iteration {}: energy {} after {}",
            k + 2,
            e[1],
            e[0]
        );
    }
    Ok(())
}

fn jitter(rng: &mut ChaCha8Rng, p: [f64; 3], s: f64) -> [f64; 3] {
    p.map(|v| v + rng.random_range(-s..s))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// Random surfaces, a fixed bottom row, a moved handle on the top row,
    /// and random hard relative, on-edge and face constraints plus a few
    /// soft ones: exact hard constraints and monotone objective at every
    /// iteration, for both energies.
    #[test]
    fn exact_constraints_and_monotone_energy(
        seed in any::<u64>(),
        nx in 3usize..8,
        ny in 3usize..8,
        n_relative in 0usize..12,
        n_edge in 0usize..6,
        n_soft in 0usize..3,
        spokes in any::<bool>(),
    ) {
        let mesh = random_surface(nx, ny, seed);
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xa4a9);
        let p = mesh.positions().to_vec();
        let n = p.len();
        let mut cs = ConstraintSet::new();
        for (i, &q) in p.iter().enumerate().take(nx + 1) {
            cs.push(Constraint::hard(ConstraintKind::Position { vertex: i, target: q })).unwrap();
        }
        let top = ny * (nx + 1) + nx / 2;
        let handle = jitter(&mut rng, p[top], 0.6);
        cs.push(Constraint::hard(ConstraintKind::Position { vertex: top, target: handle })).unwrap();
        let mut verts: Vec<usize> = (nx + 1..n).filter(|&v| v != top).collect();
        for k in 0..n_relative + n_edge + n_soft {
            verts.shuffle(&mut rng);
            let (a, b) = (verts[0], verts[1]);
            let kind = if k < n_relative {
                let d = [p[a][0] - p[b][0], p[a][1] - p[b][1], p[a][2] - p[b][2]];
                ConstraintKind::Relative { vertices: [a, b], vector: jitter(&mut rng, d, 0.1) }
            } else {
                let t = rng.random_range(0.1..0.9);
                let mid = [0, 1, 2].map(|c| t * p[a][c] + (1.0 - t) * p[b][c]);
                ConstraintKind::Edge { vertices: [a, b], t, target: jitter(&mut rng, mid, 0.1) }
            };
            cs.push(if k >= n_relative + n_edge {
                Constraint::soft(kind, rng.random_range(0.5..5.0))
            } else {
                Constraint::hard(kind)
            }).unwrap();
        }
        let energy = if spokes { ArapEnergy::Spokes } else { ArapEnergy::SpokesAndRims };
        check_run(mesh, cs, energy, 12)?;
    }
}

#[test]
fn sliver_meshes_never_give_nan_and_the_energy_still_decreases() {
    for seed in 0..3 {
        let mesh = generate::sliver_mesh(10, seed).unwrap();
        let p = mesh.positions().to_vec();
        let (lo, hi) = mesh.bounding_box();
        let mut cs = ConstraintSet::new();
        for (v, q) in p.iter().enumerate() {
            if q[1] < lo[1] + 0.05 * (hi[1] - lo[1]) {
                cs.push(Constraint::hard(ConstraintKind::Position {
                    vertex: v,
                    target: *q,
                }))
                .unwrap();
            } else if q[1] > hi[1] - 0.05 * (hi[1] - lo[1]) {
                cs.push(Constraint::hard(ConstraintKind::Position {
                    vertex: v,
                    target: [q[0], q[1] - 0.3, q[2] + 0.5],
                }))
                .unwrap();
            }
        }
        for energy in [ArapEnergy::SpokesAndRims, ArapEnergy::Spokes] {
            check_run(mesh.clone(), cs.clone(), energy, 30).unwrap();
        }
    }
}

/// ARAP goes through the crate's one solver driver: its report carries the
/// same refinement warnings as the Laplacian path. A penalty weight of 1e4
/// (relative to the problem's scale) on a scene with edge and relative
/// rows, unrefined, leaves a forward error above the warning threshold
/// (1e-8 of the length scale): `deform` on the same mesh and
/// constraints warns about it, and so must ARAP's report, in the same
/// words; once refined, neither warns. (ARAP used to keep its own factor
/// and refinement, and reported no such warning.)
#[test]
fn arap_warns_about_its_forward_error_like_the_laplacian_path() {
    use lse_deform::formulation::{FormulationChoice, Method, Refine};
    use lse_deform::{Deformer, LaplacianKind};
    let (nx, ny) = (8, 8);
    let mesh = generate::grid(nx, ny).unwrap();
    let constraints = bend_scene(&mesh, nx, ny);
    let penalty = || {
        FormulationChoice {
            weight: Some(1e4),
            ..FormulationChoice::new(Method::Penalty)
        }
        .build()
        .unwrap()
    };
    let forward_error_warnings =
        |warnings: &[lse_deform::report::Warning]| -> Vec<lse_deform::report::Warning> {
            warnings
                .iter()
                .filter(|w| w.message.contains("estimated forward error"))
                .cloned()
                .collect()
        };
    for refine in [Refine::EstimateOnly, Refine::Auto] {
        let mut laplacian = Deformer::new(
            mesh.clone(),
            LaplacianKind::Cotangent,
            constraints.clone(),
            &lse_deform::SolveOptions::default(),
        )
        .unwrap();
        laplacian.solver_mut().set_refine(Some(refine));
        laplacian
            .refactor_with(
                penalty().as_ref(),
                &lse_deform::resources::Resources::default(),
            )
            .unwrap();
        let deform = forward_error_warnings(&laplacian.solve().unwrap().report.warnings);

        let mut arap = ArapDeformer::new(
            mesh.clone(),
            constraints.clone(),
            ArapEnergy::SpokesAndRims,
            &lse_deform::SolveOptions::default(),
        )
        .unwrap();
        arap.set_refine(Some(refine));
        arap.refactor_with(
            penalty().as_ref(),
            &lse_deform::resources::Resources::default(),
        )
        .unwrap();
        arap.initialize(ArapInit::Rest).unwrap();
        arap.run(3, 0.0).unwrap();
        let report = arap.finish().unwrap();
        let arap_warnings = forward_error_warnings(&report.warnings);
        assert_eq!(
            deform.is_empty(),
            refine == Refine::Auto,
            "{refine:?}: {deform:?}"
        );
        assert_eq!(
            arap_warnings.is_empty(),
            refine == Refine::Auto,
            "{refine:?}: {arap_warnings:?}"
        );
        for w in &arap_warnings {
            assert!(
                w.message.starts_with("penalty: estimated forward error"),
                "{w}"
            );
            assert!(w.message.contains("refinement is off"), "{w}");
        }
    }
}

/// The Laplacian and the ARAP deformer share one unit-scaled set-up: on
/// the same mesh (here far from unit size, so the scaling matters) and
/// constraints they divide by the same length unit and assemble the same
/// hard rows `B X = D` bit for bit. (The linear initial guess is not the
/// Laplacian deformer's solution: it minimises the harmonic energy
/// `Σ w_ij ‖(x_i − x_j) − (p_i − p_j)‖²`, the Laplacian deformer
/// `‖L(X − P)‖²`.)
#[test]
fn both_deformers_share_the_unit_scaled_set_up() {
    use lse_deform::{Deformer, LaplacianKind};
    let (nx, ny) = (5, 6);
    let small = random_surface(nx, ny, 11);
    let mesh = small
        .with_positions(
            small
                .positions()
                .iter()
                .map(|p| p.map(|v| v * 1e-7))
                .collect(),
        )
        .unwrap();
    let cs = bend_scene(&mesh, nx, ny);
    let linear = Deformer::new(
        mesh.clone(),
        LaplacianKind::CotangentSymmetric,
        cs.clone(),
        &lse_deform::SolveOptions::default(),
    )
    .unwrap();
    let arap = ArapDeformer::new(
        mesh.clone(),
        cs,
        ArapEnergy::SpokesAndRims,
        &lse_deform::SolveOptions::default(),
    )
    .unwrap();
    assert_eq!(linear.length_unit(), mesh.length_unit());
    assert_eq!(linear.length_unit(), arap.length_unit());
    assert_eq!(linear.report().length_unit, arap.report().length_unit);
    let (p, q) = (linear.problem(), arap.problem());
    assert_eq!(p.hard_constraints(), q.hard_constraints());
    assert_eq!(p.d(), q.d());
    assert_eq!(p.b().to_dense(), q.b().to_dense());
}
