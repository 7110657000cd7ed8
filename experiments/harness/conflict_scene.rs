//! The conflict scene of the paper's Fig. 6, shared by the `conflicts` and
//! `renders` studies: the Table 1 scene plus redundant and conflicting
//! constraints appended at lower priority, its solves and its mesh.

use lse_deform::constraints::{Constraint, ConstraintKind, ConstraintSet};
use lse_deform::mesh::{Mesh, generate};
use lse_deform::scene::FixedAndHandle;
use lse_deform::{Deformer, LaplacianKind, Method, Report, formulation::FormulationChoice};

use lse_deform::error::Error;

use crate::harness::context::AnyError;
use crate::harness::context::Context;
use crate::harness::measures::{failure_kind, sci};

/// Groups of the scene's constraints, in list order.
pub const GROUPS: [&str; 5] = [
    "fixed",
    "handle",
    "redundant duplicate of fixed",
    "conflicting: handle vertex sent back",
    "conflicting: relative handle–fixed",
];

/// Weight of every constraint in the all-soft solve (the paper's Fig. 6b).
pub const SOFT_WEIGHT: f64 = 10.0;

/// Penalty weight of the penalty solve.
pub const PENALTY_WEIGHT: f64 = 1e4;

/// The conflict scene: constraints (all hard), the group of each, and the
/// fixed and handle vertices.
pub struct Scene {
    /// The constraints, in priority order.
    pub constraints: ConstraintSet,
    /// `GROUPS` index of each constraint.
    pub group: Vec<usize>,
    /// Fixed vertices.
    pub fixed: Vec<usize>,
    /// Handle vertices.
    pub handle: Vec<usize>,
    /// Vertices of the conflicting constraints.
    pub conflicted: Vec<usize>,
    /// The base scene.
    pub base: FixedAndHandle,
}

/// Builds the conflict scene on `mesh` with `extra` constraints in each of
/// the three appended groups.
pub fn scene(mesh: &Mesh, extra: usize) -> Result<Scene, AnyError> {
    let base = FixedAndHandle::paper_default(mesh);
    let (fixed, handle) = base.regions(mesh)?;
    let p = mesh.positions();
    let mut list: Vec<Constraint> = base.constraints(mesh)?.as_slice().to_vec();
    let mut group: Vec<usize> = fixed
        .iter()
        .map(|_| 0)
        .chain(handle.iter().map(|_| 1))
        .collect();
    let step_f = (fixed.len() / extra.max(1)).max(1);
    let step_h = (handle.len() / extra.max(1)).max(1);
    for &v in fixed.iter().step_by(step_f).take(extra) {
        list.push(Constraint::hard(ConstraintKind::Position {
            vertex: v,
            target: p[v],
        }));
        group.push(2);
    }
    let mut conflicted = Vec::new();
    for &v in handle.iter().step_by(step_h).take(extra) {
        list.push(Constraint::hard(ConstraintKind::Position {
            vertex: v,
            target: p[v],
        }));
        group.push(3);
        conflicted.push(v);
    }
    for (&h, &f) in handle
        .iter()
        .skip(step_h / 2)
        .step_by(step_h)
        .zip(fixed.iter().skip(step_f / 2).step_by(step_f))
        .take(extra)
    {
        let vector = [0, 1, 2].map(|k| p[h][k] - p[f][k]);
        list.push(Constraint::hard(ConstraintKind::Relative {
            vertices: [h, f],
            vector,
        }));
        group.push(4);
        conflicted.push(h);
    }
    Ok(Scene {
        constraints: ConstraintSet::from_vec(list)?,
        group,
        fixed,
        handle,
        conflicted,
        base,
    })
}

/// The same constraints, all soft with weight `w`.
pub fn all_soft(constraints: &ConstraintSet, w: f64) -> Result<ConstraintSet, AnyError> {
    Ok(ConstraintSet::from_vec(
        constraints
            .as_slice()
            .iter()
            .map(|c| Constraint::soft(c.kind.clone(), w))
            .collect(),
    )?)
}

/// `‖row·X − rhs‖` of every constraint.
pub fn residuals(constraints: &ConstraintSet, x: &[[f64; 3]]) -> Vec<f64> {
    constraints
        .as_slice()
        .iter()
        .map(|c| {
            let v = c.kind.row().apply(x);
            let r = c.kind.rhs();
            (0..3).map(|k| (v[k] - r[k]).powi(2)).sum::<f64>().sqrt()
        })
        .collect()
}

/// A solve of the scene by one method.
pub struct Solved {
    /// Method label.
    pub label: String,
    /// Positions, or the error.
    pub result: Result<(Vec<[f64; 3]>, Report), String>,
}

/// Solves the scene with the four methods of the figure: all soft
/// (w = [`SOFT_WEIGHT`]), penalty (w = [`PENALTY_WEIGHT`]), KKT, null-space
/// QR; cotangent Laplacian.
pub fn solve_all(mesh: &Mesh, sc: &Scene) -> Result<Vec<Solved>, AnyError> {
    let penalty = |w: f64| FormulationChoice {
        weight: Some(w),
        ..FormulationChoice::new(Method::Penalty)
    };
    let solve = |d: &mut Deformer,
                 c: FormulationChoice|
     -> Result<(Vec<[f64; 3]>, Report), String> {
        c.build()
            .map_err(Error::from)
            .and_then(|f| d.refactor_with(f.as_ref(), &lse_deform::resources::Resources::default()))
            .and_then(|_| d.solve())
            .map(|s| (s.positions, s.report))
            .map_err(|e| format!("{} — {e}", failure_kind(&e)))
    };
    let soft = all_soft(&sc.constraints, SOFT_WEIGHT)?;
    let mut soft_deformer = Deformer::new(
        mesh.clone(),
        LaplacianKind::Cotangent,
        soft,
        &lse_deform::SolveOptions::default(),
    )?;
    let mut d = Deformer::new(
        mesh.clone(),
        LaplacianKind::Cotangent,
        sc.constraints.clone(),
        &lse_deform::SolveOptions::default(),
    )?;
    Ok(vec![
        Solved {
            label: format!("all soft (w = {})", sci(SOFT_WEIGHT)),
            // No hard rows: the penalty formulation's normal equations are
            // those of the plain least-squares problem (its weight is unused).
            result: solve(&mut soft_deformer, penalty(1.0)),
        },
        Solved {
            label: format!("penalty (w = {})", sci(PENALTY_WEIGHT)),
            result: solve(&mut d, penalty(PENALTY_WEIGHT)),
        },
        Solved {
            label: "KKT".into(),
            result: solve(&mut d, FormulationChoice::new(Method::Kkt)),
        },
        Solved {
            label: "null-space QR (detect and remove)".into(),
            result: solve(&mut d, FormulationChoice::new(Method::NullSpaceQr)),
        },
    ])
}

/// The mesh of the experiment: the 3.5k-vertex bunny with a mesh directory,
/// else a generated bumpy sphere.
pub fn conflict_mesh(ctx: &Context) -> Result<(String, Mesh), AnyError> {
    if let Some(case) = ctx.main_mesh("bunny-3k.obj")? {
        return Ok((case.name, case.mesh));
    }
    let size = if ctx.quick { 1_500 } else { 4_000 };
    let mesh = generate::with_about_vertices(generate::GeneratedKind::BumpySphere, size, ctx.seed)?;
    Ok(("bumpy-sphere".into(), mesh))
}
