//! Affine handles: the deformed positions as an affine function of the
//! transforms of the constraint groups, precomputed once per constraint
//! configuration and evaluated per frame without a solve (DESIGN §6;
//! Botsch & Kobbelt 2004's basis functions, here with the exact hard
//! constraints of whichever formulation the [`Deformer`] was precomputed
//! with).
//!
//! **Mathematics.** A group `g` with rest targets `P_g` (k × 3) moved by
//! `M_g` (3 × 4) has targets `D_g = [P_g t_g] M_gᵀ`, `t_i = 1` for a
//! position, edge or face target and `0` for a relative vector (a
//! difference does not translate; see [`Deformer::transform_group`]). The
//! solution of `min ‖AX − C‖ s.t. BX = D` is linear in `(C, D)` column by
//! column, so
//!
//! `X = X₀ + Σ_g R_g M_gᵀ`
//!
//! with `X₀` (n × 3) the solution with every basis group's targets 0 (the
//! Laplacian coordinates and the other constraints' current targets kept)
//! and `R_g` (n × 4) the solutions for `C = 0`, every other target 0, and
//! group `g`'s targets the four columns of `[P_g t_g]`. The `3 + 4G`
//! columns are solved with the existing factor, three at a time, each
//! refined as [`Deformer::solve`] refines
//! ([`Deformer::solve_columns`]). Per frame: `n × (3 + 12G)` multiply-adds
//! over `n × (3 + 4G)` stored numbers, read once — the memory floor is
//! reading them ([`HandleBasis::bytes`]).
//!
//! **Agreement.** [`HandleBasis::evaluate`] equals [`Deformer::solve`]
//! after [`Deformer::transform_group`] of each group with its `M_g` up to
//! the forward error of the solves (both refined; tests/handle.rs checks
//! `≤ 1e-9` relative to the bounding-box diagonal for every exact
//! formulation) — as long as the deformer is not changed otherwise: a new
//! precompute, refinement mode, or target outside the basis groups
//! ([`Deformer::set_target`]) needs a new basis. A non-affine edit or a
//! non-linear energy (ARAP) is not of this form: solve in full.

use std::time::Instant;

use faer::Mat;
use rayon::prelude::*;

use crate::deform::{Affine, Deformer};
use crate::error::{Error, ProblemError};
use crate::problem::RowPlace;

/// Vertices per parallel task of [`HandleBasis::evaluate`] (a few hundred
/// KiB of basis each: large enough that scheduling is negligible).
const EVALUATE_CHUNK: usize = 8192;

/// The affine response basis of some constraint groups of a [`Deformer`]:
/// `X₀` and `R_g` in the mesh's units, one row per vertex.
#[derive(Debug, Clone)]
pub struct HandleBasis {
    groups: Vec<String>,
    n: usize,
    /// Per vertex `[X₀ (3), R_1 (4), …, R_G (4)]`, stride `3 + 4G`: one
    /// stream read per frame.
    rows: Vec<f64>,
    build_time_s: f64,
}

impl HandleBasis {
    /// Computes `X₀` and `R_g` for the groups `names` (distinct, each with
    /// at least one constraint) with the deformer's factor (it must have
    /// been precomputed) and its refinement mode, around its current rest
    /// targets. Errors: unknown or repeated group, solve before
    /// precompute, non-finite solutions.
    pub fn new(deformer: &mut Deformer, names: &[&str]) -> Result<HandleBasis, Error> {
        let t = Instant::now();
        let mut members = Vec::with_capacity(names.len());
        for (k, name) in names.iter().enumerate() {
            if names[..k].contains(name) {
                return Err(ProblemError::BadUpdate {
                    message: format!("group '{name}' is named twice for the handle basis"),
                }
                .into());
            }
            members.push(deformer.group_members(name)?);
        }
        let (c, d) = basis_right_hand_sides(deformer, &members);
        let x = deformer.solve_columns(c.as_ref(), d.as_ref())?;
        let rows = interleave(&x, deformer.length_unit(), names.len());
        Ok(HandleBasis {
            groups: names.iter().map(|s| s.to_string()).collect(),
            n: x.nrows(),
            rows,
            build_time_s: t.elapsed().as_secs_f64(),
        })
    }

    /// The group names, in the order [`HandleBasis::evaluate`] takes their
    /// transforms.
    pub fn groups(&self) -> &[String] {
        &self.groups
    }

