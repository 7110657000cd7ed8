"""The MUMPS back end from Python: `factor="mumps"` and `out_of_core=`.

A wheel built with the cargo feature `mumps` (`.ci/run` builds it so and
sets LSE_DEFORM_EXPECT_MUMPS=1) must solve with MUMPS in this process (MPI
started as one rank) to within 1e-10 of the diagonal of faer's answer,
report its `mumps` object and leave the out-of-core directory empty; a wheel
without it must refuse `factor="mumps"` with an InputError that says how to
rebuild. Either way `out_of_core=` with another factor is an InputError."""

import os

import numpy as np
import pytest

import lse_deform
from conftest import bumpy_grid, scene_items


def expect_mumps():
    return os.environ.get("LSE_DEFORM_EXPECT_MUMPS", "") not in ("", "0")


def problem():
    V, F = bumpy_grid(20)
    return V, F, scene_items(V)


def mumps_in_this_wheel():
    V, F, items = problem()
    try:
        lse_deform.deform(V, F, items, factor="mumps")
    except lse_deform.InputError as e:
        assert "not in this build" in str(e) and "--features mumps" in str(e), str(e)
        return False
    return True


def test_the_wheel_has_mumps_exactly_when_ci_says_so():
    assert mumps_in_this_wheel() == expect_mumps()


def test_out_of_core_needs_mumps():
    V, F, items = problem()
    with pytest.raises(lse_deform.InputError, match="mumps"):
        lse_deform.deform(V, F, items, factor="faer-auto", out_of_core=".")


@pytest.mark.parametrize("method", ["nullspace-qr", "kkt", "eliminate"])
def test_mumps_equals_faer_and_cleans_up(method, tmp_path):
    if not mumps_in_this_wheel():
        pytest.skip("this wheel was built without the feature mumps")
    V, F, items = problem()
    U_faer, _ = lse_deform.deform(V, F, items, method=method)
    diagonal = np.linalg.norm(V.max(0) - V.min(0))
    for out_of_core in (None, tmp_path):
        U, report = lse_deform.deform(
            V, F, items, method=method, factor="mumps", out_of_core=out_of_core
        )
        assert np.abs(U - U_faer).max() <= 1e-10 * diagonal
        facts = report["mumps"]
        assert facts["ranks"] == 1
        assert facts["out_of_core"] == (out_of_core is not None)
        assert facts["factor_entries_per_rank"][0] > 0
        assert list(tmp_path.iterdir()) == []


# Each rank writes its outcome to a file of its own: two ranks printing to
# one forwarded stdout may interleave within a line.
RANKS_SCRIPT = """
import os, sys
import lse_deform
from conftest import bumpy_grid, scene_items
out = os.path.join(sys.argv[1], "rank" + os.environ["OMPI_COMM_WORLD_RANK"])
V, F = bumpy_grid(8)
try:
    lse_deform.deform(V, F, scene_items(V), factor="mumps")
    line = "solved"
except (lse_deform.InputError, lse_deform.NumericalError) as e:
    line = type(e).__name__ + " " + str(e)
with open(out, "w") as f:
    f.write(line)
"""


def test_python_on_two_ranks_is_a_usage_error_on_each(tmp_path):
    """Python under `mpirun -np 2` serves no rank: every rank refuses
    `factor="mumps"` with an InputError that says so, before any collective
    call (on 75a9ac5 rank 1 raised NumericalError and rank 0 waited for an
    answer that never came)."""
    if not mumps_in_this_wheel():
        pytest.skip("this wheel was built without the feature mumps")
    import shutil
    import subprocess
    import sys

    if shutil.which("mpirun") is None:
        pytest.fail("mpirun is missing (MUMPS's wheel needs Open MPI)")
    env = dict(os.environ)
    env.update(
        OMPI_ALLOW_RUN_AS_ROOT="1",
        OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
        OMPI_MCA_pml="ob1",
        OMPI_MCA_btl_vader_single_copy_mechanism="none",
        OMPI_MCA_rmaps_base_oversubscribe="1",
        OPENBLAS_NUM_THREADS="1",
        PYTHONPATH=os.path.dirname(__file__),
    )
    script = tmp_path / "ranks.py"
    script.write_text(RANKS_SCRIPT)
    outcomes = tmp_path / "outcomes"
    outcomes.mkdir()
    run = subprocess.run(
        ["mpirun", "--mca", "btl", "self,tcp", "--mca", "btl_tcp_if_include", "lo",
         "-np", "2", sys.executable, str(script), str(outcomes)],
        env=env, capture_output=True, text=True, timeout=120,
    )
    found = sorted(p.name for p in outcomes.iterdir())
    assert found == ["rank0", "rank1"], run.stdout + run.stderr
    lines = [(outcomes / name).read_text() for name in found]
    assert any("rank 1 of 2" in l for l in lines), lines
    assert any("rank 0 of 2" in l for l in lines), lines
    for line in lines:
        assert line.startswith("InputError "), lines
        assert "run this program on one rank" in line, lines
