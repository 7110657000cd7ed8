//! faer's sparse `LDLᵀ` in a given elimination order (simplicial,
//! supernodal, or chosen by faer's flop-ratio heuristic), without
//! numerical pivoting.

use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::ldlt::factor::LdltRegularization;
use faer::perm::PermRef;
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LdltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky, supernodal::SupernodalLdltRef,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use super::{
    LdltBackend, LdltFactor, LdltKind, LdltSymbolic, Pivot, PivotFault, PivotRule, first_fault,
};
use crate::backend::BackendName;
use crate::backend::faer_kernel;
use crate::backend::spd::factor_size;
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;
use crate::resources::Threads;
use crate::sparse::lower_diag;

/// The name in a [`NumericalError::Backend`] from this back end.
const BACKEND: &str = "faer-ldlt";

/// Right-hand-side columns the factor's solve workspace is sized for (a
/// mesh's x, y, z); wider right-hand sides get their own.
const WORKSPACE_COLUMNS: usize = 3;

/// The parallelism of the numeric factorisation: `threads` when given,
/// otherwise every thread of rayon's pool.
fn numeric_parallelism(threads: Threads) -> Par {
    match threads.requested() {
        Some(1) => Par::Seq,
        Some(n) => Par::rayon(n),
        None => Par::rayon(0),
    }
}

/// faer's sparse `LDLᵀ` in the caller's elimination order.
#[derive(Debug, Clone, Copy)]
pub struct FaerLdlt {
    kind: LdltKind,
}

impl FaerLdlt {
    /// The variant `kind` names.
    pub fn new(kind: LdltKind) -> FaerLdlt {
        FaerLdlt { kind }
    }

    /// faer's switch between simplicial and supernodal factorisation.
    fn threshold(self) -> SupernodalThreshold {
        match self.kind {
            LdltKind::FaerAuto => SupernodalThreshold::AUTO,
            LdltKind::FaerSimplicial => SupernodalThreshold::FORCE_SIMPLICIAL,
            LdltKind::FaerSupernodal => SupernodalThreshold::FORCE_SUPERNODAL,
            // Not a faer kind (LdltKind::backend makes no FaerLdlt of it).
            LdltKind::Mumps => SupernodalThreshold::AUTO,
        }
    }
}

impl LdltBackend for FaerLdlt {
    fn name(&self) -> BackendName {
        self.kind.name().into()
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
    ) -> Result<Box<dyn LdltSymbolic>, NumericalError> {
        self.analyze_on_threads(lower, order, Threads::Own)
    }

    /// `nnz(L)` of `order` predicted from the elimination tree (the
    /// pattern of `LDLᵀ` without pivoting is that of the Cholesky factor)
    /// and its values, 8 bytes an entry, on top of what the process holds,
    /// against `budget`, before faer's symbolic analysis builds the
    /// factor's structure ([`crate::backend::spd::check_predicted_values`]).
    fn check_order_budget(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
        budget: MemoryBudget,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        let what = format!("the LDLᵀ factor of {matrix}");
        crate::backend::spd::check_predicted_values(lower, order, budget, &what, "given")
    }

    /// faer's `Par` for the numeric factorisation.
    fn analyze_on_threads(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
        threads: Threads,
    ) -> Result<Box<dyn LdltSymbolic>, NumericalError> {
        let dim = lower.ncols();
        let mut inv = vec![0usize; dim];
        for (new, &old) in order.iter().enumerate() {
            inv[old] = new;
        }
        let perm = PermRef::new_checked(order, &inv, dim);
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: self.threshold(),
            ..Default::default()
        };
        let symbolic = factorize_symbolic_cholesky(
            lower,
            Side::Lower,
            SymmetricOrdering::Custom(perm),
            params,
        )
        .map_err(|e| NumericalError::from_faer(BACKEND, "the LDLᵀ factor's structure", e))?;
        Ok(Box::new(FaerLdltSymbolic {
            symbolic: Arc::new(symbolic),
            par: numeric_parallelism(threads),
        }))
    }
}

struct FaerLdltSymbolic {
    symbolic: Arc<SymbolicCholesky<usize>>,
    /// The parallelism of every numeric factorisation.
    par: Par,
}

