//! faer's sparse `LLᵀ` (AMD ordering; simplicial, supernodal, or chosen by
//! faer's flop-ratio heuristic).

use std::borrow::Cow;
use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltError as DenseLltError, LltRegularization};
use faer::perm::PermRef;
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{MatMut, Par, Side};

use crate::cpu::clear_upper_vector_state;

use super::factor_size::{check_predicted_values, factor_size};
use super::tree_split::TreeSplit;
use super::triangular::{
    LANES, Lane, Passes, SupernodalRows, WIDE_LANES, factor_diagonal, passes, solve_lanes,
    wide_lanes_native, wide_passes,
};
use super::{SpdBackend, SpdFactor, SpdSymbolic, check_breakdown};
use crate::backend::faer_kernel;
use crate::backend::ordering::{FactorPlan, PlanUsed, inverse};
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;
use crate::resources::Threads;

/// faer's sparse Cholesky `LLᵀ` with AMD ordering.
#[derive(Debug, Clone, Copy)]
pub struct FaerLlt {
    threshold: SupernodalThreshold,
    kind: super::SpdKind,
}

impl FaerLlt {
    /// Supernodal or simplicial, chosen by faer's flop-ratio heuristic
    /// ("supernodal where it pays").
    pub fn auto() -> FaerLlt {
        FaerLlt {
            threshold: SupernodalThreshold::AUTO,
            kind: super::SpdKind::FaerAuto,
        }
    }

    /// Always supernodal (dense blocks of columns with equal structure,
    /// BLAS-3 kernels).
    pub fn supernodal() -> FaerLlt {
        FaerLlt {
            threshold: SupernodalThreshold::FORCE_SUPERNODAL,
            kind: super::SpdKind::FaerSupernodal,
        }
    }

    /// Always simplicial (column by column, up-looking).
    pub fn simplicial() -> FaerLlt {
        FaerLlt {
            threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
            kind: super::SpdKind::FaerSimplicial,
        }
    }
}

impl Default for FaerLlt {
    fn default() -> Self {
        FaerLlt::auto()
    }
}

fn backend_error(name: &str, e: impl std::fmt::Debug) -> NumericalError {
    NumericalError::Backend {
        backend: name.to_string(),
        message: format!("{e:?}"),
    }
}

impl SpdBackend for FaerLlt {
    fn name(&self) -> crate::backend::BackendName {
        self.kind.name().into()
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        self.analyze_with(lower, &FactorPlan::own(Threads::Own))
    }

    /// The plan's permutation as faer's custom ordering, and its threads
    /// as faer's `Par` for the numeric factorisation.
    fn analyze_planned(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        plan: &FactorPlan,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        self.analyze_with(lower, plan)
    }

    /// With a given permutation, `nnz(L)` predicted from the elimination
    /// tree ([`check_predicted_values`], `O(nnz(A))`) and its values (8
    /// bytes an entry, what faer stores at least) on top of what the
    /// process holds, against `budget`, before faer's symbolic analysis
    /// builds the factor's structure. Faer's own AMD needs no such check.
    fn check_plan_budget(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        plan: &FactorPlan,
        budget: MemoryBudget,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        let Some(fwd) = plan.permutation.as_deref() else {
            return Ok(());
        };
        let what = format!("the Cholesky factor of {matrix}");
        check_predicted_values(lower, fwd, budget, &what, plan.ordering)
    }
}

impl FaerLlt {
    fn analyze_with(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        plan: &FactorPlan,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: self.threshold,
            ..Default::default()
        };
        let inverse = plan.permutation.as_deref().map(inverse);
        let ordering = match (plan.permutation.as_deref(), inverse.as_deref()) {
            (Some(fwd), Some(inv)) => {
                if fwd.len() != lower.ncols() {
                    return Err(backend_error(self.kind.name(), "the permutation's length"));
                }
                SymmetricOrdering::Custom(PermRef::new_checked(fwd, inv, fwd.len()))
            }
            _ => SymmetricOrdering::Amd,
        };
        let symbolic =
            factorize_symbolic_cholesky(lower, Side::Lower, ordering, params).map_err(|e| {
                NumericalError::from_faer(self.kind.name(), "the Cholesky factor's structure", e)
            })?;
        let size = factor_size(&symbolic);
        let split = TreeSplit::new(&symbolic).map(Arc::new);
        Ok(Box::new(FaerSymbolic {
            symbolic: Arc::new(symbolic),
            split,
            name: self.kind.name(),
            nnz: size.nnz,
            index_bytes: size.index_bytes,
            threads: plan.threads.requested(),
            ordering: plan.ordering_used("amd"),
        }))
    }
}

