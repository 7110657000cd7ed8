#!/usr/bin/env python3
"""An independent definition of what `lse-deform deform` computes.

Reads only a mesh (OBJ, optionally gzip-compressed) and a constraints file
(JSON, the format of docs/cli.md §9, "Constraint files"). It never
reads `export-system` output and never imports the library or its Python
module: the Laplacians, the constraint rows, the rank decision and the
solution are all assembled and computed here, in the mesh's own units.

The problem (docs/cli.md §9, "Constraint files"; src/laplacian for the operators):

    minimise  E(X) = ||L (X - P)||_F^2 + sum_soft w_k^2 ||b_k X - d_k||^2
    subject to b_j X = d_j for every hard constraint j that is kept,

X the n x 3 deformed positions, P the rest positions, w_k the weight as
written in the file. Hard constraints are taken in list order; a hard row
whose remaining norm, after the earlier kept rows are projected out, is at
most 1e-10 of its own norm is skipped. A skipped row is redundant when its
residual at the solution is at most 1e-8 of the bounding-box diagonal, and
conflicting otherwise.

The solution comes from the augmented system

    [ a I   A   0  ] [ r/a ]   [ C ]
    [ A^T   0   B^T] [  X  ] = [ 0 ]      A = [L; w B_soft], C = [L P; w D_soft]
    [  0    B   0  ] [ mu  ]   [ D ]      B, D: the kept hard rows

factored once by SciPy's SuperLU and refined with residuals computed in
numpy.longdouble until a correction stops shrinking.

Usable as a module (see catalogue.py) or from the command line:

    python lse_reference.py MESH CONSTRAINTS [--laplacian cotan] [-o X.obj] [--json summary.json]
"""

import argparse
import gzip
import json
import math
import sys

import numpy as np
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph
import scipy.sparse.linalg as spla

LAPLACIANS = ("uniform", "cotan", "cotan-symmetric", "intrinsic-delaunay")
RANK_TOLERANCE = 1e-10  # eta, relative to each hard row's 2-norm
CONFLICT_TOLERANCE = 1e-8  # relative to the bounding-box diagonal
FLIP_TOLERANCE = 1e-12  # an edge is flipped when cot a + cot b < -this


# --------------------------------------------------------------------------
# Mesh reading
# --------------------------------------------------------------------------


def read_obj(path):
    """Vertices (n x 3 float64) and triangles (m x 3 int64, 0-based) of an
    OBJ file (`.gz` read through gzip). Only `v` and `f` records matter;
    polygons are fan-triangulated from their first corner; `i/t/n` tokens
    and negative (relative) indices are understood."""
    opener = gzip.open if str(path).endswith(".gz") else open
    with opener(path, "rt", encoding="utf-8", errors="replace") as fh:
        text = fh.read()
    coords = []
    faces = []
    for line in text.splitlines():
        if line.startswith("v "):
            parts = line.split()
            coords.append(parts[1:4])
        elif line.startswith("f "):
            parts = line.split()[1:]
            count = len(coords)
            idx = []
            for token in parts:
                k = int(token.split("/")[0])
                idx.append(k - 1 if k > 0 else count + k)
            for a in range(1, len(idx) - 1):
                faces.append((idx[0], idx[a], idx[a + 1]))
    V = np.array(coords, dtype=np.float64).reshape(-1, 3)
    F = np.array(faces, dtype=np.int64).reshape(-1, 3)
    if F.size and (F.min() < 0 or F.max() >= len(V)):
        raise ValueError(f"{path}: a face index is out of range")
    return V, F


def bbox_diagonal(V):
    return float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))


# --------------------------------------------------------------------------
# Laplacians
# --------------------------------------------------------------------------


