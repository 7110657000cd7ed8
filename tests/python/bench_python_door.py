"""The Python door measured (not collected by pytest: not test_*.py).

    python tests/python/bench_python_door.py [MESH] [--repeats R]

MESH defaults to ../shared/meshes/bunny-35k-stanford.obj. Scene: the CLI's
`lse-deform scene MESH --fixed 0.2 --handle 0.02` (position-only). Prints

1. the libigl agreement: max |U_python - U_igl| / bbox diagonal, U_igl by
   libigl's min_quad_with_fixed on L = -M^-1 C from libigl's cotmatrix and
   massmatrix (the energy ||L X - L V||^2 with the fixed rows);
2. precompute + solve through Python (`Deformer.precompute(); .solve()`,
   wall clock around the two calls) against the same through Rust
   (`cargo bench --bench python_door`, the same calls timed inside the
   Rust program, second of two runs per process), alternated round by
   round; medians and their ratio.

Needs the module installed (pip install .), libigl, and cargo.
"""

import argparse
import json
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
import scipy.sparse as sp

import lse_deform

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(pathlib.Path(__file__).parent))
from conftest import cli_binary, shared_mesh  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mesh", nargs="?", default=shared_mesh("bunny-35k-stanford.obj"))
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    import igl

    mesh = str(args.mesh)
    exe = cli_binary()
    work = pathlib.Path(tempfile.mkdtemp())
    scene = work / "scene.json"
    subprocess.run([exe, "scene", mesh, "--fixed", "0.2", "--handle", "0.02", "-o", str(scene)], check=True)
    items = json.loads(scene.read_text())["constraints"]
    assert all(c["type"] == "position" and "weight" not in c for c in items)
    b = np.array([c["vertex"] for c in items], dtype=np.int64)
    bc = np.array([c["target"] for c in items], dtype=np.float64)
    V, F = igl.read_triangle_mesh(mesh)
    diag = np.linalg.norm(V.max(axis=0) - V.min(axis=0))

    U, report = lse_deform.deform(V, F, str(scene))
    C = igl.cotmatrix(V, F)
    M = igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI)
    L = sp.csc_matrix(-(sp.diags(1.0 / M.diagonal()) @ C))
    t = time.perf_counter()
    U_igl = igl.min_quad_with_fixed(
        sp.csc_matrix(L.T @ L), -(L.T @ (L @ V)), b, bc, sp.csc_matrix((0, len(V))), np.zeros((0, 3)), True
    )
    igl_seconds = time.perf_counter() - t
    print(f"mesh {mesh}: {len(V)} vertices, {len(b)} position constraints")
    print(f"libigl agreement: max |U - U_igl| / diagonal = {np.abs(U - U_igl).max() / diag:.2e}"
          f" (forward error estimate {report['forward_error_estimate']:.1e}; libigl's solve took {igl_seconds:.3f} s)")

    deformer = lse_deform.Deformer(V, F, str(scene))
    # each Rust process runs twice and keeps the second (warm) run, as the
    # Python loop runs in one warm process
    cargo = ["cargo", "bench", "-q", "--bench", "python_door", "--", mesh, str(scene), "2"]
    subprocess.run(cargo[:5] + ["--no-run"], cwd=ROOT, check=True, capture_output=True)
    py, rs = [], []
    for _ in range(args.repeats):
        out = subprocess.run(cargo, cwd=ROOT, check=True, capture_output=True, text=True).stdout
        rs.append(json.loads(out)["seconds"][-1])
        t = time.perf_counter()
        deformer.precompute()
        deformer.solve()
        py.append(time.perf_counter() - t)
    mp, mr = statistics.median(py), statistics.median(rs)
    print(f"precompute + solve, {args.repeats} alternated rounds: Python median {mp:.3f} s, "
          f"Rust median {mr:.3f} s, ratio {mp / mr:.3f}")
    print(f"  Python {['%.3f' % s for s in py]}\n  Rust   {['%.3f' % s for s in rs]}")


if __name__ == "__main__":
    main()
