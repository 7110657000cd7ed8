//! Affine handles: the response basis `X₀ + Σ_g R_g M_gᵀ` equals a full
//! solve after `transform_group` (≤ 1e-9 of the bounding-box diagonal)
//! for every exact formulation (and for penalty refined by the method of
//! multipliers, which makes it exact), over random meshes, constraint kinds, groups
//! and affine maps; its errors are typed.

use lse_deform::constraints::{Constraint, ConstraintSet};
use lse_deform::deform::Affine;
use lse_deform::formulation::{Formulation, Refine};
use lse_deform::handle::HandleBasis;
use lse_deform::testing::{independent_constraints, random_surface, with_soft};
use lse_deform::{
    Deformer, Error, LaplacianKind, Mesh, formulation::Elimination, formulation::Kkt,
    formulation::NullSpaceQr, formulation::Penalty,
};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const IDENTITY: Affine = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
];

/// A rotation about an axis by `angle`, scaled by `s`, then translated.
fn affine(axis: [f64; 3], angle: f64, s: f64, t: [f64; 3]) -> Affine {
    let norm = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let [x, y, z] = axis.map(|v| v / norm);
    let (c, si) = (angle.cos(), angle.sin());
    let k = 1.0 - c;
    let r = [
        [c + x * x * k, x * y * k - z * si, x * z * k + y * si],
        [y * x * k + z * si, c + y * y * k, y * z * k - x * si],
        [z * x * k - y * si, z * y * k + x * si, c + z * z * k],
    ];
    [0, 1, 2].map(|i| [s * r[i][0], s * r[i][1], s * r[i][2], t[i]])
}

/// Max over vertices of `‖a_v − b_v‖` over the bounding-box diagonal.
fn max_difference(a: &[[f64; 3]], b: &[[f64; 3]], diagonal: f64) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        })
        .fold(0.0, f64::max)
        / diagonal
}

/// Builds the basis of `groups`, then for each transform set compares the
/// evaluation with `transform_group` + a full solve; returns the largest
/// relative difference.
fn basis_vs_full_solve(
    mesh: Mesh,
    constraints: Vec<Constraint>,
    formulation: &dyn Formulation,
    groups: &[&str],
    frames: &[Vec<Affine>],
) -> Result<f64, Error> {
    let diagonal = mesh.bbox_diagonal();
    let n = mesh.n_vertices();
    let set = ConstraintSet::from_vec(constraints)?;
    let mut deformer = Deformer::new(
        mesh,
        LaplacianKind::Cotangent,
        set,
        &lse_deform::SolveOptions::default(),
    )?;
    // Auto for every formulation: penalty's refinement is the method of
    // multipliers, which makes it exact (unrefined, its own forward error
    // of about w²·ε·κ would be compared, not the basis).
    deformer.solver_mut().set_refine(Some(Refine::Auto));
    deformer.refactor_with(formulation, &lse_deform::resources::Resources::default())?;
    let basis = HandleBasis::new(&mut deformer, groups)?;
    let mut out = vec![[0.0; 3]; n];
    let mut out_f32 = vec![[0.0f32; 3]; n];
    let mut worst = 0.0f64;
    for frame in frames {
        basis.evaluate(frame, &mut out)?;
        // The f32 path is the same arithmetic, rounded only at the store.
        basis.evaluate_f32(frame, &mut out_f32)?;
        for (p, q) in out.iter().zip(&out_f32) {
            assert_eq!(p.map(|v| v as f32), *q);
        }
        for (name, m) in groups.iter().zip(frame) {
            deformer.transform_group(name, m)?;
        }
        let full = deformer.solve()?.positions;
        worst = worst.max(max_difference(&out, &full, diagonal));
    }
    Ok(worst)
}

/// Hard constraints of every kind (positions only for elimination) and a
/// few soft ones, spread at random over the groups "a", "b" and none.
fn grouped_constraints(mesh: &Mesh, seed: u64, positions_only: bool) -> Vec<Constraint> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let hard = independent_constraints(mesh, &mut rng, 12, positions_only);
    let mut cs = with_soft(mesh, &mut rng, hard, 3);
    for (i, c) in cs.iter_mut().enumerate() {
        // Constraints 0 and 1 anchor the groups (both non-empty).
        let pick = if i < 2 { i } else { rng.random_range(0..3) };
        c.group = ["a", "b", ""]
            .get(pick)
            .filter(|s| !s.is_empty())
            .map(|s| s.to_string());
    }
    cs
}

fn frames(seed: u64) -> Vec<Vec<Affine>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut random = || {
        let axis = [0, 1, 2].map(|_| rng.random_range(-1.0..1.0) + 0.01);
        let t = [0, 1, 2].map(|_| rng.random_range(-0.5..0.5));
        affine(
            axis,
            rng.random_range(-1.5..1.5),
            rng.random_range(0.5..1.5),
            t,
        )
    };
    vec![
        vec![IDENTITY, IDENTITY],
        vec![random(), IDENTITY],
        vec![random(), random()],
        vec![IDENTITY, random()],
    ]
}

