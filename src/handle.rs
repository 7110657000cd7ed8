//! Affine handles: the deformed positions as an affine function of the
//! transforms of the constraint groups, precomputed once per constraint
//! configuration and evaluated per frame without a solve (docs/handles.md §1;
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
//! columns are solved with the existing factor in one pass when the
//! formulation allows (the null-space method; else three at a time) and
//! refined ([`solve_basis`]: until a correction is at most
//! [`BASIS_FORWARD_ERROR`]). Per frame: `n × (3 + 12G)` multiply-adds
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

use std::collections::HashSet;
use std::time::Instant;

use faer::{Mat, MatRef};
use rayon::prelude::*;

use crate::cpu::clear_upper_vector_state;
use crate::deform::{Affine, Deformer};
use crate::error::{Error, ProblemError};
use crate::formulation::Refine;
use crate::limits::MemoryBudget;
use crate::problem::{RowPlace, zero_matrix};

/// What the right-hand sides of the response basis are called in a refusal.
const RESPONSE_BASIS: &str = "the response basis' right-hand sides";
use crate::resources::Resources;

/// Vertices per parallel task of [`HandleBasis::evaluate`] (a few hundred
/// KiB of basis each: large enough that scheduling is negligible).
const EVALUATE_CHUNK: usize = 8192;

/// Vertices per storage block: the basis holds, per block of `LANES`
/// vertices, each of its `3 + 4G` columns as `LANES` consecutive numbers,
/// so that the per-frame arithmetic runs across vertices in SIMD lanes (a
/// row-per-vertex layout puts the 12 products of one vertex in one scalar
/// chain). A multiple of every vector width up to 512 bits.
const LANES: usize = 8;

/// The affine response basis of some constraint groups of a [`Deformer`]:
/// `X₀` and `R_g` in the mesh's units.
#[derive(Debug, Clone)]
pub struct HandleBasis {
    groups: Vec<String>,
    n: usize,
    /// Blocks of [`LANES`] vertices (the last padded with zeros), each
    /// `[X₀ x, X₀ y, X₀ z, R_1 col 0..4, …, R_G col 0..4]` with `LANES`
    /// numbers per column: one stream read per frame.
    blocks: Vec<f64>,
    build_time_s: f64,
    forward_error_estimate: f64,
}

impl HandleBasis {
    /// Computes `X₀` and `R_g` for the groups `names` (distinct, each with
    /// at least one constraint) with the deformer's factor (it must have
    /// been precomputed) and its refinement mode, around its current rest
    /// targets. Errors: unknown or repeated group, solve before
    /// precompute, non-finite solutions.
    ///
    /// The memory it needs ([`HandleBasis::estimated_bytes`]: `3 + 4G`
    /// columns of the problem's height, several times over while they are
    /// solved and refined) is checked against the memory budget of the
    /// precompute it is built on (the report's `memory_budget`) before
    /// anything is allocated: beyond it, a [`ProblemError::TooLarge`] with
    /// the estimate.
    pub fn new(deformer: &mut Deformer, names: &[&str]) -> Result<HandleBasis, Error> {
        let budget = deformer.report().memory_budget.unwrap_or_default();
        HandleBasis::with_resources(deformer, names, &Resources::with_budget(budget))
    }

