//! Lagrange multipliers: the KKT system of `min ‖AX − C‖ s.t. BX = D`,
//!
//! ```text
//! [AᵀA  sBᵀ] [X ]   [AᵀC]
//! [sB    0 ] [Λ'] = [sD ]        (Λ = sΛ' are the multipliers)
//! ```
//!
//! factored by an `LDLᵀ` back end ([`crate::backend::ldlt`]: faer's sparse
//! `LDLᵀ`) **without numerical pivoting**, in a
//! static order designed so that every pivot exists ([`kkt_ordering`]).
//!
//! **Scaling `s`.** For cotangent weights the entries of `AᵀA` are of order
//! `1/h⁴` while those of `B` are of order 1. The multiplier rows and columns
//! are scaled by `s = 2^round(log₂ max_j (AᵀA)_jj)`, which brings the
//! constraint block to the magnitude of the largest entries of `AᵀA`: the
//! normwise residual check then weighs constraint rows like vertex rows, and
//! the condition estimate measures the problem rather than the unit
//! mismatch. `s` is a power of two, so the scaling is exact; and `LDLᵀ`
//! without pivoting commutes exactly with a power-of-two diagonal scaling
//! (`L ↦ SLS⁻¹`, `D ↦ SDS`), so `s` changes neither the computed solution nor
//! which pivot is flagged. [`Prepared::factored_matrix`] returns the scaled
//! matrix; `s` is in [`Report::kkt_multiplier_scale`](crate::report::Report::kkt_multiplier_scale).
//!
//! **Pivots and singularity.** With the order of [`kkt_ordering`] every
//! leading block is nonsingular when the kept constraints are independent
//! and pin the mesh, so its inertia forces the signs: vertex pivots `> 0`,
//! multiplier pivots `< 0`. The pivot of unknown `j` is computed as
//! `d_j = K_jj − Σ_{k<j} L_jk² d_k`; it is declared zero when
//! `|d_j| ≤ τ (|K_jj| + Σ_{k<j} L_jk² |d_k|)` with `τ =`
//! [`KKT_PIVOT_TOLERANCE`], or when it has the wrong sign. A failing
//! multiplier pivot means its constraint depends on the constraints
//! eliminated before it (duplicates: the later in the list); the error is
//! [`NumericalError::Singular`] naming that constraint. The exception is a
//! multiplier pivot that is positive and above the tolerance: that is no
//! vanishing pivot but a leading vertex block that lost its definiteness in
//! floating point (vertex pivots that passed with few digits left, on
//! sliver meshes), and the error says so instead of blaming the
//! constraint. faer's `LDLᵀ` only stops at a pivot that is exactly zero,
//! and rounding rarely leaves one, so this check is what turns a singular
//! `K` into an error instead of inf/NaN.
//!
//! **Why `LDLᵀ` in a designed order rather than faer's intranode
//! Bunch–Kaufman `LBLᵀ`.** The intranode factorisation pivots only inside a
//! supernode, so it cannot rescue a zero pivot whose partner lies in another
//! supernode (the common case here: a multiplier and its vertices are rarely
//! in one supernode), and on a simplicial analysis faer's
//! `factorize_numeric_intranode_lblt` silently runs `LDLᵀ` and discards its
//! error. Its 2×2 blocks would also blur which constraint is dependent. A
//! static order in which every pivot provably exists keeps the
//! factorisation deterministic and makes a failing pivot a diagnosis.
//!
//! **Verification and refinement.** Every solve computes the normwise
//! backward error `η = ‖K y − b‖∞ / (‖K‖∞ ‖y‖∞ + ‖b‖∞)` and fails with
//! [`NumericalError::InaccurateSolution`] if it exceeds
//! [`KKT_BACKWARD_ERROR_TOLERANCE`] (a factor with runaway growth).
//! Refinement (the `refine` phase, [`super::refine`]) works on the augmented
//! system with the residual taken from `A` and `B` themselves:
//! `K [Δx; Δμ] = [Aᵀ(C − A x) − s Bᵀ μ; s (D − B x)]`.

use std::sync::Arc;
use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::amd;
use faer::sparse::{SparseColMat, SparseRowMat, SymbolicSparseColMat, Triplet};
use faer::{Mat, MatMut};