def _corner_terms(len_sq, dot, twice_area):
    """Per-corner cotangents and mixed Voronoi area contributions of a batch
    of triangles. Column k of every (m x 3) input belongs to corner k:
    `len_sq[:, k]` is the squared length of the edge opposite corner k,
    `dot[:, k]` the dot product of corner k's two edge vectors;
    `twice_area` (m,) is |u x v|."""
    cot = dot / twice_area[:, None]
    area = 0.5 * twice_area
    k1 = [1, 2, 0]
    k2 = [2, 0, 1]
    # Meyer et al. 2003, fig. 4: a non-obtuse triangle gives corner P its
    # Voronoi part (|PR|^2 cot Q + |PQ|^2 cot R) / 8, Q = k+1, R = k+2;
    # |PR| is the edge opposite Q, |PQ| the one opposite R.
    voronoi = (len_sq[:, k1] * cot[:, k1] + len_sq[:, k2] * cot[:, k2]) / 8.0
    obtuse = dot < 0.0
    any_obtuse = obtuse.any(axis=1)
    mixed = np.where(obtuse, area[:, None] / 2.0, area[:, None] / 4.0)
    corner_area = np.where(any_obtuse[:, None], mixed, voronoi)
    return cot, corner_area


def _extrinsic_terms(V, F):
    p = V[F]  # m x 3 x 3
    dots = np.empty((len(F), 3))
    len_sq = np.empty((len(F), 3))
    twice = None
    for k in range(3):
        u = p[:, (k + 1) % 3] - p[:, k]
        v = p[:, (k + 2) % 3] - p[:, k]
        dots[:, k] = np.einsum("ij,ij->i", u, v)
        e = p[:, (k + 2) % 3] - p[:, (k + 1) % 3]
        len_sq[:, k] = np.einsum("ij,ij->i", e, e)
        if k == 0:
            twice = np.linalg.norm(np.cross(u, v), axis=1)
    return _corner_terms(len_sq, dots, twice)


def _kahan_twice_area(a, b, c):
    """Twice the area of triangles with side lengths a, b, c (Heron's formula
    in Kahan's cancellation-free ordering)."""
    s = np.sort(np.stack([a, b, c], axis=1), axis=1)[:, ::-1]
    x, y, z = s[:, 0], s[:, 1], s[:, 2]  # x >= y >= z
    prod = (x + (y + z)) * (z - (x - y)) * (z + (x - y)) * (x + (y - z))
    return 0.5 * np.sqrt(np.maximum(prod, 0.0))


def _intrinsic_terms(lengths):
    """`lengths` (m x 3): column k is the length of the edge opposite
    corner k."""
    len_sq = lengths**2
    dots = np.empty_like(len_sq)
    for k in range(3):
        dots[:, k] = 0.5 * (len_sq[:, (k + 1) % 3] + len_sq[:, (k + 2) % 3] - len_sq[:, k])
    twice = _kahan_twice_area(lengths[:, 0], lengths[:, 1], lengths[:, 2])
    return _corner_terms(len_sq, dots, twice)


def _assemble_cot(n, F, cot, corner_area, area_normalised):
    """L_sym with w_ij = 1/2 sum of the cotangents opposite edge ij (one per
    incident face), optionally divided row-wise by the mixed areas."""
    rows, cols, vals = [], [], []
    for k in range(3):
        a = F[:, (k + 1) % 3]
        b = F[:, (k + 2) % 3]
        w = 0.5 * cot[:, k]
        rows += [a, b, a, b]
        cols += [b, a, a, b]
        vals += [-w, -w, w, w]
    Ls = sp.coo_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
    ).tocsr()
    Ls.sum_duplicates()
    areas = np.zeros(n)
    np.add.at(areas, F.ravel(), corner_area.ravel())
    if not area_normalised:
        return Ls, areas
    if np.any(areas <= 0.0):
        raise ValueError("a vertex has no mixed Voronoi area")
    return sp.diags(1.0 / areas) @ Ls, areas


def uniform_laplacian(n, F):
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    e = np.concatenate([e, e[:, ::-1]])
    adj = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    adj.data[:] = 1.0  # duplicates summed: back to a 0/1 pattern
    deg = np.asarray(adj.sum(axis=1)).ravel()
    if np.any(deg == 0):
        raise ValueError("a vertex is in no face")
    return (sp.identity(n, format="csr") - sp.diags(1.0 / deg) @ adj).tocsr()


def cotan_laplacian(V, F, area_normalised):
    cot, corner_area = _extrinsic_terms(V, F)
    return _assemble_cot(len(V), F, cot, corner_area, area_normalised)


