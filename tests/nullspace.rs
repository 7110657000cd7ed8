//! The paper's null-space QR method: exact constraints, rank detection in
//! priority order, conflict classification and agreement with an
//! independently computed dense solution.

use lse_deform::constraints::{Constraint, ConstraintKind, ConstraintSet};
use lse_deform::error::{Error, ProblemError};
use lse_deform::testing::{
    T_VALUES, dense_reference, dependent_constraints as dependent, independent_constraints, jitter,
    laplacian_kinds as kinds, random_surface, relative_difference,
};
use lse_deform::{Deformer, LaplacianKind, Mesh, formulation::NullSpaceQr};
use proptest::prelude::*;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// "Exact" hard constraints: a kept row's residual over the bounding-box
/// diagonal (or over the solution's largest vertex, when larger). The
/// solvers reach about 1e-15 after their default refinement.
const EXACT: f64 = 1e-13;

/// `max_i ‖X_i‖₂`.
fn largest_vertex(x: &faer::Mat<f64>) -> f64 {
    (0..x.nrows())
        .map(|i| {
            (0..x.ncols())
                .map(|c| x[(i, c)].powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max)
}

/// The rows of `B` that depend on earlier non-dependent rows, by dense
/// modified Gram–Schmidt (twice) in list order with the rank tolerance
/// relative to each row's norm: what the QR back ends decide, computed
/// without them. The generators here keep remainders well away from the
/// tolerance (0 or of order one).
fn dependent_in_priority_order(problem: &lse_deform::problem::LseProblem) -> Vec<usize> {
    let b = problem.b().to_dense();
    let mut basis: Vec<Vec<f64>> = Vec::new();
    let mut out = Vec::new();
    for k in 0..b.nrows() {
        let mut v: Vec<f64> = (0..b.ncols()).map(|j| b[(k, j)]).collect();
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        for _ in 0..2 {
            for q in &basis {
                let dot: f64 = v.iter().zip(q).map(|(a, b)| a * b).sum();
                for (a, b) in v.iter_mut().zip(q) {
                    *a -= dot * b;
                }
            }
        }
        let rest = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if rest <= 1e-10 * norm {
            out.push(k);
        } else {
            basis.push(v.iter().map(|x| x / rest).collect());
        }
    }
    out
}

fn solve(
    mesh: &Mesh,
    kind: LaplacianKind,
    constraints: Vec<Constraint>,
) -> Result<(Deformer, faer::Mat<f64>), Error> {
    let set = ConstraintSet::from_vec(constraints).unwrap();
    let mut d = Deformer::with_formulation(
        mesh.clone(),
        kind,
        set,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )?;
    let x = d.solve_matrix()?;
    Ok((d, x))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// (a) Random meshes and random mixtures of the four kinds, hard and
    /// soft, dependent or not: every kept hard constraint holds to
    /// 1e-13 × the bounding-box diagonal (the solvers reach 1e-15), and the
    /// rows reported redundant or conflicting are exactly those that a
    /// dense Gram–Schmidt in priority order finds dependent.
    #[test]
    fn hard_constraints_hold_exactly(
        seed in any::<u64>(),
        nx in 3usize..9,
        ny in 3usize..9,
        count in 1usize..25,
        kind in kinds(),
    ) {
        let mesh = random_surface(nx, ny, seed);
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
        let n = mesh.n_vertices();
        let p = mesh.positions();
        let mut cs = vec![Constraint::hard(ConstraintKind::Position { vertex: 0, target: p[0] })];
        for _ in 0..count {
            let mut verts: Vec<usize> = (0..n).collect();
            verts.shuffle(&mut rng);
            let v = verts[0];
            let target = jitter(&mut rng, p[v], 0.3);
            let kind = match rng.random_range(0..4) {
                0 => ConstraintKind::Position { vertex: v, target },
                1 => ConstraintKind::Edge { vertices: [v, verts[1]], t: T_VALUES[rng.random_range(0..5)], target },
                2 => ConstraintKind::Face { vertices: [v, verts[1], verts[2]], barycentric: [0.2, T_VALUES[rng.random_range(0..5)]], target },
                _ => ConstraintKind::Relative { vertices: [v, verts[1]], vector: jitter(&mut rng, [0.0; 3], 0.2) },
            };
            cs.push(if rng.random_bool(0.2) {
                Constraint::soft(kind, rng.random_range(0.1..10.0))
            } else {
                Constraint::hard(kind)
            });
        }
        let (d, x) = solve(&mesh, kind, cs).unwrap();
        let report = d.report();
        // Rounding scales with the solution, which conflicting rows can
        // send far from the mesh (3,662 for a diagonal of 1.44, cotangent
        // weights on 20 vertices): the larger of the two is the scale.
        let scale = mesh.bbox_diagonal().max(largest_vertex(&x));
        prop_assert!(report.max_constraint_residual <= EXACT * scale,
            "max residual {} vs scale {}", report.max_constraint_residual, scale);
        // Recompute independently from the report: every hard row not
        // reported redundant or conflicting holds.
        let problem = d.problem();
        let flagged: Vec<usize> = report.redundant.iter().copied()
            .chain(report.conflicting.iter().map(|c| c.index)).collect();
        for (k, &index) in problem.hard_constraints().iter().enumerate() {
            if !flagged.contains(&index) {
                prop_assert!(problem.hard_residual(k, &x) <= EXACT * scale);
            }
        }
        // The dependent rows, decided independently of the library's QR.
        let mut flagged = flagged;
        flagged.sort_unstable();
        let dependent: Vec<usize> = dependent_in_priority_order(problem)
            .into_iter()
            .map(|k| problem.hard_constraints()[k])
            .collect();
        prop_assert_eq!(&flagged, &dependent);
        prop_assert_eq!(report.rank, Some(problem.hard_constraints().len() - dependent.len()));
    }

    /// (b) Independent constraints plus duplicates and linear combinations:
    /// the rank is the independent count and exactly the added ones are
    /// redundant; with perturbed targets exactly the added ones conflict and
    /// the kept ones still hold.
    #[test]
    fn rank_detection_in_priority_order(
        seed in any::<u64>(),
        nx in 4usize..9,
        ny in 4usize..9,
        n_base in 3usize..15,
        n_added in 1usize..8,
        kind in kinds(),
    ) {
        let mesh = random_surface(nx, ny, seed);
        let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_add(7));
        let base = independent_constraints(&mesh, &mut rng, n_base, false);
        let added = dependent(&base, &mut rng, n_added);
        let added_indices: Vec<usize> = (base.len()..base.len() + added.len()).collect();

        let all: Vec<Constraint> = base.iter().chain(&added).cloned().collect();
        let (d, _) = solve(&mesh, kind, all).unwrap();
        let report = d.report();
        prop_assert_eq!(report.rank, Some(base.len()));
        prop_assert_eq!(&report.redundant, &added_indices);
        prop_assert!(report.conflicting.is_empty());

        // Perturb the added targets by 5% of the model size: now they conflict.
        let scale = mesh.bbox_diagonal();
        let perturbed: Vec<Constraint> = added.iter().map(|c| {
            let mut c = c.clone();
            let r = c.kind.rhs();
            c.kind.set_rhs([r[0] + 0.05 * scale, r[1], r[2]]);
            c
        }).collect();
        let all: Vec<Constraint> = base.iter().chain(&perturbed).cloned().collect();
        let (d, _) = solve(&mesh, kind, all).unwrap();
        let report = d.report();
        prop_assert_eq!(report.rank, Some(base.len()));
        prop_assert!(report.redundant.is_empty());
        let conflicting: Vec<usize> = report.conflicting.iter().map(|c| c.index).collect();
        prop_assert_eq!(conflicting, added_indices);
        prop_assert!(report.max_constraint_residual <= EXACT * scale);
    }

    /// (c) On small meshes the solution equals a dense KKT solution computed
    /// with faer's dense full-pivoting LU, to 1e-8 relative.
    #[test]
    fn agrees_with_dense_reference(
        seed in any::<u64>(),
        nx in 3usize..7,
        ny in 3usize..7,
        n_hard in 3usize..12,
        n_soft in 0usize..4,
        kind in kinds(),
    ) {
        let mesh = random_surface(nx, ny, seed);
        let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(3));
        let mut cs = independent_constraints(&mesh, &mut rng, n_hard, false);
        let p = mesh.positions();
        for _ in 0..n_soft {
            let v = rng.random_range(0..mesh.n_vertices());
            cs.push(Constraint::soft(
                ConstraintKind::Position { vertex: v, target: jitter(&mut rng, p[v], 0.2) },
                rng.random_range(0.5..5.0),
            ));
        }
        let (d, x) = solve(&mesh, kind, cs).unwrap();
        let rows: Vec<usize> = (0..d.problem().b().nrows()).collect();
        let reference = dense_reference(d.problem(), &rows);
        let diff = relative_difference(&x, &reference);
        prop_assert!(diff < 1e-8, "relative difference {diff:e}");
    }
}

