//! `SolveOptions`: the memory budget is an option of each solve, not of
//! the process. In one process, a solve given a tiny budget is refused
//! with the typed error, naming the option as the budget's source, while
//! the same solve with the default budget succeeds; every formulation's
//! precompute, the QR back ends and the response basis check the solve's
//! budget.

use lse_deform::arap::{ArapDeformer, ArapEnergy};
use lse_deform::constraints::{Constraint, ConstraintSet};
use lse_deform::error::{Error, ProblemError};
use lse_deform::handle::HandleBasis;
use lse_deform::mesh::{Mesh, generate};
use lse_deform::resources::Resources;
use lse_deform::{
    Deformer, LaplacianKind, Method, QrKind, SolveOptions, formulation::FormulationChoice,
    limits::MemoryBudget,
};

/// A 10 × 10 grid: the bottom row fixed, the top row lifted as group
/// "top", and a relative constraint so that `R` of the QR is not diagonal.
fn scene() -> (Mesh, ConstraintSet) {
    let (mesh, mut set) = positions_scene();
    set.push(Constraint::relative([55, 56], [0.1, 0.0, 0.0]))
        .unwrap();
    (mesh, set)
}

/// The grid with its position constraints only (for elimination).
fn positions_scene() -> (Mesh, ConstraintSet) {
    let mesh = generate::grid(10, 10).unwrap();
    let mut set = ConstraintSet::new();
    for v in 0..11 {
        let p = mesh.positions()[v];
        set.push(Constraint::position(v, p).in_group("fixed"))
            .unwrap();
        let top = 110 + v;
        let q = mesh.positions()[top];
        set.push(Constraint::position(top, [q[0], q[1], 0.5]).in_group("top"))
            .unwrap();
    }
    (mesh, set)
}

/// 64 bytes: less than any factor of the scene needs.
fn tiny(formulation: FormulationChoice) -> SolveOptions {
    SolveOptions {
        resources: Resources {
            budget: MemoryBudget::bytes(64),
            ..Resources::default()
        },
        ..SolveOptions::new(formulation)
    }
}

fn with_weight(method: Method) -> FormulationChoice {
    FormulationChoice {
        weight: Some(1e3),
        ..FormulationChoice::new(method)
    }
}

/// The detail of a `ProblemError::TooLarge`, or a panic naming what came
/// instead.
fn too_large(result: Result<(), Error>) -> String {
    match result {
        Err(Error::Problem(ProblemError::TooLarge { detail })) => detail,
        other => panic!("expected a TooLarge error, got {other:?}"),
    }
}