def intrinsic_delaunay(V, F):
    """Edge flips on edge lengths until every interior edge satisfies
    cot a + cot b >= -FLIP_TOLERANCE. Returns the intrinsic faces and, per
    face, the lengths opposite each corner. Half-edge h = 3f + k runs from
    F[f, k] to F[f, k+1]; the corner opposite it is k+2."""
    n = len(V)
    m = len(F)
    F = F.copy()
    tail = F.ravel()
    head = F[:, [1, 2, 0]].ravel()
    length = np.linalg.norm(V[head] - V[tail], axis=1)
    key = tail * n + head
    order = np.argsort(key, kind="stable")
    skey = key[order]
    if np.any(skey[1:] == skey[:-1]):
        raise ValueError("intrinsic Delaunay needs an oriented manifold mesh")
    rkey = head * n + tail
    pos = np.searchsorted(skey, rkey)
    pos = np.minimum(pos, len(skey) - 1)
    twin = np.where(skey[pos] == rkey, order[pos], -1)
    H = 3 * m
    hs = np.arange(H)
    flips = 0
    limit = 100 * max(H // 2, 1)
    while True:
        lf = length.reshape(m, 3)
        # lengths opposite corners: the edge opposite corner k is half-edge k+1
        opp = lf[:, [1, 2, 0]]
        cot, _ = _intrinsic_terms(opp)
        # cotangent of the angle opposite half-edge 3f+k: corner k+2
        cot_h = cot[:, [2, 0, 1]].ravel()
        interior = twin > hs
        s = np.full(H, np.inf)
        s[interior] = cot_h[interior] + cot_h[twin[interior]]
        bad = np.flatnonzero(s < -FLIP_TOLERANCE)
        if len(bad) == 0:
            break
        # an independent set: each face claimed by its lowest bad edge
        f0 = bad // 3
        f1 = twin[bad] // 3
        faces_all = np.concatenate([f0, f1])
        owners = np.concatenate([bad, bad])
        o = np.lexsort((owners, faces_all))
        first = np.ones(len(o), dtype=bool)
        first[1:] = faces_all[o][1:] != faces_all[o][:-1]
        claim = np.full(m, -1)
        claim[faces_all[o][first]] = owners[o][first]
        sel = bad[(claim[f0] == bad) & (claim[f1] == bad)]
        flips += len(sel)
        if flips > limit:
            raise RuntimeError("intrinsic Delaunay: too many flips")
        h = sel
        t = twin[h]
        fa, a = h // 3, h % 3
        fb, b = t // 3, t % 3
        h1 = 3 * fa + (a + 1) % 3  # j -> k
        h2 = 3 * fa + (a + 2) % 3  # k -> i
        t1 = 3 * fb + (b + 1) % 3  # i -> l
        t2 = 3 * fb + (b + 2) % 3  # l -> j
        i = F[fa, a]
        j = F[fa, (a + 1) % 3]
        k = F[fa, (a + 2) % 3]
        l_ = F[fb, (b + 2) % 3]
        lij, ljk, lki = length[h], length[h1], length[h2]
        lil, llj = length[t1], length[t2]
        # lay the two triangles out: i at 0, j on the x axis, k above, l below
        xk = (lij**2 + lki**2 - ljk**2) / (2 * lij)
        yk = _kahan_twice_area(lij, ljk, lki) / lij
        xl = (lij**2 + lil**2 - llj**2) / (2 * lij)
        yl = -_kahan_twice_area(lij, lil, llj) / lij
        lkl = np.hypot(xk - xl, yk - yl)
        newpos = hs.copy()
        newpos[h2] = 3 * fa + 0
        newpos[t1] = 3 * fa + 1
        newpos[t2] = 3 * fb + 0
        newpos[h1] = 3 * fb + 1
        new_length = length.copy()
        for x in (h1, h2, t1, t2):
            new_length[newpos[x]] = length[x]
        new_length[3 * fa + 2] = lkl
        new_length[3 * fb + 2] = lkl
        moved = np.ones(H, dtype=bool)
        moved[h] = False
        moved[t] = False
        new_twin = np.full(H, -1)
        src = hs[moved]
        tw = twin[src]
        new_twin[newpos[src]] = np.where(tw >= 0, newpos[np.maximum(tw, 0)], -1)
        new_twin[3 * fa + 2] = 3 * fb + 2
        new_twin[3 * fb + 2] = 3 * fa + 2
        F[fa] = np.stack([k, i, l_], axis=1)
        F[fb] = np.stack([l_, j, k], axis=1)
        length, twin = new_length, new_twin
    lf = length.reshape(m, 3)
    return F, lf[:, [1, 2, 0]], flips


def intrinsic_delaunay_laplacian(V, F):
    Fi, opp, flips = intrinsic_delaunay(V, F)
    cot, corner_area = _intrinsic_terms(opp)
    L, areas = _assemble_cot(len(V), Fi, cot, corner_area, True)
    return L, areas, Fi, opp, flips


def laplacian(V, F, kind):
    """The Laplacian of the given kind (L_ii = sum_j w_ij, L_ij = -w_ij)."""
    if kind == "uniform":
        return uniform_laplacian(len(V), F)
    if kind == "cotan":
        return cotan_laplacian(V, F, True)[0].tocsr()
    if kind == "cotan-symmetric":
        return cotan_laplacian(V, F, False)[0].tocsr()
    if kind == "intrinsic-delaunay":
        return intrinsic_delaunay_laplacian(V, F)[0].tocsr()
    raise ValueError(f"unknown Laplacian {kind!r}")


def _rel(a, b):
    """max |a - b| / max(|a|, |b|) over the entries of two sparse matrices or
    two vectors."""
    if sp.issparse(a) or sp.issparse(b):
        a = sp.csr_matrix(a)
        b = sp.csr_matrix(b)
        scale = max(abs(a).max(), abs(b).max(), 1e-300)
        return float(abs(a - b).max() / scale)
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(a)), np.max(np.abs(b)), 1e-300))


