//! Shared plumbing for the SuiteSparse back ends (feature `suitesparse`):
//! an owned `cholmod_common`, `cholmod_sparse` headers over our arrays, and
//! METIS's ordering through CHOLMOD ([`metis`], which the ordering module
//! computes a plan with: here, below both it and the CHOLMOD back end, so
//! that the ordering imports no back end).

use std::mem::MaybeUninit;

use faer::sparse::SymbolicSparseColMatRef;
use suitesparse_sys as ss;

use crate::error::NumericalError;

/// `SuiteSparse_long`, the index type of the `cholmod_l_*` / SPQR
/// interfaces (a C macro for `long`, so bindgen does not emit it).
pub(crate) type Long = std::os::raw::c_long;

/// An owned, started `cholmod_common` (the 64-bit-index "long" interface).
pub(crate) struct Common(Box<ss::cholmod_common>);

impl Common {
    /// `cholmod_l_start` with printing switched off (errors are reported
    /// through `status`, which we turn into typed errors).
    pub(crate) fn new() -> Result<Common, NumericalError> {
        let mut c: Box<MaybeUninit<ss::cholmod_common>> = Box::new_uninit();
        // SAFETY: cholmod_l_start initialises every field of the struct it is
        // given and returns TRUE on success.
        let ok = unsafe { ss::cholmod_l_start(c.as_mut_ptr()) };
        if ok == 0 {
            return Err(NumericalError::Backend {
                backend: "suitesparse".into(),
                message: "cholmod_l_start failed".into(),
            });
        }
        // SAFETY: initialised by cholmod_l_start above.
        let mut c = unsafe { c.assume_init() };
        c.print = 0;
        Ok(Common(c))
    }

    pub(crate) fn ptr(&mut self) -> *mut ss::cholmod_common {
        &mut *self.0
    }

    pub(crate) fn status(&self) -> i32 {
        self.0.status
    }
}

/// The error of the SuiteSparse call `call` of `backend` that failed with
/// CHOLMOD's `status`. `CHOLMOD_OUT_OF_MEMORY` (an allocation refused) and
/// `CHOLMOD_TOO_LARGE` (a size that overflows its integer type) are
/// [`NumericalError::OutOfMemory`], a refusal for size as an
/// [`crate::Error`]; any other status is [`NumericalError::Backend`]
/// quoting it. The codes are CHOLMOD's (`cholmod_core.h`, `status`).
pub(crate) fn status_error(backend: &str, call: &str, status: i32) -> NumericalError {
    if status == ss::CHOLMOD_OUT_OF_MEMORY || status == ss::CHOLMOD_TOO_LARGE {
        return NumericalError::out_of_memory(
            backend,
            &format!("the workspace of {call} (CHOLMOD status {status})"),
        );
    }
    NumericalError::Backend {
        backend: backend.into(),
        message: format!("{call} failed (CHOLMOD status {status})"),
    }
}

impl Drop for Common {
    fn drop(&mut self) {
        // SAFETY: started in `new`; every object allocated with this common
        // has been freed before (owners drop their objects first).
        unsafe {
            ss::cholmod_l_finish(self.ptr());
        }
    }
}

impl Common {
    /// The settings, for configuration before a call.
    pub(crate) fn get_mut(&mut self) -> &mut ss::cholmod_common {
        &mut self.0
    }
}

/// A `cholmod_sparse` header (64-bit indices, real `f64` values, sorted and
/// packed) over a compressed-column matrix of `nrow × ncol` held in `p`
/// (column pointers, `ncol + 1` of them), `i` (row indices) and `x` (values).
///
/// `stype` is CHOLMOD's symmetry flag: `0` unsymmetric, `-1` symmetric with
/// only the lower triangle stored. The header borrows nothing in Rust's
/// eyes: it is valid only while the three arrays are alive and unmoved, and
/// only for CHOLMOD/SPQR calls that read their input.
pub(crate) fn sparse_header(
    nrow: usize,
    ncol: usize,
    p: &mut [Long],
    i: &mut [Long],
    x: &mut [f64],
    stype: std::os::raw::c_int,
) -> ss::cholmod_sparse {
    // SAFETY: an all-zero cholmod_sparse is a valid value (null pointers,
    // zero sizes); the fields that matter are set below.
    let mut a: ss::cholmod_sparse = unsafe { std::mem::zeroed() };
    a.nrow = nrow as _;
    a.ncol = ncol as _;
    a.nzmax = x.len().max(1) as _;
    a.p = p.as_mut_ptr().cast();
    a.i = i.as_mut_ptr().cast();
    a.nz = std::ptr::null_mut();
    a.x = x.as_mut_ptr().cast();
    a.z = std::ptr::null_mut();
    a.stype = stype;
    a.itype = ss::CHOLMOD_LONG as _;
    a.xtype = ss::CHOLMOD_REAL as _;
    a.dtype = ss::CHOLMOD_DOUBLE as _;
    a.sorted = 1;
    a.packed = 1;
    a
}

