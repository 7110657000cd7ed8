"""Agreement with libigl's min_quad_with_fixed on position-only scenes
(libigl's (b, bc) form): the same energy ||L X - L V||^2 with L = -M^-1 C
built by libigl itself (cotmatrix, massmatrix VORONOI), solved by libigl's
own factorisation. Tolerances are relative to the bounding-box diagonal."""

import numpy as np
import pytest
import scipy.sparse as sp

import lse_deform
from conftest import bumpy_grid, fixed_and_handle, shared_mesh

igl = pytest.importorskip("igl")


def igl_laplacian(V, F):
    C = igl.cotmatrix(V, F)
    M = igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI)
    return -(sp.diags(1.0 / M.diagonal()) @ C)


def igl_deform(V, F, b, bc):
    L = sp.csc_matrix(igl_laplacian(V, F))
    Q = sp.csc_matrix(L.T @ L)
    linear = -(L.T @ (L @ V))
    empty = sp.csc_matrix((0, len(V)))
    return igl.min_quad_with_fixed(Q, linear, b.astype(np.int64), bc, empty, np.zeros((0, 3)), True)


def diagonal(V):
    return np.linalg.norm(V.max(axis=0) - V.min(axis=0))


def test_cotan_laplacian_is_libigls():
    V, F = bumpy_grid()
    ours = lse_deform.laplacian(V, F, "cotan")
    assert isinstance(ours, sp.csc_matrix)
    ref = igl_laplacian(V, F)
    assert abs(ours - ref).max() <= 1e-12 * abs(ref).max()
    sym = lse_deform.laplacian(V, F, "cotan-symmetric")
    assert abs(sym + igl.cotmatrix(V, F)).max() <= 1e-12 * abs(sym).max()


@pytest.mark.parametrize("method", ["nullspace-qr", "kkt", "eliminate"])
def test_fix_and_drag_agrees_with_min_quad_with_fixed(method):
    V, F = bumpy_grid()
    b, bc = fixed_and_handle(V)
    U, report = lse_deform.deform(V, F, (b, bc), method=method)
    ref = igl_deform(V, F, b, bc)
    assert np.abs(U - ref).max() <= 1e-9 * diagonal(V)
    assert np.abs(U[b] - bc).max() <= 1e-12 * diagonal(V)
    # the report names the formulation with the word it was chosen by
    assert report["method"] == method and report["hard_constraints"] == len(b)


def test_scattered_constraints_and_list_form_agree():
    V, F = bumpy_grid(seed=3)
    rng = np.random.default_rng(7)
    b = rng.choice(len(V), 40, replace=False)
    bc = V[b] + 0.05 * rng.standard_normal((40, 3))
    ref = igl_deform(V, F, b, bc)
    as_dicts = [{"type": "position", "vertex": int(v), "target": t.tolist()} for v, t in zip(b, bc)]
    for constraints in ((b, bc), as_dicts, {"constraints": as_dicts}):
        U, _ = lse_deform.deform(V, F, constraints)
        assert np.abs(U - ref).max() <= 1e-9 * diagonal(V)


def test_bunny_fix_and_drag_agrees_with_min_quad_with_fixed():
    path = shared_mesh("bunny-35k-stanford.obj")
    if path is None:
        pytest.skip("../shared/meshes/bunny-35k-stanford.obj is not on this machine")
    V, F = igl.read_triangle_mesh(str(path))
    b, bc = fixed_and_handle(V)
    U, _ = lse_deform.deform(V, F.astype(np.int64), (b, bc))
    ref = igl_deform(V, F, b, bc)
    assert np.abs(U - ref).max() <= 1e-9 * diagonal(V)