def _long_double_operators(V, F, kind):
    """L_sym and the mixed areas evaluated in long double (64-bit mantissa)
    from the same float64 input, rounded to float64 at the end; None when
    the intrinsic flips in long double end on another triangulation (a
    near-tie decided the other way)."""
    Vl = np.asarray(V, dtype=np.longdouble)
    if kind == "intrinsic-delaunay":
        Fi, _, _ = intrinsic_delaunay(V, F)
        Fl, opp, _ = intrinsic_delaunay(Vl, F)
        if not np.array_equal(Fi, Fl):
            return None
        cot, area = _intrinsic_terms(opp)
        Fuse = Fl
    else:
        cot, area = _extrinsic_terms(Vl, F)
        Fuse = F
    Ls, areas = _assemble_cot(len(V), Fuse, np.asarray(cot, dtype=np.float64), np.asarray(area, dtype=np.float64), False)
    return Ls, areas


def check_against_libigl(V, F, kinds=LAPLACIANS, tol=1e-12, ld_tol=1e-13):
    """Cross-checks this file's cotangent weights and mixed Voronoi areas
    against libigl: cotmatrix and massmatrix(VORONOI) for `cotan` and
    `cotan-symmetric` (L_sym = -C, cotan = -M^-1 C), and for
    `intrinsic-delaunay` intrinsic_delaunay_cotmatrix and
    massmatrix_intrinsic on libigl's own intrinsic triangulation.

    Each comparison is the largest entry difference over the largest entry.
    Above `tol`, a long-double evaluation of the same definitions from the
    same float64 input decides who is off: the check still passes when ours
    is within `ld_tol` of it and libigl's difference from it accounts for
    the disagreement (libigl computes cotangents from edge lengths, which
    loses digits on slivers: 4e-8 of the largest weight on
    bunny-35k-watertight). Returns {name: difference}; raises
    AssertionError otherwise."""
    import igl

    out = {}
    bad = []
    Fi64 = np.ascontiguousarray(F, dtype=np.int64)
    Vc = np.ascontiguousarray(V, dtype=np.float64)

    def judge(name, mine, theirs, ld_index, kind):
        d = _rel(mine, theirs)
        out[name] = d
        if d <= tol:
            return
        ld = _long_double_operators(V, F, kind)
        if ld is None:
            bad.append(f"{name}: {d:.1e} (long-double flips took another triangulation)")
            return
        exact = ld[ld_index]
        d_ours, d_igl = _rel(mine, exact), _rel(theirs, exact)
        out[name + " (ours vs long double)"] = d_ours
        out[name + " (libigl vs long double)"] = d_igl
        if not (d_ours <= ld_tol and d_igl >= 0.5 * d):
            bad.append(f"{name}: {d:.1e}, ours vs long double {d_ours:.1e}, libigl vs long double {d_igl:.1e}")

    if "cotan" in kinds or "cotan-symmetric" in kinds:
        Ls, areas = cotan_laplacian(V, F, False)
        C = igl.cotmatrix(Vc, Fi64)
        M = igl.massmatrix(Vc, Fi64, igl.MASSMATRIX_TYPE_VORONOI)
        judge("cotmatrix", Ls, -C, 0, "cotan")
        judge("massmatrix", areas, M.diagonal(), 1, "cotan")
        if "cotan" in kinds:
            Lc = sp.diags(1.0 / areas) @ Ls
            out["cotan = -M^-1 C"] = _rel(Lc, -(sp.diags(1.0 / M.diagonal()) @ C))
    if "intrinsic-delaunay" in kinds:
        L, areas, Fi, opp, flips = intrinsic_delaunay_laplacian(V, F)
        Ci, l_igl, F_igl = igl.intrinsic_delaunay_cotmatrix(Vc, Fi64)
        Mi = igl.massmatrix_intrinsic(np.ascontiguousarray(l_igl), np.ascontiguousarray(F_igl), igl.MASSMATRIX_TYPE_VORONOI)
        judge("intrinsic cotmatrix", sp.diags(areas) @ L, -Ci, 0, "intrinsic-delaunay")
        judge("intrinsic massmatrix", areas, Mi.diagonal(), 1, "intrinsic-delaunay")
    if bad:
        raise AssertionError("disagreement with libigl: " + "; ".join(bad))
    return out


