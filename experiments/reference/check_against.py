#!/usr/bin/env python3
"""Distance of a deformed mesh from a reference solution.

Usage: check_against.py SYSTEM_DIR REF.mtx DEFORMED.obj REPORT.json

SYSTEM_DIR and REF.mtx as written by `lse-deform export-system` and
augmented_lse.py (both in the problem's units: the mesh divided by the
report's `length_unit`); DEFORMED.obj and REPORT.json as written by
`lse-deform deform -o ... --report ...`.  Prints
  dX = max_i |X_i - X*_i| / bbox diagonal   and
  dE = |E - E*| / E*, E = ||A X - C||^2 (in extended precision).
"""
import json
import sys

import numpy as np
import scipy.io
import scipy.sparse as sp


def read_obj_positions(path):
    rows = [line.split()[1:4] for line in open(path) if line.startswith("v ")]
    return np.array(rows, dtype=float)


def energy(A, C, X):
    r = C.astype(np.longdouble) - A.astype(np.longdouble) @ X.astype(np.longdouble)
    return float((r * r).sum())


def main(directory, ref_path, obj_path, report_path):
    report = json.load(open(report_path))
    unit, diagonal = report["length_unit"], report["length_scale"]
    A = sp.csr_matrix(scipy.io.mmread(f"{directory}/A.mtx"))
    C = np.asarray(scipy.io.mmread(f"{directory}/C.mtx"), dtype=float)
    x_ref = np.asarray(scipy.io.mmread(ref_path), dtype=float)
    x = read_obj_positions(obj_path)
    dx = np.sqrt(((x - unit * x_ref) ** 2).sum(axis=1)).max() / diagonal
    e, e_ref = energy(A, C, x / unit), energy(A, C, x_ref)
    print(f"dX = {dx:.2e} of the diagonal, dE = {abs(e - e_ref) / e_ref:.2e} relative")


if __name__ == "__main__":
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    main(*sys.argv[1:])
