"""`deform(..., energy="arap")` and `compare(...)` against the CLI's
`deform --energy arap` and `compare --json` on a generated grid, the
warnings for options the energy does not use, and bad words."""

import json
import subprocess
import warnings

import numpy as np
import pytest

import lse_deform
from conftest import bumpy_grid, cli_binary, fixed_and_handle, write_obj


def read_obj_positions(path):
    with open(path) as f:
        return np.array([[float(t) for t in line.split()[1:4]] for line in f if line.startswith("v ")])


@pytest.fixture
def scene(tmp_path):
    """A 12 x 12 grid with its fixed-and-handle constraints, as arrays and
    as the files the CLI reads."""
    V, F = bumpy_grid(n=12)
    b, bc = fixed_and_handle(V, handle=0.05)
    mesh, constraints = tmp_path / "grid.obj", tmp_path / "scene.json"
    write_obj(mesh, V, F)
    items = [{"type": "position", "vertex": int(v), "target": t.tolist()} for v, t in zip(b, bc)]
    constraints.write_text(json.dumps({"constraints": items}))
    return V, F, str(constraints), str(mesh)


def binary():
    exe = cli_binary()
    if exe is None:
        pytest.skip("the lse-deform binary is not built (cargo build)")
    return exe


@pytest.mark.parametrize(
    "arap_energy,arap_init,iterations", [("spokes", "rest", 4), ("spokes-and-rims", "linear", 3)]
)
def test_arap_equals_the_cli(scene, tmp_path, arap_energy, arap_init, iterations):
    exe = binary()
    V, F, constraints, mesh = scene
    out, report_path = tmp_path / "out.obj", tmp_path / "report.json"
    subprocess.run(
        [exe, "deform", mesh, "-c", constraints, "-o", str(out), "--report", str(report_path),
         "--energy", "arap", "--arap-energy", arap_energy, "--arap-init", arap_init,
         "--iterations", str(iterations)],
        check=True, capture_output=True,
    )
    U, report = lse_deform.deform(
        V, F, constraints, energy="arap", arap_energy=arap_energy, arap_init=arap_init,
        iterations=iterations,
    )
    cli = json.loads(report_path.read_text())
    U_cli = read_obj_positions(out)
    assert U.shape == V.shape
    # ARAP moved the grid, and away from the linear solution
    assert np.abs(U - V).max() > 0.05
    assert np.abs(U - U_cli).max() <= 1e-12 * np.abs(U_cli).max()
    arap = report["arap"]
    assert arap["energy"] == arap_energy and arap["init"] == arap_init
    assert arap["iterations"] == iterations and arap["stop_reason"] == "iterations"
    assert arap["energies"] == pytest.approx(cli["arap"]["energies"], rel=1e-10)
    assert arap["energies"][-1] < arap["initial_energy"]
    assert report["method"] == cli["method"]


def test_arap_tolerance_stops_early(scene):
    V, F, constraints, _ = scene
    _, report = lse_deform.deform(V, F, constraints, energy="arap", iterations=50, tolerance=1e-2)
    assert report["arap"]["stop_reason"] == "tolerance"
    assert report["arap"]["iterations"] < 50


def test_laplacian_report_has_no_arap_section(scene):
    V, F, constraints, _ = scene
    _, report = lse_deform.deform(V, F, constraints)
    assert report["arap"] is None


@pytest.mark.parametrize(
    "kwargs,keyword",
    [
        (dict(iterations=3), "iterations"),
        (dict(tolerance=1e-3), "tolerance"),
        (dict(arap_energy="spokes"), "arap_energy"),
        (dict(arap_init="rest"), "arap_init"),
        (dict(energy="arap", laplacian="uniform"), "laplacian"),
    ],
)
def test_inapplicable_options_warn(scene, kwargs, keyword):
    V, F, constraints, _ = scene
    with pytest.warns(RuntimeWarning, match=r"^%s= applies to energy=" % keyword):
        lse_deform.deform(V, F, constraints, **kwargs)


def test_applicable_options_do_not_warn(scene):
    V, F, constraints, _ = scene
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        lse_deform.deform(V, F, constraints, energy="arap", iterations=2, arap_init="rest")
        lse_deform.deform(V, F, constraints, laplacian="uniform")
    assert not [w for w in caught if "applies to" in str(w.message)]


@pytest.mark.parametrize(
    "kwargs,accepted",
    [
        (dict(energy="arpa"), ["laplacian", "arap"]),
        (dict(energy="arap", arap_energy="rims"), ["spokes", "spokes-and-rims"]),
        (dict(energy="arap", arap_init="zero"), ["rest", "linear"]),
    ],
)
def test_bad_word_lists_the_accepted_words(scene, kwargs, accepted):
    V, F, constraints, _ = scene
    with pytest.raises(lse_deform.InputError) as e:
        lse_deform.deform(V, F, constraints, **kwargs)
    message = str(e.value)
    assert list(kwargs)[-1] + "=" in message
    assert message.endswith("(expected one of: %s)" % ", ".join(accepted))


def in_order(names):
    """`names` without repeats, in order of first appearance."""
    return list(dict.fromkeys(n for n in names if n is not None))


def test_compare_equals_the_cli(scene, tmp_path):
    """The module's default comparison equals the CLI's over the wheel's
    back ends (the binary may have more: it is given the wheel's lists)."""
    exe = binary()
    V, F, constraints, mesh = scene
    rows = lse_deform.compare(V, F, constraints, repeat=1, condition=False)
    spds = in_order(r["spd"] for r in rows)
    qrs = in_order(r["qr"] for r in rows if r["method"] == "nullspace-qr")
    out = tmp_path / "compare.json"
    subprocess.run(
        [exe, "compare", mesh, "-c", constraints, "--json", str(out), "--repeat", "1",
         "--no-condition", "--factor", ",".join(spds), "--qr", ",".join(qrs)],
        check=True, capture_output=True,
    )
    cli = json.loads(out.read_text())
    assert len(rows) == len(cli) > 4
    for row, cli_row in zip(rows, cli):
        assert list(row) == list(cli_row)
        for key in ("method", "qr", "spd", "weight", "status"):
            assert row[key] == cli_row[key]
        assert row["condition"] is None
        if cli_row["delta_x"] is None:
            assert row["delta_x"] is None
        else:
            assert abs(row["delta_x"] - cli_row["delta_x"]) <= 1e-12
    # the exact formulations reach the reference
    exact = [r for r in rows if r["method"] != "penalty" and r["status"] == "ok"]
    assert exact and max(r["delta_x"] for r in exact) < 1e-10


def test_compare_filters(scene):
    V, F, constraints, _ = scene
    rows = lse_deform.compare(
        V, F, constraints, methods=["penalty"], spd=["nalgebra"], weights=[1e6], repeat=1,
        condition=True,
    )
    assert [(r["method"], r["spd"], r["weight"]) for r in rows] == [("penalty", "nalgebra", 1e6)]
    assert rows[0]["condition"] > 1.0
    assert 0.0 < rows[0]["delta_x"] < 1e-2


def test_compare_bad_word_and_empty_selection(scene):
    V, F, constraints, _ = scene
    with pytest.raises(lse_deform.InputError, match="methods=.*nullspace-qr.*penalty"):
        lse_deform.compare(V, F, constraints, methods=["bogus"])
    with pytest.raises(lse_deform.InputError, match="methods="):
        lse_deform.compare(V, F, constraints, methods=["penalty"], weights=[])
