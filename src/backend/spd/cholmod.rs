//! CHOLMOD (SuiteSparse) supernodal `LLᵀ` through `suitesparse_sys`
//! (feature `suitesparse`; links the system's `libcholmod`).
//!
//! - **analysis** ([`SpdBackend::analyze`]): `cholmod_l_analyze` once, with
//!   one ordering method forced to AMD (`nmethods = 1`,
//!   `method[0].ordering = CHOLMOD_AMD`) and `supernodal = CHOLMOD_SUPERNODAL`;
//!   the symbolic factor is kept.
//! - **numeric** ([`SpdSymbolic::factorize`]): a copy of the symbolic factor
//!   (`cholmod_l_copy_factor`, no new analysis) is filled by
//!   `cholmod_l_factorize`. A matrix that is not positive definite leaves
//!   `status == CHOLMOD_NOT_POSDEF` and `L->minor` = the failing column in the
//!   permuted order; it is reported as
//!   [`NumericalError::NotPositiveDefinite`] with `L->Perm[minor]`, the
//!   original index. A completed factor gets the common breakdown check on
//!   its diagonal ([`BREAKDOWN_RATIO`](super::BREAKDOWN_RATIO)).
//! - **solve**: `cholmod_l_solve(CHOLMOD_A, …)` with all right-hand sides in
//!   one dense block.
//!
//! The matrix handed to CHOLMOD is a `cholmod_sparse` header over our own
//! arrays (64-bit indices, `stype = −1`: lower triangle, sorted, packed);
//! CHOLMOD only reads it. Everything CHOLMOD allocates is owned by a Rust
//! value whose `Drop` frees it with `cholmod_l_free_*`; each owner has its
//! own `cholmod_common` (started with `cholmod_l_start`, finished on drop), so
//! no CHOLMOD state is shared between objects.

use std::ptr;

use faer::MatMut;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use suitesparse_sys as ss;

use super::{SpdBackend, SpdFactor, SpdSymbolic, check_breakdown};
use crate::backend::openblas::{self, ThreadsFor};
use crate::backend::ordering::{FactorPlan, PlanUsed};
use crate::backend::suitesparse::{Common, Long, LowerCsc, status_error};
use crate::error::NumericalError;
use crate::resources::Threads;

const NAME: &str = "cholmod";

/// CHOLMOD's supernodal `LLᵀ` with AMD ordering.
#[derive(Debug, Clone, Copy, Default)]
pub struct Cholmod;

fn backend_error(message: impl Into<String>) -> NumericalError {
    NumericalError::Backend {
        backend: NAME.to_string(),
        message: message.into(),
    }
}

/// A CHOLMOD factor (symbolic or numeric) with the common it was made with.
struct Factor {
    l: *mut ss::cholmod_factor,
    // Declared after `l` so that it is finished after `l` is freed in Drop.
    common: Common,
}

// SAFETY: the factor and its common are owned exclusively by this value;
// CHOLMOD keeps no global mutable state besides its allocator functions
// (thread-safe malloc/free). `&self` methods only read `*l`.
unsafe impl Send for Factor {}
// SAFETY: see above: shared references only read the factor.
unsafe impl Sync for Factor {}

impl Drop for Factor {
    fn drop(&mut self) {
        if !self.l.is_null() {
            // SAFETY: `l` was allocated by CHOLMOD and is freed once.
            unsafe {
                ss::cholmod_l_free_factor(&mut self.l, self.common.ptr());
            }
        }
    }
}

impl Factor {
    fn n(&self) -> usize {
        // SAFETY: `l` is a valid factor while `self` lives.
        unsafe { (*self.l).n }
    }

    /// `L->Perm` (permuted index → original index).
    fn perm(&self) -> Vec<usize> {
        let n = self.n();
        // SAFETY: Perm has n entries for an analysed factor.
        unsafe {
            let p = (*self.l).Perm as *const Long;
            if p.is_null() {
                (0..n).collect()
            } else {
                std::slice::from_raw_parts(p, n)
                    .iter()
                    .map(|&v| v as usize)
                    .collect()
            }
        }
    }

    /// Entries of the lower triangle of `L` predicted by the analysis
    /// (`Σ ColCount`).
    fn predicted_nnz(&self) -> usize {
        let n = self.n();
        // SAFETY: ColCount has n entries for an analysed factor.
        unsafe {
            let c = (*self.l).ColCount as *const Long;
            if c.is_null() {
                0
            } else {
                std::slice::from_raw_parts(c, n)
                    .iter()
                    .map(|&v| v as usize)
                    .sum()
            }
        }
    }

