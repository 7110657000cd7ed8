"""Python keywords and the response basis: `refine=0` means zero steps; `out_of_core=`
takes bytes as its message says; `HandleBasis.evaluate` takes any mapping
(as its stub says) and checks its maps as `transform_group` does;
`basis()` before `precompute()` says so in Python's words."""

import types

import numpy as np
import pytest

import lse_deform
from conftest import bumpy_grid, fixed_and_handle, scene_items
from lse_deform import InputError


def test_refine_zero_means_zero_steps():
    V, F = bumpy_grid(n=10)
    b, bc = fixed_and_handle(V, handle=0.05)
    U0, r0 = lse_deform.deform(V, F, (b, bc), refine=0)
    Uoff, _ = lse_deform.deform(V, F, (b, bc), refine="off")
    _, r1 = lse_deform.deform(V, F, (b, bc), refine=1)
    assert r0["refinement"]["steps"] == 0
    assert np.array_equal(U0, Uoff)
    assert r1["refinement"]["steps"] == 1


def test_out_of_core_takes_bytes_and_says_what_it_takes():
    V, F = bumpy_grid(n=6)
    b, bc = fixed_and_handle(V, handle=0.05)
    # bytes are a path like str: refused for the factor, not for the type
    with pytest.raises(InputError, match="mumps"):
        lse_deform.deform(V, F, (b, bc), factor="faer-auto", out_of_core=b".")
    with pytest.raises(TypeError, match="str, bytes or os.PathLike"):
        lse_deform.deform(V, F, (b, bc), out_of_core=123)


def basis_and_deformer():
    V, F = bumpy_grid(n=12)
    d = lse_deform.Deformer(V, F, scene_items(V, handle=0.05))
    d.precompute()
    return d, d.basis(["handle"])


def test_evaluate_takes_any_mapping():
    d, basis = basis_and_deformer()
    M = np.c_[np.eye(3), [0.01, 0.0, 0.0]]
    with_dict = basis.evaluate({"handle": M})
    with_proxy = basis.evaluate(types.MappingProxyType({"handle": M}))
    assert np.array_equal(with_dict, with_proxy)
    with pytest.raises(TypeError, match="mapping"):
        basis.evaluate([("handle", M)])


def test_evaluate_refuses_the_maps_transform_group_refuses():
    d, basis = basis_and_deformer()
    huge = np.c_[np.eye(3) * 1e308, [1e308, 1e308, 1e308]]
    with pytest.raises(InputError) as by_transform:
        d.transform_group("handle", huge)
    with pytest.raises(InputError) as by_evaluate:
        basis.evaluate({"handle": huge})
    assert type(by_evaluate.value) is type(by_transform.value)


def test_basis_before_precompute_says_so():
    V, F = bumpy_grid(n=6)
    d = lse_deform.Deformer(V, F, scene_items(V, handle=0.05))
    with pytest.raises(InputError, match=r"basis\(\) needs a factorisation: call precompute\(\) first"):
        d.basis(["handle"])
