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

Errors, each an ``Exception``, with the command-line tool's one-line
messages: ``InputError`` (a ``ValueError``) for bad input, among them
``InputTypeError`` (also a ``TypeError``) for an argument of a type or
dtype that cannot be converted and ``TooLargeError`` (also a
``MemoryError``) for an array or system beyond the memory budget
(``LSE_MEMORY_LIMIT``, or the available memory) or an allocation that
failed; ``NumericalError`` (an ``ArithmeticError``) for numerical failure.
"""

from ._native import (
    Deformer,
    HandleBasis,
    InputError,
    InputTypeError,
    NumericalError,
    TooLargeError,
    __version__,
    compare,
    deform,
    laplacian,
    solve_lse,
)

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
