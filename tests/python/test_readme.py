"""The Python a new user pastes runs as written: the README's "Python"
example, and the code blocks of docs/python.md §1 in order (fix-and-drag,
Deformer, the handle basis, the weight sweep with matplotlib), each in a
temporary directory, with the expected first line."""

import contextlib
import io
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def python_blocks(path, heading):
    """The ```python blocks of the section of `path` that starts with the
    line `heading`, up to the next `## ` heading."""
    text = (ROOT / path).read_text()
    parts = re.split(rf"^{re.escape(heading)}$", text, maxsplit=1, flags=re.M)
    assert len(parts) == 2, f"{path} has no line {heading!r}"
    section = re.split(r"^## ", parts[1], maxsplit=1, flags=re.M)[0]
    return re.findall(r"```python\n(.*?)```", section, re.S)


def run_blocks(blocks, name, tmp_path, monkeypatch):
    """Runs `blocks` as one program in `tmp_path`; returns its stdout."""
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile("\n".join(blocks), name, "exec"), {"__name__": "__main__"})
    return out.getvalue()


def check_first_line(stdout):
    """Rank 60 (the sheet's two rows of 30 fixed vertices) and a residual
    and forward-error estimate at rounding level."""
    rank, residual, estimate = stdout.split("\n")[0].split()
    assert int(rank) == 60
    assert float(residual) <= 1e-12 and float(estimate) <= 1e-12


def test_the_readme_python_example_runs(tmp_path, monkeypatch):
    blocks = python_blocks("README.md", "## Python")
    assert len(blocks) == 1
    assert len(blocks[0].strip().splitlines()) <= 13  # a short example
    check_first_line(run_blocks(blocks, "README.md#python", tmp_path, monkeypatch))


def test_the_python_guide_section_1_runs(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    blocks = python_blocks("docs/python.md", "## 1. Install and a first session")
    assert len(blocks) == 2
    check_first_line(run_blocks(blocks, "docs/python.md#1", tmp_path, monkeypatch))
    assert (tmp_path / "weight-sweep.png").stat().st_size > 0