/// Soft constraints alone (`B` with no rows): the null-space method solves
/// the plain least-squares problem (`Q = I`, nothing eliminated) like every
/// other method, on a mesh and as general matrices (it used to refuse it,
/// advising a constraint without "weight").
#[test]
fn no_hard_constraint_solves_like_the_other_methods() {
    use lse_deform::{LseSolver, Method, QrKind, formulation::FormulationChoice};
    let mesh = random_surface(4, 4, 1);
    let p = mesh.positions();
    let set = ConstraintSet::from_vec(
        [
            (3, [0.2, 0.0, 0.1]),
            (12, [0.0, -0.3, 0.4]),
            (20, [0.1, 0.1, 0.1]),
        ]
        .into_iter()
        .map(|(v, d): (usize, [f64; 3])| {
            let target = [p[v][0] + d[0], p[v][1] + d[1], p[v][2] + d[2]];
            Constraint::soft(ConstraintKind::Position { vertex: v, target }, 2.0)
        })
        .collect(),
    )
    .unwrap();
    let choices: Vec<FormulationChoice> = [
        (Method::NullSpaceQr, QrKind::SparseGivens),
        (Method::NullSpaceQr, QrKind::DenseHouseholder),
        (Method::Kkt, QrKind::SparseGivens),
        (Method::Eliminate, QrKind::SparseGivens),
        (Method::Penalty, QrKind::SparseGivens),
    ]
    .into_iter()
    .map(|(method, qr)| FormulationChoice {
        qr: qr.into(),
        weight: Some(1e3),
        ..FormulationChoice::new(method)
    })
    .collect();
    let mut solutions = Vec::new();
    let mut general = Vec::new();
    for choice in &choices {
        let formulation = choice.build().unwrap();
        let mut d = Deformer::new(
            mesh.clone(),
            LaplacianKind::Cotangent,
            set.clone(),
            &lse_deform::SolveOptions::default(),
        )
        .unwrap();
        assert_eq!(d.problem().b().nrows(), 0);
        d.refactor_with(
            formulation.as_ref(),
            &lse_deform::resources::Resources::default(),
        )
        .unwrap_or_else(|e| panic!("{:?}: {e}", choice.method));
        solutions.push(d.solve_matrix().unwrap());
        // The same matrices as a general problem.
        let problem = d.problem();
        let no_rows =
            faer::sparse::SparseColMat::<usize, f64>::try_new_from_triplets(0, problem.n(), &[])
                .unwrap();
        let parts = lse_deform::problem::LseProblem::from_parts(
            problem.a().as_ref(),
            problem.c().as_ref(),
            no_rows.as_ref(),
            problem.d().as_ref(),
        )
        .unwrap();
        let mut solver = LseSolver::new(parts, &lse_deform::SolveOptions::default()).unwrap();
        solver
            .refactor_with(
                formulation.as_ref(),
                &lse_deform::resources::Resources::default(),
            )
            .unwrap_or_else(|e| panic!("{:?} (general): {e}", choice.method));
        general.push(solver.solve().unwrap());
    }
    for (k, choice) in choices.iter().enumerate() {
        for (x, first, what) in [
            (&solutions[k], &solutions[0], "mesh"),
            (&general[k], &general[0], "general"),
        ] {
            let diff = relative_difference(x, first);
            assert!(
                diff < 1e-9,
                "{:?} {what}: relative difference {diff:e}",
                choice.method
            );
        }
    }
}