    /// [`HandleBasis::new`] within the budget of `resources` instead of
    /// the precompute's.
    pub fn with_resources(
        deformer: &mut Deformer,
        names: &[&str],
        resources: &Resources,
    ) -> Result<HandleBasis, Error> {
        let t = Instant::now();
        let mut seen = HashSet::with_capacity(names.len());
        for name in names {
            if !seen.insert(*name) {
                return Err(ProblemError::BadUpdate {
                    message: format!("group '{name}' is named twice for the handle basis"),
                }
                .into());
            }
        }
        let problem = deformer.problem();
        let (n, l, m) = (problem.n(), problem.c().nrows(), problem.d().nrows());
        HandleBasis::check_memory(n, l, m, names.len(), resources.budget)?;
        let mut members = Vec::with_capacity(names.len());
        for name in names {
            members.push(deformer.group_members(name)?);
        }
        crate::interrupt::check()?;
        let (c, d) = basis_right_hand_sides(deformer, &members)?;
        let (x, forward_error_estimate) = solve_basis(deformer, c.as_ref(), d.as_ref())?;
        drop((c, d));
        crate::interrupt::check()?;
        let blocks = into_blocks(&x, deformer.length_unit(), names.len())?;
        Ok(HandleBasis {
            groups: names.iter().map(|s| s.to_string()).collect(),
            n: x.nrows(),
            blocks,
            build_time_s: t.elapsed().as_secs_f64(),
            forward_error_estimate,
        })
    }

    /// The peak bytes [`HandleBasis::new`] is estimated to need for
    /// `groups` groups on a problem of `n` unknowns (vertices), `l` rows of
    /// `A` and `m` of `B`: its `k = 3 + 4 groups` right-hand-side columns
    /// (`l + m` numbers each, held twice: as built and as the solve's
    /// copy), the solution, the solve's workspace and the refinement's
    /// residual and correction (about six columns of `n` numbers and one of
    /// `l`, per column), and the stored basis (`n` numbers per column):
    /// `8 k (3 (l + m) + 6 n)` bytes. An upper estimate: the editor's peak
    /// on a 2,025-vertex grid was 0.93, 0.88 and 0.67 of it for 100, 256
    /// and 3,000 groups.
    pub(crate) fn estimated_bytes(n: usize, l: usize, m: usize, groups: usize) -> u64 {
        let k = 3 + 4 * groups as u64;
        let per_column = 3 * (l as u64 + m as u64) + 6 * n as u64;
        k.saturating_mul(per_column).saturating_mul(8)
    }

