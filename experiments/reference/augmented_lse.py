#!/usr/bin/env python3
"""An independent reference solution of min ||A X - C|| s.t. B X = D.

Reads the Matrix Market files `lse-deform export-system` writes (A, C, B, D)
and solves the augmented system (Bjorck's formulation, condition kappa(A)
rather than kappa(A)^2, nothing shared with lse-deform's code):

    [ a*I   A   0  ] [ r/a ]   [ C ]
    [ A^T   0   B^T] [  x  ] = [ 0 ]      r = C - A x,  A^T r + B^T nu = 0
    [  0    B   0  ] [  nu ]   [ D ]

by SciPy's SuperLU (partial pivoting), then iterative refinement with the
residual of the original rows computed in extended precision
(numpy.longdouble, 64-bit mantissa on x86), until a correction stops
shrinking.  Writes X (n x k) as a dense Matrix Market array and prints the
refinement history.  Redundant rows of B make the system singular: this
reference is for problems whose hard constraints are independent.

Usage: augmented_lse.py SYSTEM_DIR OUT.mtx
"""
import sys

import numpy as np
import scipy.io
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def main(directory, out):
    A = sp.csr_matrix(scipy.io.mmread(f"{directory}/A.mtx"))
    B = sp.csr_matrix(scipy.io.mmread(f"{directory}/B.mtx"))
    C = np.asarray(scipy.io.mmread(f"{directory}/C.mtx"), dtype=float)
    D = np.asarray(scipy.io.mmread(f"{directory}/D.mtx"), dtype=float)
    l, n = A.shape
    m = B.shape[0]
    # a ~ the size of A's entries keeps the blocks balanced (Bjorck 1996, 2.5.3).
    a = float(np.sqrt(abs(A).max() * 1.0))
    K = sp.bmat(
        [
            [a * sp.identity(l), A, None],
            [A.T, None, B.T],
            [None, B, sp.csr_matrix((m, m))],
        ],
        format="csc",
    )
    rhs = np.vstack([C, np.zeros((n, C.shape[1])), D])
    lu = spla.splu(K, permc_spec="COLAMD", diag_pivot_thresh=1.0)
    y = lu.solve(rhs)
    # Extended-precision residuals of the original rows.
    K_ld = K.astype(np.longdouble)
    rhs_ld = rhs.astype(np.longdouble)
    y_ld = y.astype(np.longdouble)
    previous = np.inf
    for step in range(30):
        res = rhs_ld - K_ld @ y_ld
        dy = lu.solve(np.asarray(res, dtype=float))
        size = np.abs(dy[l : l + n]).max() / max(np.abs(y_ld[l : l + n]).max(), 1e-300)
        print(f"step {step + 1}: correction of x {size:.3e} (relative)")
        if not np.isfinite(size) or size >= previous:
            break
        y_ld = y_ld + dy.astype(np.longdouble)
        previous = size
        if size < 1e-19:
            break
    x = np.asarray(y_ld[l : l + n], dtype=float)
    scipy.io.mmwrite(out, x, comment="augmented-system reference (SciPy SuperLU + long-double refinement)")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