struct FaerSymbolic {
    symbolic: Arc<SymbolicCholesky<usize>>,
    /// How its solves are split over two threads (computed once with the
    /// symbolic factor, shared by every numeric one).
    split: Option<Arc<TreeSplit>>,
    name: &'static str,
    nnz: usize,
    index_bytes: usize,
    /// The threads asked for; `None`: by size ([`numeric_parallelism`]).
    threads: Option<usize>,
    /// The report's word for the ordering used.
    ordering: Cow<'static, str>,
}

impl FaerSymbolic {
    /// The parallelism of the numeric factorisation: the plan's threads,
    /// or by size.
    fn par(&self) -> Par {
        match self.threads {
            Some(1) => Par::Seq,
            Some(n) => Par::rayon(n),
            None => numeric_parallelism(self.symbolic.len_val()),
        }
    }
}

impl SpdSymbolic for FaerSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn SpdFactor>, NumericalError> {
        let symbolic = &*self.symbolic;
        let n = symbolic.nrows();
        let par = self.par();
        let mut values = vec![0.0f64; symbolic.len_val()];
        let mut mem = MemBuffer::try_new(
            symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()),
        )
        .map_err(|_| {
            NumericalError::out_of_memory(self.name, "the numeric factorisation's workspace")
        })?;
        let fwd: Vec<usize> = match symbolic.perm() {
            Some(p) => p.arrays().0.to_vec(),
            None => (0..n).collect(),
        };
        let result = symbolic.factorize_numeric_llt(
            &mut values,
            lower,
            Side::Lower,
            LltRegularization::default(),
            par,
            MemStack::new(&mut mem),
            Default::default(),
        );
        match result {
            Ok(_) => {}
            Err(DenseLltError::NonPositivePivot { index }) => {
                let index = failing_column(symbolic, index);
                return Err(NumericalError::NotPositiveDefinite {
                    matrix: String::new(),
                    unknown: fwd.get(index).copied().unwrap_or(index),
                    vertex: None,
                    pivot: None,
                });
            }
        }
        let diag = factor_diagonal(symbolic, &values);
        check_breakdown(&diag, &fwd, lower)?;
        let inv_diag = diag.iter().map(|d| 1.0 / d).collect();
        // From here on the values are in the row-major supernode layout of
        // our triangular solves (faer's own solve must not see them).
        SupernodalRows::transpose_in_place(symbolic, &mut values);
        Ok(Box::new(FaerFactor {
            symbolic: Arc::clone(&self.symbolic),
            values,
            nnz: self.nnz,
            index_bytes: self.index_bytes,
            work: vec![[0.0; LANES]; n],
            inv_diag,
            scratch: Vec::new(),
            second: None,
            split: self.split.clone(),
            split_wide: None,
            fwd,
        }))
    }

    fn factor_nnz(&self) -> usize {
        self.nnz
    }

    /// Refuses a factorisation that would not fit: the factor's values
    /// and the factorisation's workspace ([`FaerSymbolic::workspace_bytes`])
    /// on top of what the process holds, against `budget`
    /// ([`MemoryBudget::check_on_top`]); and all that plus faer's
    /// matrix-multiply kernel against the address-space limit, which it
    /// then reserves ([`faer_kernel::reserve`]).
    fn check_budget(
        &self,
        budget: MemoryBudget,
        dim: usize,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        let par = self.par();
        let values = (self.symbolic.len_val() as u64).saturating_mul(8);
        let total = values.saturating_add(self.workspace_bytes(par));
        let what = || {
            format!(
                "the Cholesky factor of {matrix} ({dim} unknowns, {} entries after fill-in) and its workspace",
                self.nnz
            )
        };
        budget
            .check_on_top(total, || format!("{} would need", what()))
            .map_err(|detail| ProblemError::TooLarge { detail })?;
        faer_kernel::reserve(par, total, &what())
    }

    fn plan_used(&self) -> PlanUsed {
        let threads = match self.par() {
            Par::Seq => 1,
            Par::Rayon(n) => n.get(),
        };
        PlanUsed {
            ordering: self.ordering.clone(),
            threads: Some(threads),
        }
    }
}

