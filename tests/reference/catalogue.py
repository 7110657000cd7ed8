#!/usr/bin/env python3
"""The reference catalogue: lse-deform checked from outside.

Builds scenes (generated meshes always, real meshes when the mesh directory
is there), writes their constraints files, runs the `lse-deform` binary on
each with every formulation and back end of the build, computes the
independent reference of lse_reference.py from the same mesh and
constraints files, and compares:

  positions   max vertex distance / bounding-box diagonal      <= 1e-10
  energy      |E(X_lib) - E(X_ref)| / E(X_ref), both by the    <= 1e-12
              reference's own E
  rank, redundant and conflicting sets (methods with rank detection)
              identical; conflict residuals within 1e-9 of the diagonal

One line per run, a summary, the wall time and, last, `N passed, N failed`.
Exit status 1 on any failure.

    python tests/reference/catalogue.py [--mesh-dir DIR] [--bin PATH] [--jobs N] [--keep DIR] [--only SUBSTRING]
                                        [--factor NAME [--launcher CMD]]

With --factor NAME (e.g. mumps) only the methods that take a factor back
end run, each with `--factor NAME`, against the same targets; --launcher CMD
runs every deform through CMD (e.g. `mpirun -np 2 ...`).

Environment: LSE_DEFORM_BIN (the binary; default target/release/lse-deform
if it exists and is newer than target/debug/lse-deform, else the debug one),
LSE_MESH_DIR (default ../shared/meshes from the repository root), CI (when
set, a missing mesh directory or a missing numpy/scipy/libigl is a failure,
not a skip).
"""

import argparse
import concurrent.futures
import json
import os
import pathlib
import shlex
import shutil
import subprocess
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
IN_CI = bool(os.environ.get("CI"))

try:
    import numpy as np
    import scipy  # noqa: F401
except ImportError as exc:  # pragma: no cover - environment problem
    print(f"FAIL  setup: numpy/scipy missing ({exc}); pip install numpy scipy libigl")
    print("0 passed, 1 failed")
    sys.exit(1)
try:
    import igl  # noqa: F401

    HAVE_IGL = True
except ImportError:
    HAVE_IGL = False

sys.path.insert(0, str(HERE))
import lse_reference as R  # noqa: E402

POS_TOL = 1e-10
ENERGY_TOL = 1e-12
CONFLICT_RESIDUAL_TOL = 1e-9
SOFT_WEIGHTS = (0.1, 1.0, 10.0, 100.0)
LAPS = R.LAPLACIANS
CLASSES = ("hard", "hard+soft", "all-kinds", "redundant", "conflicting")

# --------------------------------------------------------------------------
# Scenes
# --------------------------------------------------------------------------


def mesh_edges(F):
    e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0)


