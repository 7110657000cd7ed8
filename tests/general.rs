//! General problems from their matrices (`LseProblem::from_parts`), solved
//! through `LseSolver` by every formulation and back end that applies, and
//! the constraint-group API of `Deformer`.

#![allow(clippy::needless_range_loop)]

use faer::Mat;
use faer::sparse::{SparseColMat, Triplet};
use lse_deform::error::{Error, NumericalError, ProblemError};
use lse_deform::formulation::{Formulation, FormulationChoice, Method, Refine};
use lse_deform::problem::LseProblem;
use lse_deform::testing::{dense_reference, random_lse, relative_difference};
use lse_deform::{
    Constraint, ConstraintSet, Deformer, LaplacianKind, LseSolver, QrKind, SpdKind,
    formulation::Kkt, formulation::NullSpaceQr,
};

#[test]
fn null_space_on_every_back_end_matches_the_dense_reference_and_names_dependent_rows() {
    for (seed, k) in [(1u64, 3usize), (2, 1), (3, 5)] {
        let lse = random_lse(40, 12, 6, k, seed);
        let reference = dense_reference(&lse.problem, &lse.independent_rows);
        for q in QrKind::available() {
            for s in SpdKind::available() {
                let choice = FormulationChoice {
                    qr: q.into(),
                    spd: s.into(),
                    ..FormulationChoice::new(Method::NullSpaceQr)
                };
                let f = choice.build().unwrap();
                let mut solver = LseSolver::with_formulation(
                    lse.problem.clone(),
                    f.as_ref(),
                    &lse_deform::resources::Resources::default(),
                )
                .unwrap();
                let x = solver.solve().unwrap();
                assert_eq!((x.nrows(), x.ncols()), (40, k));
                let diff = relative_difference(&x, &reference);
                assert!(diff < 1e-10, "{q}/{s}, k = {k}: {diff:e}");
                let report = solver.report();
                assert_eq!(report.rank, Some(lse.independent_rows.len()), "{q}/{s}");
                assert_eq!(
                    report.redundant, lse.redundant,
                    "{q}/{s}: {:?}",
                    report.conflicting
                );
                let conflicting: Vec<usize> = report.conflicting.iter().map(|c| c.index).collect();
                assert_eq!(conflicting, lse.conflicting, "{q}/{s}");
                assert!(report.max_constraint_residual < 1e-12, "{q}/{s}");
                assert_eq!(report.energy, None);
            }
        }
    }
}