use super::record::{PrecomputeRecord, Precomputed};
use super::util::{RowKind, split_normal};
use super::{Formulation, Prepared};
use crate::backend::FactorKind;
use crate::backend::ldlt::{FaerLdlt, LdltBackend, LdltKind, PivotFault, PivotRule};
use crate::backend::ordering::FactorPlan;
use crate::backend::qr::{QrBackend, RankTolerance, SparseGivens};
use crate::backend::spd::SpdKind;
use crate::condition::{self, ConditionEstimate, InverseOperator, LowerSymmetricOperator};
use crate::error::{Error, NumericalError, ProblemError};
use crate::mesh::topology::UnionFind;
use crate::problem::{LseProblem, pivot_columns};
use crate::report::{MethodFacts, first_non_finite};
use crate::resources::{FillOrdering, Resources, Threads};
use crate::sparse::{
    add_bt_times, at_residual, at_times, hard_residual_compensated, lower_diag, lower_sym_mul,
    lower_sym_norm_inf, lower_to_full, row_entries,
};

/// Singularity tolerance `τ` of a KKT pivot relative to the magnitude it
/// was computed from: `|d_j| ≤ τ (|K_jj| + Σ_k L_jk² |d_k|)` declares `d_j`
/// zero.
///
/// `τ = 1000 ε ≈ 2.2e-13`, the same as the SPD back ends'
/// [`crate::backend::spd::BREAKDOWN_RATIO`] and for the same reason: the
/// rounding error of `d_j` is a small multiple of `ε` times that magnitude,
/// so a pivot below `1000 ε` of it has at most three significant digits left
/// and is indistinguishable from zero. For a multiplier the ratio is the
/// squared sine of the angle (in the `(AᵀA)⁻¹` metric) between its
/// constraint row and the rows eliminated before it, so KKT flags rows whose
/// new information is below `√τ ≈ 5e-7`, where the null-space QR (which
/// works with the rows, not their squares) resolves down to its rank
/// tolerance `1e-10`: KKT cannot tell near-dependence apart more finely.
pub const KKT_PIVOT_TOLERANCE: f64 = 1000.0 * f64::EPSILON;

/// Largest accepted normwise backward error of a KKT solve,
/// `η = ‖K y − b‖∞ / (‖K‖∞ ‖y‖∞ + ‖b‖∞)`, after iterative refinement.
///
/// `1e-10`: a backward-stable solve gives `η` of order `ε` times the growth
/// of the static-pivot factorisation; `1e-10` allows a growth of about 10⁵
/// while still guaranteeing that `y` exactly solves a system within 1e-10
/// relative of `K`. Because the multiplier rows are scaled to the magnitude
/// of `‖AᵀA‖`, this bounds the hard-constraint residuals by about
/// `1e-10 ‖X‖∞`, the accuracy the null-space method is tested to.
pub const KKT_BACKWARD_ERROR_TOLERANCE: f64 = 1e-10;

/// The KKT / Lagrange-multiplier formulation, factored by an `LDLᵀ` back
/// end ([`crate::backend::ldlt`]) in a static order.
#[derive(Clone)]
pub struct Kkt {
    /// The `LDLᵀ` back end: one of the catalogue's ([`LdltKind::backend`]:
    /// faer's simplicial, supernodal or its choice; MUMPS's) or one brought
    /// from outside.
    pub ldlt: Arc<dyn LdltBackend>,
}

impl Default for Kkt {
    /// faer's `LDLᵀ`, simplicial or supernodal by its own choice.
    fn default() -> Kkt {
        Kkt::with_backend(Arc::new(FaerLdlt::new(LdltKind::FaerAuto)))
    }
}

impl std::fmt::Debug for Kkt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Kkt")
            .field("ldlt", &self.ldlt.name())
            .finish()
    }
}

impl Kkt {
    /// The KKT formulation over `ldlt`.
    pub fn with_backend(ldlt: Arc<dyn LdltBackend>) -> Kkt {
        Kkt { ldlt }
    }

    /// The KKT formulation in the `LDLᵀ` variant an SPD kind selects
    /// ([`LdltKind::for_spd`]): `FaerAuto`, `FaerSimplicial`,
    /// `FaerSupernodal` or `Mumps` (in a build with it); `None` for the
    /// other kinds, which have no `LDLᵀ`.
    pub(crate) fn for_spd(spd: SpdKind) -> Option<Kkt> {
        let backend = LdltKind::for_spd(spd)?.backend().ok()?;
        Some(Kkt::with_backend(backend))
    }

    /// Always simplicial (column by column).
    pub fn simplicial() -> Kkt {
        Kkt::with_backend(Arc::new(FaerLdlt::new(LdltKind::FaerSimplicial)))
    }

    /// Always supernodal (dense `LDLᵀ` on blocks of columns).
    pub fn supernodal() -> Kkt {
        Kkt::with_backend(Arc::new(FaerLdlt::new(LdltKind::FaerSupernodal)))
    }
}

const MATRIX: &str = "the KKT matrix [AᵀA sBᵀ; sB 0]";