# --------------------------------------------------------------------------
# Constraints
# --------------------------------------------------------------------------


class Constraints:
    """Rows of the constraints file: `rows` (list of (vertex indices,
    coefficients)), `targets` (k x 3), `weights` (None for hard), `kinds`."""

    def __init__(self, rows, targets, weights, kinds):
        self.rows = rows
        self.targets = np.asarray(targets, dtype=np.float64).reshape(-1, 3)
        self.weights = weights
        self.kinds = kinds

    @property
    def hard(self):
        return [i for i, w in enumerate(self.weights) if w is None]

    @property
    def soft(self):
        return [i for i, w in enumerate(self.weights) if w is not None]

    def matrix(self, indices, n):
        """The rows `indices` as a sparse (len x n) matrix and their targets."""
        r, c, v = [], [], []
        for out, i in enumerate(indices):
            verts, coef = self.rows[i]
            r += [out] * len(verts)
            c += list(verts)
            v += list(coef)
        Bm = sp.coo_matrix((v, (r, c)), shape=(len(indices), n)).tocsr()
        Bm.sum_duplicates()
        return Bm, self.targets[list(indices)].reshape(-1, 3)


def read_constraints(path_or_obj, n):
    if isinstance(path_or_obj, (dict, list)):
        data = path_or_obj
    else:
        with open(path_or_obj, "rb") as fh:
            raw = fh.read()
        if raw.startswith(b"\xef\xbb\xbf"):
            raw = raw[3:]
        data = json.loads(raw.decode("utf-8"))
    items = data["constraints"] if isinstance(data, dict) else data
    rows, targets, weights, kinds = [], [], [], []
    for idx, c in enumerate(items):
        kind = c["type"]
        if kind == "position":
            verts, coef, target = [c["vertex"]], [1.0], c["target"]
        elif kind == "edge":
            t = float(c["t"])
            verts, coef, target = list(c["vertices"]), [t, 1.0 - t], c["target"]
        elif kind == "face":
            s, t = (float(x) for x in c["barycentric"])
            verts, coef, target = list(c["vertices"]), [s, t, 1.0 - s - t], c["target"]
        elif kind == "relative":
            verts, coef, target = list(c["vertices"]), [1.0, -1.0], c["vector"]
        else:
            raise ValueError(f"constraint {idx}: unknown type {kind!r}")
        if any(not (0 <= int(v) < n) for v in verts):
            raise ValueError(f"constraint {idx}: vertex out of range")
        w = c.get("weight")
        if w is not None and not float(w) > 0:
            raise ValueError(f"constraint {idx}: weight must be > 0")
        rows.append(([int(v) for v in verts], coef))
        targets.append([float(x) for x in target])
        weights.append(None if w is None else float(w))
        kinds.append(kind)
    return Constraints(rows, targets, weights, kinds)


