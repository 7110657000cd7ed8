//! General problems from their matrices (`LseProblem::from_parts`), solved
//! through `LseSolver` by every formulation and back end that applies, and
//! the constraint-group API of `Deformer`.

#![allow(clippy::needless_range_loop)]

use faer::Mat;
use faer::sparse::{SparseColMat, Triplet};
use lse_deform::error::{Error, NumericalError, ProblemError};
use lse_deform::formulation::{Formulation, FormulationChoice, Method};
use lse_deform::problem::LseProblem;
use lse_deform::testing::{dense_reference, random_lse, relative_difference};
use lse_deform::{
    Constraint, ConstraintSet, Deformer, Kkt, LaplacianKind, LseSolver, NullSpaceQr, QrKind,
    SpdKind,
};

#[test]
fn null_space_on_every_back_end_matches_the_dense_reference_and_names_dependent_rows() {
    for (seed, k) in [(1u64, 3usize), (2, 1), (3, 5)] {
        let lse = random_lse(40, 12, 6, k, seed);
        let reference = dense_reference(&lse.problem, &lse.independent_rows);
        for q in QrKind::available() {
            for s in SpdKind::available() {
                let choice = FormulationChoice {
                    qr: q,
                    spd: s,
                    ..FormulationChoice::new(Method::NullSpaceQr)
                };
                let f = choice.build().unwrap();
                let mut solver = LseSolver::new(lse.problem.clone());
                solver.precompute(f.as_ref()).unwrap();
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
                assert_eq!(report.laplacian, None);
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
        let mut solver = LseSolver::new(lse.problem.clone());
        solver.precompute(f.as_ref()).unwrap();
        let x = solver.solve().unwrap();
        assert!(relative_difference(&x, &reference) < 1e-9);
    }
    // Penalty: the hard rows hold to O(1/w²).
    let mut solver = LseSolver::new(lse.problem.clone());
    solver.precompute(&lse_deform::Penalty::new(1e4)).unwrap();
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
    let mut solver = LseSolver::new(problem);
    solver
        .precompute(&lse_deform::Elimination::default())
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
        Box::new(lse_deform::Penalty::new(10.0)),
        Box::new(Kkt::default()),
    ];
    for f in formulations {
        let mut solver = LseSolver::new(problem.clone());
        let err = solver.precompute(f.as_ref()).unwrap_err();
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
    let mut solver = LseSolver::new(lse.problem.clone());
    solver.precompute(&NullSpaceQr::default()).unwrap();
    let x = solver.solve().unwrap();
    let mut y = Mat::<f64>::zeros(25, 3);
    solver.solve_into(y.as_mut()).unwrap();
    assert_eq!(relative_difference(&y, &x), 0.0);
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
    let mut d = Deformer::new(mesh, LaplacianKind::Cotangent, set).unwrap();
    d.precompute(&NullSpaceQr::default()).unwrap();
    d
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
        let mut solver = LseSolver::new(lse.problem.clone());
        solver.precompute(&NullSpaceQr::default()).unwrap();
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
        let mut d = Deformer::new(mesh, LaplacianKind::Cotangent, ConstraintSet::from_vec(all).unwrap()).unwrap();
        d.precompute(&NullSpaceQr::default()).unwrap();
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
    let Err(ProblemError::InvalidArgument { message }) = "qr".parse::<Method>() else {
        panic!("unknown method accepted");
    };
    assert!(
        Method::ALL.iter().all(|m| message.contains(m.name())),
        "{message}"
    );
    // Each built formulation reports the method it was chosen as.
    let mut penalty = FormulationChoice::new(Method::Penalty);
    penalty.weight = Some(1e4);
    assert!(penalty.build().unwrap().name().starts_with("penalty"));
    let refused = |choice: FormulationChoice, needle: &str| match choice.build() {
        Err(ProblemError::InvalidArgument { message }) => {
            assert!(message.contains(needle), "{choice:?}: {message}")
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
    // KKT factors with faer's LDLᵀ only.
    for spd in [SpdKind::Nalgebra, SpdKind::Cholmod] {
        let choice = FormulationChoice {
            spd,
            ..FormulationChoice::new(Method::Kkt)
        };
        refused(choice, "faer-auto, faer-simplicial or faer-supernodal");
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