fn formulations(positions_only: bool) -> Vec<(&'static str, Box<dyn Formulation>)> {
    let mut out: Vec<(&'static str, Box<dyn Formulation>)> = vec![
        ("nullspace-qr", Box::new(NullSpaceQr::default())),
        ("kkt", Box::new(Kkt::default())),
        ("penalty", Box::new(Penalty::new(1e3))),
    ];
    if positions_only {
        out.push(("eliminate", Box::new(Elimination::default())));
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn basis_equals_full_solve(
        seed in any::<u64>(),
        nx in 4usize..9,
        ny in 4usize..9,
        positions_only in any::<bool>(),
    ) {
        let mesh = random_surface(nx, ny, seed);
        let cs = grouped_constraints(&mesh, seed ^ 0x5eed, positions_only);
        for (name, f) in formulations(positions_only) {
            let worst = basis_vs_full_solve(mesh.clone(), cs.clone(), f.as_ref(), &["a", "b"], &frames(seed))
                .map_err(|e| TestCaseError::fail(format!("{name}: {e}")))?;
            prop_assert!(worst <= 1e-9, "{name}: basis differs from the full solve by {worst:e} of the diagonal");
        }
    }
}

/// The paper's scene on a grid: bottom row fixed, top row a handle moved
/// by a large rotation and translation; a basis over the handle only (the
/// fixed group keeps its current targets in `X₀`).
#[test]
fn handle_only_basis_on_a_grid_matches_every_formulation() {
    let mesh = lse_deform::mesh::generate::grid(12, 12).unwrap();
    let p = mesh.positions().to_vec();
    let mut cs = Vec::new();
    for v in 0..13 {
        let mut fixed = Constraint::hard(lse_deform::constraints::ConstraintKind::Position {
            vertex: v,
            target: p[v],
        });
        fixed.group = Some("fixed".into());
        cs.push(fixed);
        let top = 12 * 13 + v;
        let mut handle = Constraint::hard(lse_deform::constraints::ConstraintKind::Position {
            vertex: top,
            target: p[top],
        });
        handle.group = Some("handle".into());
        cs.push(handle);
    }
    let moves = vec![
        vec![affine([1.0, 0.0, 0.0], 0.9, 1.0, [0.0, 0.2, 0.6])],
        vec![affine([0.3, 1.0, 0.2], -0.4, 1.2, [0.1, -0.3, 0.0])],
        vec![IDENTITY],
    ];
    for (name, f) in formulations(true) {
        let worst =
            basis_vs_full_solve(mesh.clone(), cs.clone(), f.as_ref(), &["handle"], &moves).unwrap();
        assert!(worst <= 1e-9, "{name}: {worst:e}");
    }
}

/// The identity reproduces the rest solve; the response to the
/// translation column of a handle is 1 at the handle's vertices (they
/// follow a translation exactly) and 0 at the fixed ones — checked through
/// evaluate with a pure translation.
#[test]
fn translation_moves_handle_vertices_exactly_and_fixed_ones_not_at_all() {
    let mesh = lse_deform::mesh::generate::grid(6, 6).unwrap();
    let p = mesh.positions().to_vec();
    let mut cs = Vec::new();
    for v in 0..7 {
        let mut c = Constraint::hard(lse_deform::constraints::ConstraintKind::Position {
            vertex: v,
            target: p[v],
        });
        c.group = Some("fixed".into());
        cs.push(c);
        let mut h = Constraint::hard(lse_deform::constraints::ConstraintKind::Position {
            vertex: 42 + v,
            target: p[42 + v],
        });
        h.group = Some("handle".into());
        cs.push(h);
    }
    let mut deformer = Deformer::with_formulation(
        mesh,
        LaplacianKind::Cotangent,
        ConstraintSet::from_vec(cs).unwrap(),
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    let basis = HandleBasis::new(&mut deformer, &["fixed", "handle"]).unwrap();
    let mut out = vec![[0.0; 3]; 49];
    let shift = [
        [1.0, 0.0, 0.0, 0.25],
        [0.0, 1.0, 0.0, -0.5],
        [0.0, 0.0, 1.0, 2.0],
    ];
    basis.evaluate(&[IDENTITY, shift], &mut out).unwrap();
    for v in 0..7 {
        for c in 0..3 {
            assert!((out[v][c] - p[v][c]).abs() < 1e-12);
            assert!((out[42 + v][c] - (p[42 + v][c] + shift[c][3])).abs() < 1e-12);
        }
    }
    // The flat grid at rest is its own solution.
    basis.evaluate(&[IDENTITY, IDENTITY], &mut out).unwrap();
    assert!(max_difference(&out, &p, 1.0) < 1e-12);
}

#[test]
fn bad_requests_are_typed_errors() {
    let mesh = lse_deform::mesh::generate::grid(4, 4).unwrap();
    let p = mesh.positions().to_vec();
    let mut c = Constraint::hard(lse_deform::constraints::ConstraintKind::Position {
        vertex: 0,
        target: p[0],
    });
    c.group = Some("h".into());
    let mut deformer = Deformer::new(
        mesh,
        LaplacianKind::Cotangent,
        ConstraintSet::from_vec(vec![c]).unwrap(),
        &lse_deform::SolveOptions::default(),
    )
    .unwrap();
    deformer
        .refactor_with(
            &NullSpaceQr::default(),
            &lse_deform::resources::Resources::default(),
        )
        .unwrap();
    let unknown = HandleBasis::new(&mut deformer, &["nope"])
        .unwrap_err()
        .to_string();
    assert!(
        unknown.contains("nope") && unknown.contains("h"),
        "{unknown}"
    );
    assert!(
        HandleBasis::new(&mut deformer, &["h", "h"])
            .unwrap_err()
            .to_string()
            .contains("twice")
    );
    let basis = HandleBasis::new(&mut deformer, &["h"]).unwrap();
    let mut out = vec![[0.0; 3]; 25];
    assert!(basis.evaluate(&[], &mut out).is_err());
    assert!(basis.evaluate(&[IDENTITY], &mut out[..3]).is_err());
    let mut nan = IDENTITY;
    nan[1][2] = f64::NAN;
    assert!(
        basis
            .evaluate(&[nan], &mut out)
            .unwrap_err()
            .to_string()
            .contains("non-finite")
    );
}