    /// The diagonal of a numeric `LLᵀ` factor in the permuted order.
    fn diagonal(&self) -> Result<Vec<f64>, NumericalError> {
        let n = self.n();
        let mut diag = vec![0.0; n];
        // SAFETY: the arrays read are those CHOLMOD documents for a numeric
        // supernodal (super, pi, px, x) or simplicial (p, x) factor, with the
        // sizes it documents.
        unsafe {
            let l = &*self.l;
            if l.xtype != ss::CHOLMOD_REAL as i32 {
                return Err(backend_error("factor has no numerical values"));
            }
            let x = l.x as *const f64;
            if l.is_super != 0 {
                let ns = l.nsuper;
                let sup = std::slice::from_raw_parts(l.super_ as *const Long, ns + 1);
                let pi = std::slice::from_raw_parts(l.pi as *const Long, ns + 1);
                let px = std::slice::from_raw_parts(l.px as *const Long, ns + 1);
                for s in 0..ns {
                    let (k1, k2) = (sup[s] as usize, sup[s + 1] as usize);
                    let nsrow = (pi[s + 1] - pi[s]) as usize;
                    let psx = px[s] as usize;
                    for (t, d) in diag[k1..k2].iter_mut().enumerate() {
                        *d = *x.add(psx + t * nsrow + t);
                    }
                }
            } else {
                if l.is_ll == 0 {
                    return Err(backend_error("expected an LLᵀ factor, got LDLᵀ"));
                }
                let p = std::slice::from_raw_parts(l.p as *const Long, n + 1);
                for (j, d) in diag.iter_mut().enumerate() {
                    *d = *x.add(p[j] as usize);
                }
            }
        }
        Ok(diag)
    }
}

/// Settings shared by analysis and factorisation.
fn configure(common: &mut Common) {
    let c = common.get_mut();
    c.nmethods = 1;
    c.method[0].ordering = ss::CHOLMOD_AMD as _;
    c.postorder = 1;
    c.supernodal = ss::CHOLMOD_SUPERNODAL as _;
    c.final_ll = 1;
}

impl SpdBackend for Cholmod {
    fn name(&self) -> crate::backend::BackendName {
        super::SpdKind::Cholmod.name().into()
    }

    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        analyze_with(lower, &FactorPlan::own(Threads::Own))
    }

    /// The plan's permutation through `cholmod_l_analyze_p` (one method,
    /// `CHOLMOD_GIVEN`; CHOLMOD still postorders its elimination tree,
    /// which keeps every column's fill), and its threads as OpenBLAS's
    /// count for each factorisation.
    fn analyze_planned(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        plan: &FactorPlan,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        analyze_with(lower, plan)
    }
}

fn analyze_with(
    lower: SymbolicSparseColMatRef<'_, usize>,
    plan: &FactorPlan,
) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
    if lower.nrows() != lower.ncols() {
        return Err(backend_error(format!(
            "matrix is {} × {}, not square",
            lower.nrows(),
            lower.ncols()
        )));
    }
    let mut csc = LowerCsc::new(lower, None);
    let mut common = Common::new()?;
    configure(&mut common);
    let mut header = csc.header();
    let l = match &plan.permutation {
        None => {
            // SAFETY: `header` describes valid arrays owned by `csc`,
            // alive for the call; the common is started.
            unsafe { ss::cholmod_l_analyze(&mut header, common.ptr()) }
        }
        Some(perm) => {
            if perm.len() != lower.nrows() {
                return Err(backend_error("the permutation's length"));
            }
            let mut given: Vec<Long> = perm.iter().map(|&p| p as Long).collect();
            common.get_mut().method[0].ordering = ss::CHOLMOD_GIVEN as _;
            // SAFETY: as above; `given` holds n entries, a permutation.
            unsafe {
                ss::cholmod_l_analyze_p(
                    &mut header,
                    given.as_mut_ptr(),
                    ptr::null_mut(),
                    0,
                    common.ptr(),
                )
            }
        }
    };
    if l.is_null() {
        return Err(status_error(NAME, "cholmod_l_analyze", common.status()));
    }
    let symbolic = Factor { l, common };
    let nnz = symbolic.predicted_nnz();
    Ok(Box::new(CholmodSymbolic {
        symbolic,
        n: lower.nrows(),
        lower_nnz: csc.x.len(),
        nnz,
        threads: plan.threads.requested(),
        ordering: plan.ordering_used("amd"),
    }))
}

struct CholmodSymbolic {
    symbolic: Factor,
    n: usize,
    /// Entries of the analysed lower triangle.
    lower_nnz: usize,
    nnz: usize,
    /// OpenBLAS's threads for each factorisation; `None`: its own.
    threads: Option<usize>,
    /// The report's word for the ordering used.
    ordering: std::borrow::Cow<'static, str>,
}

