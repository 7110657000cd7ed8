#!/usr/bin/env python3
"""Why ours and libigl's `arap_solve` drift apart: libigl's iteration
re-implemented from libigl's own building blocks, with the rotations fitted
in double and in single precision.

    $PY experiments/arap_float_check.py \\
        MESH.obj SCENE.json WORK_DIR --iterations 10,100,1000

Run experiments/arap_compare.py with the same WORK_DIR first: it leaves our
positions after N iterations in WORK_DIR/ours_N.ply. This script then runs

- `igl.arap_solve` (spokes-and-rims, max_iter = N, libigl's tutorial
  initial guess: the rest pose with U[b] = bc);
- the same iteration written out in numpy/scipy, step by step as in
  libigl's arap.cpp: U[b] = bc; S = covariances of the spokes-and-rims
  energy (cotangent weights from `igl.cotmatrix_entries`), normalised by
  max |S| as libigl does; R = `igl.fit_rotations(S, single_precision)`;
  the global step (-L) U = K R with U[b] = bc (L = `igl.cotmatrix`, one
  sparse LU of the free block), once with `single_precision=True` (what
  `arap_solve` calls: `polar_svd3x3`, a fixed 4-sweep float Jacobi SVD) and
  once with `single_precision=False` (`polar_svd` in double);

and prints, per N, the largest coordinate difference over the bounding-box
diagonal between: ours and libigl; ours and the double re-implementation;
the single-precision re-implementation and libigl; the double and single
re-implementations. One JSON object per N on stdout, all of them in
WORK_DIR/float_check.json.
"""

import argparse
import json
import os

import igl
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def read_ply_doubles(path, n):
    with open(path, "rb") as fh:
        data = fh.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    return np.frombuffer(data, dtype="<f8", count=3 * n, offset=end).reshape(n, 3)


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
    ap.add_argument("mesh")
    ap.add_argument("scene")
    ap.add_argument("work")
    ap.add_argument("--iterations", default="10,100,1000")
    a = ap.parse_args()
    v, f = igl.read_triangle_mesh(a.mesh)
    v = np.ascontiguousarray(v, dtype=np.float64)
    f = np.ascontiguousarray(f, dtype=np.int64)
    with open(a.scene) as fh:
        cons = json.load(fh)["constraints"]
    b = np.array([c["vertex"] for c in cons], dtype=np.int64)
    bc = np.array([c["target"] for c in cons], dtype=np.float64)
    diag = np.linalg.norm(v.max(axis=0) - v.min(axis=0))
    checkpoints = sorted({int(s) for s in a.iterations.split(",") if s})
    it = Iteration(v, f, b, bc)
    double = it.run(checkpoints, single=False)
    single = it.run(checkpoints, single=True)

    def gap(x, y):
        return float(np.abs(x - y).max() / diag)

    rows = []
    for n in checkpoints:
        data = igl.ARAPData()
        data.energy = igl.ARAP_ENERGY_TYPE_SPOKES_AND_RIMS
        data.max_iter = n
        igl.arap_precomputation(v, f, 3, b.astype(np.int32), data)
        u0 = v.copy()
        u0[b] = bc
        libigl = igl.arap_solve(bc, data, u0)
        row = {
            "mesh": os.path.basename(a.mesh),
            "iterations": n,
            "double_reimplementation_vs_single_reimplementation": gap(double[n], single[n]),
            "single_reimplementation_vs_libigl": gap(single[n], libigl),
            "double_reimplementation_vs_libigl": gap(double[n], libigl),
        }
        ours_path = os.path.join(a.work, f"ours_{n}.ply")
        if os.path.exists(ours_path):
            ours = read_ply_doubles(ours_path, v.shape[0])
            row["ours_vs_libigl"] = gap(ours, libigl)
            row["ours_vs_double_reimplementation"] = gap(ours, double[n])
            row["ours_vs_single_reimplementation"] = gap(ours, single[n])
        rows.append(row)
        print(json.dumps(row), flush=True)
    with open(os.path.join(a.work, "float_check.json"), "w") as fh:
        json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
