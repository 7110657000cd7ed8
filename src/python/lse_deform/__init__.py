"""Laplacian mesh deformation with exact (hard) and soft constraints, and
sparse least squares with equality constraints, by the constrained
least-squares method of Masuda et al. (SMI 2006) -- the Rust crate
``lse-deform`` from Python.

Conventions are libigl's: ``V`` float64 n x 3, ``F`` int64 m x 3, sparse
matrices from ``scipy.sparse``; C- and Fortran-ordered arrays alike.

- ``deform(V, F, constraints, ...) -> (U, report)``; ``energy="arap"``
  for as-rigid-as-possible iterations
- ``compare(V, F, constraints, ...) -> rows``: every formulation and back
  end against one reference (``lse-deform compare --json``)
- ``Deformer(V, F, constraints, ...)``: ``precompute()``, then
  ``set_targets``/``transform_group`` and ``solve()`` per frame;
  ``solve(refine="off", estimate=False)`` for a frame without refinement,
  estimate or diagnostics
- ``Deformer.basis(groups) -> HandleBasis``: ``evaluate({group: M})``
  gives the positions for affine maps of the groups without a solve
- ``laplacian(V, F, kind) -> scipy.sparse.csc_matrix``
- ``solve_lse(A, C, B, D, ...) -> (X, report)``: min ||AX - C|| s.t. BX = D
- ``factor=`` (and ``compare``'s ``factor=`` list) also takes your own
  factorisation: an object with ``name``, ``analyze(lower)``,
  ``factorize(lower)`` and ``solve(rhs)`` (docs/python.md §7); the report
  and ``compare``'s rows name it by its ``name``

Errors, each an ``Exception``, with the command-line tool's one-line
messages: ``InputError`` (a ``ValueError``) for bad input, among them
``InputTypeError`` (also a ``TypeError``) for an argument of a type or
dtype that cannot be converted and ``TooLargeError`` (also a
``MemoryError``) for an array or system beyond the memory budget
(``LSE_MEMORY_LIMIT``, or the available memory) or an allocation that
failed; ``NumericalError`` (an ``ArithmeticError``) for numerical failure,
among them an exception raised by your own ``factor=`` object (chained as
``__cause__``).
An argument of the wrong type (``method=1``) is an ``InputTypeError``,
an integer out of range (``iterations=-1``) an ``InputError``, whichever
keyword it is. Ctrl-C during a call raises ``KeyboardInterrupt`` at the
library's next check (between phases and iterations, at most 50 ms apart;
a numeric factorisation under way runs to its end first); a ``Deformer``
stays usable (an interrupted ``precompute()`` leaves it to be
precomputed again).
"""

import functools as _functools
import inspect as _inspect

from . import _native
from ._native import (
    HandleBasis,
    InputError,
    InputTypeError,
    NumericalError,
    TooLargeError,
    __version__,
)

_NOTE = "while processing '"


def _documented(e):
    """The documented exception for one that the conversion of an argument
    raised before the call began (a ``TypeError`` for a wrong type, an
    ``OverflowError`` for an integer out of range, the argument named in
    a note), or None when ``e`` is one of the module's own."""
    if isinstance(e, InputError):
        return None
    if isinstance(e, OverflowError):
        cls = InputError
    elif isinstance(e, TypeError):
        cls = InputTypeError
    else:
        return None
    notes = [n[len(_NOTE):].rstrip("'") for n in getattr(e, "__notes__", ()) if n.startswith(_NOTE)]
    return cls(f"{notes[0]}=: {e}" if notes else str(e))


def _translated(native):
    """``native`` raising only the documented classes (see the module)."""

    @_functools.wraps(native)
    def call(*args, **kwargs):
        try:
            return native(*args, **kwargs)
        except (TypeError, OverflowError) as e:
            documented = _documented(e)
            if documented is None:
                raise
            raise documented from None

    return call


compare = _translated(_native.compare)
deform = _translated(_native.deform)
laplacian = _translated(_native.laplacian)
solve_lse = _translated(_native.solve_lse)


class Deformer(_native.Deformer):
    __doc__ = _native.Deformer.__doc__
    __slots__ = ()

    @_translated
    def __new__(cls, *args, **kwargs):
        return _native.Deformer.__new__(cls, *args, **kwargs)


for _name, _method in vars(_native.Deformer).items():
    if not _name.startswith("_") and callable(_method):
        setattr(Deformer, _name, _translated(_method))

try:  # the keywords of the native constructor, for help() and inspect
    Deformer.__signature__ = _inspect.signature(_native.Deformer)
except (TypeError, ValueError):
    pass

__all__ = [
    "Deformer",
    "HandleBasis",
    "InputError",
    "InputTypeError",
    "NumericalError",
    "TooLargeError",
    "__version__",
    "compare",
    "deform",
    "laplacian",
    "solve_lse",
]
