"""Every class of bad input from Python: a TypeError for what cannot be
converted, InputError (a ValueError) for what the library refuses, with
the message naming the place, NumericalError for numerical failure — and
never a crash of the interpreter."""

import json

import numpy as np
import pytest
import scipy.sparse as sp

import lse_deform
from lse_deform import InputError, NumericalError
from conftest import bumpy_grid, fixed_and_handle

V, F = bumpy_grid(n=8)
B_IDX, BC = fixed_and_handle(V)


def deform(V=V, F=F, constraints=(B_IDX, BC), **kw):
    return lse_deform.deform(V, F, constraints, **kw)


def test_exception_hierarchy():
    assert issubclass(InputError, ValueError)
    assert issubclass(NumericalError, ArithmeticError)


@pytest.mark.parametrize(
    "bad, exc, words",
    [
        (V.astype(complex), TypeError, "complex128"),
        (V.astype(object), TypeError, "object"),
        (np.full(V.shape, "x"), TypeError, "dtype"),
        ("not an array", TypeError, "dtype"),
        (None, TypeError, "V"),
        (V[:, :2], InputError, "n × 3"),
        (V.ravel(), InputError, "n × 3"),
        (V[None], InputError, "n × 3"),
        (np.zeros((0, 3)), InputError, None),
        ([[0.0, 1.0], [2.0]], TypeError, "V"),
    ],
)
def test_bad_vertices(bad, exc, words):
    with pytest.raises(exc) as e:
        deform(V=bad)
    if words:
        assert words in str(e.value)


def test_non_finite_vertex_names_it():
    for value in (np.nan, np.inf):
        W = V.copy()
        W[5, 1] = value
        with pytest.raises(InputError, match="vertex 5 has a non-finite coordinate"):
            deform(V=W)


@pytest.mark.parametrize(
    "bad, exc, words",
    [
        (F.astype(float), TypeError, "integer"),
        (F[:, :2], InputError, "n × 3"),
        (np.zeros((0, 3), dtype=np.int64), InputError, "empty mesh"),
        (np.where(np.arange(F.size).reshape(F.shape) == 7, -1, F), InputError, "face 2 refers to vertex -1"),
        (np.where(np.arange(F.size).reshape(F.shape) == 7, 2**62, F), InputError, "refers to vertex 4611686018427387904"),
        (np.where(np.arange(F.size).reshape(F.shape) == 7, np.iinfo(np.uint64).max, F.astype(np.uint64)), InputError, "face 2"),
        (np.r_[F, F[:1]], InputError, "repeats face 0"),
        (np.r_[F, [[0, 0, 1]]], InputError, "uses vertex 0 twice"),
    ],
)
def test_bad_faces(bad, exc, words):
    with pytest.raises(exc, match=words):
        deform(F=bad)


@pytest.mark.parametrize(
    "constraints, exc, words",
    [
        ([{"type": "pin", "vertex": 0, "target": [0, 0, 0]}], InputError, "unknown type 'pin'"),
        ([{"type": "position", "vertex": 0, "target": [0, 0, 0], "wieght": 2}], InputError, "unknown field 'wieght'"),
        ([{"type": "position", "vertex": 10**6, "target": [0, 0, 0]}], InputError, "vertex 1000000 is out of range"),
        ([{"type": "position", "vertex": 0, "target": [0, float("nan"), 0]}], InputError, r"\['target'\]\[1\] = NaN is not finite"),
        ([{"type": "position", "vertex": 0, "target": [0, 0]}], InputError, "constraint 0: field 'target'"),
        ([{"type": "position", "vertex": 0, "target": [0, 0, 0], "weight": -1}], InputError, "weight -1 is invalid"),
        ([], InputError, "no constraints"),
        ((B_IDX, BC[:-1]), InputError, "targets"),
        ((-B_IDX - 1, BC), InputError, r"b\[0\] = -1 is not an index"),
        ((B_IDX.astype(float), BC), TypeError, "integer"),
        ((B_IDX, BC[:, :2]), InputError, "n × 3"),
        ((np.array([2**62]), BC[:1]), InputError, "out of range"),
        (5, TypeError, "constraints must be"),
        ("/nonexistent/scene.json", InputError, "/nonexistent/scene.json"),
        ([{"type": "position", "vertex": object(), "target": [0, 0, 0]}], TypeError, "vertex"),
    ],
)
def test_bad_constraints(constraints, exc, words):
    with pytest.raises(exc, match=words):
        deform(constraints=constraints)


def test_numpy_scalars_and_arrays_in_dicts_are_accepted():
    items = [{"type": "position", "vertex": np.int64(v), "target": t} for v, t in zip(B_IDX, BC)]
    U, _ = deform(constraints=items)
    U_ref, _ = deform()
    assert np.array_equal(U, U_ref)


def test_self_containing_constraint_list_is_refused():
    nested = []
    nested.append(nested)
    with pytest.raises(InputError, match="nested deeper"):
        deform(constraints=[{"type": "position", "vertex": 0, "target": nested}])


def test_bad_constraint_file(tmp_path):
    p = tmp_path / "c.json"
    p.write_text('{"constraints": [ {"type": "position", "vertex": 0,, } ]}')
    with pytest.raises(InputError, match="malformed JSON at line 1"):
        deform(constraints=p)
    p.write_text(json.dumps({"constraints": [{"type": "position", "vertex": 0, "target": [0, 0, 0]}]}))
    U, _ = deform(constraints=p)  # os.PathLike works
    assert U.shape == V.shape


