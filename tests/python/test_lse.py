"""solve_lse on general problems: agreement with a dense KKT solution by
numpy, exact naming of redundant and conflicting rows, every sparse format
and memory order, and the round trip with `lse-deform export-system`."""

import json
import subprocess

import numpy as np
import pytest
import scipy.io
import scipy.sparse as sp

import lse_deform
from conftest import bumpy_grid, cli_binary, fixed_and_handle, write_obj


def random_problem(seed, n=14, l=24, m0=5, k=3):
    """A sparse full-rank A (l x n), B0 (m0 x n) of independent rows, then
    B = [B0; 2 redundant rows; 1 conflicting row], each dependent row a
    combination of earlier rows. Returns A, C, B, D, the reference X from
    the dense KKT system of (A, B0) and the indices (redundant, conflicting)."""
    rng = np.random.default_rng(seed)
    A = sp.random(l, n, density=0.35, random_state=rng, format="csc") + sp.eye(l, n, format="csc")
    B0 = sp.random(m0, n, density=0.4, random_state=rng, format="csr").toarray()
    B0[np.arange(m0), rng.choice(n, m0, replace=False)] += 1.0
    C = rng.standard_normal((l, k))
    D0 = rng.standard_normal((m0, k))
    w1, w2, w3 = rng.standard_normal(m0), rng.standard_normal(m0), rng.standard_normal(m0)
    # rows: 0, 1, 2, redundant (of 0..2), 3, 4, redundant (of all), conflicting
    combos = [np.r_[w1[:3], 0, 0], w2, w3]
    rows = [B0[0], B0[1], B0[2], combos[0] @ B0, B0[3], B0[4], combos[1] @ B0, combos[2] @ B0]
    rhs = [D0[0], D0[1], D0[2], combos[0] @ D0, D0[3], D0[4], combos[1] @ D0, combos[2] @ D0 + 1.0]
    B, D = np.array(rows), np.array(rhs)
    Ad = A.toarray()
    kkt = np.block([[Ad.T @ Ad, B0.T], [B0, np.zeros((m0, m0))]])
    X = np.linalg.solve(kkt, np.r_[Ad.T @ C, D0])[:n]
    return A, C, sp.csr_matrix(B), D, X, [3, 6], [7]


@pytest.mark.parametrize("seed", range(6))
def test_agrees_with_dense_kkt_and_names_dependent_rows(seed):
    A, C, B, D, X_ref, redundant, conflicting = random_problem(seed)
    X, report = lse_deform.solve_lse(A, C, B, D)
    assert np.abs(X - X_ref).max() <= 1e-10 * max(1.0, np.abs(X_ref).max())
    assert report["rank"] == 5
    assert report["redundant"] == redundant
    assert [c["index"] for c in report["conflicting"]] == conflicting
    kept = [i for i in range(B.shape[0]) if i not in redundant + conflicting]
    assert np.abs(B[kept] @ X - D[kept]).max() <= 1e-12 * max(1.0, np.abs(D).max())


@pytest.mark.parametrize("k", [1, 2, 4])
def test_any_number_of_columns_and_1d(k):
    A, C, B, D, _, _, _ = random_problem(11, k=k)
    keep = [0, 1, 2, 4, 5]
    Ad, Bd = A.toarray(), B.toarray()[keep]
    kkt = np.block([[Ad.T @ Ad, Bd.T], [Bd, np.zeros((5, 5))]])
    ref = np.linalg.solve(kkt, np.r_[Ad.T @ C, D[keep]])[: A.shape[1]]
    X, _ = lse_deform.solve_lse(A, C, sp.csr_matrix(Bd), D[keep])
    assert X.shape == ref.shape and np.abs(X - ref).max() <= 1e-10 * np.abs(ref).max()
    if k == 1:
        x, _ = lse_deform.solve_lse(A, C[:, 0], sp.csr_matrix(Bd), D[keep][:, 0])
        assert x.shape == (A.shape[1],) and np.abs(x - ref[:, 0]).max() <= 1e-10 * np.abs(ref).max()


def test_formats_and_memory_orders_read_alike():
    A, C, B, D, X_ref, _, _ = random_problem(3)
    X, _ = lse_deform.solve_lse(A, C, B, D)
    variants = [
        (A.tocsr(), C, B.tocsc(), D),
        (A.tocoo(), np.asfortranarray(C), B.tocoo(), np.asfortranarray(D)),
        (sp.csc_array(A), C, sp.lil_matrix(B), D),
        (A.toarray(), C, B.toarray(), D),
        (np.asfortranarray(A.toarray()), C[::1], B, D),
    ]
    # a non-contiguous, negatively strided view of the same C
    wide = np.zeros((C.shape[0], 2 * C.shape[1]))
    wide[:, ::2] = C[:, ::-1]
    assert np.array_equal(wide[:, -2::-2], C)
    variants.append((A, wide[:, -2::-2], B, D))
    for args in variants:
        Y, _ = lse_deform.solve_lse(*args)
        assert np.abs(Y - X).max() <= 1e-13 * np.abs(X).max()
    # unsorted indices and duplicate entries (summed, as scipy does)
    coo = A.tocoo()
    dup = sp.coo_matrix(
        (np.r_[coo.data * 0.5, coo.data * 0.5], (np.r_[coo.row, coo.row], np.r_[coo.col, coo.col])),
        shape=A.shape,
    )
    Y, _ = lse_deform.solve_lse(dup, C, B, D)
    assert np.abs(Y - X).max() <= 1e-12 * np.abs(X).max()


