#!/usr/bin/env python3
"""The Python door's side of the `python` experiment (experiments/python.rs).

    python python_door.py MESH.obj SCENE.json

Needs the `lse_deform` package (pip install .), numpy, scipy and libigl.
SCENE.json holds position constraints only (a `lse-deform scene` file).

First prints one JSON line: the libigl agreement — max |U - U_igl| / bbox
diagonal, U from `lse_deform.deform(V, F, SCENE)` (cotangent Laplacian,
null-space QR), U_igl from libigl's `min_quad_with_fixed` on L = -M^-1 C
from libigl's own `cotmatrix` and `massmatrix(VORONOI)` (the energy
||L X - L V||^2 with the constrained rows fixed) — our forward-error
estimate, libigl's solve time and the versions.

Then, for every line "run" on stdin, one precompute + solve through the
module (`Deformer.precompute(); Deformer.solve()`, wall clock around the
two calls, the result a numpy array) and one JSON line {"seconds": s}.
The experiment alternates these rounds with the same calls timed inside
Rust, so that both see the same machine state. Ends at end of input.
"""

import json
import platform
import sys
import time
from importlib.metadata import version

import igl
import numpy as np
import scipy.sparse as sp

import lse_deform


def agreement(mesh, scene):
    items = json.load(open(scene))["constraints"]
    if not all(c["type"] == "position" and "weight" not in c for c in items):
        raise SystemExit("the scene must hold hard position constraints only")
    b = np.array([c["vertex"] for c in items], dtype=np.int64)
    bc = np.array([c["target"] for c in items], dtype=np.float64)
    V, F = igl.read_triangle_mesh(mesh)
    diag = np.linalg.norm(V.max(axis=0) - V.min(axis=0))
    U, report = lse_deform.deform(V, F, scene)
    C = igl.cotmatrix(V, F)
    M = igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI)
    L = sp.csc_matrix(-(sp.diags(1.0 / M.diagonal()) @ C))
    t = time.perf_counter()
    U_igl = igl.min_quad_with_fixed(
        sp.csc_matrix(L.T @ L), -(L.T @ (L @ V)), b, bc,
        sp.csc_matrix((0, len(V))), np.zeros((0, 3)), True,
    )
    return V, F, {
        "vertices": int(len(V)),
        "constraints": int(len(b)),
        "libigl_max_difference_over_diagonal": float(np.abs(U - U_igl).max() / diag),
        "forward_error_estimate": float(report["forward_error_estimate"]),
        "libigl_solve_s": time.perf_counter() - t,
        "python_version": platform.python_version(),
        "numpy_version": np.__version__,
        "scipy_version": version("scipy"),
        "libigl_version": version("libigl"),
    }


def main():
    mesh, scene = sys.argv[1:3]
    V, F, first = agreement(mesh, scene)
    print(json.dumps(first), flush=True)
    deformer = lse_deform.Deformer(V, F, scene)
    for line in sys.stdin:
        if line.strip() != "run":
            raise SystemExit(f"unexpected input {line!r}")
        t = time.perf_counter()
        deformer.precompute()
        np.asarray(deformer.solve())
        print(json.dumps({"seconds": time.perf_counter() - t}), flush=True)


if __name__ == "__main__":
    main()
