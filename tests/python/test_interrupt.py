"""Ctrl-C during a long native call raises ``KeyboardInterrupt`` at the
library's next check for signals (between phases and iterations, at most
50 ms apart; a numeric factorisation under way ends first), not when the
call returns; afterwards a
``Deformer`` is usable (an interrupted ``precompute()`` leaves it to be
precomputed again).

Each call runs in a child interpreter that receives a real SIGINT; the
child is killed if it overruns. The bound is one of responsiveness, with
a generous margin over the checks' interval, not a measure of speed."""

import pathlib
import signal
import subprocess
import sys
import textwrap
import time

# Seconds between the signal and the KeyboardInterrupt in the child.
BOUND_S = 3.0

TESTS = str(pathlib.Path(__file__).resolve().parent)

PRELUDE = """
import sys, time
sys.path.insert(0, {tests!r})
import numpy as np
import lse_deform
from conftest import bumpy_grid, fixed_and_handle
V, F = bumpy_grid(n={n})
b, bc = fixed_and_handle(V)
"""


def interrupted(body, n=24, wait=1.0):
    """Runs `body` (which prints "ready" right before its long call and
    "interrupted <time.monotonic()>" when it catches KeyboardInterrupt) in
    a child, sends SIGINT `wait` seconds after "ready", and returns the
    seconds from the signal to the KeyboardInterrupt and the child's
    output lines."""
    code = textwrap.dedent(PRELUDE).format(tests=TESTS, n=n) + textwrap.dedent(body)
    child = subprocess.Popen(
        [sys.executable, "-c", code],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        ready = child.stdout.readline().strip()
        assert ready == "ready", ready + child.stderr.read()
        time.sleep(wait)
        assert child.poll() is None, "the call ended before the signal"
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        try:
            out, err = child.communicate(timeout=BOUND_S + 30)
        except subprocess.TimeoutExpired:
            child.kill()
            out, err = child.communicate()
            raise AssertionError(f"no KeyboardInterrupt {BOUND_S + 30} s after SIGINT: {out}{err}")
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()
    lines = out.splitlines()
    caught = [l for l in lines if l.startswith("interrupted ")]
    assert caught, out + err
    delay = float(caught[0].split()[1]) - sent
    print(f"KeyboardInterrupt {delay:.3f} s after SIGINT")
    return delay, lines


def test_ctrl_c_stops_arap_iterations():
    delay, _ = interrupted(
        """
        print("ready", flush=True)
        try:
            lse_deform.deform(V, F, (b, bc), energy="arap", iterations=10**9)
        except KeyboardInterrupt:
            print("interrupted", time.monotonic(), flush=True)
        """
    )
    assert delay <= BOUND_S


def test_ctrl_c_stops_a_long_run_of_solves():
    """compare solves each configuration `repeat` times in one call."""
    delay, _ = interrupted(
        """
        print("ready", flush=True)
        try:
            lse_deform.compare(V, F, (b, bc), methods=["nullspace-qr"], repeat=10**9, condition=False)
        except KeyboardInterrupt:
            print("interrupted", time.monotonic(), flush=True)
        """
    )
    assert delay <= BOUND_S


def test_an_interrupted_precompute_leaves_a_usable_deformer():
    """A precompute of a 400 x 400 grid takes well over the 0.1 s after
    which the signal comes: the KeyboardInterrupt comes from inside it,
    and leaves no factor (solve says to precompute), and a precompute
    after it gives what a fresh Deformer gives."""
    delay, lines = interrupted(
        """
        d = lse_deform.Deformer(V, F, (b, bc))
        print("ready", flush=True)
        try:
            d.precompute()
        except KeyboardInterrupt:
            print("interrupted", time.monotonic(), flush=True)
        try:
            d.solve()
            print("solve: ok")
        except lse_deform.InputError as e:
            print("solve: InputError", e)
        d.precompute()
        U = d.solve()
        fresh = lse_deform.Deformer(V, F, (b, bc))
        fresh.precompute()
        print("same as fresh:", np.array_equal(U, fresh.solve()))
        """,
        n=400,
        wait=0.1,
    )
    assert delay <= BOUND_S
    solve = [l for l in lines if l.startswith("solve: ")]
    assert solve and solve[0].startswith("solve: InputError") and "precompute" in solve[0], lines
    assert "same as fresh: True" in lines, lines
