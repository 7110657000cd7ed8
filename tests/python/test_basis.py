"""`Deformer.basis(groups)` and `HandleBasis.evaluate`: equal to
`transform_group` + `solve()` over rigid handle motions (on a generated
grid and the Stanford bunny with the CLI scene's groups), stale after
what would change that answer, and typed errors; and the cheap frame
`solve(refine="off", estimate=False)`. Tolerances are relative to the
bounding-box diagonal."""

import os

import numpy as np
import pytest

import lse_deform
from conftest import bumpy_grid, read_obj, scene_items, shared_mesh
from lse_deform import InputError, InputTypeError, TooLargeError

V, F = bumpy_grid(n=16)
ITEMS = scene_items(V, handle=0.05)


def diagonal(V):
    return np.linalg.norm(V.max(axis=0) - V.min(axis=0))


def rotation(axis, angle):
    """Rodrigues' rotation about the unit vector `axis`."""
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def rigid_frames(centroid, scale, frames=20):
    """3 x 4 maps: a rotation about an axis through `centroid`, growing to
    0.6 rad, and a translation growing to 0.1 `scale`."""
    for f in range(1, frames + 1):
        s = f / frames
        R = rotation([0.3, 1.0, 0.5], 0.6 * s)
        t = centroid - R @ centroid + scale * s * np.array([0.1, -0.05, 0.08])
        yield np.c_[R, t]


def handle_centroid(items):
    return np.array([c["target"] for c in items if c.get("group") == "handle"]).mean(axis=0)


def deformer(V=V, F=F, items=ITEMS, **kwargs):
    d = lse_deform.Deformer(V, F, items, **kwargs)
    d.precompute()
    return d


def bunny():
    path = shared_mesh("bunny-35k-stanford.obj")
    if path is None:
        pytest.skip("../shared/meshes/bunny-35k-stanford.obj is not on this machine")
    V, F = read_obj(path)
    return V, F, scene_items(V)


@pytest.mark.parametrize("mesh", ["grid", "bunny"])
def test_evaluate_equals_transform_group_and_solve(mesh):
    V_, F_, items = (V, F, ITEMS) if mesh == "grid" else bunny()
    d = deformer(V_, F_, items)
    basis = d.basis(["handle"])
    assert basis.groups == ["handle"] and basis.bytes >= len(V_) * 7 * 8
    assert basis.build_time_s > 0 and 0 <= basis.forward_error_estimate <= 1e-9
    diag = diagonal(V_)
    out = np.empty((len(V_), 3))
    for k, M in enumerate(rigid_frames(handle_centroid(items), diag)):
        # alternate the forms: 3 x 4, 4 x 4, nested lists, into `out`
        if k % 4 == 0:
            U = basis.evaluate({"handle": M})
        elif k % 4 == 1:
            U = basis.evaluate({"handle": np.r_[M, [[0, 0, 0, 1]]]})
        elif k % 4 == 2:
            U = basis.evaluate({"handle": M.tolist()})
        else:
            U = basis.evaluate({"handle": M}, out=out)
            assert U is out
        assert U.shape == (len(V_), 3) and U.dtype == np.float64
        # transform_group of a group of the basis does not make it stale
        d.transform_group("handle", M)
        assert np.abs(U - d.solve()).max() <= 1e-10 * diag


def test_a_group_left_out_is_at_its_rest_pose_and_other_constraints_keep_their_targets():
    d = deformer()
    M = next(rigid_frames(handle_centroid(ITEMS), diagonal(V)))
    # moved before the basis is built: the fixed group's current targets
    # are part of the basis, the handle's current transform is not
    d.transform_group("fixed", np.c_[np.eye(3), [0.0, 0.0, 0.02]])
    d.transform_group("handle", M)
    basis = d.basis(["handle"])
    d.transform_group("handle", np.eye(4))
    assert np.abs(basis.evaluate({}) - d.solve()).max() <= 1e-10 * diagonal(V)
    # two groups, one left out
    both = d.basis(["fixed", "handle"])
    d.transform_group("fixed", np.eye(4))
    d.transform_group("handle", M)
    assert np.abs(both.evaluate({"handle": M}) - d.solve()).max() <= 1e-10 * diagonal(V)


def test_a_changed_deformer_makes_the_basis_refuse():
    d = deformer()
    fixed = d.group("fixed")
    stale = "earlier configuration of the Deformer.*Deformer.basis"
    M = next(rigid_frames(handle_centroid(ITEMS), diagonal(V)))

    basis = d.basis(["handle"])
    d.set_targets([fixed[0]], [np.array(ITEMS[fixed[0]]["target"]) + [0.0, 0.0, 0.05]])
    with pytest.raises(InputError, match=stale) as refused:
        basis.evaluate({"handle": M})
    assert "set_targets() was called since" in str(refused.value)
    assert "Deformer.basis(['handle'])" in str(refused.value) or 'Deformer.basis(["handle"])' in str(refused.value)
    fresh = d.basis(["handle"])
    d.transform_group("handle", M)
    assert np.abs(fresh.evaluate({"handle": M}) - d.solve()).max() <= 1e-10 * diagonal(V)

    # set_targets inside the basis's group moves its rest targets
    handle = d.group("handle")
    d.set_targets([handle[0]], [ITEMS[handle[0]]["target"]])
    with pytest.raises(InputError, match=stale):
        fresh.evaluate({})

    # transform_group of a group outside the basis; of one inside it is fine
    basis = d.basis(["handle"])
    both = d.basis(["handle", "fixed"])
    d.transform_group("fixed", np.eye(4))
    with pytest.raises(InputError, match="transform_group\\('fixed'\\)"):
        basis.evaluate({})
    both.evaluate({})

    # a new precompute (a new factor)
    basis = d.basis(["handle"])
    d.precompute()
    with pytest.raises(InputError, match="precompute"):
        basis.evaluate({})