    /// [`HandleBasis::estimated_bytes`] on top of what the process holds
    /// against the memory `budget` ([`crate::limits`], as the
    /// factorisations count it): [`ProblemError::TooLarge`] with the
    /// estimate when it exceeds it (what [`HandleBasis::new`] checks
    /// first; a caller can check before its precompute).
    pub(crate) fn check_memory(
        n: usize,
        l: usize,
        m: usize,
        groups: usize,
        budget: MemoryBudget,
    ) -> Result<(), Error> {
        let k = 3 + 4 * groups as u64;
        budget.check_on_top(HandleBasis::estimated_bytes(n, l, m, groups), || {
            format!(
                "the response basis of {groups} group(s) on {n} vertices ({k} solved columns of {n} numbers, with the solve's workspace) would need"
            )
        })
        .map_err(|detail| ProblemError::TooLarge { detail }.into())
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

    /// The bytes of `X₀` and the `R_g` (with the last block's padding):
    /// what one evaluation reads.
    pub fn bytes(&self) -> usize {
        self.blocks.len() * std::mem::size_of::<f64>()
    }

    /// Seconds [`HandleBasis::new`] took (the solves of its `3 + 4G`
    /// columns and their refinement).
    pub fn build_time_s(&self) -> f64 {
        self.build_time_s
    }

    /// The forward-error estimate of the basis columns, relative to the
    /// length scale (see [`BASIS_FORWARD_ERROR`]).
    pub fn forward_error_estimate(&self) -> f64 {
        self.forward_error_estimate
    }

    /// One stored number, in the mesh's units: column `j` of vertex `v`,
    /// where columns `0..3` are `X₀`'s coordinates and `3 + 4g + k` is
    /// column `k` of `R_g` (`k = 3`: the response to the translation).
    /// What a client that evaluates the basis itself (the editor's page)
    /// is sent. Panics when `v` or `j` is out of range.
    pub fn entry(&self, v: usize, j: usize) -> f64 {
        let columns = 3 + 4 * self.groups.len();
        assert!(
            v < self.n && j < columns,
            "entry ({v}, {j}) of a basis of {} × {columns}",
            self.n
        );
        self.blocks[(v / LANES) * columns * LANES + j * LANES + v % LANES]
    }

    /// `out = X₀ + Σ_g R_g M_gᵀ` (positions in the mesh's units) for the
    /// transforms `m[g]` of [`HandleBasis::groups`] (the identity leaves a
    /// group at its rest targets). Allocates nothing; parallel over
    /// vertices (rayon), as memory-bound as a read of the basis. Errors:
    /// wrong count of transforms or of output rows, a non-finite matrix
    /// entry.
    pub fn evaluate(&self, m: &[Affine], out: &mut [[f64; 3]]) -> Result<(), Error> {
        self.evaluate_with(m, out, |x| x)
    }

    /// [`HandleBasis::evaluate`] rounded to `f32` as it is written: the
    /// format a renderer uploads (the editor's `GET /api/positions`
    /// default), without an `f64` copy of the positions in between. The
    /// arithmetic is the same `f64` as `evaluate`'s; only the store rounds
    /// (relative error ≤ 2⁻²⁴ of each coordinate).
    pub fn evaluate_f32(&self, m: &[Affine], out: &mut [[f32; 3]]) -> Result<(), Error> {
        self.evaluate_with(m, out, |x| x.map(|v| v as f32))
    }

    fn evaluate_with<T: Send>(
        &self,
        m: &[Affine],
        out: &mut [T],
        store: impl Fn([f64; 3]) -> T + Sync,
    ) -> Result<(), Error> {
        self.check_transforms(m, out.len())?;
        let stride = (3 + 4 * m.len()) * LANES;
        self.blocks
            .par_chunks(stride * (EVALUATE_CHUNK / LANES))
            .zip(out.par_chunks_mut(EVALUATE_CHUNK))
            .for_each_init(clear_upper_vector_state, |(), (blocks, out)| {
                for (block, out) in blocks.chunks_exact(stride).zip(out.chunks_mut(LANES)) {
                    let x = evaluate_block(block, m);
                    for (lane, p) in out.iter_mut().enumerate() {
                        *p = store([x[0][lane], x[1][lane], x[2][lane]]);
                    }
                }
            });
        Ok(())
    }

    fn check_transforms(&self, m: &[Affine], out_rows: usize) -> Result<(), Error> {
        if m.len() != self.groups.len() || out_rows != self.n {
            return Err(ProblemError::Dimensions {
                message: format!(
                    "{} transforms and {out_rows} output rows given, the basis has {} groups and {} vertices",
                    m.len(),
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
        Ok(())
    }
}

/// `X₀ + Σ_g R_g M_gᵀ` for the [`LANES`] vertices of one block, coordinate
/// by coordinate across the lanes (the loops over lanes vectorise).
#[inline]
fn evaluate_block(block: &[f64], m: &[Affine]) -> [[f64; LANES]; 3] {
    let column = |j: usize| -> &[f64; LANES] {
        block[j * LANES..(j + 1) * LANES]
            .try_into()
            .expect("a block holds whole columns")
    };
    let mut x = [*column(0), *column(1), *column(2)];
    for (g, mg) in m.iter().enumerate() {
        let r = [
            column(3 + 4 * g),
            column(4 + 4 * g),
            column(5 + 4 * g),
            column(6 + 4 * g),
        ];
        for (xc, mc) in x.iter_mut().zip(mg) {
            for lane in 0..LANES {
                xc[lane] += r[0][lane] * mc[0]
                    + r[1][lane] * mc[1]
                    + r[2][lane] * mc[2]
                    + r[3][lane] * mc[3];
            }
        }
    }
    x
}

/// With [`Refine::Auto`], the basis columns are refined until a correction
/// is at most this (relative to the length scale): the `1e-9` agreement
/// with a full solve that [`HandleBasis::evaluate`] promises. The error
/// left after that correction is at most `ρ/(1 − ρ)` of it when the
/// refinement contracts the error by `ρ` per step
/// ([`crate::formulation::iterative_refinement`]): within the promise for any `ρ ≤ ½`,
/// and under a ninth of it for `ρ ≤ 0.1` — while a first correction this
/// small means the solve itself was accurate to about that, and `ρ`, the
/// same solve's error applied to the residual, is of the same order. The
/// reported estimate is that last correction (the error before it), not
/// the smaller error after it.
pub const BASIS_FORWARD_ERROR: f64 = 1e-9;

/// The `3 + 4G` columns in one solve. With the deformer's refinement mode
/// [`Refine::Auto`]: refined until a correction is at most
/// [`BASIS_FORWARD_ERROR`] ([`Refine::Until`]; on the Stanford bunny's
/// scene one step, whose correction is `1.1e-10`, where `Auto` would take
/// a second only to see it at the rounding floor). Other modes are used as
/// they are.
fn solve_basis(
    deformer: &mut Deformer,
    c: MatRef<'_, f64>,
    d: MatRef<'_, f64>,
) -> Result<(Mat<f64>, f64), Error> {
    let mode = match deformer.solver().refine_mode() {
        Refine::Auto => Refine::Until(BASIS_FORWARD_ERROR),
        mode => mode,
    };
    deformer.solver_mut().solve_columns(c, d, mode)
}

/// The `3 + 4G` right-hand-side columns of the basis, in the problem's
/// units: `X₀`'s (the problem's `C` and `D` with the groups' rows zeroed),
/// then per group the columns of `[P_g / unit, t_g]` in its rows, zero
/// elsewhere.
fn basis_right_hand_sides(
    deformer: &Deformer,
    members: &[Vec<usize>],
) -> Result<(Mat<f64>, Mat<f64>), Error> {
    let problem = deformer.problem();
    let unit = deformer.length_unit();
    let rest = deformer.rest_targets();
    let n_lap = problem.n_laplacian_rows();
    let soft = problem.soft_constraints();
    let k = 3 + 4 * members.len();
    let (l, m) = (problem.c().nrows(), problem.d().nrows());
    let mut c = zero_matrix(RESPONSE_BASIS, l, k)?;
    let mut d = zero_matrix(RESPONSE_BASIS, m, k)?;
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
                RowPlace::Soft(r) => (&mut c, n_lap + r, soft[r].row_weight),
            };
            for j in 0..3 {
                target[(row, j)] = 0.0;
            }
            for j in 0..4 {
                target[(row, 3 + 4 * g + j)] = scale * column[j];
            }
        }
    }
    Ok((c, d))
}

fn allocation_failed(r: usize, c: usize) -> Error {
    ProblemError::TooLarge {
        detail: format!(
            "the response basis: allocating {r} × {c} numbers ({}) failed",
            crate::limits::format_bytes((r as u64).saturating_mul(c as u64).saturating_mul(8))
        ),
    }
    .into()
}

/// The blocks of [`HandleBasis`] in the mesh's units from the solved
/// columns (problem units): positions and the responses to the linear part
/// scale by `unit`; the response to the translation column is already a
/// length per length.
fn into_blocks(x: &Mat<f64>, unit: f64, n_groups: usize) -> Result<Vec<f64>, Error> {
    let columns = 3 + 4 * n_groups;
    let n_blocks = x.nrows().div_ceil(LANES);
    let len = n_blocks * columns * LANES;
    let mut blocks = Vec::new();
    blocks
        .try_reserve_exact(len)
        .map_err(|_| allocation_failed(n_blocks * LANES, columns))?;
    blocks.resize(len, 0.0);
    for (b, block) in blocks.chunks_exact_mut(columns * LANES).enumerate() {
        for j in 0..columns {
            let translation_column = j >= 3 && (j - 3) % 4 == 3;
            let scale = if translation_column { 1.0 } else { unit };
            for lane in 0..LANES {
                let v = b * LANES + lane;
                if v < x.nrows() {
                    block[j * LANES + lane] = x[(v, j)] * scale;
                }
            }
        }
    }
    Ok(blocks)
}