/// The name of faer's AMD ordering in the errors of the KKT order.
const AMD: &str = "faer-amd";

/// The static elimination order of the KKT unknowns: entry `i` is the
/// unknown eliminated `i`-th, with vertices numbered `0..n` and the
/// multiplier of hard row `k` numbered `n + k`.
///
/// 1. **Vertices** in the approximate-minimum-degree order of the graph of
///    `AᵀA + BᵀB` (the vertex graph with every constraint's vertices
///    coupled, which is the fill its multiplier will cause).
/// 2. **Multipliers** right after the last of their vertices, ties in list
///    order. A multiplier eliminated before all its vertices meets a zero
///    (or rank-deficient) leading block: its row restricted to the
///    eliminated vertices may vanish or depend on others' restrictions even
///    when the full rows are independent. After its last vertex, its full
///    row is in the leading block, so the block is nonsingular exactly when
///    the rows placed so far are independent.
/// 3. **Deferred vertices.** `AᵀA` is singular when a mesh component is not
///    pinned by soft rows (`L` annihilates the component's translations).
///    A leading block holding a whole such component would then need its
///    pinning multiplier already placed; to guarantee it, one vertex per
///    component whose translation the soft rows leave free is moved to the
///    end — preferably one that no hard row touches, so that every pinning
///    multiplier comes before it. Before the tail, every leading vertex
///    block is then positive definite; in the tail, the translations are
///    pinned by the hard rows already placed (the condition
///    [`crate::problem::check_pinned`] checks for the whole problem).
///
/// Under these rules every leading block is nonsingular iff the hard rows
/// are independent, so a failing pivot names a dependent constraint. The
/// one case the rule cannot cover — every vertex of a component is touched
/// by hard rows and those not touching the deferred vertex do not pin it —
/// shows up as a failing *vertex* pivot, reported as such.
pub fn kkt_ordering(problem: &LseProblem) -> Result<Vec<usize>, Error> {
    let (pattern, _, _) = split_normal(problem);
    ordering_from_pattern(problem, &pattern, None)
}

/// The static elimination order ([`kkt_ordering`]) with the vertices in
/// `vertex_order` (a permutation of `0..n`) instead of AMD's when given.
fn ordering_from_pattern(
    problem: &LseProblem,
    pattern: &SymbolicSparseColMat<usize>,
    vertex_order: Option<&[usize]>,
) -> Result<Vec<usize>, Error> {
    let n = problem.n();
    let b = problem.b().as_ref();
    let m = b.nrows();

    // 1. AMD on the vertex graph (or the order given).
    let amd_fwd = match vertex_order {
        Some(order) => order.to_vec(),
        None => vertex_amd(pattern)?,
    };

    // 3. Components free under the soft rows, and their deferred vertices.
    let mut in_hard = vec![false; n];
    for k in 0..m {
        for &v in row_entries(b, k).0 {
            in_hard[v] = true;
        }
    }
    let (component_of, n_components) = laplacian_components(problem);
    let free = soft_free_components(problem, &component_of, n_components);
    // Latest vertex in AMD order per free component: untouched by hard rows
    // if possible, else any.
    let mut best_untouched: Vec<Option<usize>> = vec![None; n_components];
    let mut best_any: Vec<Option<usize>> = vec![None; n_components];
    for &v in &amd_fwd {
        let c = component_of[v];
        if free[c] {
            best_any[c] = Some(v);
            if !in_hard[v] {
                best_untouched[c] = Some(v);
            }
        }
    }
    let mut deferred = vec![false; n];
    for c in 0..n_components {
        if let Some(v) = best_untouched[c].or(best_any[c]) {
            deferred[v] = true;
        }
    }
    let vertex_order: Vec<usize> = amd_fwd
        .iter()
        .copied()
        .filter(|&v| !deferred[v])
        .chain(amd_fwd.iter().copied().filter(|&v| deferred[v]))
        .collect();
    let mut pos = vec![0usize; n];
    for (p, &v) in vertex_order.iter().enumerate() {
        pos[v] = p;
    }

    // 2. Multipliers after their last vertex, in list order on ties.
    let mut after: Vec<Vec<usize>> = vec![Vec::new(); n];
    for k in 0..m {
        let last = row_entries(b, k)
            .0
            .iter()
            .map(|&v| pos[v])
            .max()
            .unwrap_or(n.saturating_sub(1));
        after[last].push(k);
    }
    let mut order = Vec::with_capacity(n + m);
    for (p, &v) in vertex_order.iter().enumerate() {
        order.push(v);
        order.extend(after[p].iter().map(|&k| n + k));
    }
    Ok(order)
}