class SceneBuilder:
    """Deterministic constraint lists on one mesh. Every free constraint uses
    vertices no other free constraint uses, so rows are dependent only
    where a scene makes them so on purpose."""

    def __init__(self, V, F, seed, fixed=0.12, handle=0.04):
        self.V, self.F = V, F
        self.rng = np.random.default_rng(seed)
        self.diag = R.bbox_diagonal(V)
        n = len(V)
        ext = V.max(axis=0) - V.min(axis=0)
        axis = int(np.argmax(ext))
        side = int(np.argsort(ext)[1])
        order = np.lexsort((np.arange(n), V[:, axis]))
        nf = max(3, int(round(fixed * n)))
        nh = max(3, int(round(handle * n)))
        self.fixed = np.sort(order[:nf])
        self.handle = np.sort(order[n - nh :])
        # the handle turns by 0.3 rad about `axis` through its centroid and
        # moves by 10 % of the diagonal along the second-longest axis
        c = V[self.handle].mean(axis=0)
        ang = 0.3
        rot = np.eye(3)
        a, b = [k for k in range(3) if k != axis]
        rot[a, a], rot[a, b], rot[b, a], rot[b, b] = np.cos(ang), -np.sin(ang), np.sin(ang), np.cos(ang)
        move = np.zeros(3)
        move[side] = 0.1 * self.diag
        self.handle_target = (V[self.handle] - c) @ rot.T + c + move
        self.used = np.zeros(n, dtype=bool)
        self.used[self.fixed] = True
        self.used[self.handle] = True
        self.edges = mesh_edges(F)
        self.w_i = 0

    # targets -------------------------------------------------------------
    def disp(self, scale=0.03):
        d = self.rng.standard_normal(3)
        return d / np.linalg.norm(d) * scale * self.diag

    def weight(self):
        w = SOFT_WEIGHTS[self.w_i % len(SOFT_WEIGHTS)]
        self.w_i += 1
        return w

    # pieces --------------------------------------------------------------
    def fixed_rows(self):
        return [pos(v, self.V[v]) for v in self.fixed]

    def handle_rows(self):
        return [pos(v, t) for v, t in zip(self.handle, self.handle_target)]

    def free_vertices(self, k):
        free = np.flatnonzero(~self.used)
        pick = self.rng.choice(free, size=k, replace=False)
        self.used[pick] = True
        return [int(v) for v in pick]

    def free_edge(self):
        ok = np.flatnonzero(~self.used[self.edges[:, 0]] & ~self.used[self.edges[:, 1]])
        e = self.edges[self.rng.choice(ok)]
        self.used[e] = True
        return [int(e[0]), int(e[1])]

    def free_face(self):
        ok = np.flatnonzero(~self.used[self.F].any(axis=1))
        f = self.F[self.rng.choice(ok)]
        self.used[f] = True
        return [int(x) for x in f]

    def target_of(self, verts, coef):
        return sum(c * self.V[v] for v, c in zip(verts, coef))

    def position(self, soft=False):
        (v,) = self.free_vertices(1)
        return pos(v, self.V[v] + self.disp(), self.weight() if soft else None)

    def edge(self, soft=False):
        e = self.free_edge()
        t = float(self.rng.uniform(0.2, 0.8))
        return edge(e, t, self.target_of(e, [t, 1 - t]) + self.disp(), self.weight() if soft else None)

    def face(self, soft=False):
        f = self.free_face()
        s, t, _ = self.rng.dirichlet([2.0, 2.0, 2.0])
        return face(f, (s, t), self.target_of(f, [s, t, 1 - s - t]) + self.disp(), self.weight() if soft else None)

    def relative(self, soft=False):
        i, j = self.free_vertices(2)
        return rel(i, j, self.V[i] - self.V[j] + self.disp(0.02), self.weight() if soft else None)

    def softs(self, n_pos=20, n_face=5, n_edge=0, n_rel=0):
        out = [self.position(True) for _ in range(n_pos)]
        out += [self.face(True) for _ in range(n_face)]
        out += [self.edge(True) for _ in range(n_edge)]
        out += [self.relative(True) for _ in range(n_rel)]
        return out

    def hards(self, k=3):
        return [g() for g in (self.edge, self.face, self.relative) for _ in range(k)]

    def relative_tree(self, k):
        """`k` hard relative rows forming a tree along a feature: a walk of
        free vertices, each step to the free neighbour farthest along the
        mesh's longest axis, every fourth vertex also sprouting a one-edge
        branch; each row ties a vertex to its parent (target: their offset
        plus a small move). A tree has no cycle, so the rows are
        independent."""
        n = len(self.V)
        nbrs = [[] for _ in range(n)]
        for a, b in self.edges:
            nbrs[a].append(int(b))
            nbrs[b].append(int(a))
        ext = self.V.max(axis=0) - self.V.min(axis=0)
        along = self.V[:, int(np.argmax(ext))]
        free = np.flatnonzero(~self.used)
        (v,) = [int(x) for x in free[np.argsort(along[free])[len(free) // 4 : len(free) // 4 + 1]]]
        self.used[v] = True
        rows, path = [], [v]
        while len(rows) < k and path:
            options = [u for u in nbrs[path[-1]] if not self.used[u]]
            if not options:
                path.pop()  # a dead end: go on from an earlier vertex
                continue
            v = path[-1]
            u = max(options, key=lambda x: (along[x], x))
            self.used[u] = True
            rows.append(rel(u, v, self.V[u] - self.V[v] + self.disp(0.01)))
            if len(rows) % 4 == 0 and len(rows) < k:
                side = [w for w in nbrs[u] if not self.used[w]]
                if side:
                    w = side[0]
                    self.used[w] = True
                    rows.append(rel(w, u, self.V[w] - self.V[u] + self.disp(0.01)))
            path.append(u)
        return rows

    def shuffle(self, rows):
        perm = self.rng.permutation(len(rows))
        return [rows[i] for i in perm]

    # dependent rows ------------------------------------------------------
    def dependent_rows(self, variant, conflict):
        """Rows that depend on earlier ones: consistent (redundant), and when
        `conflict`, also inconsistent ones (offsets from 1e-6 to 1e-2 of the
        diagonal). Returns (rows placed before the fixed/handle block, rows
        placed after it)."""
        before, after = [], []
        fx = [int(v) for v in self.rng.choice(self.fixed, size=min(12, len(self.fixed)), replace=False)]
        tgt = {v: self.V[v] for v in fx}
        offsets = [1e-2, 1e-3, 1e-6]

        def off(k):
            d = self.rng.standard_normal(3)
            return d / np.linalg.norm(d) * offsets[k % len(offsets)] * self.diag

        if variant == "positions":
            # repeats of fixed and handle positions
            for v in fx[:4]:
                after.append(pos(v, tgt[v]))
            hv, ht = int(self.handle[0]), self.handle_target[0]
            after += [pos(hv, ht), pos(hv, ht)]
            if conflict:
                for k, v in enumerate(fx[4:7]):
                    after.append(pos(v, tgt[v] + off(k)))
                after.append(pos(hv, ht + off(1)))
                # priority: a free vertex fixed twice, the first target wins
                (u,) = self.free_vertices(1)
                after += [pos(u, self.V[u] + self.disp()), pos(u, self.V[u] + self.disp())]
            return before, after
        if variant == "hub":
            # relatives from one free hub vertex to many fixed vertices:
            # the first fixes the hub, every later one depends on it
            (hub,) = self.free_vertices(1)
            hub_t = self.V[hub] + self.disp()
            for k, v in enumerate(fx):
                vec = hub_t - tgt[v]
                if conflict and k % 3 == 2:
                    vec = vec + off(k)
                after.append(rel(hub, v, vec))
            return before, after
        # mixed kinds
        a, b, c = fx[0], fx[1], fx[2]
        after.append(pos(a, tgt[a]))  # exact repeat
        after.append(rel(a, b, tgt[a] - tgt[b]))
        t = float(self.rng.uniform(0.2, 0.8))
        after.append(edge([a, b], t, t * tgt[a] + (1 - t) * tgt[b]))
        s, tt, _ = self.rng.dirichlet([2.0, 2.0, 2.0])
        after.append(face([a, b, c], (s, tt), s * tgt[a] + tt * tgt[b] + (1 - s - tt) * tgt[c]))
        # a cycle of relatives among free vertices: the third follows
        i, j, k = self.free_vertices(3)
        v1, v2 = self.V[i] - self.V[j] + self.disp(0.01), self.V[j] - self.V[k] + self.disp(0.01)
        after += [rel(i, j, v1), rel(j, k, v2), rel(i, k, v1 + v2)]
        # a face that is a combination of an edge and a position
        f = self.free_face()
        s, tt, _ = self.rng.dirichlet([2.0, 2.0, 2.0])
        tk = self.V[f[2]] + self.disp()
        te = self.target_of(f[:2], [s / (s + tt), tt / (s + tt)]) + self.disp()
        after += [pos(f[2], tk), edge(f[:2], s / (s + tt), te), face(f, (s, tt), (s + tt) * te + (1 - s - tt) * tk)]
        if conflict:
            d, e, g = fx[3], fx[4], fx[5]
            after.append(pos(d, tgt[d] + off(0)))
            after.append(rel(d, e, tgt[d] - tgt[e] + off(1)))
            t = float(self.rng.uniform(0.2, 0.8))
            after.append(edge([e, g], t, t * tgt[e] + (1 - t) * tgt[g] + off(2)))
            s, tt, _ = self.rng.dirichlet([2.0, 2.0, 2.0])
            after.append(face([d, e, g], (s, tt), s * tgt[d] + tt * tgt[e] + (1 - s - tt) * tgt[g] + off(0)))
            i, j, k = self.free_vertices(3)
            v1, v2 = self.V[i] - self.V[j], self.V[j] - self.V[k]
            after += [rel(i, j, v1), rel(j, k, v2), rel(i, k, v1 + v2 + off(1))]
            # priority: a relative placed before the fixed block ties two
            # vertices that the fixed block later fixes apart
            p, q = fx[6], fx[7]
            before.append(rel(p, q, tgt[p] - tgt[q] + off(0)))
        return before, after

    def build(self, cls, variant="mixed"):
        fixed, handle = self.fixed_rows(), self.handle_rows()
        if cls == "hard":
            return fixed + handle
        if cls == "hard+soft":
            return self.shuffle(fixed + handle + self.softs(20, 5, 3, 0))
        if cls == "all-kinds":
            return self.shuffle(fixed + handle + self.hards(3) + self.softs(12, 4, 4, 4))
        if cls == "done-means":
            # the Done-means scene: hard positions, edges, faces and
            # relatives, 20 soft positions and 5 soft faces
            return self.shuffle(fixed + handle + self.hards(4) + self.softs(20, 5))
        if cls == "relative-tree":
            # hard positions and a tree of hard relative rows (found in the latest round of faults:
            # MUMPS's KKT lost its digits on such scenes)
            return self.shuffle(fixed + handle + self.relative_tree(int(variant)))
        if cls == "edges-beside-positions":
            # a handful of hard edge points beside the hard positions
            return self.shuffle(fixed + handle + [self.edge() for _ in range(int(variant))])
        conflict = cls == "conflicting"
        before, after = self.dependent_rows(variant, conflict)
        extra = self.hards(2) if variant == "mixed" else []
        soft = self.softs(8, 3, 2, 2)
        # soft rows interleaved: the report's indices are file indices
        tail = after + soft
        tail = [tail[i] for i in self.rng.permutation(len(tail))] if variant != "positions" else after + soft
        return before + fixed + handle + extra + tail


def _vec(x):
    return [float(v) for v in x]


def _w(row, w):
    if w is not None:
        row["weight"] = float(w)
    return row


def pos(v, target, w=None):
    return _w({"type": "position", "vertex": int(v), "target": _vec(target)}, w)


def edge(vs, t, target, w=None):
    return _w({"type": "edge", "vertices": [int(x) for x in vs], "t": float(t), "target": _vec(target)}, w)


def face(vs, st, target, w=None):
    return _w(
        {"type": "face", "vertices": [int(x) for x in vs], "barycentric": [float(st[0]), float(st[1])], "target": _vec(target)},
        w,
    )


def rel(i, j, vec, w=None):
    return _w({"type": "relative", "vertices": [int(i), int(j)], "vector": _vec(vec)}, w)


# --------------------------------------------------------------------------
# Methods and back ends
# --------------------------------------------------------------------------


def configs_for_factor(factor, suitesparse):
    """(label, arguments) of every method that takes a factor back end, each
    with `--factor factor`; nullspace-qr with each QR back end of the build."""
    qrs = ["sparse-givens", "dense-householder"] + (["spqr"] if suitesparse else [])
    ns = [(f"nullspace-qr {q} {factor}", ["--method", "nullspace-qr", "--qr", q, "--factor", factor]) for q in qrs]
    pen = [(f"penalty 1e4 {factor}", ["--method", "penalty", "--weight", "1e4", "--refine", "auto", "--factor", factor])]
    kkt = [(f"kkt {factor}", ["--method", "kkt", "--factor", factor])]
    eli = [(f"eliminate {factor}", ["--method", "eliminate", "--factor", factor])]
    return ns, pen, kkt, eli


def configs(suitesparse, factor=None):
    """(label, arguments) for every formulation and back end of the build,
    or with `factor` only the runs of that factor back end."""
    if factor:
        return configs_for_factor(factor, suitesparse)
    ns = [
        ("nullspace-qr sparse-givens faer-auto", ["--method", "nullspace-qr", "--qr", "sparse-givens", "--spd", "faer-auto"]),
        ("nullspace-qr dense-householder faer-supernodal", ["--method", "nullspace-qr", "--qr", "dense-householder", "--spd", "faer-supernodal"]),
        ("nullspace-qr sparse-givens faer-simplicial", ["--method", "nullspace-qr", "--qr", "sparse-givens", "--spd", "faer-simplicial"]),
        ("nullspace-qr dense-householder nalgebra", ["--method", "nullspace-qr", "--qr", "dense-householder", "--spd", "nalgebra"]),
    ]
    if suitesparse:
        ns.append(("nullspace-qr spqr cholmod", ["--method", "nullspace-qr", "--qr", "spqr", "--spd", "cholmod"]))
    spd = ["faer-auto", "faer-supernodal", "faer-simplicial", "nalgebra"] + (["cholmod"] if suitesparse else [])
    pen = [(f"penalty 1e4 {s}", ["--method", "penalty", "--weight", "1e4", "--refine", "auto", "--spd", s]) for s in spd]
    kkt = [(f"kkt {s}", ["--method", "kkt", "--spd", s]) for s in ("faer-auto", "faer-supernodal", "faer-simplicial")]
    eli = [(f"eliminate {s}", ["--method", "eliminate", "--spd", s]) for s in spd]
    return ns, pen, kkt, eli


def runs_for(scene_no, full, suitesparse, factor=None):
    """The runs of one scene. `full`: every null-space back end, else two of
    them (rotating); penalty, kkt and eliminate each once with a rotating
    SPD back end. With `factor`: nullspace-qr once, its QR back end
    rotating (the QR pairings are the default catalogue's; this one tests
    the factor), then penalty, kkt and eliminate."""
    ns, pen, kkt, eli = configs(suitesparse, factor)
    if factor:
        chosen = [ns[scene_no % len(ns)]]
    elif full:
        chosen = list(ns)
    else:
        chosen = [ns[scene_no % len(ns)], ns[(scene_no + 1) % len(ns)]]
    chosen.append(pen[scene_no % len(pen)])
    chosen.append(kkt[scene_no % len(kkt)])
    chosen.append(eli[scene_no % len(eli)])
    return chosen


# --------------------------------------------------------------------------
# Running and comparing
# --------------------------------------------------------------------------


def run_binary(binary, mesh, cons, lap, label, args, workdir, tag, launcher=()):
    out = workdir / f"{tag}.obj"
    rep = workdir / f"{tag}.report.json"
    cmd = list(launcher) + [str(binary), "deform", str(mesh), "-c", str(cons), "--laplacian", lap, "-o", str(out), "--report", str(rep)] + args
    t0 = time.time()
    p = subprocess.run(cmd, capture_output=True, text=True)
    return {"rc": p.returncode, "stderr": p.stderr, "stdout": p.stdout, "out": out, "report": rep, "seconds": time.time() - t0}


def expected_refusal(method, cons_kinds_hard, has_dependent):
    if method == "eliminate" and any(k != "position" for k in cons_kinds_hard):
        return "eliminate does not support", "eliminate takes hard position constraints only (docs/cli.md §2: other kinds are refused)"
    if method == "kkt" and has_dependent:
        return "is singular", "kkt refuses dependent hard constraints (docs/cli.md §2: redundant constraints -> Singular error)"
    return None


# The penalty method with W = 1e4 relative to the largest column norm of A
# (docs/cli.md §3, "The penalty weight is relative"): a soft row of weight 100 sets
# that norm, and a hard relative, edge or face row then enters AᵀA + (Ws)²BᵀB
# with a weight ~1e12 times the Laplacian's, so eliminating one of its
# unknowns cancels the penalty term and the next pivot is rounding. The
# library detects this and exits 3 (docs/cli.md §6: "numerical failure: a
# non-positive pivot ..."); recorded as not applicable, with the message.
PENALTY_BREAKDOWN = "the penalty normal matrix"

# MUMPS's Cholesky does not hand out its pivots, so the breakdown above is
# not refused as faer refuses it (docs/distributed.md §4): an exactly zero
# pivot is its error -10 ("numerically singular", exit 3), a pivot that
# rounding turned negative is refused by MUMPS's count of negative pivots
# ("negative pivot", exit 3) or met in the factorisation as not positive
# (its error -40, "not positive definite", exit 3; seen once on two ranks,
# bunny-35k-watertight/cotan/all-kinds at 1e4, which faer refuses as a
# breakdown and one rank by its count of negative pivots), and a pivot that lost its digits without
# turning negative shows only in the forward-error warning of the solve,
# with exit 0 and a wrong mesh. With --factor mumps a penalty run that fails
# the comparison *and* carries that warning is the same breakdown, not
# applicable; one without the warning is a failure.
MUMPS_PENALTY_SINGULAR = ("numerically singular", "negative pivot", "not positive definite")
FORWARD_ERROR_WARNING = "estimated forward error"



def compare(ref, V, F, res, method):
    """Returns (ok, detail dict, message)."""
    diag = ref["diagonal"]
    X, Fx = R.read_obj(res["out"])
    if X.shape != V.shape:
        return False, {}, f"output has {len(X)} vertices, expected {len(V)}"
    pos_err = float(np.max(np.linalg.norm(X - ref["X"], axis=1)) / diag)
    E_lib = R.energy(ref["L"], V, X, *ref["soft"])
    E_ref = ref["energy"]
    e_rel = float(abs(E_lib - E_ref) / max(E_ref, np.finfo(float).tiny))
    rep = json.loads(res["report"].read_text())
    problems = []
    if not pos_err <= POS_TOL:
        problems.append(f"positions {pos_err:.2e} > {POS_TOL:g}")
    if not e_rel <= ENERGY_TOL:
        problems.append(f"energy {e_rel:.2e} > {ENERGY_TOL:g}")
    detail = {"pos": pos_err, "energy": e_rel, "fee": rep.get("forward_error_estimate")}
    if method != "penalty":
        if rep["rank"] != ref["rank"]:
            problems.append(f"rank {rep['rank']} != {ref['rank']}")
        red = rep["redundant"]
        conf = rep["conflicting"]
        if not isinstance(red, list) or sorted(red) != sorted(ref["redundant"]):
            problems.append(f"redundant {red} != {sorted(ref['redundant'])}")
        lib_conf = {c["index"]: c["residual"] for c in conf} if isinstance(conf, list) else conf
        if not isinstance(lib_conf, dict) or sorted(lib_conf) != sorted(ref["conflicting"]):
            problems.append(f"conflicting {sorted(lib_conf) if isinstance(lib_conf, dict) else lib_conf} != {sorted(ref['conflicting'])}")
        else:
            worst = 0.0
            for k, r in lib_conf.items():
                worst = max(worst, abs(r - ref["conflicting"][k]) / diag)
            detail["conf_res"] = worst
            if not worst <= CONFLICT_RESIDUAL_TOL:
                problems.append(f"conflict residuals differ by {worst:.2e} of the diagonal")
    else:
        if rep["redundant"] != "not detected" or rep["conflicting"] != "not detected":
            problems.append("penalty reports rank detection it does not have")
    return not problems, detail, "; ".join(problems)


def check_mumps_report(rep, launched):
    """The report's `mumps` object of a `--factor mumps` run: present, with
    one entry per rank; under a launcher, more than one rank (otherwise the
    pass would not test the distributed factorisation). Returns the problem
    or None."""
    m = rep.get("mumps")
    if not isinstance(m, dict):
        return "the report has no mumps object"
    ranks = m.get("ranks")
    if not isinstance(ranks, int) or ranks < 1:
        return f"mumps.ranks is {ranks!r}"
    if launched and ranks < 2:
        return f"mumps.ranks is {ranks} under the launcher (expected several ranks)"
    entries = m.get("factor_entries_per_rank")
    if not isinstance(entries, list) or len(entries) != ranks or not all(e > 0 for e in entries):
        return f"mumps.factor_entries_per_rank is {entries!r} for {ranks} ranks"
    return None


def find_binary(arg):
    if arg:
        return pathlib.Path(arg)
    env = os.environ.get("LSE_DEFORM_BIN")
    if env:
        return pathlib.Path(env)
    rel_, dbg = ROOT / "target/release/lse-deform", ROOT / "target/debug/lse-deform"
    if rel_.exists() and (not dbg.exists() or rel_.stat().st_mtime >= dbg.stat().st_mtime):
        return rel_
    return dbg


def compare_outputs(work, earlier, emit, partial):
    """Compare this run's output meshes with an earlier run's, byte for byte.

    An output mesh is a `SCENE__RUN.obj` file (the inputs have no `__`).
    Every output of either run must exist in the other (with `partial`, a
    run of some scenes only, only this run's outputs are looked up) and be
    identical; returns the number of meshes that are not (each a failure)."""
    ours = {p.name for p in work.glob("*__*.obj")}
    theirs = {p.name for p in earlier.glob("*__*.obj") if not partial or p.name in ours}
    bad = same = 0
    for name in sorted(ours | theirs):
        if name not in ours or name not in theirs:
            emit(f"FAIL  same outputs: {name} exists only in {'this run' if name in ours else earlier}")
            bad += 1
        elif (work / name).read_bytes() != (earlier / name).read_bytes():
            emit(f"FAIL  same outputs: {name} differs from {earlier / name}")
            bad += 1
        else:
            same += 1
    emit(f"same outputs: {same} of {len(ours | theirs)} output meshes byte-identical to {earlier}")
    return bad


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", help="lse-deform binary (default: $LSE_DEFORM_BIN, else target/{release,debug}/lse-deform)")
    ap.add_argument("--mesh-dir", help="real meshes (default: $LSE_MESH_DIR, else ../shared/meshes from the repository root)")
    ap.add_argument("--jobs", type=int, default=2, help="binary runs in parallel (default 2)")
    ap.add_argument("--keep", help="keep meshes, scenes and outputs in this directory")
    ap.add_argument("--only", help="run only scenes whose name contains this")
    ap.add_argument(
        "--same-outputs-as",
        metavar="DIR",
        help="with --keep: every output mesh (SCENE__RUN.obj) must be byte-identical to the file of the same name "
        "in DIR, a --keep directory of an earlier run (a refactoring that may not change a computed number)",
    )
    ap.add_argument("--no-real", action="store_true", help="generated meshes only (not allowed under CI)")
    ap.add_argument(
        "--factor",
        metavar="NAME",
        help="only the methods that take a factor back end (nullspace-qr, penalty, kkt, eliminate), each with "
        "--factor NAME (e.g. mumps); the build must have it",
    )
    ap.add_argument(
        "--launcher",
        metavar="CMD",
        help="run every deform through this command (shell words), e.g. "
        "'mpirun -np 2 --mca btl self,tcp --mca btl_tcp_if_include lo'; with --factor mumps the report must then "
        "show several ranks",
    )
    args = ap.parse_args()
    launcher = shlex.split(args.launcher) if args.launcher else []
    if args.same_outputs_as and not args.keep:
        ap.error("--same-outputs-as needs --keep DIR (the outputs are compared after the run)")
    t_start = time.time()
    binary = find_binary(args.bin)
    failures = 0
    passes = 0
    na = 0
    na_penalty = 0

    def emit(line):
        print(line, flush=True)

    if not binary.exists():
        emit(f"FAIL  setup: no binary at {binary} (cargo build --bin lse-deform, or set LSE_DEFORM_BIN)")
        emit("0 passed, 1 failed")
        return 1
    if not HAVE_IGL:
        if IN_CI:
            emit("FAIL  setup: libigl (pip install libigl) is missing; CI needs the operator cross-check")
            emit("0 passed, 1 failed")
            return 1
        emit("note: libigl missing, the operator cross-check against igl is skipped")
    mesh_dir = pathlib.Path(args.mesh_dir or os.environ.get("LSE_MESH_DIR") or (ROOT.parent / "shared" / "meshes"))
    real = mesh_dir.is_dir() and not args.no_real
    setup_fail = []
    if not real:
        if IN_CI:
            setup_fail.append(f"real meshes: {mesh_dir} is not a directory (or --no-real) and CI is set")
        else:
            emit(f"note: no real meshes ({mesh_dir} absent or --no-real); generated meshes only")

    work = pathlib.Path(args.keep) if args.keep else pathlib.Path(tempfile.mkdtemp(prefix="lse-ref-"))
    work.mkdir(parents=True, exist_ok=True)
    emit(f"binary {binary}; mesh dir {mesh_dir if real else '(none)'}; work {work}")

    # the meshes ---------------------------------------------------------
    generated = {}
    for name, nv in (("icosphere", 642), ("bumpy-sphere", 642), ("grid", 900), ("unsymmetric-grid", 900), ("sliver", 900)):
        path = work / f"{name}.obj"
        p = subprocess.run([str(binary), "generate", name, "--vertices", str(nv), "-o", str(path)], capture_output=True, text=True)
        if p.returncode != 0:
            setup_fail.append(f"generate {name}: {p.stderr.strip()}")
        generated[name] = path
    # suitesparse in this build?
    probe = work / "probe.json"
    probe.write_text(json.dumps({"constraints": [{"type": "position", "vertex": 0, "target": [0, 0, 0]}]}))
    p = subprocess.run(
        [str(binary), "deform", str(generated["icosphere"]), "-c", str(probe), "-o", str(work / "probe.obj"), "--qr", "spqr", "--spd", "cholmod"],
        capture_output=True,
        text=True,
    )
    suitesparse = p.returncode == 0
    emit(f"suitesparse back ends (spqr, cholmod): {'yes' if suitesparse else 'no (' + p.stderr.strip().splitlines()[0][:90] + '...)'}")
    if args.factor:
        p = subprocess.run(
            launcher
            + [str(binary), "deform", str(generated["icosphere"]), "-c", str(probe), "-o", str(work / "probe.obj"), "--factor", args.factor],
            capture_output=True,
            text=True,
        )
        emit(f"factor back end: {args.factor} only{'; launcher: ' + args.launcher if launcher else ''}")
        if p.returncode != 0:
            # every run would fail the same way: stop here
            emit(f"FAIL  setup: --factor {args.factor}{' under the launcher' if launcher else ''}: exit {p.returncode}: {p.stderr.strip()[:300]}")
            emit(f"{passes} passed, {failures + 1} failed")
            return 1
    for msg in setup_fail:
        emit(f"FAIL  setup: {msg}")
        failures += 1

    # the scenes: (name, mesh path, laplacian, class, variant, seed, full)
    scenes = []
    gen_names = list(generated)
    variants = {
        "redundant": ["mixed", "positions", "hub", "mixed"],
        "conflicting": ["positions", "mixed", "mixed", "hub"],
    }
    k = 0
    for li, lap in enumerate(LAPS):
        for ci, cls in enumerate(CLASSES):
            g = gen_names[(li + ci) % len(gen_names)]
            var = variants.get(cls, ["-"] * 4)[li]
            scenes.append((f"{g}/{lap}/{cls}" + (f"({var})" if var != "-" else ""), generated[g], lap, cls, var, 1000 + k, True))
            k += 1
    # the ill-conditioned generated sliver mesh with every Laplacian
    for li, lap in enumerate(LAPS):
        scenes.append((f"sliver/{lap}/all-kinds", generated["sliver"], lap, "all-kinds", "-", 2000 + li, True))
    # hard relative rows in a tree along mesh edges beside hard positions
    # (found in the latest round of faults: MUMPS's KKT took rounding-level pivots and lost every
    # digit on such scenes, with as few as 30 rows)
    for li, (g, lap, k) in enumerate((("icosphere", "cotan", 30), ("grid", "uniform", 100))):
        scenes.append((f"{g}/{lap}/relative-tree({k})", generated[g], lap, "relative-tree", str(k), 2100 + li, True))
    if real:
        # every Laplacian x class on a real mesh (rotating through eight),
        # then the Done-means scene and the ill-conditioned ones with every
        # back end
        rotation = [
            "bunny-3k.obj",
            "camelhead-11k-open.obj",
            "dragon-10k.obj",
            "max-planck-5k-decimated.obj",
            "fandisk-6k.obj",
            "demosthenes-8k-open.obj",
            "rocker-arm-10k.obj",
            "armadillo-15k-remeshed.obj",
        ]
        real_variants = {
            "redundant": ["positions", "hub", "mixed", "mixed"],
            "conflicting": ["mixed", "positions", "hub", "mixed"],
        }
        real_plan = []
        for li, lap in enumerate(LAPS):
            for ci, cls in enumerate(CLASSES):
                var = real_variants.get(cls, ["-"] * 4)[li]
                real_plan.append((rotation[(5 * li + ci) % len(rotation)], lap, cls, var, False))
        real_plan += [
            # the scenes for KKT over MUMPS: a tree of hard relative
            # rows, and a few hard edge points beside many hard positions
            ("bunny-3k.obj", "cotan", "relative-tree", "100", False),
            ("dragon-10k.obj", "cotan-symmetric", "relative-tree", "300", False),
            ("bunny-3k.obj", "uniform", "edges-beside-positions", "8", False),
            # the Done-means scene: the 35k-vertex Stanford Bunny, cotangent
            ("bunny-35k-stanford.obj", "cotan", "done-means", "-", True),
            ("bunny-35k-stanford.obj", "intrinsic-delaunay", "done-means", "-", False),
            # ill-conditioned: triangles down to 0.0017 degrees (aspect ratio
            # 38,772), and camelhead's 73 triangles under 1 degree
            ("bunny-35k-watertight.obj", "cotan", "all-kinds", "-", True),
            ("camelhead-11k-open.obj", "cotan", "all-kinds", "-", True),
            ("camelhead-11k-open.obj", "intrinsic-delaunay", "all-kinds", "-", True),
        ]
        for i, (mname, lap, cls, var, full) in enumerate(real_plan):
            path = mesh_dir / mname
            if not path.exists():
                emit(f"FAIL  setup: {path} is missing")
                failures += 1
                continue
            stem = mname[:-4] if mname.endswith(".obj") else mname
            scenes.append((f"{stem}/{lap}/{cls}" + (f"({var})" if var != "-" else ""), path, lap, cls, var, 3000 + i, full))
    if args.only:
        scenes = [s for s in scenes if args.only in s[0]]

    # the runs -----------------------------------------------------------
    stats = {}  # (class key) -> worst pos, worst energy
    pool = concurrent.futures.ThreadPoolExecutor(max_workers=max(1, args.jobs))
    mesh_cache = {}
    igl_checked = set()
    n_runs = 0
    for si, (name, mesh, lap, cls, var, seed, full) in enumerate(scenes):
        if mesh not in mesh_cache:
            mesh_cache[mesh] = R.read_obj(mesh)
        V, F = mesh_cache[mesh]
        # about 700 hard positions on the 3k Bunny beside the edge points
        sb = SceneBuilder(V, F, seed, fixed=0.16 if cls == "edges-beside-positions" else 0.12)
        rows = sb.build(cls, var)
        tag = name.replace("/", "_").replace("(", "_").replace(")", "").replace("+", "_")
        cons_path = work / f"{tag}.json"
        cons_path.write_text(json.dumps({"constraints": rows}, indent=0))
        cons = R.read_constraints(cons_path, len(V))
        hard_kinds = [cons.kinds[i] for i in cons.hard]
        runs = runs_for(si, full, suitesparse, args.factor)
        futures = []
        for label, rargs in runs:
            method = rargs[1]
            if method == "penalty" and cls == "conflicting":
                futures.append((label, method, None, "penalty has no rank detection and no exact solution under conflicting hard constraints (docs/cli.md §5)"))
                continue
            fut = pool.submit(run_binary, binary, mesh, cons_path, lap, label, rargs, work, f"{tag}__{label.replace(' ', '_')}", launcher)
            futures.append((label, method, fut, None))
            n_runs += 1
        # the reference, while the binary runs
        t0 = time.time()
        igl_note = ""
        key = (str(mesh), "intrinsic" if lap == "intrinsic-delaunay" else "cotan")
        if HAVE_IGL and key not in igl_checked and lap != "uniform":
            igl_checked.add(key)
            try:
                check = R.check_against_libigl(V, F, (lap,))
                igl_note = "; vs libigl " + ", ".join(f"{k} {v:.0e}" for k, v in check.items())
            except AssertionError as exc:
                emit(f"FAIL  {name}: operator cross-check: {exc}")
                failures += 1
        try:
            ref = R.solve(V, F, cons, lap)
        except Exception as exc:  # noqa: BLE001
            for label, _, fut, _ in futures:
                if fut:
                    fut.result()
                    emit(f"FAIL  {name} :: {label}: no reference: {exc!r}")
                    failures += 1
            continue
        t_ref = time.time() - t0
        has_dep = len(ref["redundant"]) + len(ref["conflicting"]) > 0
        emit(
            f"scene {name}: {len(V)} vertices, {len(cons.hard)} hard + {len(cons.soft)} soft, reference rank {ref['rank']}, "
            f"{len(ref['redundant'])} redundant, {len(ref['conflicting'])} conflicting, {t_ref:.1f} s, "
            f"refinement {len(ref['refinement'])} steps (last {ref['refinement'][-1]:.0e}){igl_note}"
        )
        for label, method, fut, reason in futures:
            prefix = f"{name} :: {label}"
            if fut is None:
                emit(f"N/A   {prefix}: {reason}")
                na += 1
                continue
            res = fut.result()
            refusal = expected_refusal(method, hard_kinds, has_dep)
            if res["rc"] != 0:
                err = res["stderr"].strip().splitlines()
                first = next((l for l in err if l.startswith("error")), err[-1] if err else "")
                if refusal and refusal[0] in res["stderr"]:
                    emit(f"N/A   {prefix}: refused as documented ({refusal[1]}): {first[:140]}")
                    na += 1
                elif method == "penalty" and res["rc"] == 3 and PENALTY_BREAKDOWN in res["stderr"]:
                    emit(f"N/A   {prefix}: penalty breakdown, exit 3 (W=1e4 relative to a soft weight of up to 100; see PENALTY_BREAKDOWN): {first[:160]}")
                    na += 1
                    na_penalty += 1
                elif method == "penalty" and args.factor == "mumps" and res["rc"] == 3 and any(m in res["stderr"] for m in MUMPS_PENALTY_SINGULAR):
                    emit(f"N/A   {prefix}: penalty breakdown, exit 3 as MUMPS's refusal (see MUMPS_PENALTY_SINGULAR): {first[:160]}")
                    na += 1
                    na_penalty += 1
                else:
                    emit(f"FAIL  {prefix}: exit {res['rc']}: {first[:200]}")
                    failures += 1
                continue
            ok, detail, msg = compare(ref, V, F, res, method)
            if args.factor == "mumps":
                problem = check_mumps_report(json.loads(res["report"].read_text()), bool(launcher))
                if problem:
                    ok, msg = False, "; ".join(m for m in (msg, problem) if m)
                elif not ok and method == "penalty" and FORWARD_ERROR_WARNING in res["stderr"]:
                    warning = next((l for l in res["stderr"].splitlines() if FORWARD_ERROR_WARNING in l), "")
                    emit(f"N/A   {prefix}: penalty breakdown, exit 0 with the forward-error warning (see FORWARD_ERROR_WARNING; {msg}): {warning[:160]}")
                    na += 1
                    na_penalty += 1
                    continue
            note = " (an expected refusal did not happen)" if refusal else ""
            extra = f" conf_res={detail['conf_res']:.1e}" if ref["conflicting"] and "conf_res" in detail else ""
            fee = detail.get("fee")
            summary = f"pos={detail.get('pos', float('nan')):.2e} dE={detail.get('energy', float('nan')):.2e}{extra} fee={fee if fee is None else f'{fee:.0e}'} {res['seconds']:.1f}s"
            if method != "penalty":
                summary += f" rank={ref['rank']} red={len(ref['redundant'])} conf={len(ref['conflicting'])}"
            if ok:
                emit(f"PASS  {prefix}: {summary}{note}")
                passes += 1
            else:
                emit(f"FAIL  {prefix}: {msg} [{summary}]{note}")
                failures += 1
            sk = (lap, cls)
            st = stats.setdefault(sk, {"pass": 0, "fail": 0, "pos": 0.0, "energy": 0.0, "fail_pos": 0.0})
            if ok:
                st["pass"] += 1
                st["pos"] = max(st["pos"], detail["pos"])
                st["energy"] = max(st["energy"], detail["energy"])
            else:
                st["fail"] += 1
                st["fail_pos"] = max(st["fail_pos"], detail.get("pos", float("nan")))
    pool.shutdown()
    if args.same_outputs_as:
        failures += compare_outputs(work, pathlib.Path(args.same_outputs_as), emit, bool(args.only))
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)

    emit("")
    emit(f"summary: {len(scenes)} scenes, {n_runs} binary runs, {na} not applicable ({na_penalty} of them penalty breakdowns)")
    emit(f"{'laplacian':<20} {'class':<12} {'pass':>4} {'fail':>4}  worst pos (pass)  worst dE (pass)  worst pos (fail)")
    for (lap, cls), st in sorted(stats.items(), key=lambda kv: (LAPS.index(kv[0][0]), kv[0][1])):
        emit(
            f"{lap:<20} {cls:<12} {st['pass']:>4} {st['fail']:>4}  {st['pos']:16.2e}  {st['energy']:15.2e}  "
            + (f"{st['fail_pos']:16.2e}" if st["fail"] else f"{'-':>16}")
        )
    emit(f"wall time {time.time() - t_start:.1f} s")
    emit(f"{passes} passed, {failures} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