    /// The number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.n
    }

    /// The bytes of `X₀` and the `R_g`: what one evaluation reads.
    pub fn bytes(&self) -> usize {
        self.rows.len() * std::mem::size_of::<f64>()
    }

    /// Seconds [`HandleBasis::new`] took (the solves of its `3 + 4G`
    /// columns and their refinement).
    pub fn build_time_s(&self) -> f64 {
        self.build_time_s
    }

    /// `out = X₀ + Σ_g R_g M_gᵀ` (positions in the mesh's units) for the
    /// transforms `m[g]` of [`HandleBasis::groups`] (the identity leaves a
    /// group at its rest targets). Allocates nothing; parallel over
    /// vertices (rayon), as memory-bound as a read of the basis. Errors: wrong count of
    /// transforms or of output rows, a non-finite matrix entry.
    pub fn evaluate(&self, m: &[Affine], out: &mut [[f64; 3]]) -> Result<(), Error> {
        if m.len() != self.groups.len() || out.len() != self.n {
            return Err(ProblemError::Dimensions {
                message: format!(
                    "{} transforms and {} output rows given, the basis has {} groups and {} vertices",
                    m.len(),
                    out.len(),
                    self.groups.len(),
                    self.n
                ),
            }
            .into());
        }
        if let Some(g) = m
            .iter()
            .position(|t| t.iter().flatten().any(|v| !v.is_finite()))
        {
            return Err(ProblemError::BadUpdate {
                message: format!(
                    "transform of group '{}': the matrix has a non-finite entry",
                    self.groups[g]
                ),
            }
            .into());
        }
        let stride = 3 + 4 * m.len();
        self.rows
            .par_chunks(stride * EVALUATE_CHUNK)
            .zip(out.par_chunks_mut(EVALUATE_CHUNK))
            .for_each(|(rows, out)| {
                for (row, p) in rows.chunks_exact(stride).zip(out.iter_mut()) {
                    let mut x = [row[0], row[1], row[2]];
                    for (g, mg) in m.iter().enumerate() {
                        let r = &row[3 + 4 * g..7 + 4 * g];
                        for c in 0..3 {
                            x[c] += r[0] * mg[c][0]
                                + r[1] * mg[c][1]
                                + r[2] * mg[c][2]
                                + r[3] * mg[c][3];
                        }
                    }
                    *p = x;
                }
            });
        Ok(())
    }
}

/// The `3 + 4G` right-hand-side columns of the basis, in the problem's
/// units: `X₀`'s (the problem's `C` and `D` with the groups' rows zeroed),
/// then per group the columns of `[P_g / unit, t_g]` in its rows, zero
/// elsewhere.
fn basis_right_hand_sides(deformer: &Deformer, members: &[Vec<usize>]) -> (Mat<f64>, Mat<f64>) {
    let problem = deformer.problem();
    let unit = deformer.length_unit();
    let rest = deformer.rest_targets();
    let n_lap = problem.n_laplacian_rows();
    let soft = problem.soft_constraints();
    let k = 3 + 4 * members.len();
    let (l, m) = (problem.c().nrows(), problem.d().nrows());
    let mut c = Mat::<f64>::zeros(l, k);
    let mut d = Mat::<f64>::zeros(m, k);
    c.as_mut()
        .submatrix_mut(0, 0, l, 3)
        .copy_from(problem.c().as_ref());
    d.as_mut()
        .submatrix_mut(0, 0, m, 3)
        .copy_from(problem.d().as_ref());
    for (g, group) in members.iter().enumerate() {
        for &i in group {
            let translate = deformer.constraints()[i].kind.pins_translation();
            let u = rest[i];
            let column = [u[0] / unit, u[1] / unit, u[2] / unit, f64::from(translate)];
            // A group member has a row (a hard row of D or a soft row of C).
            let Some(place) = problem.place(i) else {
                continue;
            };
            let (target, row, scale) = match place {
                RowPlace::Hard(r) => (&mut d, r, 1.0),
                RowPlace::Soft(r) => (&mut c, n_lap + r, soft[r].1),
            };
            for j in 0..3 {
                target[(row, j)] = 0.0;
            }
            for j in 0..4 {
                target[(row, 3 + 4 * g + j)] = scale * column[j];
            }
        }
    }
    (c, d)
}

/// Per vertex `[X₀, R_1, …]` in the mesh's units from the solved columns
/// (problem units): positions and the responses to the linear part scale
/// by `unit`; the response to the translation column is already a length
/// per length.
fn interleave(x: &Mat<f64>, unit: f64, n_groups: usize) -> Vec<f64> {
    let stride = 3 + 4 * n_groups;
    let mut rows = vec![0.0; x.nrows() * stride];
    for (v, row) in rows.chunks_exact_mut(stride).enumerate() {
        for j in 0..stride {
            let translation_column = j >= 3 && (j - 3) % 4 == 3;
            let scale = if translation_column { 1.0 } else { unit };
            row[j] = x[(v, j)] * scale;
        }
    }
    rows
}
