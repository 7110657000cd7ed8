#!/usr/bin/env python3
"""Why ours and libigl's `arap_solve` drift apart: libigl's iteration
re-implemented from libigl's own building blocks, with the rotations fitted
in double and in single precision (run by experiments/arap.rs).

    python3 arap_float_check.py DIR --iterations 10,100

DIR holds what experiments/arap.rs and arap_libigl.py wrote: the problem
(V.f64, F.i64, b.i32, bc.f64), libigl's positions after N iterations
(libigl_trace_N.f64, rest-pose start) and ours (ours_N.f64). The
re-implementation follows libigl's arap.cpp step by step: U[b] = bc;
S = covariances of the spokes-and-rims energy (cotangent weights from
`igl.cotmatrix_entries`), normalised by max |S| as libigl does;
R = `igl.fit_rotations(S, single_precision)`; the global step (-L) U = K R
with U[b] = bc (L = `igl.cotmatrix`, one sparse LU of the free block), once
with `single_precision=True` (what `arap_solve` calls: `polar_svd3x3`, a
fixed 4-sweep float Jacobi SVD) and once with `False` (`polar_svd` in
double). Prints one JSON list, one object per N: the largest coordinate
difference over the bounding-box diagonal between ours and libigl, ours and
the double re-implementation, the single re-implementation and libigl, and
the double and single re-implementations.
"""

import argparse
import json
import os
import sys

import igl
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


class Iteration:
    """libigl's arap_solve loop (spokes-and-rims, no dynamics, no groups)."""

    def __init__(self, v, f, b, bc):
        self.v, self.f, self.b, self.bc = v, f, b, bc
        n = v.shape[0]
        # C[t, k]: half cotangent of the angle at corner k, for the edge
        # opposite it, from f[k+1] to f[k+2].
        self.c = igl.cotmatrix_entries(v, f)
        self.tail = f[:, [1, 2, 0]]
        self.head = f[:, [2, 0, 1]]
        self.rest_edges = v[self.head] - v[self.tail]  # (m, 3 edges, 3)
        q = -igl.cotmatrix(v, f)
        free = np.setdiff1d(np.arange(n), b)
        self.free = free
        q = sp.csc_matrix(q)
        self.q_fb = q[free][:, b]
        self.lu = spla.splu(sp.csc_matrix(q[free][:, free]))

    def covariances(self, u):
        # Per triangle T = sum_k c_k p_k x_kᵀ (libigl's S = rest ⊗ deformed),
        # added to each of the three corners.
        x = u[self.head] - u[self.tail]
        t = np.einsum("tk,tka,tkb->tab", self.c, self.rest_edges, x)
        n = self.v.shape[0]
        s = np.zeros((n, 3, 3))
        for k in range(3):
            np.add.at(s, self.f[:, k], t)
        return s

    def rotations(self, s, single):
        n = s.shape[0]
        stacked = np.ascontiguousarray(s.transpose(1, 0, 2).reshape(3 * n, 3))
        stacked /= np.abs(stacked).max()
        r = igl.fit_rotations(stacked, single)  # 3 × 3n, block r = R_rᵀ... as arap.cpp
        return np.ascontiguousarray(r.reshape(3, n, 3).transpose(1, 0, 2))

    def rhs(self, r):
        # b_i = sum over edges (tail → head) of c_k R̄_t p_k, + at head, − at tail,
        # with R̄_t the mean of the corners' rotations.
        rbar = (r[self.f[:, 0]] + r[self.f[:, 1]] + r[self.f[:, 2]]) / 3.0
        rp = np.einsum("tab,tkb->tka", rbar, self.rest_edges) * self.c[:, :, None]
        n = self.v.shape[0]
        out = np.zeros((n, 3))
        for k in range(3):
            np.add.at(out, self.head[:, k], rp[:, k])
            np.subtract.at(out, self.tail[:, k], rp[:, k])
        return out

    def run(self, checkpoints, single):
        u = self.v.copy()
        u[self.b] = self.bc
        out = {}
        for it in range(1, max(checkpoints) + 1):
            u[self.b] = self.bc
            r = self.rotations(self.covariances(u), single)
            rhs = self.rhs(r)
            u = u.copy()
            u[self.free] = self.lu.solve(rhs[self.free] - self.q_fb @ self.bc)
            u[self.b] = self.bc
            if it in checkpoints:
                out[it] = u.copy()
        return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--iterations", default="10,100")
    a = ap.parse_args()

    def load(name, dtype):
        return np.fromfile(os.path.join(a.dir, name), dtype=dtype)

    v = np.ascontiguousarray(load("V.f64", "<f8").reshape(-1, 3))
    f = np.ascontiguousarray(load("F.i64", "<i8").reshape(-1, 3))
    b = np.ascontiguousarray(load("b.i32", "<i4")).astype(np.int64)
    bc = np.ascontiguousarray(load("bc.f64", "<f8").reshape(-1, 3))
    diag = np.linalg.norm(v.max(axis=0) - v.min(axis=0))
    checkpoints = sorted({int(s) for s in a.iterations.split(",") if s})
    it = Iteration(v, f, b, bc)
    double = it.run(checkpoints, single=False)
    single = it.run(checkpoints, single=True)

    def gap(x, y):
        return float(np.abs(x - y).max() / diag)

    rows = []
    for n in checkpoints:
        libigl = load(f"libigl_trace_{n}.f64", "<f8").reshape(-1, 3)
        ours = load(f"ours_{n}.f64", "<f8").reshape(-1, 3)
        rows.append(
            {
                "iterations": n,
                "ours_vs_libigl": gap(ours, libigl),
                "ours_vs_double_reimplementation": gap(ours, double[n]),
                "single_reimplementation_vs_libigl": gap(single[n], libigl),
                "double_vs_single_reimplementation": gap(double[n], single[n]),
            }
        )
    json.dump(rows, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