# --------------------------------------------------------------------------
# Rank decision in priority order
# --------------------------------------------------------------------------


def rank_decision(Bh, eta=RANK_TOLERANCE):
    """Greedy decision over the rows of Bh (hard rows in list order): a row is
    skipped when its remaining norm, after the earlier kept rows are
    projected out, is <= eta * its norm. Rows can only depend on rows they
    are connected to through shared unknowns, so the decision is made per
    connected component of the row-unknown graph, densely (Gram-Schmidt with
    reorthogonalisation). Returns a boolean `kept` array."""
    m, n = Bh.shape
    kept = np.ones(m, dtype=bool)
    if m == 0:
        return kept
    Bc = Bh.tocsr()
    pattern = Bc.copy()
    pattern.data = np.ones_like(pattern.data)
    graph = sp.bmat([[None, pattern], [pattern.T, None]], format="csr")
    ncomp, label = csgraph.connected_components(graph, directed=False)
    row_label = label[:m]
    counts = np.bincount(row_label, minlength=ncomp)
    for comp in np.flatnonzero(counts > 1):
        rows = np.flatnonzero(row_label == comp)  # increasing = list order
        sub = Bc[rows]
        cols = np.unique(sub.indices)
        dense = sub[:, cols].toarray()
        basis = np.zeros((0, len(cols)))
        for r_local, r in enumerate(rows):
            b = dense[r_local]
            norm_b = np.linalg.norm(b)
            res = b.copy()
            for _ in range(2):
                if len(basis):
                    res = res - basis.T @ (basis @ res)
            norm_r = np.linalg.norm(res)
            if norm_r <= eta * norm_b:
                kept[r] = False
            else:
                basis = np.vstack([basis, res / norm_r])
    return kept


# --------------------------------------------------------------------------
# Solve
# --------------------------------------------------------------------------


def _ld_matvec(M, x):
    """M @ x with M's entries and x in long double (SciPy's sparse kernels
    accumulate in the matrix's dtype)."""
    return sp.csr_matrix(M).astype(np.longdouble) @ np.asarray(x, dtype=np.longdouble)


def energy(L, P, X, soft_B, soft_D, soft_w):
    """E(X) in long double."""
    X = np.asarray(X, dtype=np.longdouble)
    P = np.asarray(P, dtype=np.longdouble)
    lap = _ld_matvec(L, X - P)
    e = np.sum(lap * lap)
    if soft_B.shape[0]:
        r = _ld_matvec(soft_B, X) - np.asarray(soft_D, dtype=np.longdouble)
        w2 = np.asarray(soft_w, dtype=np.longdouble) ** 2
        e = e + np.sum(w2[:, None] * r * r)
    return e