@pytest.mark.parametrize(
    "kw, exc, words",
    [
        (dict(method="bogus"), InputError, "unknown method 'bogus'"),
        (dict(laplacian="bogus"), InputError, "unknown Laplacian 'bogus'"),
        (dict(method="penalty"), InputError, "weight=: the penalty method needs a weight"),
        (dict(method="penalty", weight=float("nan")), InputError, "weight NaN"),
        (dict(qr="bogus"), InputError, "bogus"),
        (dict(spd="bogus"), InputError, "bogus"),
        (dict(refine="sometimes"), InputError, "refinement 'sometimes'"),
        (dict(refine=-1), InputError, "refine"),
        (dict(refine=True), TypeError, "refine"),
        (dict(refine=2.5), TypeError, "refine"),
    ],
)
def test_bad_options(kw, exc, words):
    with pytest.raises(exc, match=words):
        deform(**kw)


def test_conflicting_hard_constraints_are_reported_not_raised():
    items = [{"type": "position", "vertex": int(v), "target": t.tolist()} for v, t in zip(B_IDX, BC)]
    items.append({"type": "position", "vertex": int(B_IDX[0]), "target": (BC[0] + 1).tolist()})
    U, report = deform(constraints=items)
    assert [c["index"] for c in report["conflicting"]] == [len(items) - 1]
    assert np.all(np.isfinite(U))


def test_deformer_misuse():
    d = lse_deform.Deformer(V, F, [{"type": "position", "vertex": int(v), "target": t.tolist(), "group": "g"} for v, t in zip(B_IDX, BC)])
    with pytest.raises(InputError, match=r"solve\(\) needs a factorisation: call precompute\(\) first"):
        d.solve()
    d.precompute()
    with pytest.raises(InputError, match="constraint 999 does not exist"):
        d.set_targets([999], [[0, 0, 0]])
    with pytest.raises(InputError, match=r"indices\[0\] = -1"):
        d.set_targets([-1], [[0, 0, 0]])
    with pytest.raises(InputError, match="2 indices but 1 targets"):
        d.set_targets([0, 1], [[0, 0, 0]])
    with pytest.raises(InputError, match="'target' is not finite"):
        d.set_targets([0], [[0, np.inf, 0]])
    with pytest.raises(InputError, match="no constraint group 'nope'"):
        d.transform_group("nope", np.eye(4))
    with pytest.raises(InputError, match="last row"):
        d.transform_group("g", 2 * np.eye(4))
    with pytest.raises(InputError, match="n × 4"):
        d.transform_group("g", np.eye(3))
    with pytest.raises(InputError, match="non-finite"):
        d.transform_group("g", np.full((3, 4), np.nan))
    # after all the refused calls the deformer still solves the rest pose
    U, _ = deform(constraints=(B_IDX, BC))
    assert np.abs(d.solve() - U).max() <= 1e-12


def small_lse():
    A = sp.eye(4, format="csc")
    C = np.arange(12.0).reshape(4, 3)
    B = sp.csr_matrix(np.ones((1, 4)))
    D = np.ones((1, 3))
    return A, C, B, D


def csc_with(**arrays):
    A = sp.eye(4, format="csc")
    for k, v in arrays.items():
        setattr(A, k, v)
    return A


@pytest.mark.parametrize(
    "change, exc, words",
    [
        (dict(C=np.ones((5, 3))), InputError, "problem matrices"),
        (dict(D=np.ones((1, 2))), InputError, "problem matrices"),
        (dict(C=np.full((4, 3), np.nan)), InputError, r"C\[0, 0\] = NaN"),
        (dict(B=sp.csr_matrix((1, 4))), InputError, "row 0 of B has no nonzero"),
        (dict(A=sp.csc_matrix(np.diag([1.0, 1, 1, 0])), B=sp.csr_matrix(np.eye(4)[:1])), InputError, "unknown 3"),
        (dict(A="A"), TypeError, "A"),
        (dict(A=csc_with(indices=np.array([0, 1, 2, 9], dtype=np.int32))), InputError, "row index 9"),
        (dict(A=csc_with(indptr=np.array([0, 2, 1, 3, 4], dtype=np.int32))), InputError, "indptr decreases"),
        (dict(A=csc_with(indptr=np.array([0, 1, 2, 3, 99], dtype=np.int32))), InputError, "indptr"),
        (dict(A=csc_with(indices=np.array([0, -1, 2, 3], dtype=np.int32))), InputError, "indices"),
        (dict(A=csc_with(data=np.array([1, np.nan, 1, 1]))), InputError, r"A\[1, 1\] = NaN"),
        (dict(A=sp.csc_matrix((2**62, 4)), C=np.ones((0, 3))), InputError, "too large"),
        (dict(A=sp.coo_matrix(([1.0], ([0], [2**40])), shape=(4, 2**41))), InputError, "too large"),
        (dict(C=np.ones((4, 3), dtype=complex)), TypeError, "complex"),
    ],
)
def test_bad_matrices(change, exc, words):
    A, C, B, D = small_lse()
    args = dict(A=A, C=C, B=B, D=D)
    args.update(change)
    with pytest.raises(exc, match=words):
        lse_deform.solve_lse(args["A"], args["C"], args["B"], args["D"])


def test_singular_general_problem_names_the_free_unknown():
    A = sp.csc_matrix(np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0]]))
    B = sp.csr_matrix(np.array([[0.0, 0.0, 1.0]]))
    with pytest.raises(NumericalError, match="free"):
        lse_deform.solve_lse(A, np.ones((3, 3)), B, np.ones((1, 3)))