#[test]
fn a_tiny_budget_is_refused_per_solve_and_the_default_succeeds_in_the_same_process() {
    let (mesh, set) = scene();
    // Elimination needs position constraints only.
    let (_, positions_only) = positions_scene();
    let cases = [
        (FormulationChoice::new(Method::NullSpaceQr), &set),
        (
            FormulationChoice {
                qr: QrKind::DenseHouseholder.into(),
                ..FormulationChoice::new(Method::NullSpaceQr)
            },
            &set,
        ),
        (with_weight(Method::Penalty), &set),
        (FormulationChoice::new(Method::Kkt), &set),
        (FormulationChoice::new(Method::Eliminate), &positions_only),
    ];
    for (formulation, constraints) in cases {
        let name = format!("{} / {}", formulation.method, formulation.qr);
        let mut small = Deformer::new(
            mesh.clone(),
            LaplacianKind::Cotangent,
            constraints.clone(),
            &lse_deform::SolveOptions::default(),
        )
        .unwrap();
        let detail = too_large(small.refactor(&tiny(formulation.clone())));
        assert!(
            detail.ends_with(
                "more than the memory budget of 64 B (the memory budget of the solve options)"
            ),
            "{name}: {detail}"
        );
        assert!(!detail.contains("--"), "{name}: a CLI flag in {detail}");

        let mut default = Deformer::new(
            mesh.clone(),
            LaplacianKind::Cotangent,
            constraints.clone(),
            &lse_deform::SolveOptions::default(),
        )
        .unwrap();
        default
            .refactor(&SolveOptions::new(formulation.clone()))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let solution = default.solve().unwrap();
        // Penalty only approximates the hard rows.
        let tolerance = if formulation.method == Method::Penalty {
            1e-2
        } else {
            1e-9
        };
        assert!(
            solution.report.max_constraint_residual < tolerance,
            "{name}"
        );

        // The refused deformer takes a budget that fits and then succeeds.
        small
            .refactor(&SolveOptions {
                resources: Resources {
                    budget: MemoryBudget::unlimited(),
                    ..Resources::default()
                },
                ..SolveOptions::new(formulation)
            })
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

#[test]
fn the_qr_factor_is_checked_against_the_solve_budget_before_the_cholesky_factor() {
    // The dense Householder blocks are sized before any factor: the
    // refusal names them, not the Cholesky factor.
    let (mesh, set) = scene();
    let mut d = Deformer::new(
        mesh,
        LaplacianKind::Cotangent,
        set,
        &lse_deform::SolveOptions::default(),
    )
    .unwrap();
    let formulation = FormulationChoice {
        qr: QrKind::DenseHouseholder.into(),
        ..FormulationChoice::new(Method::NullSpaceQr)
    };
    let detail = too_large(d.refactor(&tiny(formulation)));
    assert!(detail.contains("dense Householder blocks"), "{detail}");
    let detail = too_large(d.refactor(&tiny(FormulationChoice::new(Method::Kkt))));
    assert!(detail.contains("the KKT matrix"), "{detail}");
}

#[test]
fn the_response_basis_uses_the_precomputes_budget_or_the_one_given() {
    let (mesh, set) = scene();
    let mut d = Deformer::new(
        mesh,
        LaplacianKind::Cotangent,
        set,
        &SolveOptions::default(),
    )
    .unwrap();
    HandleBasis::new(&mut d, &["top"]).unwrap();
    // Less than 7 columns of 121 vertices.
    let tiny = Resources {
        budget: MemoryBudget::bytes(4096),
        ..Resources::default()
    };
    let e = HandleBasis::with_resources(&mut d, &["top"], &tiny).unwrap_err();
    let detail = too_large(Err(e));
    assert!(
        detail.contains("the response basis of 1 group(s)"),
        "{detail}"
    );
    assert!(detail.contains("solve options"), "{detail}");
}

#[test]
fn arap_takes_the_options_budget_and_refinement() {
    let (mesh, set) = scene();
    let mut arap = ArapDeformer::new(
        mesh.clone(),
        set.clone(),
        ArapEnergy::SpokesAndRims,
        &lse_deform::SolveOptions::default(),
    )
    .unwrap();
    let formulation = FormulationChoice::new(Method::NullSpaceQr);
    too_large(arap.refactor(&tiny(formulation.clone())));
    let _arap = ArapDeformer::new(
        mesh,
        set,
        ArapEnergy::SpokesAndRims,
        &SolveOptions::new(formulation),
    )
    .unwrap();
}

#[test]
fn an_invalid_formulation_is_refused_before_the_solver_changes() {
    let (mesh, set) = scene();
    let mut d = Deformer::new(
        mesh,
        LaplacianKind::Cotangent,
        set,
        &SolveOptions::default(),
    )
    .unwrap();
    let before = d.report().clone();
    let no_weight = SolveOptions {
        resources: Resources {
            budget: MemoryBudget::bytes(64),
            ..Resources::default()
        },
        ..SolveOptions::new(FormulationChoice::new(Method::Penalty))
    };
    match d.refactor(&no_weight) {
        Err(Error::Problem(ProblemError::InvalidOption { .. })) => {}
        other => panic!("expected InvalidOption, got {other:?}"),
    }
    assert_eq!(d.report(), &before);
    // The earlier factor still solves.
    d.solve().unwrap();
}

#[test]
fn the_default_budget_is_the_process_default() {
    assert_eq!(
        SolveOptions::default().resources.budget.limit(),
        lse_deform::limits::memory_budget()
    );
    assert_eq!(MemoryBudget::bytes(5).limit(), 5);
}