/// Connected components of the graph of the Laplacian rows of `A` (vertices
/// sharing a row are connected): the components whose translations `L`
/// annihilates.
fn laplacian_components(problem: &LseProblem) -> (Vec<usize>, usize) {
    let n = problem.n();
    let n_lap = problem.n_laplacian_rows();
    let a = problem.a();
    let (ptr, rows) = (a.symbolic().col_ptr(), a.symbolic().row_idx());
    let mut sets = UnionFind::new(n);
    let mut anchor = vec![usize::MAX; n_lap];
    for j in 0..n {
        for &r in &rows[ptr[j]..ptr[j + 1]] {
            if r < n_lap {
                if anchor[r] == usize::MAX {
                    anchor[r] = j;
                } else {
                    sets.union(anchor[r], j);
                }
            }
        }
    }
    sets.components()
}

/// For each component, whether its translation is left free by the soft
/// rows: `null(A)` is spanned by `Σ_c t_c 1_c` with `S t = 0`, `S` the
/// coefficient sums of the soft rows per component. Gaussian elimination
/// with partial pivoting on the columns of `S`; a column without a pivot
/// (entries `≤ 1e-12` × the row's coefficient norm count as zero, as in
/// [`crate::problem::check_pinned`]) is free, and the pivot columns have
/// full rank, so fixing the free components pins all the others.
fn soft_free_components(
    problem: &LseProblem,
    component_of: &[usize],
    n_components: usize,
) -> Vec<bool> {
    let n_lap = problem.n_laplacian_rows();
    let a = problem.a();
    let n_soft = a.nrows() - n_lap;
    let mut free = vec![true; n_components];
    if n_soft == 0 {
        return free;
    }
    let (ptr, rows, val) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
    // Sums per soft row and component, over the components soft rows touch.
    let mut touched: Vec<usize> = Vec::new();
    let mut column_of = vec![usize::MAX; n_components];
    let mut sums: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n_soft];
    let mut norms = vec![0.0f64; n_soft];
    for j in 0..a.ncols() {
        for p in ptr[j]..ptr[j + 1] {
            if rows[p] >= n_lap {
                let r = rows[p] - n_lap;
                let c = component_of[j];
                if column_of[c] == usize::MAX {
                    column_of[c] = touched.len();
                    touched.push(c);
                }
                norms[r] += val[p] * val[p];
                match sums[r].iter_mut().find(|e| e.0 == c) {
                    Some(e) => e.1 += val[p],
                    None => sums[r].push((c, val[p])),
                }
            }
        }
    }
    let cols = touched.len();
    let mut dense: Vec<Vec<f64>> = sums
        .iter()
        .zip(&norms)
        .map(|(row, &nrm)| {
            let tol = 1e-12 * nrm.sqrt();
            let mut d = vec![0.0; cols];
            for &(c, s) in row {
                if s.abs() > tol {
                    d[column_of[c]] = s;
                }
            }
            d
        })
        .collect();
    for (col, has_pivot) in pivot_columns(&mut dense, cols).into_iter().enumerate() {
        if has_pivot {
            free[touched[col]] = false;
        }
    }
    free
}

/// faer's AMD on the vertex graph `pattern` (`fwd[i]` eliminated `i`-th).
fn vertex_amd(pattern: &SymbolicSparseColMat<usize>) -> Result<Vec<usize>, Error> {
    let n = pattern.ncols();
    let mut amd_fwd = vec![0usize; n];
    let mut amd_inv = vec![0usize; n];
    let nnz = pattern.row_idx().len();
    let mut mem = MemBuffer::try_new(amd::order_scratch::<usize>(n, nnz))
        .map_err(|_| NumericalError::out_of_memory(AMD, "the ordering's workspace"))?;
    amd::order(
        &mut amd_fwd,
        &mut amd_inv,
        pattern.as_ref(),
        amd::Control::default(),
        MemStack::new(&mut mem),
    )
    .map_err(|e| NumericalError::from_faer(AMD, "the KKT vertices' ordering", e))?;
    Ok(amd_fwd)
}

/// The KKT order under `resources`: the vertices in AMD's order (own) or
/// in the one the resources hold, each multiplier after its last vertex;
/// with the report's word for it and the seconds computing a held one.
fn held_kkt_ordering(
    problem: &LseProblem,
    pattern: &SymbolicSparseColMat<usize>,
    resources: &Resources,
) -> Result<(Vec<usize>, String, f64), Error> {
    if resources.ordering == FillOrdering::Own {
        let order = ordering_from_pattern(problem, pattern, None)?;
        return Ok((order, "own (kkt)".into(), 0.0));
    }
    let t = Instant::now();
    let plan = FactorPlan::new(
        &resources.ordering,
        resources.threads,
        pattern.as_ref(),
        &|k| k,
        problem.n(),
    )?;
    let ordering_s = t.elapsed().as_secs_f64();
    let order = ordering_from_pattern(problem, pattern, plan.permutation.as_deref())?;
    Ok((order, format!("{} (kkt)", plan.ordering), ordering_s))
}