impl FaerSymbolic {
    /// Bytes a numeric factorisation at `par` allocates besides the
    /// factor's values, at its peak: faer's scratch
    /// (`factorize_numeric_llt_scratch`), a copy of the largest supernode
    /// (the transposition into the solves' layout), and per unknown the
    /// permutation, the diagonal, its inverse and one group of solve lanes.
    fn workspace_bytes(&self, par: Par) -> u64 {
        let symbolic = &*self.symbolic;
        let scratch = symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .size_bytes();
        let largest = match symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(s) => s
                .col_ptr_for_val()
                .windows(2)
                .map(|w| w[1] - w[0])
                .max()
                .unwrap_or(0),
            SymbolicCholeskyRaw::Simplicial(_) => 0,
        };
        let per_unknown = 8 * (3 + LANES);
        (scratch as u64)
            .saturating_add(8 * largest as u64)
            .saturating_add((symbolic.nrows() * per_unknown) as u64)
    }
}

/// Factors with fewer stored values than this are factored on one thread.
///
/// faer's supernodal numeric factorisation with `Par::rayon` on this
/// 2-core machine, against `Par::Seq` (medians of 5, reduced normal
/// matrices of the paper's scene): Dragon 50k, 3.1 M values: 52 against
/// 28 ms; Bunny 35k, 3.9 M: 60 against 35 ms; Igea 134k, 22 M: 310 against
/// 270 ms; Igea 537k, 118 M: 1.85 against 2.2 s. Below tens of millions
/// of values the supernodes are too small for the tasks to pay for their
/// synchronisation.
const PARALLEL_NUMERIC_MIN_VALUES: usize = 50_000_000;

/// The parallelism of a numeric factorisation with `len_val` values.
fn numeric_parallelism(len_val: usize) -> Par {
    if len_val >= PARALLEL_NUMERIC_MIN_VALUES {
        Par::rayon(0)
    } else {
        Par::Seq
    }
}

/// The 0-based permuted column of a `NonPositivePivot { index }` error.
///
/// faer 0.24 is inconsistent here: its supernodal (and dense) `LLᵀ` report
/// the 0-based column, its simplicial `LLᵀ` reports `k + 1` for a failure in
/// column `k` (`sparse/linalg/cholesky.rs`, `index: *k + 1`). The back-end
/// tests pin this down with a matrix whose failing pivot is known.
pub(super) fn failing_column(symbolic: &SymbolicCholesky<usize>, index: usize) -> usize {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(_) => index.saturating_sub(1),
        SymbolicCholeskyRaw::Supernodal(_) => index,
    }
}

struct FaerFactor {
    symbolic: Arc<SymbolicCholesky<usize>>,
    values: Vec<f64>,
    nnz: usize,
    index_bytes: usize,
    /// `fwd[i]`: the original unknown at permuted position `i`.
    fwd: Vec<usize>,
    /// One group of right-hand sides in permuted order (a lane per
    /// unknown), reused by every solve so that the drag loop allocates
    /// nothing.
    work: Vec<Lane>,
    /// `1 / L_ii` in permuted order.
    inv_diag: Vec<f64>,
    /// Scratch of the triangular solves (the backward accumulator of the
    /// widest supernode).
    scratch: Vec<Lane>,
    /// The lanes and scratch of the second thread (of a split solve, or of
    /// a solve with more than [`LANES`] columns), allocated by the first
    /// such solve; the first thread uses `work` and `scratch`.
    second: Option<(Vec<Lane>, Vec<Lane>)>,
    /// How a one-group solve is split over two threads (`None`: small or
    /// unbalanced tree, or simplicial).
    split: Option<Arc<TreeSplit>>,
    /// Both threads' wide lanes and scratch of a split solve of up to
    /// [`WIDE_LANES`] columns (allocated by the first such solve).
    split_wide: Option<LaneBuffers<WIDE_LANES>>,
}

/// What the triangular solves of one factor read, shared by the threads
/// of a wide solve.
struct GroupSolver<'a> {
    symbolic: &'a SymbolicCholesky<usize>,
    values: &'a [f64],
    inv_diag: &'a [f64],
    fwd: &'a [usize],
}

