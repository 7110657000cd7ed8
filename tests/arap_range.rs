//! ARAP over the range of double precision: a mesh in units from 1e-150 to
//! 1e150 deforms like the unscaled one (the problem is assembled in the
//! mesh's length unit, as the Laplacian deformer's), with the report's
//! energies and residuals in the mesh's units; a target whose squared
//! distances overflow is a numerical error (exit code 3) that stops the
//! iterations, however many were asked for.

use std::path::Path;

use lse_deform::arap::{ArapDeformer, ArapEnergy, ArapInit};
use lse_deform::constraints::{Constraint, ConstraintKind, ConstraintSet};
use lse_deform::error::{Error, NumericalError};
use lse_deform::testing::random_surface;
use lse_deform::{Mesh, formulation::NullSpaceQr};

mod common;
use common::path_in;

/// The bottom row fixed, the top row moved, one hard relative constraint
/// and two soft ones (a position and an edge), all lengths times `s`.
fn scene(mesh: &Mesh, nx: usize, ny: usize, s: f64) -> ConstraintSet {
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
            target: [q[0] + 0.3 * s, q[1] - 0.4 * s, q[2] + 0.6 * s],
        }))
        .unwrap();
    }
    let mid = (ny / 2) * (nx + 1);
    cs.push(Constraint::hard(ConstraintKind::Relative {
        vertices: [mid + nx, mid],
        vector: [0.8 * s, 0.1 * s, 0.2 * s],
    }))
    .unwrap();
    let q = p[mid + 2];
    cs.push(Constraint::soft(
        ConstraintKind::Position {
            vertex: mid + 2,
            target: [q[0], q[1], q[2] + 0.5 * s],
        },
        3.0,
    ))
    .unwrap();
    cs.push(Constraint::soft(
        ConstraintKind::Edge {
            vertices: [mid + 3, mid + 4],
            t: 0.25,
            target: [0.4 * s, 0.5 * s, 0.3 * s],
        },
        0.5,
    ))
    .unwrap();
    cs
}

fn scaled(mesh: &Mesh, s: f64) -> Mesh {
    mesh.with_positions(mesh.positions().iter().map(|p| p.map(|v| v * s)).collect())
        .unwrap()
}