impl Formulation for Kkt {
    fn method(&self) -> super::Method {
        super::Method::Kkt
    }

    fn precompute_with(
        &self,
        problem: &LseProblem,
        resources: &Resources,
    ) -> Result<Precomputed, Error> {
        let n = problem.n();
        let m = problem.b().nrows();

        // Normal pattern and values, the scale, and K (lower, original order).
        let t = Instant::now();
        let (pattern, ata, _) = split_normal(problem);
        let ata_lower = SparseColMat::new(pattern.clone(), ata);
        let max_diag = (0..n)
            .map(|j| lower_diag(ata_lower.as_ref(), j))
            .fold(0.0f64, f64::max);
        let scale = if max_diag > 0.0 && max_diag.is_finite() {
            2f64.powi(max_diag.log2().round() as i32)
        } else {
            1.0
        };
        let mut record = PrecomputeRecord::new(
            self.method(),
            FactorKind::Ldlt(self.ldlt.name()),
            MethodFacts::Kkt {
                multiplier_scale: scale,
            },
        );
        record.rank = Some(m);
        let k_lower = assemble_kkt(&ata_lower, problem, scale);
        record.timings.normal_matrix = t.elapsed().as_secs_f64();
        record.sizes.normal = Some(2 * k_lower.val().len() - (n + m));

        crate::interrupt::check()?;
        let t = Instant::now();
        let (order, ordering, ordering_s) = held_kkt_ordering(problem, &pattern, resources)?;
        record.timings.preparation = t.elapsed().as_secs_f64() - ordering_s;
        record.timings.ordering = ordering_s;
        record.ordering = Some(ordering.into());

        crate::interrupt::check()?;
        let t = Instant::now();
        let matrix = "the KKT matrix [AᵀA Bᵀ; B 0]";
        self.ldlt
            .check_order_budget(k_lower.symbolic(), &order, resources.budget, matrix)?;
        let symbolic = match resources.threads {
            Threads::Own => self.ldlt.analyze(k_lower.symbolic(), &order)?,
            threads => self
                .ldlt
                .analyze_on_threads(k_lower.symbolic(), &order, threads)?,
        };
        record.timings.symbolic = t.elapsed().as_secs_f64();
        record.threads = symbolic.threads_used();
        symbolic.check_budget(resources.budget, n + m, matrix)?;

        crate::interrupt::check()?;
        let t = Instant::now();
        let factor = symbolic.factorize(k_lower.as_ref())?;
        crate::interrupt::check()?;
        let rule = PivotRule {
            positive: n,
            tolerance: KKT_PIVOT_TOLERANCE,
        };
        if let Some(fault) = factor.pivot_fault(k_lower.as_ref(), rule) {
            return Err(pivot_error(fault, &order, problem)?.into());
        }
        record.timings.numeric = t.elapsed().as_secs_f64();
        record.sizes.factor = Some(factor.nnz());
        record.sizes.factor_bytes = Some(factor.bytes());
        record.backend_facts = factor.facts();

        let norm = lower_sym_norm_inf(k_lower.as_ref());
        let system = Box::new(PreparedKkt {
            factor,
            k_lower,
            norm,
            scale,
            n,
            multipliers: Mat::zeros(m, problem.c().ncols()),
            pending_multipliers: None,
        });
        Ok(Precomputed { system, record })
    }
}