#[test]
fn kkt_penalty_and_elimination_solve_general_problems() {
    // Independent rows only: KKT needs them.
    let lse = random_lse(30, 10, 0, 2, 7);
    let reference = dense_reference(&lse.problem, &lse.independent_rows);
    for f in [
        Box::new(Kkt::default()) as Box<dyn Formulation>,
        Box::new(Kkt::simplicial()),
    ] {
        let mut solver = LseSolver::with_formulation(
            lse.problem.clone(),
            f.as_ref(),
            &lse_deform::resources::Resources::default(),
        )
        .unwrap();
        let x = solver.solve().unwrap();
        assert!(relative_difference(&x, &reference) < 1e-9);
    }
    // Penalty: the hard rows hold to O(1/w²).
    let mut solver = LseSolver::with_formulation(
        lse.problem.clone(),
        &lse_deform::formulation::Penalty::new(1e4),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    let x = solver.solve().unwrap();
    assert!(relative_difference(&x, &reference) < 1e-5);
    assert!(solver.report().max_constraint_residual < 1e-5);

    // Elimination: rows with one nonzero (coefficient 2: X_j = d / 2).
    let n = 6;
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(
        n - 1,
        n,
        &(0..n - 1)
            .flat_map(|i| [Triplet::new(i, i, -1.0), Triplet::new(i, i + 1, 1.0)])
            .collect::<Vec<_>>(),
    )
    .unwrap();
    let c = Mat::<f64>::zeros(n - 1, 1);
    let b = SparseColMat::<usize, f64>::try_new_from_triplets(
        2,
        n,
        &[Triplet::new(0, 0, 2.0), Triplet::new(1, n - 1, 2.0)],
    )
    .unwrap();
    let d = Mat::from_fn(2, 1, |i, _| if i == 0 { 0.0 } else { 2.0 * 5.0 });
    let problem = LseProblem::from_parts(a.as_ref(), c.as_ref(), b.as_ref(), d.as_ref()).unwrap();
    let mut solver = LseSolver::with_formulation(
        problem,
        &lse_deform::formulation::Elimination::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    let x = solver.solve().unwrap();
    // A chain with both ends fixed: the straight line 0, 1, ..., 5.
    for i in 0..n {
        assert!((x[(i, 0)] - i as f64).abs() < 1e-12, "{i}: {}", x[(i, 0)]);
    }
}

fn sparse(rows: usize, cols: usize, t: &[(usize, usize, f64)]) -> SparseColMat<usize, f64> {
    let t: Vec<_> = t.iter().map(|&(i, j, v)| Triplet::new(i, j, v)).collect();
    SparseColMat::try_new_from_triplets(rows, cols, &t).unwrap()
}

#[test]
fn from_parts_refuses_bad_matrices_with_the_place() {
    let a = sparse(2, 2, &[(0, 0, 1.0), (1, 1, 1.0)]);
    let b = sparse(1, 2, &[(0, 0, 1.0)]);
    let c = Mat::<f64>::zeros(2, 3);
    let d = Mat::<f64>::zeros(1, 3);
    let from =
        |a: &SparseColMat<usize, f64>, c: &Mat<f64>, b: &SparseColMat<usize, f64>, d: &Mat<f64>| {
            LseProblem::from_parts(a.as_ref(), c.as_ref(), b.as_ref(), d.as_ref())
        };
    assert!(from(&a, &c, &b, &d).is_ok());
    // Shapes.
    assert!(matches!(
        from(&a, &Mat::zeros(3, 3), &b, &d),
        Err(ProblemError::Dimensions { .. })
    ));
    assert!(matches!(
        from(&a, &c, &b, &Mat::zeros(1, 2)),
        Err(ProblemError::Dimensions { .. })
    ));
    assert!(matches!(
        from(&a, &c, &sparse(1, 3, &[(0, 0, 1.0)]), &d),
        Err(ProblemError::Dimensions { .. })
    ));
    assert!(matches!(
        from(&a, &Mat::zeros(2, 0), &b, &Mat::zeros(1, 0)),
        Err(ProblemError::Dimensions { .. })
    ));
    // Non-finite entries, with matrix, row and column.
    let mut bad_c = c.clone();
    bad_c[(1, 2)] = f64::NAN;
    let err = from(&a, &bad_c, &b, &d).unwrap_err();
    assert!(
        matches!(err, ProblemError::NonFiniteEntry { matrix: "C", row: 1, col: 2, value } if value.is_nan()),
        "{err}"
    );
    assert!(err.to_string().contains("C[1, 2]"), "{err}");
    let bad_a = sparse(2, 2, &[(0, 0, 1.0), (1, 1, f64::INFINITY)]);
    assert!(matches!(
        from(&bad_a, &c, &b, &d),
        Err(ProblemError::NonFiniteEntry {
            matrix: "A",
            row: 1,
            col: 1,
            ..
        })
    ));
    let mut bad_d = d.clone();
    bad_d[(0, 0)] = f64::NEG_INFINITY;
    assert!(matches!(
        from(&a, &c, &b, &bad_d),
        Err(ProblemError::NonFiniteEntry {
            matrix: "D",
            row: 0,
            col: 0,
            ..
        })
    ));
    // A row of B with only a stored zero is empty; stored zeros elsewhere are fine.
    let b_zero = sparse(2, 2, &[(0, 0, 1.0), (0, 1, 0.0), (1, 1, 0.0)]);
    let err = from(&a, &c, &b_zero, &Mat::zeros(2, 3)).unwrap_err();
    assert_eq!(err, ProblemError::EmptyConstraintRow { row: 1 });
    assert!(err.to_string().contains("row 1 of B"));
    // An unknown in no row.
    let a_gap = sparse(2, 3, &[(0, 0, 1.0), (1, 1, 1.0)]);
    let b3 = sparse(1, 3, &[(0, 0, 1.0)]);
    assert_eq!(
        from(&a_gap, &c, &b3, &d).unwrap_err(),
        ProblemError::UnusedUnknown { unknown: 2 }
    );
}

#[test]
fn a_singular_general_problem_names_the_free_unknown() {
    // Columns 2 and 3 of A are equal and no row of B touches them: X[2] −
    // X[3] is free.
    let a = sparse(
        3,
        4,
        &[
            (0, 0, 1.0),
            (1, 1, 1.0),
            (2, 2, 1.0),
            (2, 3, 1.0),
            (0, 1, 0.5),
        ],
    );
    let b = sparse(1, 4, &[(0, 0, 1.0), (0, 1, 1.0)]);
    let problem = LseProblem::from_parts(
        a.as_ref(),
        Mat::<f64>::zeros(3, 1).as_ref(),
        b.as_ref(),
        Mat::<f64>::zeros(1, 1).as_ref(),
    )
    .unwrap();
    let formulations: Vec<Box<dyn Formulation>> = vec![
        Box::new(NullSpaceQr::default()),
        Box::new(lse_deform::formulation::Penalty::new(10.0)),
        Box::new(Kkt::default()),
    ];
    for f in formulations {
        let resources = lse_deform::resources::Resources::default();
        let Err(err) = LseSolver::with_formulation(problem.clone(), f.as_ref(), &resources) else {
            panic!("{}: the singular problem was factored", f.name());
        };
        match &err {
            Error::Numerical(NumericalError::FreeUnknown { unknown, .. }) => {
                assert!([2, 3].contains(unknown), "{}: {err}", f.name());
                assert!(err.to_string().contains(&format!("unknown {unknown}")));
                assert!(!err.to_string().contains("vertex"), "{err}");
            }
            other => panic!("{}: expected FreeUnknown, got {other}", f.name()),
        }
    }
}

#[test]
fn solve_into_matches_solve_and_checks_its_output_shape() {
    let lse = random_lse(25, 8, 2, 3, 11);
    let mut solver = LseSolver::with_formulation(
        lse.problem.clone(),
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    let x = solver.solve().unwrap();
    assert!(solver.report().forward_error_estimate.is_some());
    let mut y = Mat::<f64>::zeros(25, 3);
    solver.solve_into(y.as_mut()).unwrap();
    assert_eq!(relative_difference(&y, &x), 0.0);
    assert!(solver.report().timings_s.refine > 0.0, "auto refined");
    // The report does not keep the estimate and residuals of the solve
    // before (not computed: no diagnostics), and without refinement not
    // the last refine phase either.
    assert_eq!(solver.report().forward_error_estimate, None);
    solver.set_refine(Some(Refine::EstimateOnly));
    solver.solve_into(y.as_mut()).unwrap();
    let report = solver.report();
    assert_eq!(report.timings_s.refine, 0.0);
    assert_eq!(report.forward_error_estimate, None);
    assert!(report.refinement.is_none());
    assert!(report.max_constraint_residual.is_nan() && report.least_squares_residual.is_nan());
    let json = serde_json::to_value(report).unwrap();
    assert!(json["max_constraint_residual"].is_null() && json["forward_error_estimate"].is_null());
    // diagnose fills them again
    solver.diagnose(y.as_ref());
    assert!(
        solver.report().forward_error_estimate.is_none(),
        "no refinement ran"
    );
    assert!(solver.report().max_constraint_residual.is_finite());
    solver.set_refine(None);
    let mut wrong = Mat::<f64>::zeros(25, 2);
    assert!(matches!(
        solver.solve_into(wrong.as_mut()),
        Err(Error::Problem(ProblemError::Dimensions { .. }))
    ));
    // New right-hand sides without refactoring: C doubled, D doubled → X doubled.
    let c2 = Mat::from_fn(lse.problem.c().nrows(), 3, |i, j| {
        2.0 * lse.problem.c()[(i, j)]
    });
    let d2 = Mat::from_fn(lse.problem.d().nrows(), 3, |i, j| {
        2.0 * lse.problem.d()[(i, j)]
    });
    solver.set_rhs_matrices(c2.as_ref(), d2.as_ref()).unwrap();
    let x2 = solver.solve().unwrap();
    let doubled = Mat::from_fn(25, 3, |i, j| 2.0 * x[(i, j)]);
    assert!(relative_difference(&x2, &doubled) < 1e-13);
}

fn grid_deformer() -> Deformer {
    let mesh = lse_deform::mesh::generate::grid(6, 6).unwrap();
    let p = mesh.positions().to_vec();
    let mut set = ConstraintSet::new();
    for v in 0..7 {
        assert_eq!(
            set.push(Constraint::position(v, p[v]).in_group("base"))
                .unwrap(),
            set.len() - 1
        );
    }
    for v in 42..49 {
        set.push(Constraint::position(v, p[v]).in_group("handle"))
            .unwrap();
    }
    set.push(
        Constraint::relative(
            [21, 27],
            [
                p[21][0] - p[27][0],
                p[21][1] - p[27][1],
                p[21][2] - p[27][2],
            ],
        )
        .in_group("handle"),
    )
    .unwrap();
    Deformer::with_formulation(
        mesh,
        LaplacianKind::Cotangent,
        set,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap()
}

#[test]
fn transform_group_moves_rest_targets_and_does_not_accumulate() {
    let mut d = grid_deformer();
    let rest: Vec<[f64; 3]> = d.rest_targets().to_vec();
    let members = d.group_members("handle").unwrap();
    assert_eq!(members, (7..15).collect::<Vec<_>>());
    // A rotation about z by 90° and a lift.
    let m = [
        [0.0, -1.0, 0.0, 0.5],
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.25],
    ];
    d.transform_group("handle", &m).unwrap();
    d.transform_group("handle", &m).unwrap();
    for &i in &members {
        let u = rest[i];
        let got = d.constraints()[i].kind.rhs();
        let expected = if i == 14 {
            [-u[1], u[0], u[2]]
        } else {
            [-u[1] + 0.5, u[0], u[2] + 0.25]
        };
        assert_eq!(got, expected, "constraint {i}");
    }
    // The same targets through set_targets give the same solution.
    let x = d.solve_matrix().unwrap();
    let targets: Vec<(usize, [f64; 3])> = members
        .iter()
        .map(|&i| (i, d.constraints()[i].kind.rhs()))
        .collect();
    let mut e = grid_deformer();
    e.set_targets(&targets).unwrap();
    assert_eq!(relative_difference(&e.solve_matrix().unwrap(), &x), 0.0);
    // The identity restores the rest pose.
    let id = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ];
    d.transform_group("handle", &id).unwrap();
    for &i in &members {
        assert_eq!(d.constraints()[i].kind.rhs(), rest[i]);
    }
    // set_group_targets sets new rest targets.
    let lifted: Vec<[f64; 3]> = members
        .iter()
        .map(|&i| [rest[i][0], rest[i][1], rest[i][2] + 1.0])
        .collect();
    d.set_group_targets("handle", &lifted).unwrap();
    d.transform_group("handle", &id).unwrap();
    assert_eq!(d.constraints()[7].kind.rhs(), lifted[0]);
}

#[test]
fn refused_group_updates_change_nothing() {
    let mut d = grid_deformer();
    let before = d.constraints().clone();
    let err = d.transform_group("nope", &[[0.0; 4]; 3]).unwrap_err();
    assert!(err.to_string().contains("base, handle"), "{err}");
    let mut nan = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ];
    nan[1][3] = f64::NAN;
    assert!(d.transform_group("handle", &nan).is_err());
    // Overflow to infinity in the result.
    let huge = [
        [1e308, 1e308, 0.0, 1e308],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ];
    assert!(d.transform_group("handle", &huge).is_err());
    assert!(d.set_group_targets("handle", &[[0.0; 3]]).is_err());
    assert!(d.set_targets(&[(0, [1.0; 3]), (99, [0.0; 3])]).is_err());
    assert_eq!(d.constraints(), &before);
    assert!(
        d.rest_targets()
            .iter()
            .zip(before.as_slice())
            .all(|(r, c)| *r == c.kind.rhs())
    );
}

#[test]
fn groups_round_trip_through_json() {
    let d = grid_deformer();
    let text = d.constraints().to_json();
    assert!(text.contains("\"group\":\"handle\""), "{text}");
    let back = lse_deform::constraints::parse_constraints(&text).unwrap();
    assert_eq!(&back, d.constraints());
    let err = lse_deform::constraints::parse_constraints(
        r#"{"constraints": [{"type": "position", "vertex": 0, "target": [0,0,0], "group": 3}]}"#,
    )
    .unwrap_err();
    assert!(err.to_string().contains("'group'"), "{err}");
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(32))]

    /// Random general problems: the rank, the redundant and the conflicting
    /// rows are the constructed ones, and X equals the dense oracle's.
    #[test]
    fn random_general_problems_match_the_oracle(lse in lse_deform::testing::random_lses()) {
        let mut solver = LseSolver::with_formulation(lse.problem.clone(), &NullSpaceQr::default(), &lse_deform::resources::Resources::default()).unwrap();
        let x = solver.solve().unwrap();
        let report = solver.report();
        proptest::prop_assert_eq!(report.rank, Some(lse.independent_rows.len()));
        proptest::prop_assert_eq!(&report.redundant, &lse.redundant);
        let conflicting: Vec<usize> = report.conflicting.iter().map(|c| c.index).collect();
        proptest::prop_assert_eq!(conflicting, lse.conflicting.clone());
        let reference = dense_reference(&lse.problem, &lse.independent_rows);
        proptest::prop_assert!(relative_difference(&x, &reference) < 1e-9);
    }

    /// Scaled meshes: the constructed rank and dependent constraints are
    /// found whatever the units.
    #[test]
    fn constraint_mixes_on_scaled_meshes(
        mesh in lse_deform::testing::scaled_meshes(),
        seed in proptest::prelude::any::<u64>(),
    ) {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let base = lse_deform::testing::independent_constraints(&mesh, &mut rng, 6, false);
        let added = lse_deform::testing::dependent_constraints(&base, &mut rng, 3);
        let all: Vec<Constraint> = base.iter().chain(&added).cloned().collect();
        let mut d = Deformer::with_formulation(mesh, LaplacianKind::Cotangent, ConstraintSet::from_vec(all).unwrap(), &NullSpaceQr::default(), &lse_deform::resources::Resources::default()).unwrap();
        d.solve_matrix().unwrap();
        proptest::prop_assert_eq!(d.report().rank, Some(base.len()));
        proptest::prop_assert_eq!(d.report().redundant.clone(), (6..9).collect::<Vec<_>>());
    }
}