def test_evaluate_errors():
    d = deformer()
    basis = d.basis(["handle"])
    M = np.c_[np.eye(3), np.zeros(3)]
    n = len(V)
    with pytest.raises(InputTypeError, match="dict"):
        basis.evaluate([M])
    with pytest.raises(InputError, match="'fixed' is not in this basis"):
        basis.evaluate({"fixed": M})
    with pytest.raises(InputError, match="'nope' is not in this basis"):
        basis.evaluate({"nope": M})
    with pytest.raises(InputTypeError, match="keys are group names"):
        basis.evaluate({1: M})
    with pytest.raises(InputError, match=r"transforms\['handle'\].*shape"):
        basis.evaluate({"handle": np.eye(3)})
    with pytest.raises(InputError, match=r"transforms\['handle'\] must be 3 × 4"):
        basis.evaluate({"handle": np.zeros((5, 4))})
    projective = np.eye(4)
    projective[3, 2] = 0.1
    with pytest.raises(InputError, match=r"transforms\['handle'\].*last row"):
        basis.evaluate({"handle": projective})
    with pytest.raises(InputError, match="'handle'.*non-finite"):
        basis.evaluate({"handle": np.c_[np.eye(3), [np.nan, 0, 0]]})
    with pytest.raises(InputTypeError, match=r"transforms\['handle'\]"):
        basis.evaluate({"handle": "identity"})
    # a last row off by rounding is [0, 0, 0, 1]
    nearly = np.eye(4)
    nearly[3, :] += 1e-15
    assert np.abs(basis.evaluate({"handle": nearly}) - basis.evaluate({})).max() <= 1e-12
    d.transform_group("handle", nearly)

    for bad, error, message in [
        (np.zeros((n, 3), dtype=np.float32), InputTypeError, "dtype"),
        (np.zeros((n, 3)).tolist(), InputTypeError, "list"),
        (np.zeros((n + 1, 3)), InputError, "shape"),
        (np.zeros((n, 3), order="F"), InputError, "C-contiguous"),
        (np.zeros((n, 6))[:, ::2], InputError, "C-contiguous"),
    ]:
        with pytest.raises(error, match=message):
            basis.evaluate({}, out=bad)
    readonly = np.zeros((n, 3))
    readonly.setflags(write=False)
    with pytest.raises(InputError, match="not writable"):
        basis.evaluate({}, out=readonly)


def test_basis_errors():
    d = lse_deform.Deformer(V, F, ITEMS)
    with pytest.raises(InputError, match="precompute"):
        d.basis(["handle"])
    d.precompute()
    with pytest.raises(InputTypeError, match="list of group names"):
        d.basis("handle")
    with pytest.raises(InputError, match="'nope'"):
        d.basis(["nope"])
    with pytest.raises(InputError, match="'handle' is named twice"):
        d.basis(["handle", "handle"])


def resident_bytes():
    """This process's resident set (Linux: /proc/self/statm)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def test_a_basis_beyond_the_memory_budget_is_too_large():
    # 60 single-vertex groups: 243 columns, far beyond the factor's memory
    items = [dict(c) for c in ITEMS]
    free = [c for c in items if c["group"] == "handle"][:1]
    loose = sorted(set(range(len(V))) - {c["vertex"] for c in items})[:60]
    items = [c for c in items if c["group"] == "fixed"] + free
    items += [{"type": "position", "vertex": v, "target": V[v].tolist(), "group": "g%d" % i} for i, v in enumerate(loose)]
    # The budget is of the whole process (what it holds counts, as for the
    # factorisations): 2 MiB more than this process holds now.
    d = deformer(items=items, memory_limit=str(resident_bytes() + (2 << 20)))
    with pytest.raises(TooLargeError, match="response basis of 60 group"):
        d.basis(["g%d" % i for i in range(60)])
    # the same budget holds the basis of one group
    assert d.basis(["g0"]).groups == ["g0"]


def test_cheap_frame_skips_the_estimate_and_the_diagnostics():
    d = deformer()
    M = next(rigid_frames(handle_centroid(ITEMS), diagonal(V)))
    d.transform_group("handle", M)
    refined = d.solve()
    assert d.report["forward_error_estimate"] is not None

    # refine="off" alone still computes one correction, for the estimate
    off = d.solve(refine="off")
    report = d.report
    assert report["refinement"]["mode"] == "off" and report["forward_error_estimate"] is not None

    cheap = d.solve(refine="off", estimate=False)
    assert np.abs(cheap - off).max() <= 1e-14 * diagonal(V)  # the same solve, uncorrected
    assert np.abs(cheap - refined).max() <= 1e-8 * diagonal(V)
    report = d.report
    assert report["forward_error_estimate"] is None and report["refinement"] is None
    assert report["max_constraint_residual"] is None and report["least_squares_residual"] is None
    assert report["timings_s"]["refine"] == 0.0 and report["timings_s"]["solve"] > 0

    # refine= applies to its call only: the Deformer's own ('auto') stays
    d.solve()
    assert d.report["refinement"]["mode"] == "auto"

    # estimate=False with refinement on is refused
    with pytest.raises(InputError, match="estimate=False applies to refine='off' only"):
        d.solve(estimate=False)
    with pytest.raises(InputError, match="estimate=False"):
        d.solve(refine=2, estimate=False)
    # penalty's own refinement is off: estimate=False alone is the cheap frame
    p = lse_deform.Deformer(V, F, ITEMS, method="penalty", weight=1e6)
    p.precompute()
    p.solve(estimate=False)
    assert p.report["forward_error_estimate"] is None