def solve(V, F, constraints, kind, max_steps=40, verbose=False):
    """The reference solution. Returns a dict with X, kept, rank, redundant,
    conflicting ({index: residual}), energy and the refinement history."""
    n = len(V)
    L = laplacian(V, F, kind)
    hard = constraints.hard
    soft = constraints.soft
    Bh, Dh = constraints.matrix(hard, n)
    kept = rank_decision(Bh)
    kept_idx = [hard[i] for i in np.flatnonzero(kept)]
    B, D = constraints.matrix(kept_idx, n)
    Bs, Ds = constraints.matrix(soft, n)
    w = np.array([constraints.weights[i] for i in soft], dtype=np.float64)
    A = sp.vstack([L, sp.diags(w) @ Bs]).tocsr() if len(soft) else L.tocsr()
    C = np.vstack([L @ V, w[:, None] * Ds]) if len(soft) else L @ V
    ell = A.shape[0]
    mk = B.shape[0]
    alpha = math.sqrt(abs(A).max())
    if mk:
        K = sp.bmat(
            [
                [alpha * sp.identity(ell), A, None],
                [A.T, None, B.T],
                [None, B, sp.csr_matrix((mk, mk))],
            ],
            format="csc",
        )
        rhs = np.vstack([C, np.zeros((n, 3)), D])
    else:
        K = sp.bmat([[alpha * sp.identity(ell), A], [A.T, None]], format="csc")
        rhs = np.vstack([C, np.zeros((n, 3))])
    lu = spla.splu(K, permc_spec="COLAMD", diag_pivot_thresh=1.0)
    y = lu.solve(rhs)
    # residuals of the original rows in long double
    K_ld = sp.csr_matrix(K).astype(np.longdouble)
    rhs_ld = rhs.astype(np.longdouble)
    y_ld = y.astype(np.longdouble)
    history = []
    previous = np.inf
    xs = slice(ell, ell + n)
    for step in range(max_steps):
        res = rhs_ld - K_ld @ y_ld
        dy = lu.solve(np.asarray(res, dtype=np.float64))
        xmax = float(np.max(np.abs(y_ld[xs])))
        size = float(np.max(np.abs(dy[xs]))) / max(xmax, 1e-300)
        history.append(size)
        if not np.isfinite(size) or size >= previous:
            break
        y_ld = y_ld + dy.astype(np.longdouble)
        previous = size
        if size < 1e-19:
            break
    X_ld = y_ld[xs]
    X = np.asarray(X_ld, dtype=np.float64)
    diag = bbox_diagonal(V)
    # classify skipped rows
    redundant, conflicting = [], {}
    for local, j in enumerate(hard):
        if kept[local]:
            continue
        verts, coef = constraints.rows[j]
        r = np.zeros(3, dtype=np.longdouble)
        for v, c in zip(verts, coef):
            r += np.longdouble(c) * X_ld[v]
        r -= constraints.targets[j].astype(np.longdouble)
        res = float(np.sqrt(np.sum(r * r)))
        if res <= CONFLICT_TOLERANCE * diag:
            redundant.append(j)
        else:
            conflicting[j] = res
    max_kept = 0.0
    if mk:
        rk = _ld_matvec(B, X_ld) - D.astype(np.longdouble)
        max_kept = float(np.sqrt(np.max(np.sum(rk * rk, axis=1))))
    e = energy(L, V, X_ld, Bs, Ds, w)
    return {
        "X": X,
        "X_ld": X_ld,
        "L": L,
        "soft": (Bs, Ds, w),
        "rank": int(kept.sum()),
        "kept": kept_idx,
        "redundant": redundant,
        "conflicting": conflicting,
        "energy": e,
        "refinement": history,
        "max_kept_residual": max_kept,
        "diagonal": diag,
    }


def write_obj(path, X, F):
    with open(path, "w") as fh:
        for p in X:
            fh.write(f"v {p[0]!r} {p[1]!r} {p[2]!r}\n")
        for f in F:
            fh.write(f"f {f[0] + 1} {f[1] + 1} {f[2] + 1}\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mesh")
    ap.add_argument("constraints")
    ap.add_argument("--laplacian", default="cotan", choices=LAPLACIANS)
    ap.add_argument("-o", "--output", help="write the reference positions as OBJ")
    ap.add_argument("--json", help="write rank, redundant, conflicting, energy as JSON")
    ap.add_argument("--check-libigl", action="store_true", help="cross-check the operators against libigl")
    args = ap.parse_args()
    V, F = read_obj(args.mesh)
    cons = read_constraints(args.constraints, len(V))
    if args.check_libigl:
        print(json.dumps(check_against_libigl(V, F, (args.laplacian,))))
    out = solve(V, F, cons, args.laplacian)
    summary = {
        "rank": out["rank"],
        "redundant": out["redundant"],
        "conflicting": [{"index": k, "residual": v} for k, v in out["conflicting"].items()],
        "energy": float(out["energy"]),
        "refinement": out["refinement"],
        "max_kept_residual": out["max_kept_residual"],
    }
    print(json.dumps(summary))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(summary, fh, indent=1)
    if args.output:
        write_obj(args.output, out["X"], F)


if __name__ == "__main__":
    sys.exit(main())