@pytest.mark.parametrize("method", ["nullspace-qr", "kkt"])
def test_fortran_order_mesh_input(method):
    V, F = bumpy_grid()
    b, bc = fixed_and_handle(V)
    U, _ = lse_deform.deform(V, F, (b, bc), method=method)
    U_f, _ = lse_deform.deform(np.asfortranarray(V), np.asfortranarray(F), (b, np.asfortranarray(bc)), method=method)
    assert np.array_equal(U, U_f)
    # Fortran order must not be read as C order: the transposed buffer of a
    # 3 x n array viewed as n x 3 is the same logical matrix
    U_t, _ = lse_deform.deform(np.ascontiguousarray(V.T).T, np.ascontiguousarray(F.T).T, (b, bc), method=method)
    assert np.array_equal(U, U_t)
    # other dtypes are converted: int32 faces, float32-exact positions
    U_i, _ = lse_deform.deform(V, F.astype(np.int32), (b.astype(np.uint32), bc), method=method)
    assert np.array_equal(U, U_i)


def test_export_system_round_trip(tmp_path):
    exe = cli_binary()
    if exe is None:
        pytest.skip("the lse-deform binary is not built (cargo build)")
    V, F = bumpy_grid(n=20)
    b, bc = fixed_and_handle(V)
    mesh, scene = tmp_path / "grid.obj", tmp_path / "scene.json"
    write_obj(mesh, V, F)
    items = [{"type": "position", "vertex": int(v), "target": t.tolist()} for v, t in zip(b, bc)]
    # a relative constraint between two handle vertices (implied by their
    # positions) and a repeated position: both redundant
    items.append({"type": "relative", "vertices": [int(b[-1]), int(b[-2])], "vector": (bc[-1] - bc[-2]).tolist()})
    items.append(dict(items[0]))
    scene.write_text(json.dumps({"constraints": items}))
    out = tmp_path / "sys"
    subprocess.run([exe, "export-system", str(mesh), "-c", str(scene), "-o", str(out)], check=True, capture_output=True)
    read = lambda name: scipy.io.mmread(str(out / name))
    A, C, B, D = sp.csc_matrix(read("A.mtx")), read("C.mtx"), sp.csc_matrix(read("B.mtx")), read("D.mtx")
    X, report = lse_deform.solve_lse(A, C, B, D)
    unit = json.loads((out / "meta.json").read_text())["length_unit"]
    U, deform_report = lse_deform.deform(V, F, str(scene))
    assert np.abs(X * unit - U).max() <= 1e-12 * np.abs(U).max()
    assert report["redundant"] == deform_report["redundant"] == [len(items) - 2, len(items) - 1]
    # and the CLI's own solve of the same files
    subprocess.run([exe, "solve", str(out), "-o", str(tmp_path / "X.mtx")], check=True, capture_output=True)
    assert np.abs(scipy.io.mmread(str(tmp_path / "X.mtx")) - X).max() <= 1e-12 * np.abs(X).max()


@pytest.mark.parametrize("seed,k", [(21, 3), (22, 4), (23, 2)])
def test_cli_solve_names_exactly_the_dependent_rows(tmp_path, seed, k):
    """`lse-deform solve` on Matrix Market files of a random sparse LSE with
    constructed redundant and conflicting rows of B: the report names
    exactly those rows and X is the dense KKT solution."""
    exe = cli_binary()
    if exe is None:
        pytest.skip("the lse-deform binary is not built (cargo build)")
    A, C, B, D, X_ref, redundant, conflicting = random_problem(seed, k=k)
    for name, m in [("A", sp.coo_matrix(A)), ("B", sp.coo_matrix(B)), ("C", C), ("D", D)]:
        scipy.io.mmwrite(tmp_path / f"{name}.mtx", m)
    args = [exe, "solve"]
    for name in "acbd":
        args += [f"--{name}", str(tmp_path / f"{name.upper()}.mtx")]
    args += ["-o", str(tmp_path / "X.mtx"), "--report", str(tmp_path / "r.json")]
    done = subprocess.run(args, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["rank"] == 5
    assert report["redundant"] == redundant
    assert [c["index"] for c in report["conflicting"]] == conflicting
    X = np.asarray(scipy.io.mmread(tmp_path / "X.mtx"))
    assert np.abs(X - X_ref).max() <= 1e-10 * max(1.0, np.abs(X_ref).max())