#[test]
fn every_vertex_constrained_gives_the_targets() {
    let mesh = random_surface(4, 3, 2);
    let targets: Vec<[f64; 3]> = (0..mesh.n_vertices())
        .map(|v| [v as f64 * 0.1, (v % 3) as f64, -(v as f64)])
        .collect();
    let cs = targets
        .iter()
        .enumerate()
        .map(|(v, &t)| {
            Constraint::hard(ConstraintKind::Position {
                vertex: v,
                target: t,
            })
        })
        .collect();
    let (d, x) = solve(&mesh, LaplacianKind::Cotangent, cs).unwrap();
    assert_eq!(d.report().rank, Some(mesh.n_vertices()));
    for (v, t) in targets.iter().enumerate() {
        for c in 0..3 {
            // X is in the problem's units: positions / length_unit.
            assert!((x[(v, c)] * d.length_unit() - t[c]).abs() <= 1e-15 * t[c].abs().max(1.0));
        }
    }
}

#[test]
fn dragging_reuses_the_factorisation_and_matches_a_fresh_solve() {
    let mesh = random_surface(8, 8, 3);
    let p = mesh.positions().to_vec();
    let mut cs: Vec<Constraint> = (0..9)
        .map(|v| {
            Constraint::hard(ConstraintKind::Position {
                vertex: v,
                target: p[v],
            })
        })
        .collect();
    let handle = 76;
    cs.push(Constraint::hard(ConstraintKind::Position {
        vertex: handle,
        target: p[handle],
    }));
    cs.push(Constraint::soft(
        ConstraintKind::Position {
            vertex: 40,
            target: p[40],
        },
        2.0,
    ));
    let (mut d, _) = solve(&mesh, LaplacianKind::Cotangent, cs.clone()).unwrap();
    let moved = [p[handle][0], p[handle][1], p[handle][2] + 0.4];
    let soft_moved = [p[40][0] + 0.1, p[40][1], p[40][2]];
    d.set_target(9, moved).unwrap();
    d.set_target(10, soft_moved).unwrap();
    let dragged = d.solve_matrix().unwrap();

    cs[9].kind.set_rhs(moved);
    cs[10].kind.set_rhs(soft_moved);
    let (_, fresh) = solve(&mesh, LaplacianKind::Cotangent, cs).unwrap();
    assert!(relative_difference(&dragged, &fresh) < 1e-13);
    assert!((dragged[(handle, 2)] * d.length_unit() - moved[2]).abs() < 1e-14);
}