impl GroupSolver<'_> {
    /// Solves the columns of `rhs` in place, [`LANES`] at a time, through
    /// `w` (a lane per unknown) and `scratch`, on this thread.
    fn solve_groups(&self, rhs: MatMut<'_, f64>, w: &mut [Lane], scratch: &mut Vec<Lane>) {
        self.solve_groups_with(rhs, w, |w| {
            solve_lanes(self.symbolic, self.values, self.inv_diag, w, scratch)
        });
    }

    /// Solves the columns of `rhs` in place in groups of `W`, gathered
    /// into `w` (a lane per unknown, in the factor's order) and solved
    /// there by `solve`.
    fn solve_groups_with<const W: usize>(
        &self,
        mut rhs: MatMut<'_, f64>,
        w: &mut [[f64; W]],
        mut solve: impl FnMut(&mut [[f64; W]]),
    ) {
        let k = rhs.ncols();
        for g0 in (0..k).step_by(W) {
            let width = W.min(k - g0);
            if width < W {
                for lane in w.iter_mut() {
                    *lane = [0.0; W];
                }
            }
            for c in 0..width {
                let col = rhs.as_ref().col(g0 + c);
                for (lane, &src) in w.iter_mut().zip(self.fwd) {
                    lane[c] = col[src];
                }
            }
            solve(w);
            for c in 0..width {
                let mut col = rhs.as_mut().col_mut(g0 + c);
                for (lane, &dst) in w.iter().zip(self.fwd) {
                    col[dst] = lane[c];
                }
            }
        }
    }

    /// One group of up to `W` columns solved on two threads by `split`,
    /// through `(w, scratch)` on this thread and `(w2, scratch2)` on the
    /// other.
    fn solve_split<const W: usize>(
        &self,
        rhs: MatMut<'_, f64>,
        split: &TreeSplit,
        passes: Passes<W>,
        (w, scratch): (&mut [[f64; W]], &mut Vec<[f64; W]>),
        (w2, scratch2): (&mut [[f64; W]], &mut Vec<[f64; W]>),
    ) {
        self.solve_groups_with(rhs, w, |w| {
            split.solve(
                passes,
                self.symbolic,
                self.values,
                self.inv_diag,
                (w, scratch),
                (w2, scratch2),
            )
        });
    }
}

/// The lanes and scratch of the two threads of a split solve.
struct LaneBuffers<const W: usize> {
    w: Vec<[f64; W]>,
    scratch: Vec<[f64; W]>,
    w2: Vec<[f64; W]>,
    scratch2: Vec<[f64; W]>,
}

impl<const W: usize> LaneBuffers<W> {
    fn new(n: usize) -> Self {
        LaneBuffers {
            w: vec![[0.0; W]; n],
            scratch: Vec::new(),
            w2: vec![[0.0; W]; n],
            scratch2: Vec::new(),
        }
    }
}

impl SpdFactor for FaerFactor {
    fn dim(&self) -> usize {
        self.symbolic.nrows()
    }

    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) -> Result<(), NumericalError> {
        let k = rhs.ncols();
        let solver = GroupSolver {
            symbolic: &self.symbolic,
            values: &self.values,
            inv_diag: &self.inv_diag,
            fwd: &self.fwd,
        };
        let n = self.work.len();
        // One group: on two threads along the elimination tree when it
        // splits ([`TreeSplit`]), else on this one.
        if let Some(split) = &self.split {
            if k <= LANES {
                let second = self
                    .second
                    .get_or_insert_with(|| (vec![[0.0; LANES]; n], Vec::new()));
                let first = (&mut self.work[..], &mut self.scratch);
                solver.solve_split(rhs, split, passes(), first, (&mut second.0, &mut second.1));
                return Ok(());
            }
            if k <= WIDE_LANES && wide_lanes_native() {
                let b = self.split_wide.get_or_insert_with(|| LaneBuffers::new(n));
                let (first, second) = (
                    (&mut b.w[..], &mut b.scratch),
                    (&mut b.w2[..], &mut b.scratch2),
                );
                solver.solve_split(rhs, split, wide_passes(), first, second);
                return Ok(());
            }
        }
        if k <= LANES {
            solver.solve_groups(rhs, &mut self.work, &mut self.scratch);
            return Ok(());
        }
        // Two or more groups: the first half of them on this thread, the
        // rest on another, each with its own lanes, reading the same factor
        // (the Bunny's basis, seven columns, minimum of 40 solves: 13.1 ms
        // for the two groups one after the other, 6.3 ms side by side).
        let groups = k.div_ceil(LANES);
        let second = self
            .second
            .get_or_insert_with(|| (vec![[0.0; LANES]; n], Vec::new()));
        let (left, right) = rhs.split_at_col_mut(groups.div_ceil(2) * LANES);
        let (work, scratch) = (&mut self.work, &mut self.scratch);
        // The second half on a pool thread, the first on this one
        // (`in_place_scope` rather than `join`, whose call from outside the
        // pool hands both halves to the pool and, measured on the Bunny's
        // basis, ran them one after the other in about half of 45 solves).
        rayon::in_place_scope(|scope| {
            scope.spawn(|_| {
                clear_upper_vector_state();
                solver.solve_groups(right, &mut second.0, &mut second.1);
            });
            clear_upper_vector_state();
            solver.solve_groups(left, work, scratch);
        });
        Ok(())
    }

    fn nnz(&self) -> usize {
        self.nnz
    }

    fn bytes(&self) -> usize {
        self.values.len() * 8 + self.index_bytes
    }
}
