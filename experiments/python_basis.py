#!/usr/bin/env python3
"""What a frame of a rigid handle drag costs from Python, three ways,
side by side on the same frames.

    python python_basis.py MESH.obj SCENE.json [FRAMES]

Needs the `lse_deform` package (pip install .) and numpy. SCENE.json is a
`lse-deform scene` file (groups "fixed" and "handle"). The handle turns
about an axis through its rest centroid (to 0.6 rad) and moves (to 0.1 of
the bounding-box diagonal) over FRAMES frames (default 20). Per frame,
wall clock around each call:

- `evaluate`: `basis.evaluate({"handle": M}, out=out)` of
  `Deformer.basis(["handle"])` (built once, `build_s`);
- `evaluate_new`: the same into a new array (the two alternate which
  runs first: the first read of the basis after a solve is from memory,
  the second from cache);
- `solve`: `transform_group("handle", M)` + `solve()` (refined, with
  diagnostics: the library default);
- `solve_cheap`: `solve(refine="off", estimate=False)` for the same
  targets.

Prints one JSON line: the medians, the ratios of `evaluate` to `solve`
and `solve_cheap` to `solve`, and the largest difference between the
basis's and the refined solve's positions over the diagonal.
"""

import json
import statistics
import sys
import time

import numpy as np

import lse_deform


def read_obj(path):
    V, F = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                V.append([float(t) for t in line.split()[1:4]])
            elif line.startswith("f "):
                F.append([int(t.split("/")[0]) - 1 for t in line.split()[1:4]])
    return np.array(V, dtype=np.float64), np.array(F, dtype=np.int64)


def rotation(axis, angle):
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def timed(f):
    t = time.perf_counter()
    result = f()
    return time.perf_counter() - t, result


def main():
    mesh, scene = sys.argv[1:3]
    frames = int(sys.argv[3]) if len(sys.argv) > 3 else 20
    V, F = read_obj(mesh)
    items = json.load(open(scene))["constraints"]
    centroid = np.array([c["target"] for c in items if c.get("group") == "handle"]).mean(axis=0)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    deformer = lse_deform.Deformer(V, F, scene)
    precompute_s, _ = timed(deformer.precompute)
    deformer.solve()
    build_s, basis = timed(lambda: deformer.basis(["handle"]))
    out = np.empty((len(V), 3))
    times = {"evaluate": [], "evaluate_new": [], "solve": [], "solve_cheap": []}
    difference = 0.0
    for f in range(1, frames + 1):
        s = f / frames
        R = rotation([0.3, 1.0, 0.5], 0.6 * s)
        M = np.c_[R, centroid - R @ centroid + diag * s * np.array([0.1, -0.05, 0.08])]
        # the first read of the basis after a solve finds it out of cache:
        # alternate which of the two goes first
        calls = [
            ("evaluate", lambda: basis.evaluate({"handle": M}, out=out)),
            ("evaluate_new", lambda: basis.evaluate({"handle": M})),
        ]
        for name, call in calls if f % 2 else calls[::-1]:
            t, _ = timed(call)
            times[name].append(t)
        t, U = timed(lambda: (deformer.transform_group("handle", M), deformer.solve())[1])
        times["solve"].append(t)
        t, _ = timed(lambda: deformer.solve(refine="off", estimate=False))
        times["solve_cheap"].append(t)
        difference = max(difference, float(np.abs(out - U).max()) / diag)
    medians = {k + "_median_s": statistics.median(v) for k, v in times.items()}
    print(json.dumps({
        "vertices": len(V),
        "handle_constraints": sum(c.get("group") == "handle" for c in items),
        "frames": frames,
        "precompute_s": precompute_s,
        "build_s": build_s,
        "basis_bytes": basis.bytes,
        "basis_forward_error_estimate": basis.forward_error_estimate,
        **medians,
        "evaluate_over_solve": medians["evaluate_median_s"] / medians["solve_median_s"],
        "solve_cheap_over_solve": medians["solve_cheap_median_s"] / medians["solve_median_s"],
        "max_difference_over_diagonal": difference,
    }))


if __name__ == "__main__":
    main()