#[test]
fn formulation_choices_name_themselves_and_refuse_what_they_cannot_build() {
    for method in Method::ALL {
        assert_eq!(method.name().parse::<Method>().unwrap(), method);
    }
    let Err(e) = "qr".parse::<Method>() else {
        panic!("unknown method accepted");
    };
    let message = e.to_string();
    // The old spelling of the elimination method is an alias.
    assert_eq!("elimination".parse::<Method>().unwrap(), Method::Eliminate);
    assert!(
        Method::ALL.iter().all(|m| message.contains(m.name())),
        "{message}"
    );
    // Each built formulation reports the method it was chosen as.
    let mut penalty = FormulationChoice::new(Method::Penalty);
    penalty.weight = Some(1e4);
    assert!(penalty.build().unwrap().name().starts_with("penalty"));
    for method in Method::ALL {
        let choice = FormulationChoice {
            weight: Some(1.0),
            ..FormulationChoice::new(method)
        };
        assert_eq!(choice.build().unwrap().method(), method);
    }
    let refused = |choice: FormulationChoice, needle: &str| match choice.build() {
        Err(e @ ProblemError::InvalidOption { .. }) => {
            let message = e.to_string();
            assert!(message.contains(needle), "{choice:?}: {message}");
            // The library's own terms, no command-line flag.
            assert!(!message.contains("--"), "{choice:?}: {message}");
        }
        Err(e) => panic!("{choice:?}: {e}"),
        Ok(_) => panic!("{choice:?} built"),
    };
    // The penalty method needs a finite positive weight.
    for weight in [
        None,
        Some(0.0),
        Some(-1.0),
        Some(f64::NAN),
        Some(f64::INFINITY),
    ] {
        let choice = FormulationChoice {
            weight,
            ..FormulationChoice::new(Method::Penalty)
        };
        refused(choice, "weight");
    }
    // KKT factors with faer's or MUMPS's LDLᵀ only.
    for spd in [SpdKind::Nalgebra, SpdKind::Cholmod] {
        let choice = FormulationChoice {
            spd: spd.into(),
            ..FormulationChoice::new(Method::Kkt)
        };
        refused(
            choice,
            "faer-auto, faer-simplicial, faer-supernodal or mumps",
        );
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
    /// A set's groups, whether built by `from_vec`, by `push` or read back
    /// from its JSON, are exactly what a scan of its constraints finds:
    /// each group's members in increasing order, names in order of first
    /// appearance.
    #[test]
    fn groups_are_what_a_scan_of_the_constraints_finds(
        labels in proptest::collection::vec(0usize..4, 0..40)
    ) {
        let name = |l: usize| ["a", "handle 1", "fixed"].get(l).copied();
        let list: Vec<Constraint> = labels
            .iter()
            .enumerate()
            .map(|(v, &l)| {
                let c = Constraint::position(v, [v as f64, 0.0, 1.0]);
                match name(l) {
                    Some(g) => c.in_group(g),
                    None => c,
                }
            })
            .collect();
        let from_vec = ConstraintSet::from_vec(list.clone()).unwrap();
        let mut pushed = ConstraintSet::new();
        for c in list {
            pushed.push(c).unwrap();
        }
        let read = lse_deform::constraints::parse_constraints(&from_vec.to_json()).unwrap();
        let mut names: Vec<&str> = Vec::new();
        for g in labels.iter().filter_map(|&l| name(l)) {
            if !names.contains(&g) {
                names.push(g);
            }
        }
        for set in [&from_vec, &pushed, &read] {
            proptest::prop_assert_eq!(set.group_names(), names.clone());
            for g in ["a", "handle 1", "fixed", "b"] {
                let scan: Vec<usize> = (0..labels.len())
                    .filter(|&i| name(labels[i]) == Some(g))
                    .collect();
                proptest::prop_assert_eq!(set.group(g), scan.as_slice());
            }
        }
        proptest::prop_assert_eq!(&pushed, &from_vec);
    }
}
/// The entries of the case `general.proptest-regressions` recorded: `A`
/// (16 × 11), `C` (16 × 5), `B` (12 × 11), `D` (12 × 5).
const RECORDED_A: [(usize, usize, f64); 39] = [
    (0, 0, 1.6088464820394663),
    (4, 0, 0.23037813322417744),
    (5, 0, -0.6455489750881958),
    (6, 0, 0.46332389250330586),
    (8, 0, 0.754282301471259),
    (1, 1, 2.3826594580164073),
    (12, 1, -0.21634591365741596),
    (15, 1, 0.16502329313769115),
    (1, 2, -0.8496076883680832),
    (2, 2, 1.7467965120283975),
    (7, 2, -0.9265026327486154),
    (9, 2, -0.7385103414563758),
    (11, 2, -0.6668372409476913),
    (12, 2, 0.13260089621061333),
    (3, 3, 1.822949839591121),
    (5, 3, 0.08778117292367416),
    (7, 3, -0.9285292071457358),
    (9, 3, -0.8610003448165853),
    (4, 4, 1.2027794524970306),
    (9, 4, -0.7184377131820701),
    (12, 4, 0.053487705939196495),
    (0, 5, 0.3073835793451116),
    (5, 5, 1.6574072830273423),
    (12, 5, -0.668076001795201),
    (6, 6, 1.0499408430404715),
    (6, 7, -0.6576208587864922),
    (7, 7, 1.266213443996883),
    (11, 7, 0.4070399265595164),
    (12, 7, 0.08524832348173872),
    (8, 8, 1.5060792082241776),
    (0, 9, -0.011758994007827095),
    (6, 9, 0.6759584874401923),
    (8, 9, 0.7456699272937564),
    (9, 9, 1.6152675419873608),
    (3, 10, -0.8901600485573207),
    (7, 10, -0.6911412099858403),
    (9, 10, 0.22052287225879263),
    (10, 10, 1.3555417657538722),
    (13, 10, 0.6704462987231414),
];
const RECORDED_C: [[f64; 5]; 16] = [
    [
        -0.33652730479674364,
        -0.6416629690254894,
        -0.8821542368100626,
        0.4495556853717533,
        0.2658991059309357,
    ],
    [
        -0.2830759856351359,
        0.9355913008472845,
        0.4605744142678203,
        0.3985021752917861,
        0.535893316845454,
    ],
    [
        -0.4302958725533528,
        0.7234706734419971,
        -0.19889712824442052,
        0.7911472332065208,
        0.24349675996811193,
    ],
    [
        0.1756595934931524,
        -0.8602040175343424,
        -0.09895650286230273,
        -0.3983606832982196,
        0.30080824204950574,
    ],
    [
        -0.2336472891207717,
        -0.28836575620924165,
        0.7517293959260591,
        0.5163334444752383,
        0.6153139461512684,
    ],
    [
        0.2723302134422836,
        -0.0795471412620743,
        -0.6003525814404505,
        0.6649516630758834,
        0.23890698777387964,
    ],
    [
        -0.055337853718800734,
        0.8088968984981921,
        0.11604094546750998,
        -0.26589516419093284,
        -0.27967662643595004,
    ],
    [
        0.2850074595083085,
        0.7575548438057864,
        0.963281958315398,
        0.9234599412149729,
        -0.7767797573983959,
    ],
    [
        -0.18507855847779942,
        0.9680516466010993,
        -0.3427800809963313,
        -0.710600648345483,
        0.1863079676214281,
    ],
    [
        -0.2938201274863008,
        0.1304356621944751,
        -0.8422016859662822,
        0.04563847564650825,
        -0.6806985625231192,
    ],
    [
        -0.373406208235759,
        -0.14003266928679636,
        -0.6647811769908967,
        -0.27873411780266943,
        0.20374719829776922,
    ],
    [
        0.4529347949415219,
        0.7991335384480487,
        -0.33155698077077744,
        0.7268971886623379,
        -0.8650410466925802,
    ],
    [
        -0.28754889080709756,
        -0.18344680413465309,
        -0.35165947864321945,
        -0.45978417771857627,
        0.20251788527367376,
    ],
    [
        0.7887603135637047,
        -0.6520464762511207,
        -0.5071448110879491,
        -0.9854383115776324,
        0.23686778800658725,
    ],
    [
        0.8885972523248369,
        -0.9904769972854486,
        0.43423736575217653,
        0.8672409319175793,
        0.7228384270612724,
    ],
    [
        -0.5787532568656344,
        -0.8268382399864249,
        0.045181948424546814,
        0.7557828020808119,
        -0.883297445791273,
    ],
];
const RECORDED_B: [(usize, usize, f64); 37] = [
    (0, 0, 0.6813731917503367),
    (0, 2, 1.454798416022189),
    (0, 4, 0.5924821359824366),
    (1, 2, 1.2277836663499029),
    (1, 5, 0.6641351571354055),
    (1, 8, 0.9713607746284878),
    (2, 1, 0.7781778375918413),
    (2, 4, 1.4686394196578618),
    (2, 6, 0.6580507491428762),
    (3, 2, 1.3234912363913591),
    (3, 6, 0.7564037810775532),
    (3, 8, 0.70663673682165),
    (4, 0, 1.0575492500717283),
    (4, 1, 1.3900844138927178),
    (4, 2, 0.9051157753531633),
    (5, 1, 1.1846528297954808),
    (5, 5, 0.7682741350374487),
    (5, 8, 0.7484668950182249),
    (6, 0, -0.12909630734231325),
    (6, 1, -1.6710829222154677),
    (6, 2, 1.3506949147281082),
    (6, 4, 0.9932171723985662),
    (7, 7, 1.0),
    (7, 8, 0.17129192504347357),
    (8, 1, -1.0204188623929604),
    (8, 4, 1.6582626731641927),
    (8, 5, -1.231590507589628),
    (8, 6, 0.74301491553698),
    (8, 8, -1.199838288327377),
    (9, 1, 1.0),
    (9, 2, 0.6161544696019619),
    (10, 0, -0.584880414441408),
    (10, 1, 0.6312089011976715),
    (10, 2, -0.859854711859786),
    (10, 4, -0.5085776802464975),
    (11, 7, 1.0),
    (11, 8, 0.13620073510581854),
];
const RECORDED_D: [[f64; 5]; 12] = [
    [
        0.030577729513574514,
        -0.8859734847867085,
        -0.14750650957895584,
        -0.8888600509491327,
        0.7224333038458255,
    ],
    [
        -0.23717141350831739,
        0.49081416573928527,
        -0.5092000092149975,
        -0.24285718590452587,
        -0.5909700459668956,
    ],
    [
        -0.8695838291148772,
        0.5421086918987932,
        0.947609941408198,
        0.6807107059865531,
        -0.9279352399192655,
    ],
    [
        0.3950162031539981,
        -0.7251663305747513,
        0.2567398481098566,
        0.14790245058543627,
        -0.6517534177521256,
    ],
    [
        -0.13847839735971368,
        -0.506020770121129,
        -0.5425498773948765,
        0.5617251702734842,
        0.04412277699150291,
    ],
    [
        -0.6302745129315857,
        -0.1895375488514497,
        -0.635391929105904,
        0.8889232542366132,
        -0.5415890982180591,
    ],
    [
        0.21773058222210145,
        -0.8769059213335402,
        0.40494861800424653,
        -2.1653302264526633,
        1.1580209773786958,
    ],
    [
        0.5075939173424167,
        -0.00565641693250063,
        -0.5462397430704056,
        0.2872404046676458,
        -0.5297883903876635,
    ],
    [
        1.0285085875596907,
        0.9159433124793964,
        2.0885327085473167,
        -0.6563978265839691,
        -0.17954501386897126,
    ],
    [
        -0.7153584397403372,
        0.5806703162215681,
        -0.705147310052956,
        0.9663970474145067,
        -0.12327451504475029,
    ],
    [
        -0.477788073999236,
        1.1270304753808256,
        -0.31847790794667086,
        1.37298240615733,
        -0.6979377631546038,
    ],
    [
        0.8877934253779887,
        -0.5434848903155536,
        0.7513315292327665,
        0.27598658813000476,
        -0.6722563735265092,
    ],
];

/// The case `tests/general.proptest-regressions` recorded, replayed from its
/// values: the seed no longer reproduced it (the strategy changed after it
/// was saved), so the file is gone and the case lives here. Its recorded
/// expectation was wrong — the generator of the time gave rows 7 and 11
/// the same pivot column (since fixed), so row 11 is not independent: a
/// dense Gram–Schmidt in priority order leaves rows 6, 8, 10 and 11
/// remainders below 1e-16 and every other row one above 0.04. Every back
/// end must find exactly those four, split by their residual against the
/// accurate reference, and match that reference.
#[test]
fn the_recorded_general_case_keeps_its_rank_and_dependent_rows() {
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(
        16,
        11,
        &RECORDED_A.map(|(i, j, v)| Triplet::new(i, j, v)),
    )
    .unwrap();
    let b = SparseColMat::<usize, f64>::try_new_from_triplets(
        12,
        11,
        &RECORDED_B.map(|(i, j, v)| Triplet::new(i, j, v)),
    )
    .unwrap();
    let c = Mat::from_fn(16, 5, |i, j| RECORDED_C[i][j]);
    let d = Mat::from_fn(12, 5, |i, j| RECORDED_D[i][j]);
    let problem = LseProblem::from_parts(a.as_ref(), c.as_ref(), b.as_ref(), d.as_ref()).unwrap();
    // Dense Gram–Schmidt (twice) in list order.
    let dense_b = b.to_dense();
    let mut basis: Vec<Vec<f64>> = Vec::new();
    let (mut kept, mut dependent) = (Vec::new(), Vec::new());
    for k in 0..12 {
        let mut v: Vec<f64> = (0..11).map(|j| dense_b[(k, j)]).collect();
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        for _ in 0..2 {
            for q in &basis {
                let dot: f64 = v.iter().zip(q).map(|(x, y)| x * y).sum();
                for (x, y) in v.iter_mut().zip(q) {
                    *x -= dot * y;
                }
            }
        }
        let rest = v.iter().map(|x| x * x).sum::<f64>().sqrt() / norm;
        assert!(
            !(1e-14..0.04).contains(&rest),
            "row {k}: remainder {rest:e}"
        );
        if rest < 1e-14 {
            dependent.push(k);
        } else {
            kept.push(k);
            basis.push(v.iter().map(|x| x / (rest * norm)).collect());
        }
    }
    assert_eq!(dependent, vec![6, 8, 10, 11]);
    let reference = lse_deform::testing::accurate_reference(&problem, &kept);
    let (redundant, conflicting): (Vec<usize>, Vec<usize>) = dependent
        .iter()
        .partition(|&&k| problem.hard_residual(k, &reference) < 1e-12);
    assert_eq!(
        (redundant.len(), conflicting.len()),
        (2, 2),
        "{redundant:?}"
    );
    for q in QrKind::available() {
        let choice = FormulationChoice {
            qr: q.into(),
            ..FormulationChoice::new(Method::NullSpaceQr)
        };
        let mut solver = LseSolver::with_formulation(
            problem.clone(),
            choice.build().unwrap().as_ref(),
            &lse_deform::resources::Resources::default(),
        )
        .unwrap();
        let x = solver.solve().unwrap();
        let report = solver.report();
        assert_eq!(report.rank, Some(kept.len()), "{q}");
        assert_eq!(report.redundant, redundant, "{q}");
        let found: Vec<usize> = report.conflicting.iter().map(|c| c.index).collect();
        assert_eq!(found, conflicting, "{q}");
        let diff = relative_difference(&x, &reference);
        assert!(diff < 1e-13, "{q}: {diff:e}");
    }
}