#[test]
fn unpinned_component_is_named_before_factorising() {
    // Two separate triangles; constraints only on the first (vertex 3..5 free).
    let mesh = Mesh::new(
        vec![
            [0., 0., 0.],
            [1., 0., 0.],
            [0., 1., 0.],
            [5., 0., 0.],
            [6., 0., 0.],
            [5., 1., 0.],
        ],
        vec![[0, 1, 2], [3, 4, 5]],
    )
    .unwrap();
    let pos = |v: usize| {
        Constraint::hard(ConstraintKind::Position {
            vertex: v,
            target: [0.0; 3],
        })
    };
    let rel = |a: usize, b: usize| {
        Constraint::hard(ConstraintKind::Relative {
            vertices: [a, b],
            vector: [1.0, 0.0, 0.0],
        })
    };
    let set = ConstraintSet::from_vec(vec![pos(0), rel(4, 3)]).unwrap();
    let err = Deformer::new(
        mesh.clone(),
        LaplacianKind::Uniform,
        set,
        &lse_deform::SolveOptions::default(),
    )
    .err()
    .unwrap();
    assert!(
        matches!(
            err,
            Error::Problem(ProblemError::UnpinnedComponent {
                component: 1,
                vertices: 3,
                example_vertex: 3
            })
        ),
        "{err}"
    );
    // A relative constraint across the components pins the second one.
    let set = ConstraintSet::from_vec(vec![pos(0), rel(4, 0)]).unwrap();
    assert!(
        Deformer::new(
            mesh.clone(),
            LaplacianKind::Uniform,
            set,
            &lse_deform::SolveOptions::default()
        )
        .is_ok()
    );
    // Relative constraints alone pin nothing.
    let set = ConstraintSet::from_vec(vec![rel(1, 0), rel(4, 3)]).unwrap();
    let err = Deformer::new(
        mesh.clone(),
        LaplacianKind::Uniform,
        set,
        &lse_deform::SolveOptions::default(),
    )
    .err()
    .unwrap();
    assert!(matches!(
        err,
        Error::Problem(ProblemError::UnpinnedComponent { component: 0, .. })
    ));
    // No constraints at all.
    let err = Deformer::new(
        mesh,
        LaplacianKind::Uniform,
        ConstraintSet::new(),
        &lse_deform::SolveOptions::default(),
    )
    .err()
    .unwrap();
    assert!(matches!(err, Error::Problem(ProblemError::NoConstraints)));
}
