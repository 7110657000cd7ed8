"""The Deformer: one factorisation, many target updates, each equal to a
fresh deform of the moved constraints; the report's keys are the CLI's."""

import json
import subprocess

import numpy as np
import pytest

import lse_deform
from conftest import bumpy_grid, cli_binary, fixed_and_handle, write_obj

V, F = bumpy_grid(n=16)
B_IDX, BC = fixed_and_handle(V, handle=0.05)
N_FIXED = int(round(0.2 * len(V)))


def items(targets):
    return [
        {"type": "position", "vertex": int(v), "target": t.tolist(), **({"group": "handle"} if i >= N_FIXED else {})}
        for i, (v, t) in enumerate(zip(B_IDX, targets))
    ]


@pytest.mark.parametrize("method", ["nullspace-qr", "kkt", "eliminate"])
def test_set_targets_and_transform_group_match_fresh_solves(method):
    d = lse_deform.Deformer(V, F, items(BC), method=method)
    d.precompute()
    first = d.solve()
    assert np.abs(first - lse_deform.deform(V, F, (B_IDX, BC), method=method)[0]).max() <= 1e-12

    moved = BC.copy()
    moved[N_FIXED:] += [0.0, 0.0, 0.3]
    d.set_targets(np.arange(N_FIXED, len(B_IDX)), moved[N_FIXED:])
    expected = lse_deform.deform(V, F, (B_IDX, moved), method=method)[0]
    assert np.abs(d.solve() - expected).max() <= 1e-12

    # a rotation about z and a lift, applied to the (new) rest targets
    c, s = np.cos(0.4), np.sin(0.4)
    M = np.array([[c, -s, 0, 0.1], [s, c, 0, 0], [0, 0, 1, 0.2]])
    d.transform_group("handle", M)
    turned = moved.copy()
    turned[N_FIXED:] = moved[N_FIXED:] @ M[:, :3].T + M[:, 3]
    expected = lse_deform.deform(V, F, (B_IDX, turned), method=method)[0]
    assert np.abs(d.solve() - expected).max() <= 1e-12
    # not cumulative; the 4 x 4 form; the identity puts the group back
    d.transform_group("handle", np.r_[M, [[0, 0, 0, 1]]])
    assert np.abs(d.solve() - expected).max() <= 1e-12
    d.transform_group("handle", np.eye(4))
    assert np.abs(d.solve() - lse_deform.deform(V, F, (B_IDX, moved), method=method)[0]).max() <= 1e-12
    assert d.group("handle") == list(range(N_FIXED, len(B_IDX)))
    assert d.report["hard_constraints"] == len(B_IDX)


def test_report_has_the_cli_keys(tmp_path):
    _, report = lse_deform.deform(V, F, (B_IDX, BC))
    exe = cli_binary()
    if exe is None:
        pytest.skip("the lse-deform binary is not built (cargo build)")
    write_obj(tmp_path / "m.obj", V, F)
    (tmp_path / "c.json").write_text(json.dumps({"constraints": items(BC)}))
    subprocess.run(
        [exe, "deform", str(tmp_path / "m.obj"), "-c", str(tmp_path / "c.json"), "-o", str(tmp_path / "o.obj"), "--report", str(tmp_path / "r.json")],
        check=True,
        capture_output=True,
    )
    cli = json.loads((tmp_path / "r.json").read_text())
    assert set(report) == set(cli)
    assert set(report["timings_s"]) == set(cli["timings_s"])
    assert (report["rank"], report["redundant"]) == (cli["rank"], cli["redundant"])


def test_penalty_default_is_the_cli_default_and_refine_passes_through():
    # the report's warnings are RuntimeWarnings, as the CLI prints them
    with pytest.warns(RuntimeWarning) as caught:
        _, off = lse_deform.deform(V, F, (B_IDX, BC), method="penalty", weight=1.0)
    assert any("estimated forward error" in str(w.message) for w in caught)
    assert off["refinement"]["mode"] == "off" and off["redundant"] == "not detected"
    with pytest.warns(RuntimeWarning, match="hold only approximately"):
        U, auto = lse_deform.deform(V, F, (B_IDX, BC), method="penalty", weight=1.0, refine="auto")
    assert auto["refinement"]["mode"] == "auto" and auto["refinement"]["steps"] >= 1
    exact = lse_deform.deform(V, F, (B_IDX, BC))[0]
    assert np.abs(U - exact).max() <= 1e-9
    _, three = lse_deform.deform(V, F, (B_IDX, BC), refine=3)
    assert three["refinement"]["steps"] <= 3


def test_a_conflicting_constraint_is_a_runtime_warning_naming_the_earlier_one():
    # constraint 0 fixes vertex B_IDX[0]; the last one asks it elsewhere
    v0 = int(B_IDX[0])
    conflict = {"type": "position", "vertex": v0, "target": (BC[0] + [0.0, 0.0, 0.1]).tolist()}
    cs = items(BC) + [conflict]
    n = len(cs) - 1
    message = "constraint %d conflicts with constraint 0 and was dropped" % n
    with pytest.warns(RuntimeWarning, match=message):
        U, report = lse_deform.deform(V, F, cs)
    assert [c["index"] for c in report["conflicting"]] == [n]
    assert any(w.startswith(message) for w in report["warnings"])
    assert np.abs(U[v0] - BC[0]).max() <= 1e-12
    # the Deformer's solve warns alike, every time
    d = lse_deform.Deformer(V, F, cs)
    d.precompute()
    for _ in range(2):
        with pytest.warns(RuntimeWarning, match=message):
            d.solve()
