"""The rule of conftest.py: under CI a skipped test fails the run; outside
it a skip is a skip. Checked on a throw-away test file run by a nested
pytest with this directory's conftest.py."""

import os
import pathlib
import shutil
import subprocess
import sys

HERE = pathlib.Path(__file__).resolve().parent


def run_nested(tmp_path, body, ci, other=None):
    shutil.copy(HERE / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "test_nested.py").write_text(body)
    if other is not None:
        (tmp_path / "test_other.py").write_text(other)
    env = {k: v for k, v in os.environ.items() if k != "CI"}
    if ci is not None:
        env["CI"] = ci
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(tmp_path)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )


SKIPS = """
import pytest

def test_runs():
    assert True

def test_skips():
    pytest.skip("a file that is not on this machine")
"""

SKIPS_MODULE = """
import pytest
pytest.importorskip("a_module_that_does_not_exist")

def test_never_collected():
    assert True
"""

PASSES = """
def test_runs():
    assert True
"""


def test_a_skip_fails_under_ci_and_only_there(tmp_path):
    for ci in ("1", "true"):
        r = run_nested(tmp_path, SKIPS, ci)
        assert r.returncode == 1, r.stdout + r.stderr
        assert "a file that is not on this machine" in r.stdout, r.stdout
    for ci in (None, "", "0", "false"):
        r = run_nested(tmp_path, SKIPS, ci)
        assert r.returncode == 0, (ci, r.stdout + r.stderr)


def test_a_skipped_module_fails_under_ci(tmp_path):
    # next to a module that passes, so that only the skip can fail the run
    r = run_nested(tmp_path, SKIPS_MODULE, "1", other=PASSES)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "a_module_that_does_not_exist" in r.stdout, r.stdout


def test_a_clean_run_passes_under_ci(tmp_path):
    r = run_nested(tmp_path, PASSES, "1")
    assert r.returncode == 0, r.stdout + r.stderr