/// Runs `iterations` from the linear guess: positions and the report.
fn run(mesh: Mesh, cs: ConstraintSet, iterations: usize) -> (Vec<[f64; 3]>, lse_deform::Report) {
    let mut arap = ArapDeformer::with_formulation(
        mesh,
        cs,
        ArapEnergy::SpokesAndRims,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    arap.initialize(ArapInit::Linear).unwrap();
    arap.run(iterations, 0.0).unwrap();
    (arap.positions(), arap.report().clone())
}

/// A mesh and its scene scaled by 1e±100 and 1e±150 give the unscaled
/// positions times the scale (to 1e-10 of the diagonal), energies times
/// the scale squared and residuals times the scale (soft weights mean the
/// same in every unit). Without the length unit, 1e±100 fail: the
/// triangles' squared areas overflow or underflow.
#[test]
fn a_mesh_in_units_from_1e_minus_150_to_1e150_deforms_like_the_unscaled_one() {
    let (nx, ny) = (6, 7);
    let mesh = random_surface(nx, ny, 4);
    let (x1, r1) = run(mesh.clone(), scene(&mesh, nx, ny, 1.0), 15);
    let a1 = r1.arap.clone().unwrap();
    let diagonal = mesh.bbox_diagonal();
    assert!(a1.energies.iter().all(|e| e.is_finite() && *e > 0.0));
    for s in [1e-150, 1e-100, 1e100, 1e150] {
        let m = scaled(&mesh, s);
        let (xs, rs) = run(m.clone(), scene(&m, nx, ny, s), 15);
        let gap = xs
            .iter()
            .zip(&x1)
            .flat_map(|(a, b)| (0..3).map(move |c| (a[c] / s - b[c]).abs()))
            .fold(0.0, f64::max);
        assert!(
            gap <= 1e-10 * diagonal,
            "scale {s:e}: positions differ by {gap:e}"
        );
        let a = rs.arap.clone().unwrap();
        assert_eq!(a.energies.len(), a1.energies.len());
        let relative = |x: f64, y: f64| (x - y).abs() / y.abs().max(f64::MIN_POSITIVE);
        assert!(
            relative(a.initial_energy / s / s, a1.initial_energy) <= 1e-9,
            "scale {s:e}: initial energy {:e} vs {:e}",
            a.initial_energy,
            a1.initial_energy
        );
        for (k, (e, e1)) in a.energies.iter().zip(&a1.energies).enumerate() {
            assert!(
                relative(e / s / s, *e1) <= 1e-9,
                "scale {s:e}, iteration {}: energy {e:e} vs {e1:e}",
                k + 1
            );
        }
        for (r, r1) in a.constraint_residuals.iter().zip(&a1.constraint_residuals) {
            assert!(*r <= 1e-10 * diagonal * s && *r1 <= 1e-10 * diagonal);
        }
        assert_eq!(rs.soft_residuals.len(), 2);
        for (q, q1) in rs.soft_residuals.iter().zip(&r1.soft_residuals) {
            assert!(q1.residual > 1e-3, "the soft constraints pull");
            assert!(
                relative(q.residual / s, q1.residual) <= 1e-8,
                "scale {s:e}: soft residual {:e} vs {:e}",
                q.residual,
                q1.residual
            );
        }
        assert!(relative(rs.length_scale / s, r1.length_scale) <= 1e-12);
    }
}

/// A target at 1e160 on a unit mesh: the positions are finite but the
/// squared edge lengths of the energy overflow. A typed numerical error at
/// the initial guess (with either guess), not NaN energies.
#[test]
fn an_energy_beyond_double_precision_is_a_numerical_error() {
    let (nx, ny) = (4, 4);
    let mesh = random_surface(nx, ny, 2);
    let mut cs = scene(&mesh, nx, ny, 1.0);
    cs.set_rhs(1, [1e160, 0.0, 0.0]).unwrap();
    for init in [ArapInit::Linear, ArapInit::Rest] {
        let mut arap = ArapDeformer::with_formulation(
            mesh.clone(),
            cs.clone(),
            ArapEnergy::Spokes,
            &NullSpaceQr::default(),
            &lse_deform::resources::Resources::default(),
        )
        .unwrap();
        let e = arap.initialize(init).unwrap_err();
        assert!(
            matches!(
                e,
                Error::Numerical(NumericalError::NonFiniteEnergy { iteration: 0, .. })
            ),
            "{init:?}: {e}"
        );
        assert_eq!(e.exit_code(), 3);
    }
    // Moved there between iterations: the error names the iteration.
    let cs = scene(&mesh, nx, ny, 1.0);
    let mut arap = ArapDeformer::with_formulation(
        mesh,
        cs,
        ArapEnergy::Spokes,
        &NullSpaceQr::default(),
        &lse_deform::resources::Resources::default(),
    )
    .unwrap();
    arap.initialize(ArapInit::Linear).unwrap();
    arap.iterate(2).unwrap();
    arap.set_target(1, [-1e160, 0.0, 0.0]).unwrap();
    let e = arap.iterate(5).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Numerical(NumericalError::NonFiniteEnergy { iteration: 3, .. })
        ),
        "{e}"
    );
    assert!(arap.positions().iter().flatten().all(|v| v.is_finite()));
}

/// Through the binary: `deform --energy arap` with a target near 1e160
/// and a tolerance with (practically) unlimited iterations exits 3 at
/// once, naming the energy, and writes neither mesh nor report (before,
/// its energies were NaN, the tolerance test never fired, and it ran
/// forever).
#[test]
fn deform_arap_with_a_target_near_1e160_exits_3_and_stops() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = path_in(dir.path(), "grid.obj");
    let o = common::run(&["generate", "grid", "--vertices", "100", "-o", &mesh]);
    assert!(o.status.success());
    let scene = path_in(dir.path(), "huge.json");
    std::fs::write(
        &scene,
        r#"{"constraints": [
            {"type": "position", "vertex": 0, "target": [0, 0, 0]},
            {"type": "position", "vertex": 1, "target": [0.1, 0, 0]},
            {"type": "position", "vertex": 99, "target": [1e160, 0, 0]}
        ]}"#,
    )
    .unwrap();
    let (out, report) = (
        path_in(dir.path(), "out.obj"),
        path_in(dir.path(), "r.json"),
    );
    for init in ["linear", "rest"] {
        let o = common::run(&[
            "deform",
            &mesh,
            "-c",
            &scene,
            "-o",
            &out,
            "--report",
            &report,
            "--energy",
            "arap",
            "--arap-init",
            init,
            "--tolerance",
            "1e-6",
            "--iterations",
            "1000000000",
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(3), "{init}: {err}");
        assert!(
            err.contains("ARAP: the energy of the initial guess is"),
            "{init}: {err}"
        );
        assert!(!Path::new(&out).exists() && !Path::new(&report).exists());
    }
}