/// Lower triangle in CHOLMOD's 64-bit CSC layout (owned arrays).
pub(crate) struct LowerCsc {
    n: usize,
    p: Vec<Long>,
    i: Vec<Long>,
    /// The values (the lower triangle's entries, in order).
    pub(crate) x: Vec<f64>,
}

impl LowerCsc {
    /// Copies the lower triangle (rows ≥ column) of `pattern`, with `values`
    /// when given (else zeros).
    pub(crate) fn new(
        pattern: SymbolicSparseColMatRef<'_, usize>,
        values: Option<&[f64]>,
    ) -> LowerCsc {
        let n = pattern.ncols();
        let mut p = Vec::with_capacity(n + 1);
        let mut i = Vec::new();
        let mut x = Vec::new();
        p.push(0);
        for j in 0..n {
            for q in pattern.col_range(j) {
                let r = pattern.row_idx()[q];
                if r >= j {
                    i.push(r as Long);
                    x.push(values.map_or(0.0, |v| v[q]));
                }
            }
            p.push(i.len() as Long);
        }
        LowerCsc { n, p, i, x }
    }

    /// A `cholmod_sparse` header over the arrays (valid while `self` is
    /// borrowed; CHOLMOD only reads it).
    pub(crate) fn header(&mut self) -> ss::cholmod_sparse {
        sparse_header(self.n, self.n, &mut self.p, &mut self.i, &mut self.x, -1)
    }
}

/// METIS's nested-dissection ordering of the pattern `lower` through
/// `cholmod_l_metis` (postordered), `perm[i]` eliminated `i`-th.
pub(crate) fn metis(lower: SymbolicSparseColMatRef<'_, usize>) -> Result<Vec<usize>, String> {
    let mut csc = LowerCsc::new(lower, None);
    let mut common = Common::new().map_err(|e| e.to_string())?;
    let mut header = csc.header();
    let mut perm: Vec<Long> = vec![0; lower.nrows()];
    // SAFETY: `header` describes arrays owned by `csc`; `perm` has n
    // entries; no subset is given.
    let ok = unsafe {
        ss::cholmod_l_metis(
            &mut header,
            std::ptr::null_mut(),
            0,
            1,
            perm.as_mut_ptr(),
            common.ptr(),
        )
    };
    if ok == 0 {
        return Err(format!(
            "cholmod_l_metis failed (status {})",
            common.status()
        ));
    }
    Ok(perm.into_iter().map(|p| p as usize).collect())
}

#[cfg(test)]
mod tests {
    use super::status_error;

    /// CHOLMOD's codes (`cholmod_core.h`): −2 out of memory and −3 too
    /// large are refusals for size (exit 2); −4 invalid input and −5 a GPU
    /// problem are back-end failures (exit 3) quoting the code.
    #[test]
    fn out_of_memory_and_too_large_are_refusals_for_size() {
        let exit =
            |status| crate::Error::from(status_error("cholmod", "cholmod_l_analyze", status));
        for status in [-2, -3] {
            let e = exit(status);
            assert_eq!(e.exit_code(), 2, "{e}");
            assert!(
                e.to_string().contains(&format!("CHOLMOD status {status}")),
                "{e}"
            );
        }
        for status in [-4, -5] {
            let e = exit(status);
            assert_eq!(e.exit_code(), 3, "{e}");
            assert!(
                e.to_string().contains(&format!(
                    "cholmod_l_analyze failed (CHOLMOD status {status})"
                )),
                "{e}"
            );
        }
    }
}
