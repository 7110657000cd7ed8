"""The request layer from Python: keywords left out mean the
library's defaults (`DeformOptions::default()`, `ArapOptions::default()`,
the documented values), and `factor=` is the name of the factorisation
keyword with `spd=`, its old name, still accepted."""

import warnings

import numpy as np
import pytest

import lse_deform
from lse_deform import InputError, InputTypeError
from conftest import bumpy_grid, fixed_and_handle


@pytest.fixture
def scene():
    V, F = bumpy_grid(n=10)
    b, bc = fixed_and_handle(V, handle=0.05)
    return V, F, (b, bc)


def test_no_keywords_are_the_documented_defaults(scene):
    V, F, c = scene
    U, report = lse_deform.deform(V, F, c)
    W, explicit = lse_deform.deform(
        V, F, c, laplacian="cotan", method="nullspace-qr", qr="sparse-givens",
        factor="faer-auto", energy="laplacian",
    )
    assert np.array_equal(U, W)
    assert report["method"] == explicit["method"] == "nullspace-qr"


def test_no_arap_keywords_are_the_documented_defaults(scene):
    V, F, c = scene
    U, report = lse_deform.deform(V, F, c, energy="arap")
    W, _ = lse_deform.deform(
        V, F, c, energy="arap", arap_energy="spokes-and-rims", iterations=10,
        tolerance=0.0, arap_init="linear",
    )
    assert np.array_equal(U, W)
    assert report["arap"]["iterations"] == 10
    assert report["arap"]["init"] == "linear"


@pytest.mark.parametrize("entry", ["deform", "Deformer"])
def test_spd_is_the_old_name_of_factor(scene, entry):
    V, F, c = scene

    def positions(**kw):
        if entry == "deform":
            return lse_deform.deform(V, F, c, method="kkt", **kw)[0]
        d = lse_deform.Deformer(V, F, c, method="kkt", **kw)
        d.precompute()
        return d.solve()

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        new = positions(factor="faer-simplicial")
        old = positions(spd="faer-simplicial")
        both = positions(factor="faer-simplicial", spd="faer-simplicial")
    assert np.array_equal(new, old) and np.array_equal(new, both)


def test_spd_and_factor_disagreeing_is_an_input_error(scene):
    V, F, c = scene
    with pytest.raises(InputError, match="factor= and spd="):
        lse_deform.deform(V, F, c, factor="faer-simplicial", spd="faer-supernodal")


def test_a_bad_factor_names_the_keyword(scene):
    V, F, c = scene
    with pytest.raises(InputError, match="factor="):
        lse_deform.deform(V, F, c, method="kkt", factor="nalgebra")


def test_compare_takes_factor_and_spd(scene):
    V, F, c = scene
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        new = lse_deform.compare(V, F, c, methods=["kkt"], factor=["faer-simplicial"], repeat=1, condition=False)
        old = lse_deform.compare(V, F, c, methods=["kkt"], spd=["faer-simplicial"], repeat=1, condition=False)
    assert [r["spd"] for r in new] == [r["spd"] for r in old] == ["faer-simplicial"]


def test_threads_and_ordering_are_held_and_reported(scene):
    """threads= and ordering= reach the back end and the report says what
    was used; a given permutation is followed and changes no result;
    the CLI's words and bad values are refused as InputErrors naming the
    keyword."""
    V, F, items = scene
    U, own = lse_deform.deform(V, F, items)
    assert own["ordering"] == "own (amd)" and own["threads"] == 1
    U1, r = lse_deform.deform(V, F, items, ordering="amd", threads=1, factor="faer-simplicial")
    assert r["ordering"] == "amd" and r["threads"] == 1
    assert r["timings_s"]["ordering"] > 0
    U2, n = lse_deform.deform(V, F, items, ordering="amd", threads=1, factor="nalgebra")
    assert n["nnz"]["factor"] == r["nnz"]["factor"]
    order = np.arange(len(V))[::-1]
    U3, g = lse_deform.deform(V, F, items, ordering=order)
    assert g["ordering"] == "given"
    diagonal = np.linalg.norm(V.max(axis=0) - V.min(axis=0))
    for other in (U1, U2, U3):
        assert np.abs(other - U).max() <= 1e-9 * diagonal
    for keyword, bad in (("ordering", "colamd"), ("threads", 0), ("threads", "two"), ("ordering", [0, 0])):
        with pytest.raises(InputError) as e:
            lse_deform.deform(V, F, items, **{keyword: bad})
        assert keyword in str(e.value) or "permutation" in str(e.value), str(e.value)
    rows = lse_deform.compare(
        V, F, items, methods=["nullspace-qr"], qr=["sparse-givens"], factor=["faer-simplicial"],
        ordering="amd", threads=1, condition=False, repeat=1,
    )
    assert [(row["ordering"], row["threads"]) for row in rows] == [("amd", 1)]


def test_numpy_integers_are_integers_wherever_ints_are(scene):
    """A numpy integer scalar is an int to every integer keyword (threads=
    refused np.int64(2) as a type error on aa82d57); a float, or a bool,
    stays a type error, and numpy's 0 a value error like Python's 0."""
    V, F, items = scene
    _, expected = lse_deform.deform(V, F, items, threads=2, factor="faer-simplicial", refine=2)
    for kind in (np.int64, np.int32, np.uint8):
        _, r = lse_deform.deform(V, F, items, threads=kind(2), factor="faer-simplicial", refine=kind(2))
        assert r["threads"] == expected["threads"] == 2, kind
        assert r["refinement"]["steps"] == expected["refinement"]["steps"], kind
    for bad in (2.0, np.float64(2.0), True):
        with pytest.raises(InputTypeError):
            lse_deform.deform(V, F, items, threads=bad)
    with pytest.raises(InputError, match="threads="):
        lse_deform.deform(V, F, items, threads=np.int64(0))
