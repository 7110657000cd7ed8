"""Shared helpers of the Python tests: generated meshes (no file needed),
the CLI's fixed-and-handle scene, the shared meshes when they are there,
and the `lse-deform` binary for the export-system round trip.

Under CI (the environment variable `CI` set to anything but empty, 0,
false or no, as CI services and `.ci/run` do) a skipped test fails the
run: a test that cannot run there (a missing module, mesh or binary)
proves nothing, and must not pass as if it did."""

import os
import pathlib
import shutil

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def bumpy_grid(n=24, seed=1):
    """An open (n x n)-vertex height field with smooth bumps: V float64,
    F int64, consistently oriented, no degenerate triangle."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.5, n))
    z = 0.08 * np.sin(5.0 * x) * np.cos(4.0 * y) + 0.01 * rng.standard_normal(x.shape)
    V = np.c_[x.ravel(), y.ravel(), z.ravel()]
    faces = []
    for i in range(n - 1):
        for j in range(n - 1):
            a = i * n + j
            faces += [[a, a + 1, a + n], [a + 1, a + n + 1, a + n]]
    return V, np.array(faces, dtype=np.int64)


def fixed_and_handle(V, fixed=0.2, handle=0.02):
    """The CLI's `scene --fixed F --handle H` (src/scene.rs): the lowest
    `fixed` fraction of vertices along the longest axis stays, the `handle`
    fraction nearest the top vertex moves by 15 % of the diagonal along the
    next axis. Returns libigl's (b, bc)."""
    n = len(V)
    extent = V.max(axis=0) - V.min(axis=0)
    axis = int(np.argmax(extent))
    order = np.lexsort((np.arange(n), V[:, axis]))
    fixed_v = np.sort(order[: int(round(fixed * n))])
    is_fixed = np.zeros(n, dtype=bool)
    is_fixed[fixed_v] = True
    top = V[order[-1]]
    free = np.flatnonzero(~is_fixed)
    d2 = ((V[free] - top) ** 2).sum(axis=1)
    near = free[np.lexsort((free, d2))]
    handle_v = np.sort(near[: int(round(handle * n))])
    offset = np.zeros(3)
    offset[(axis + 1) % 3] = 0.15 * np.linalg.norm(extent)
    b = np.r_[fixed_v, handle_v].astype(np.int64)
    bc = V[b].copy()
    bc[len(fixed_v):] += offset
    return b, bc


def scene_items(V, fixed=0.2, handle=0.02):
    """`fixed_and_handle`'s constraints as the CLI's `scene` writes them:
    position constraints, the fixed ones in group "fixed", then the handle
    in group "handle" (src/scene.rs)."""
    b, bc = fixed_and_handle(V, fixed=fixed, handle=handle)
    n_fixed = int(round(fixed * len(V)))
    return [
        {"type": "position", "vertex": int(v), "target": t.tolist(), "group": "fixed" if i < n_fixed else "handle"}
        for i, (v, t) in enumerate(zip(b, bc))
    ]


def read_obj(path):
    """V float64, F int64 of an OBJ with `v x y z` and `f i j k` records
    only (../shared/meshes/README.md)."""
    V, F = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                V.append([float(t) for t in line.split()[1:4]])
            elif line.startswith("f "):
                F.append([int(t.split("/")[0]) - 1 for t in line.split()[1:4]])
    return np.array(V, dtype=np.float64), np.array(F, dtype=np.int64)


def shared_mesh(name):
    """A mesh of ../shared/meshes (next to the repository), or None."""
    path = ROOT.parent / "shared" / "meshes" / name
    return path if path.exists() else None


def cli_binary():
    """The `lse-deform` binary: $LSE_DEFORM_BIN, target/{release,debug}, or PATH.

    When $LSE_DEFORM_BIN is set (as `.ci/run` does) it is returned as it is,
    so that a missing binary fails the tests that need it instead of
    skipping them."""
    if os.environ.get("LSE_DEFORM_BIN"):
        return os.environ["LSE_DEFORM_BIN"]
    candidates = [str(ROOT / "target" / p / "lse-deform") for p in ("release", "debug")]
    candidates += [shutil.which("lse-deform")]
    for c in candidates:
        if c and os.access(c, os.X_OK):
            return c
    return None


def write_obj(path, V, F):
    with open(path, "w") as f:
        for v in V:
            f.write("v %.17g %.17g %.17g\n" % tuple(v))
        for t in F:
            f.write("f %d %d %d\n" % tuple(t + 1))


@pytest.fixture
def grid():
    return bumpy_grid()


def in_ci():
    """Whether `CI` is set (to anything but empty, 0, false or no)."""
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


_SKIPPED = []


def _note_skip(report):
    if report.skipped and not hasattr(report, "wasxfail"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        _SKIPPED.append("%s: %s" % (report.nodeid or "(collection)", reason))


def pytest_runtest_logreport(report):
    _note_skip(report)


def pytest_collectreport(report):
    _note_skip(report)


def pytest_terminal_summary(terminalreporter):
    if in_ci() and _SKIPPED:
        terminalreporter.write_line(
            "CI is set, so these skips fail the run:", red=True, bold=True
        )
        for line in _SKIPPED:
            terminalreporter.write_line("  " + line, red=True)


def pytest_sessionfinish(session, exitstatus):
    if in_ci() and _SKIPPED and session.exitstatus == 0:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
