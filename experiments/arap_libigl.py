#!/usr/bin/env python3
"""libigl's ARAP on a mesh and position constraints, for experiments/arap.rs.

    python3 arap_libigl.py DIR --iterations 10,100,1000 --trace 1,2,5,10

DIR holds the problem as raw little-endian arrays written by
experiments/arap.rs: V.f64 (n × 3), F.i64 (m × 3), b.i32 (the constrained
vertices) and bc.f64 (their targets, k × 3), row-major, so that both sides
read exactly the same numbers. For each N in --iterations, runs
`arap_solve` with `max_iter = N` from libigl's tutorial initial guess (the
rest pose with U[b] = bc) and writes DIR/libigl_iter_N.f64 (n × 3
little-endian doubles, row-major). For --trace, chains `arap_solve` calls
(each iteration depends on U only, so chaining equals one call with the
summed max_iter) and writes DIR/libigl_trace_K.f64 after K iterations.
Prints one JSON object on stdout: the libigl version, the precompute time,
and per run its total and per-iteration wall-clock seconds.
"""

import argparse
import json
import os
import sys
import time

import igl
import numpy as np


def libigl_version():
    try:
        from importlib.metadata import version

        return version("libigl")
    except Exception:  # noqa: BLE001 - any failure: the version is unknown
        return getattr(igl, "__version__", "unknown")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out_dir")
    ap.add_argument("--iterations", default="10,100,1000")
    ap.add_argument("--trace", default="")
    a = ap.parse_args()

    def load(name, dtype):
        return np.fromfile(os.path.join(a.out_dir, name), dtype=dtype)

    v = np.ascontiguousarray(load("V.f64", "<f8").reshape(-1, 3))
    f = np.ascontiguousarray(load("F.i64", "<i8").reshape(-1, 3))
    b = np.ascontiguousarray(load("b.i32", "<i4"))
    bc = np.ascontiguousarray(load("bc.f64", "<f8").reshape(-1, 3))

    def precompute(max_iter):
        data = igl.ARAPData()
        data.energy = igl.ARAP_ENERGY_TYPE_SPOKES_AND_RIMS
        data.max_iter = max_iter
        t = time.perf_counter()
        igl.arap_precomputation(v, f, 3, b, data)
        return data, time.perf_counter() - t

    def initial():
        u = v.copy()
        u[b] = bc
        return u

    out = {
        "libigl_version": libigl_version(),
        "vertices": int(v.shape[0]),
        "faces": int(f.shape[0]),
        "runs": [],
        "trace": [],
    }
    for n in [int(s) for s in a.iterations.split(",") if s]:
        data, pre = precompute(n)
        u0 = initial()
        t = time.perf_counter()
        u = igl.arap_solve(bc, data, u0)
        total = time.perf_counter() - t
        np.ascontiguousarray(u, dtype="<f8").tofile(
            os.path.join(a.out_dir, f"libigl_iter_{n}.f64")
        )
        out["runs"].append(
            {
                "max_iter": n,
                "precompute_s": pre,
                "total_s": total,
                "time_per_iteration_s": total / max(n, 1),
            }
        )
    checkpoints = sorted({int(s) for s in a.trace.split(",") if s})
    if checkpoints:
        u = initial()
        done = 0
        elapsed = 0.0
        for k in checkpoints:
            data, _ = precompute(k - done)
            t = time.perf_counter()
            u = igl.arap_solve(bc, data, u)
            elapsed += time.perf_counter() - t
            done = k
            np.ascontiguousarray(u, dtype="<f8").tofile(
                os.path.join(a.out_dir, f"libigl_trace_{k}.f64")
            )
            out["trace"].append({"iterations": k, "elapsed_s": elapsed})
    json.dump(out, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
