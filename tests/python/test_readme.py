"""The README's "Python" section runs as a new user would paste it: its
code blocks in order (fix-and-drag, Deformer, the weight sweep with
matplotlib), in a temporary directory, with the expected first line."""

import contextlib
import io
import os
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def python_blocks():
    text = (ROOT / "README.md").read_text()
    section = text.split("\n## Python\n", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", section, re.S)


def test_the_readme_python_section_runs(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    blocks = python_blocks()
    assert len(blocks) == 2
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile("\n".join(blocks), "README.md#python", "exec"), {"__name__": "__main__"})
    rank, residual, estimate = out.getvalue().split("\n")[0].split()
    assert int(rank) == 60
    assert float(residual) <= 1e-12 and float(estimate) <= 1e-12
    assert (tmp_path / "weight-sweep.png").stat().st_size > 0