/// `tril(K)` in the original order: column `j < n` holds `tril(AᵀA)[:, j]`
/// then `s·b_kj` in rows `n + k`; column `n + k` holds an explicit zero
/// diagonal (so that every column has its diagonal).
fn assemble_kkt(
    ata_lower: &SparseColMat<usize, f64>,
    problem: &LseProblem,
    scale: f64,
) -> SparseColMat<usize, f64> {
    let n = problem.n();
    let b = problem.b().as_ref();
    let m = b.nrows();
    // Bᵀ by columns: for vertex j, the rows k (increasing) and values.
    let mut count = vec![0usize; n + 1];
    for &j in b.symbolic().col_idx() {
        count[j + 1] += 1;
    }
    for j in 0..n {
        count[j + 1] += count[j];
    }
    let mut bt_k = vec![0usize; count[n]];
    let mut bt_v = vec![0.0; count[n]];
    let mut fill = count.clone();
    for k in 0..m {
        let (cols, vals) = row_entries(b, k);
        for (&j, &v) in cols.iter().zip(vals) {
            bt_k[fill[j]] = k;
            bt_v[fill[j]] = scale * v;
            fill[j] += 1;
        }
    }
    let (ptr, rows, val) = (
        ata_lower.symbolic().col_ptr(),
        ata_lower.symbolic().row_idx(),
        ata_lower.val(),
    );
    let mut col_ptr = Vec::with_capacity(n + m + 1);
    col_ptr.push(0);
    let mut out_rows = Vec::with_capacity(rows.len() + bt_k.len() + m);
    let mut out_vals = Vec::with_capacity(rows.len() + bt_k.len() + m);
    for j in 0..n {
        out_rows.extend_from_slice(&rows[ptr[j]..ptr[j + 1]]);
        out_vals.extend_from_slice(&val[ptr[j]..ptr[j + 1]]);
        for p in count[j]..count[j + 1] {
            out_rows.push(n + bt_k[p]);
            out_vals.push(bt_v[p]);
        }
        col_ptr.push(out_rows.len());
    }
    for k in 0..m {
        out_rows.push(n + k);
        out_vals.push(0.0);
        col_ptr.push(out_rows.len());
    }
    SparseColMat::new(
        SymbolicSparseColMat::new_checked(n + m, n + m, col_ptr, None, out_rows),
        out_vals,
    )
}

/// How a failing pivot was found.
enum FoundKind {
    /// Computed, and too small or of the wrong sign.
    Computed,
    /// A multiplier pivot computed positive and far from zero: the vertex
    /// pivots before it lost their digits.
    LostDigits,
    /// Flagged by the back end's own test.
    Test,
}

/// The error of the first pivot that breaks the module documentation's
/// rule ([`PivotRule`]: vertex pivots positive, multiplier pivots
/// negative, each above [`KKT_PIVOT_TOLERANCE`] of its magnitude), from
/// whichever back end reported it: a [`NumericalError::Singular`] naming
/// its constraint or vertex ([`NumericalError::FreeUnknown`] for a general
/// problem's unknown).
fn pivot_error(
    fault: PivotFault,
    order: &[usize],
    problem: &LseProblem,
) -> Result<NumericalError, Error> {
    let n = problem.n();
    let (unknown, found, found_kind) = match fault {
        PivotFault::Reported { message } => {
            return Ok(NumericalError::Singular {
                matrix: MATRIX.into(),
                detail: message,
            });
        }
        PivotFault::Computed {
            position,
            dim,
            pivot,
        } => {
            let found = describe_pivot(position, dim, pivot.value, pivot.magnitude);
            // A multiplier pivot positive and far from zero is not a
            // vanishing pivot: the vertex pivots before it passed the test
            // with too few digits left.
            let lost = pivot.unknown >= n
                && pivot.value > 0.0
                && pivot.value.abs() / pivot.magnitude > KKT_PIVOT_TOLERANCE;
            let kind = if lost {
                FoundKind::LostDigits
            } else {
                FoundKind::Computed
            };
            (pivot.unknown, found, kind)
        }
        PivotFault::Null { unknown, test } if unknown >= n => {
            // A back end that merges the members of a dependent group may
            // flag another member than the static order's first: name the
            // first row that depends on the rows before it; when the QR
            // finds every row independent, no constraint is blamed.
            let Some(k) = first_dependent_row(problem, order)? else {
                return Ok(NumericalError::Singular {
                    matrix: MATRIX.into(),
                    detail: format!(
                        "a multiplier pivot was flagged ({test}), yet a rank-revealing QR of B keeps every hard row: the factorisation lost its digits, no constraint is dependent (use nullspace-qr)"
                    ),
                });
            };
            (n + k, test, FoundKind::Test)
        }
        PivotFault::Null { unknown, test } => (unknown, test, FoundKind::Test),
    };
    // A computed pivot states what was expected of it; a back end's own
    // test speaks for itself.
    let computed = !matches!(found_kind, FoundKind::Test);
    let expected =
        |sign: &str| format!("expected {sign} and above {KKT_PIVOT_TOLERANCE:e} of that magnitude");
    if unknown < n && problem.is_general() {
        let detail = if computed {
            format!("{found}; {}", expected("positive"))
        } else {
            found
        };
        return Ok(NumericalError::FreeUnknown {
            matrix: MATRIX.into(),
            unknown,
            detail,
        });
    }
    let with = |sign: &str| {
        if computed {
            format!("{found} ({})", expected(sign))
        } else {
            found.clone()
        }
    };
    let detail = if unknown < n {
        format!(
            "vertex {unknown}: {}: AᵀA is singular on the unknowns eliminated so far and the hard constraints eliminated before it do not pin them — a mesh component is free to move, or its constraints defeat the static pivot order (use nullspace-qr)",
            with("positive")
        )
    } else {
        let k = unknown - n;
        let index = problem.hard_constraints()[k];
        let row = RowKind::of_row(problem.b().as_ref(), k);
        if matches!(found_kind, FoundKind::LostDigits) {
            format!(
                "the pivots eliminated before hard constraint {index} (row {k} of B, {row}) lost their digits: for its multiplier, {found} (expected negative; a positive pivot this far from zero is not a dependence but AᵀA nearly singular on the vertices eliminated before it, as on meshes with slivers) — the static pivot order fails here (use nullspace-qr)"
            )
        } else {
            format!(
                "hard constraint {index} (row {k} of B, {row}) depends on the constraints eliminated before it: for its multiplier, {}; redundant or conflicting hard constraints make the KKT matrix singular — remove it, make it soft, or use nullspace-qr, which skips it",
                with("negative")
            )
        }
    };
    Ok(NumericalError::Singular {
        matrix: MATRIX.into(),
        detail,
    })
}

