//! The typed report and its aliases: a formulation's precompute returns
//! its record (the method's own facts typed), the report's
//! `factor_backend` and its alias `spd_backend`, `warning_codes` of the
//! refinement warnings, the refinement mode `off` under its new name
//! ([`Refine::EstimateOnly`]) and the old module path, and the condition
//! estimate's method serialised to the sentence it always was.

use std::path::Path;

use lse_deform::condition::ConditionMethod;
use lse_deform::constraints::read_constraints_file;
use lse_deform::formulation::{Formulation, Kkt, NullSpaceQr, Penalty, Refine};
use lse_deform::mesh::read_mesh;
use lse_deform::report::{MethodFacts, WarningKind};
use lse_deform::{Deformer, LaplacianKind, Method};

fn deformer() -> Deformer {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/report_shape");
    let mesh = read_mesh(
        &dir.join("grid.obj"),
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap()
    .mesh;
    let constraints = read_constraints_file(
        &dir.join("positions.json"),
        lse_deform::limits::MemoryBudget::default(),
    )
    .unwrap();
    Deformer::new(
        mesh,
        LaplacianKind::Cotangent,
        constraints,
        &lse_deform::SolveOptions::default(),
    )
    .unwrap()
}

#[test]
fn off_is_the_estimate_only_mode_and_is_written_off() {
    assert_eq!("off".parse::<Refine>().unwrap(), Refine::EstimateOnly);
    assert_eq!("estimate".parse::<Refine>().unwrap(), Refine::EstimateOnly);
    assert_eq!(Refine::EstimateOnly.to_string(), "off");
    assert_eq!(
        serde_json::to_value(Refine::EstimateOnly).unwrap(),
        serde_json::json!("off")
    );
}

#[test]
fn precompute_records_carry_the_methods_own_facts() {
    let d = deformer();
    let facts = |f: &dyn Formulation| f.precompute(d.problem()).unwrap().record;
    let record = facts(&Penalty::new(1e4));
    assert_eq!(record.method, Method::Penalty);
    assert_eq!(record.rank, None);
    assert_eq!(record.warnings.len(), 1);
    assert_eq!(record.warnings[0].kind, WarningKind::PenaltyApproximate);
    let MethodFacts::Penalty {
        weight,
        weight_unit,
    } = record.facts
    else {
        panic!("{:?}", record.facts)
    };
    assert_eq!(weight, 1e4);
    assert!(weight_unit > 0.0 && weight_unit.log2().fract() == 0.0);
    let record = facts(&Kkt::default());
    assert!(
        matches!(record.facts, MethodFacts::Kkt { multiplier_scale } if multiplier_scale > 0.0)
    );
    assert_eq!(record.rank, Some(20));
    let record = facts(&NullSpaceQr::default());
    assert_eq!(record.facts, MethodFacts::NullSpace);
    assert!(record.sizes.aq2.is_some() && record.timings.qr >= 0.0);
}

#[test]
fn factor_backend_and_its_alias_spd_backend_agree() {
    let mut d = deformer();
    d.refactor_with(
        &Kkt::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    let report = serde_json::to_value(d.report()).unwrap();
    assert_eq!(report["factor_backend"], "faer-ldlt-auto");
    assert_eq!(report["spd_backend"], report["factor_backend"]);
    assert_eq!(d.report().spd_backend(), d.report().factor_backend);
    assert!(report["kkt_multiplier_scale"].is_number());
    assert!(report["penalty_weight"].is_null());
}

#[test]
fn condition_method_is_typed_and_serialised_as_its_sentence() {
    let mut d = deformer();
    d.refactor_with(
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    let estimate = d.solver_mut().estimate_condition().unwrap().clone();
    assert_eq!(
        estimate.method,
        ConditionMethod::Lanczos {
            matrix: "(AQ2)ᵀ(AQ2)".into()
        }
    );
    let report = serde_json::to_value(d.report()).unwrap();
    assert_eq!(
        report["condition_estimate"]["method"],
        "Lanczos with full reorthogonalisation on (AQ2)ᵀ(AQ2) for |λ|max and on its inverse (solves with the factor) for |λ|min"
    );
}
