#!/usr/bin/env python3
"""Ours (`lse-deform deform --energy arap`) against libigl's `arap_solve`,
side by side in one run, on a position-only scene.

    $PY experiments/arap_compare.py \\
        target/release/lse-deform MESH.obj SCENE.json WORK_DIR --iterations 10,100,1000

SCENE.json is a `lse-deform scene` file of hard position constraints. Both
start from the rest pose with the constrained vertices at their targets
(`--arap-init rest`), spokes-and-rims energy, the same max_iter. Prints, per
N, `max |ours − libigl| / bbox diagonal` and the mean time per iteration of
each (ours: local + global steps from the report; libigl: the arap_solve
call divided by N), and their ratio.
"""

import argparse
import json
import os
import subprocess
import sys
import time

import igl
import numpy as np


def read_ply_doubles(path, n):
    with open(path, "rb") as fh:
        data = fh.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    return np.frombuffer(data, dtype="<f8", count=3 * n, offset=end).reshape(n, 3)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("binary")
    ap.add_argument("mesh")
    ap.add_argument("scene")
    ap.add_argument("work")
    ap.add_argument("--iterations", default="10,100,1000")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    v, f = igl.read_triangle_mesh(a.mesh)
    v = np.ascontiguousarray(v, dtype=np.float64)
    f = np.ascontiguousarray(f, dtype=np.int64)
    with open(a.scene) as fh:
        cons = json.load(fh)["constraints"]
    b = np.array([c["vertex"] for c in cons], dtype=np.int32)
    bc = np.array([c["target"] for c in cons], dtype=np.float64)
    diag = np.linalg.norm(v.max(axis=0) - v.min(axis=0))
    rows = []
    for n in [int(s) for s in a.iterations.split(",")]:
        data = igl.ARAPData()
        data.energy = igl.ARAP_ENERGY_TYPE_SPOKES_AND_RIMS
        data.max_iter = n
        t = time.perf_counter()
        igl.arap_precomputation(v, f, 3, b, data)
        igl_pre = time.perf_counter() - t
        u0 = v.copy()
        u0[b] = bc
        t = time.perf_counter()
        u = igl.arap_solve(bc, data, u0)
        igl_total = time.perf_counter() - t
        out = os.path.join(a.work, f"ours_{n}.ply")
        rep = os.path.join(a.work, f"ours_{n}.json")
        subprocess.run(
            [a.binary, "deform", a.mesh, "-c", a.scene, "-o", out, "--report", rep,
             "--energy", "arap", "--arap-energy", "spokes-and-rims",
             "--arap-init", "rest", "--iterations", str(n), "--tolerance", "0"],
            check=True,
        )
        ours = read_ply_doubles(out, v.shape[0])
        with open(rep) as fh:
            r = json.load(fh)
        arap = r["arap"]
        ours_iter = (arap["local_time_s"] + arap["global_time_s"]) / arap["iterations"]
        igl_iter = igl_total / n
        row = {
            "mesh": os.path.basename(a.mesh),
            "vertices": int(v.shape[0]),
            "iterations": n,
            "max_difference_over_diagonal": float(np.abs(ours - u).max() / diag),
            "ours_time_per_iteration_s": ours_iter,
            "ours_local_s": arap["local_time_s"] / n,
            "ours_global_s": arap["global_time_s"] / n,
            "libigl_time_per_iteration_s": igl_iter,
            "ratio": ours_iter / igl_iter,
            "ours_precompute_s": r["timings_s"]["qr"] + r["timings_s"]["preparation"]
            + r["timings_s"]["normal_matrix"] + r["timings_s"]["symbolic"]
            + r["timings_s"]["numeric"],
            "libigl_precompute_s": igl_pre,
            "ours_final_energy": arap["energies"][-1],
        }
        rows.append(row)
        print(json.dumps(row), flush=True)
    json.dump(rows, open(os.path.join(a.work, "summary.json"), "w"), indent=1)


if __name__ == "__main__":
    main()