impl SpdSymbolic for CholmodSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn SpdFactor>, NumericalError> {
        if lower.nrows() != self.n || lower.ncols() != self.n {
            return Err(backend_error(
                "the matrix does not have the dimension that was analysed",
            ));
        }
        let mut csc = LowerCsc::new(lower.symbolic(), Some(lower.val()));
        if csc.x.len() != self.lower_nnz {
            return Err(backend_error(
                "the matrix does not have the pattern that was analysed",
            ));
        }
        let mut common = Common::new()?;
        configure(&mut common);
        // SAFETY: the symbolic factor is valid and only read; the copy is
        // allocated with the new common and owned by `factor` below.
        let l = unsafe { ss::cholmod_l_copy_factor(self.symbolic.l, common.ptr()) };
        if l.is_null() {
            return Err(status_error(NAME, "cholmod_l_copy_factor", common.status()));
        }
        let mut factor = Factor { l, common };
        let mut header = csc.header();
        let _threads = ThreadsFor::new(self.threads);
        // SAFETY: `header` describes arrays owned by `csc`; `factor.l` is a
        // copy of the symbolic factor of this pattern.
        let ok = unsafe { ss::cholmod_l_factorize(&mut header, factor.l, factor.common.ptr()) };
        let status = factor.common.status();
        if status == ss::CHOLMOD_NOT_POSDEF as i32 {
            // SAFETY: `l` valid; minor < n on failure.
            let minor = unsafe { (*factor.l).minor } as usize;
            let perm = factor.perm();
            return Err(NumericalError::NotPositiveDefinite {
                matrix: String::new(),
                unknown: perm.get(minor).copied().unwrap_or(minor),
                vertex: None,
                pivot: None,
            });
        }
        if ok == 0 || status < 0 {
            return Err(status_error(NAME, "cholmod_l_factorize", status));
        }
        let diag = factor.diagonal()?;
        check_breakdown(&diag, &factor.perm(), lower)?;
        Ok(Box::new(CholmodFactor {
            factor,
            nnz: self.nnz,
        }))
    }

    fn factor_nnz(&self) -> usize {
        self.nnz
    }

    /// The threads: those asked for when OpenBLAS is loaded (it is set
    /// for each factorisation), otherwise OpenBLAS's count in effect.
    fn plan_used(&self) -> PlanUsed {
        PlanUsed {
            ordering: self.ordering.clone(),
            threads: openblas::threads_used(self.threads),
        }
    }
}

struct CholmodFactor {
    factor: Factor,
    nnz: usize,
}

impl SpdFactor for CholmodFactor {
    fn dim(&self) -> usize {
        self.factor.n()
    }

    /// `cholmod_l_solve(CHOLMOD_A)` on all columns at once. CHOLMOD fails
    /// here only when out of memory: a [`NumericalError::OutOfMemory`]
    /// with CHOLMOD's status.
    fn solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) -> Result<(), NumericalError> {
        let (n, k) = (rhs.nrows(), rhs.ncols());
        if n == 0 || k == 0 {
            return Ok(());
        }
        let mut data = vec![0.0f64; n * k];
        for c in 0..k {
            for r in 0..n {
                data[c * n + r] = rhs[(r, c)];
            }
        }
        // SAFETY: an all-zero cholmod_dense is a valid value; the fields that
        // matter are set below and point into `data`, alive for the call.
        let mut b: ss::cholmod_dense = unsafe { std::mem::zeroed() };
        b.nrow = n as _;
        b.ncol = k as _;
        b.nzmax = (n * k) as _;
        b.d = n as _;
        b.x = data.as_mut_ptr().cast();
        b.z = ptr::null_mut();
        b.xtype = ss::CHOLMOD_REAL as _;
        b.dtype = ss::CHOLMOD_DOUBLE as _;
        let common = self.factor.common.ptr();
        // SAFETY: valid factor and right-hand side; the result is owned below.
        let mut x =
            unsafe { ss::cholmod_l_solve(ss::CHOLMOD_A as _, self.factor.l, &mut b, common) };
        if x.is_null() {
            // SAFETY: `common` is this factor's valid CHOLMOD workspace.
            let status = unsafe { (*common).status };
            return Err(status_error(NAME, "cholmod_l_solve", status));
        }
        // SAFETY: `x` is an n × k real dense matrix with leading dimension d.
        unsafe {
            let xd = &*x;
            let d = xd.d as usize;
            let xs = xd.x as *const f64;
            for c in 0..k {
                for r in 0..n {
                    rhs[(r, c)] = *xs.add(c * d + r);
                }
            }
            ss::cholmod_l_free_dense(&mut x, common);
        }
        Ok(())
    }

    fn nnz(&self) -> usize {
        self.nnz
    }

    fn bytes(&self) -> usize {
        // SAFETY: `l` valid; xsize / ssize are the sizes of x and s.
        unsafe {
            let l = &*self.factor.l;
            if l.is_super != 0 {
                l.xsize * 8 + l.ssize * 8
            } else {
                l.nzmax * 16
            }
        }
    }
}
