#!/usr/bin/env python3
"""The Python rows of the `drag` experiment (experiments/drag_python.rs).

    python drag_python.py MESH.obj SCENE.json FRAMES.bin MIDDLE OUT_DIR

Needs the `lse_deform` package (pip install .) and numpy. SCENE.json is the
paper's scene (`lse-deform scene`: a `fixed` and a `handle` group of hard
position constraints); FRAMES.bin holds the handle's transform of every
frame, F x 3 x 4 float64 in native byte order (`[R | t]`, applied to the
handle's rest targets); MIDDLE is the 1-based frame whose shapes are kept.

One deformer (cotangent Laplacian, null-space QR, default refinement: the
module's defaults) is precomputed and solved once (warm-up, not timed),
then `basis(["handle"])` is built (timed). The frames then run twice, each
path as a drag runs it, frame after frame (as the Rust rows do; a solve
between two evaluations would evict the basis from the caches, which no
drag on the basis path does):

- the basis: `basis.evaluate({"handle": M}, out=buffer)` for every frame;
- the solve: `transform_group("handle", M)` then `solve()` for every frame.

Each is timed by the wall clock around its calls; the hard-constraint
residual (max over the constrained vertices of |x - target| over the
bounding-box diagonal) is measured after the clock has stopped. Prints one
JSON line with the timings and residuals, and writes the MIDDLE frame's
shapes (n x 3 float64, native order) to OUT_DIR/basis_middle.bin and
OUT_DIR/solve_middle.bin.
"""

import json
import os
import platform
import sys
import time

import numpy as np

import lse_deform


def read_obj(path):
    V, F = [], []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if parts and parts[0] == "v":
                V.append([float(x) for x in parts[1:4]])
            elif parts and parts[0] == "f":
                F.append([int(p.split("/")[0]) - 1 for p in parts[1:4]])
    return np.array(V, dtype=np.float64), np.array(F, dtype=np.int64)


class Targets:
    """The constrained vertices and their rest targets, by group."""

    def __init__(self, scene):
        items = json.load(open(scene))["constraints"]
        groups = {}
        for c in items:
            if c["type"] != "position" or "weight" in c:
                raise SystemExit("the scene must hold hard position constraints only")
            groups.setdefault(c.get("group"), []).append(c)
        self.fixed_v, self.fixed_t = self._arrays(groups.get("fixed", []))
        self.handle_v, self.handle_rest = self._arrays(groups.get("handle", []))

    @staticmethod
    def _arrays(items):
        v = np.array([c["vertex"] for c in items], dtype=np.int64)
        t = np.array([c["target"] for c in items], dtype=np.float64).reshape(-1, 3)
        return v, t

    def residual(self, X, M, diagonal):
        moved = self.handle_rest @ M[:, :3].T + M[:, 3]
        r = max(
            np.linalg.norm(X[self.fixed_v] - self.fixed_t, axis=1).max(initial=0.0),
            np.linalg.norm(X[self.handle_v] - moved, axis=1).max(initial=0.0),
        )
        return float(r / diagonal)


def timed(call):
    t = time.perf_counter()
    out = call()
    return time.perf_counter() - t, out


def main():
    mesh, scene, frames_file, middle, out_dir = sys.argv[1:6]
    middle = int(middle)
    V, F = read_obj(mesh)
    diagonal = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    frames = np.fromfile(frames_file, dtype=np.float64).reshape(-1, 3, 4)
    targets = Targets(scene)
    deformer = lse_deform.Deformer(V, F, scene)
    deformer.precompute()
    np.asarray(deformer.solve())
    build_s, basis = timed(lambda: deformer.basis(["handle"]))
    buffer = np.empty((len(V), 3), dtype=np.float64)
    rows = {"basis": [], "solve": [], "solve_phase": [], "refine": []}
    residual = {"basis": 0.0, "solve": 0.0}
    for f, M in enumerate(frames, start=1):
        s, X = timed(lambda: basis.evaluate({"handle": M}, out=buffer))
        rows["basis"].append(s)
        residual["basis"] = max(residual["basis"], targets.residual(X, M, diagonal))
        if f == middle:
            np.asarray(X, dtype=np.float64).tofile(os.path.join(out_dir, "basis_middle.bin"))
    for f, M in enumerate(frames, start=1):
        s, X = timed(lambda: (deformer.transform_group("handle", M), deformer.solve())[1])
        rows["solve"].append(s)
        timings = deformer.report["timings_s"]
        rows["solve_phase"].append(timings["solve"])
        rows["refine"].append(timings["refine"])
        residual["solve"] = max(residual["solve"], targets.residual(X, M, diagonal))
        if f == middle:
            np.asarray(X, dtype=np.float64).tofile(os.path.join(out_dir, "solve_middle.bin"))
    print(json.dumps({
        "python_version": platform.python_version(),
        "numpy_version": np.__version__,
        "basis_build_s": build_s,
        "basis_s": rows["basis"],
        "solve_frame_s": rows["solve"],
        "solve_phase_s": rows["solve_phase"],
        "refine_s": rows["refine"],
        "basis_residual": residual["basis"],
        "solve_residual": residual["solve"],
    }), flush=True)


if __name__ == "__main__":
    main()