/// The first hard row, in the order in which `order` eliminates the
/// multipliers, that depends on the rows before it: a rank-revealing QR of
/// `Bᵀ` with the rows in that order (sparse Givens, the null-space method's
/// rank tolerance). In the static order every multiplier comes after all
/// its vertices, so the multiplier pivot of faer's `LDLᵀ` vanishes exactly
/// at such a row (module documentation): this names the constraint faer
/// names, for the dependences both tolerances see.
fn first_dependent_row(problem: &LseProblem, order: &[usize]) -> Result<Option<usize>, Error> {
    let n = problem.n();
    let b = problem.b().as_ref();
    let sequence: Vec<usize> = order.iter().filter(|&&u| u >= n).map(|&u| u - n).collect();
    let mut triplets = Vec::new();
    for (i, &k) in sequence.iter().enumerate() {
        let (cols, vals) = row_entries(b, k);
        triplets.extend(cols.iter().zip(vals).map(|(&j, &v)| Triplet::new(i, j, v)));
    }
    let reordered =
        SparseRowMat::try_new_from_triplets(sequence.len(), n, &triplets).map_err(|e| {
            ProblemError::from_creation(
                "the constraint rows in priority order",
                24 * triplets.len() as u64,
                e,
            )
        })?;
    let qr = SparseGivens::default().factor(reordered.as_ref(), RankTolerance::default())?;
    let mut kept = vec![false; sequence.len()];
    for &i in qr.kept() {
        kept[i] = true;
    }
    Ok(kept.iter().position(|&k| !k).map(|i| sequence[i]))
}

/// A factored KKT system. Invariant: `factor` is the `LDLᵀ` factor of
/// `k_lower` (scaled by `scale`), all pivots checked.
struct PreparedKkt {
    factor: Box<dyn crate::backend::ldlt::LdltFactor>,
    k_lower: SparseColMat<usize, f64>,
    norm: f64,
    scale: f64,
    n: usize,
    /// `μ` (the scaled multipliers `Λ'`) of the last solve, refined along
    /// with `x`.
    multipliers: Mat<f64>,
    /// `Δμ` of the last correction, added by `accept_correction`.
    pending_multipliers: Option<Mat<f64>>,
}

impl PreparedKkt {
    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) -> Result<(), NumericalError> {
        self.factor.solve_in_place(rhs)
    }

    /// `max_c ‖b_c − K y_c‖∞ / (‖K‖∞ ‖y_c‖∞ + ‖b_c‖∞)` and the residual.
    fn backward_error(&self, y: &Mat<f64>, b: &Mat<f64>) -> (f64, Mat<f64>) {
        let mut ky = Mat::<f64>::zeros(y.nrows(), y.ncols());
        lower_sym_mul(self.k_lower.as_ref(), y.as_ref(), ky.as_mut());
        let r = b - &ky;
        let mut worst = 0.0f64;
        for c in 0..y.ncols() {
            let (mut rn, mut yn, mut bn) = (0.0f64, 0.0f64, 0.0f64);
            for i in 0..y.nrows() {
                rn = rn.max(r[(i, c)].abs());
                yn = yn.max(y[(i, c)].abs());
                bn = bn.max(b[(i, c)].abs());
            }
            let denom = self.norm * yn + bn;
            let eta = if denom > 0.0 { rn / denom } else { rn };
            worst = worst.max(if eta.is_nan() { f64::INFINITY } else { eta });
        }
        (worst, r)
    }
}