impl LdltSymbolic for FaerLdltSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn LdltFactor>, NumericalError> {
        let symbolic = Arc::clone(&self.symbolic);
        let mut values = vec![0.0f64; symbolic.len_val()];
        let par = self.par;
        let mut mem = MemBuffer::try_new(
            symbolic.factorize_numeric_ldlt_scratch::<f64>(par, Default::default()),
        )
        .map_err(|_| {
            NumericalError::out_of_memory(BACKEND, "the numeric factorisation's workspace")
        })?;
        let result = symbolic.factorize_numeric_ldlt(
            &mut values,
            lower,
            Side::Lower,
            LdltRegularization::default(),
            par,
            MemStack::new(&mut mem),
            Default::default(),
        );
        let failure = result.err().map(|e| format!("faer's LDLᵀ reported {e:?}"));
        let workspace =
            MemBuffer::try_new(symbolic.solve_in_place_scratch::<f64>(WORKSPACE_COLUMNS, Par::Seq))
                .map_err(|_| NumericalError::out_of_memory(BACKEND, "the solves' workspace"))?;
        Ok(Box::new(FaerLdltFactor {
            symbolic,
            values,
            workspace,
            failure,
        }))
    }

    fn factor_values(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Refuses a factorisation that would not fit: the factor's values,
    /// faer's scratch of the factorisation (`factorize_numeric_ldlt_scratch`)
    /// and of a solve of [`WORKSPACE_COLUMNS`] columns, and the pivots'
    /// per-unknown arrays, on top of what the process holds, against
    /// `budget` ([`MemoryBudget::check_on_top`]); and all that plus faer's
    /// matrix-multiply kernel against the address-space limit, which it
    /// then reserves ([`faer_kernel::reserve`]).
    fn check_budget(
        &self,
        budget: MemoryBudget,
        dim: usize,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        let symbolic = &*self.symbolic;
        let scratch = symbolic
            .factorize_numeric_ldlt_scratch::<f64>(self.par, Default::default())
            .and(symbolic.solve_in_place_scratch::<f64>(WORKSPACE_COLUMNS, Par::Seq))
            .size_bytes() as u64;
        let total = (symbolic.len_val() as u64)
            .saturating_add(4 * dim as u64)
            .saturating_mul(8)
            .saturating_add(scratch);
        let what = || {
            format!(
                "the LDLᵀ factor of {matrix} ({dim} unknowns, {} entries after fill-in) and its workspace",
                symbolic.len_val()
            )
        };
        budget
            .check_on_top(total, || format!("{} would need", what()))
            .map_err(|detail| ProblemError::TooLarge { detail })?;
        faer_kernel::reserve(self.par, total, &what())
    }

    fn threads_used(&self) -> Option<usize> {
        Some(match self.par {
            Par::Seq => 1,
            Par::Rayon(n) => n.get(),
        })
    }
}

/// Invariant: `values` is the numeric factor of the matrix given to
/// `factorize` under `symbolic`; `workspace` fits a solve of
/// [`WORKSPACE_COLUMNS`] columns.
struct FaerLdltFactor {
    symbolic: Arc<SymbolicCholesky<usize>>,
    values: Vec<f64>,
    workspace: MemBuffer,
    failure: Option<String>,
}

impl FaerLdltFactor {
    /// Every pivot in elimination order, with the magnitude it was computed
    /// from; `lower` is the matrix factored (for `K_jj`).
    fn pivots(&self, lower: SparseColMatRef<'_, usize, f64>) -> Vec<Pivot> {
        let dim = self.dim();
        let fwd: Vec<usize> = match self.symbolic.perm() {
            Some(p) => p.arrays().0.to_vec(),
            None => (0..dim).collect(),
        };
        let mut d = vec![0.0f64; dim];
        self.for_each_entry(|i, k, v| {
            if i == k {
                d[k] = v;
            }
        });
        let mut magnitude: Vec<f64> = (0..dim).map(|i| lower_diag(lower, fwd[i]).abs()).collect();
        self.for_each_entry(|i, k, v| {
            if i != k {
                magnitude[i] += v * v * d[k].abs();
            }
        });
        (0..dim)
            .map(|i| Pivot {
                unknown: fwd[i],
                value: d[i],
                magnitude: magnitude[i],
            })
            .collect()
    }

    /// Visits every stored entry of the factor in permuted coordinates:
    /// `f(i, k, value)` with `i == k` for the pivot `d_k` and `i > k` for
    /// `L_ik`.
    fn for_each_entry(&self, mut f: impl FnMut(usize, usize, f64)) {
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(s) => {
                let (col_ptr, row_idx) = (s.col_ptr(), s.row_idx());
                for k in 0..s.ncols() {
                    for p in col_ptr[k]..col_ptr[k + 1] {
                        f(row_idx[p], k, self.values[p]);
                    }
                }
            }
            SymbolicCholeskyRaw::Supernodal(s) => {
                let l = SupernodalLdltRef::new(s, &self.values);
                for sn in 0..s.n_supernodes() {
                    let node = l.supernode(sn);
                    let (start, pattern, block) = (node.start(), node.pattern(), node.val());
                    let width = block.ncols();
                    for t in 0..width {
                        let k = start + t;
                        f(k, k, block[(t, t)]);
                        for r in t + 1..width {
                            f(start + r, k, block[(r, t)]);
                        }
                        for (q, &i) in pattern.iter().enumerate() {
                            f(i, k, block[(width + q, t)]);
                        }
                    }
                }
            }
        }
    }
}

impl LdltFactor for FaerLdltFactor {
    fn dim(&self) -> usize {
        self.symbolic.nrows()
    }

    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) -> Result<(), NumericalError> {
        let factor = LdltRef::new(&self.symbolic, &self.values);
        if rhs.ncols() > WORKSPACE_COLUMNS {
            // A wider block needs a workspace of its own: refused typed
            // when it cannot be allocated (never a silent no-op).
            let mut buf = MemBuffer::try_new(
                self.symbolic
                    .solve_in_place_scratch::<f64>(rhs.ncols(), Par::Seq),
            )
            .map_err(|_| NumericalError::out_of_memory(BACKEND, "a wide solve's workspace"))?;
            factor.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, MemStack::new(&mut buf));
            return Ok(());
        }
        factor.solve_in_place_with_conj(
            Conj::No,
            rhs,
            Par::Seq,
            MemStack::new(&mut self.workspace),
        );
        Ok(())
    }

    fn nnz(&self) -> usize {
        factor_size(&self.symbolic).nnz
    }

    fn bytes(&self) -> usize {
        factor_size(&self.symbolic).total_bytes()
    }

    fn pivot_fault(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
        rule: PivotRule,
    ) -> Option<PivotFault> {
        first_fault(&self.pivots(lower), rule, self.failure.as_deref())
    }
}