impl Prepared for PreparedKkt {
    fn solve(&mut self, problem: &LseProblem) -> Result<Mat<f64>, Error> {
        let n = self.n;
        let m = problem.b().nrows();
        let k = problem.c().ncols();
        let atc = at_times(problem.a().as_ref(), problem.c().as_ref());
        let mut b = Mat::<f64>::zeros(n + m, k);
        b.as_mut().submatrix_mut(0, 0, n, k).copy_from(&atc);
        for r in 0..m {
            for c in 0..k {
                b[(n + r, c)] = self.scale * problem.d()[(r, c)];
            }
        }
        let mut y = b.clone();
        self.solve_in_place(y.as_mut())?;
        let (eta, _) = self.backward_error(&y, &b);
        if eta.is_nan() || eta > KKT_BACKWARD_ERROR_TOLERANCE {
            return Err(NumericalError::InaccurateSolution {
                matrix: MATRIX.into(),
                backward_error: eta,
                tolerance: KKT_BACKWARD_ERROR_TOLERANCE,
            }
            .into());
        }
        let x = y.submatrix(0, 0, n, k).to_owned();
        if let Some(vertex) = first_non_finite(x.as_ref()) {
            return Err(NumericalError::NonFiniteSolution { vertex }.into());
        }
        self.multipliers = y.submatrix(n, 0, m, k).to_owned();
        self.pending_multipliers = None;
        Ok(x)
    }

    /// Refinement on the augmented system with the residual from `A` and
    /// `B`: `K [Δx; Δμ] = [Aᵀ(C − A x) − s Bᵀ μ; s (D − B x)]`, the last in
    /// twice the working precision.
    fn correction(
        &mut self,
        problem: &LseProblem,
        x: &Mat<f64>,
    ) -> Result<Option<Mat<f64>>, Error> {
        let n = self.n;
        let m = problem.b().nrows();
        let k = x.ncols();
        let mut top = at_residual(problem.a().as_ref(), problem.c().as_ref(), x.as_ref());
        add_bt_times(
            problem.b().as_ref(),
            self.multipliers.as_ref(),
            -self.scale,
            top.as_mut(),
        );
        // In twice the working precision: a kept row with a small
        // remainder reproduces in a plain residual the rounding its own
        // solve left in `x` (see the null-space formulation's correction).
        let bottom =
            hard_residual_compensated(problem.b().as_ref(), problem.d().as_ref(), x.as_ref());
        let mut y = Mat::<f64>::zeros(n + m, k);
        y.as_mut().submatrix_mut(0, 0, n, k).copy_from(&top);
        for r in 0..m {
            for c in 0..k {
                y[(n + r, c)] = self.scale * bottom[(r, c)];
            }
        }
        self.solve_in_place(y.as_mut())?;
        self.pending_multipliers = Some(y.submatrix(n, 0, m, k).to_owned());
        Ok(Some(y.submatrix(0, 0, n, k).to_owned()))
    }

    fn accept_correction(&mut self) {
        if let Some(dm) = self.pending_multipliers.take() {
            self.multipliers += &dm;
        }
    }

    fn refactorizations(&self) -> usize {
        self.factor.refactorizations()
    }

    fn skipped(&self) -> &[usize] {
        &[]
    }

    fn estimate_condition(&mut self) -> Result<ConditionEstimate, Error> {
        let k_lower = self.k_lower.clone();
        let dim = k_lower.ncols();
        let mut matrix = LowerSymmetricOperator::new(k_lower.as_ref());
        let mut inverse = InverseOperator::new(dim, |rhs| {
            self.solve_in_place(rhs)?;
            Ok(())
        });
        condition::estimate(
            &mut matrix,
            &mut inverse,
            "the scaled KKT matrix [AᵀA sBᵀ; sB 0]",
        )
    }

    fn factored_matrix(&self) -> Option<SparseColMat<usize, f64>> {
        Some(lower_to_full(self.k_lower.as_ref()))
    }
}

/// "pivot 4 of 12 in elimination order is -1.5e-20, 3.2e-18 of the
/// magnitude it was computed from", without a `NaN` ratio when that
/// magnitude is zero or a pivot is not finite.
fn describe_pivot(position: usize, dim: usize, pivot: f64, magnitude: f64) -> String {
    let head = format!("pivot {} of {dim} in elimination order", position + 1);
    if !pivot.is_finite() {
        return format!("{head} is {pivot} (not finite)");
    }
    if magnitude == 0.0 || !magnitude.is_finite() {
        return format!(
            "{head} is {pivot:e}, computed from entries of magnitude {magnitude:e}: nothing was left to pivot on"
        );
    }
    format!(
        "{head} is {pivot:e}, {:e} of the magnitude it was computed from",
        pivot.abs() / magnitude
    )
}
