"""Type stubs of the native module (src/python/*.rs)."""

import os
from typing import Any, Dict, List, Mapping, Optional, Protocol, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt
import scipy.sparse

__version__: str

class InputError(ValueError):
    """Bad input (the CLI's exit code 2); the message says what and where."""

class NumericalError(ArithmeticError):
    """A numerical failure (the CLI's exit code 3)."""

class InputTypeError(InputError, TypeError):
    """An argument of a type or dtype that cannot be converted."""

class TooLargeError(InputError, MemoryError):
    """An input or system beyond the memory budget (LSE_MEMORY_LIMIT or
    the available memory), or an allocation that failed."""

# Every call raises only these classes: a keyword of the wrong type is an
# InputTypeError, an integer keyword out of range an InputError (the
# package lse_deform translates the conversion's TypeError and
# OverflowError). Ctrl-C during a call raises KeyboardInterrupt at the
# library's next check (between phases and iterations, at most 50 ms
# apart; a numeric factorisation under way runs to its end first); a
# Deformer stays usable (after an interrupted precompute(), precompute
# again).

Report = Dict[str, Any]
"""The CLI's JSON report as a dict: method, rank, redundant, conflicting,
max_constraint_residual, forward_error_estimate, timings_s, warnings, ..."""

Constraints = Union[
    Sequence[Mapping[str, Any]],  # JSON format: [{"type": "position", "vertex": 3, "target": [x, y, z]}, ...]
    Mapping[str, Any],  # {"constraints": [...]}, a whole constraints file
    str,
    "os.PathLike[str]",  # a constraints file
    Tuple[npt.ArrayLike, npt.ArrayLike],  # libigl's (b, bc): vertex indices, k x 3 targets
]
Refine = Union[None, str, int]
"""None (the method's default: 'auto' for exact methods, 'off' for
penalty), 'auto', 'off' or a number of steps."""
Matrix = Union[scipy.sparse.spmatrix, scipy.sparse.sparray, npt.ArrayLike]

class FactorSolver(Protocol):
    """What factorize may return: one factorisation that solves."""

    def solve(self, rhs: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]: ...

class FactorBackend(Protocol):
    """Your own SPD factorisation, for factor= (docs/python.md §7).

    name: a non-empty str, no word of the catalogue; read once, when the
    object is given; the report's factor_backend and compare's rows.
    analyze(lower): the pattern of the lower triangle (csc_matrix n x n,
    sorted indices, diagonal included, every value 1.0); fixed until the
    next analyze. Its return value is ignored.
    factorize(lower): the same pattern with the values to factor (a new
    matrix each call). Returns None (the object holds this factorisation
    and solve() solves with it: the library factors a matrix again, after
    analyze again if needed, when another was factored in between, and
    counts it in report['refactorizations']) or an object with
    solve(rhs) that solves with this factorisation.
    solve(rhs): rhs float64 (n, k), C order; returns A^-1 rhs as a float64
    numpy.ndarray of shape (n, k) (it may overwrite and return rhs).

    Calls into one object are serialised and hold the GIL. An exception
    it raises is a NumericalError whose __cause__ is that exception (a
    KeyboardInterrupt is raised as it is); a wrong return (type, dtype,
    shape) an InputError; a non-finite solution a NumericalError. A
    missing member is an InputError naming it, before any work."""

    name: str

    def analyze(self, lower: scipy.sparse.csc_matrix) -> Any: ...
    def factorize(self, lower: scipy.sparse.csc_matrix) -> Optional[FactorSolver]: ...
    def solve(self, rhs: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]: ...

Factor = Union[str, FactorBackend]
"""A word of the catalogue ('faer-auto', ...) or your own FactorBackend."""
MemoryLimit = Union[None, int, str]
"""The memory budget of the precompute: None (the default:
LSE_MEMORY_LIMIT when set, else the available memory), a number of bytes
or a size such as '2G' (powers of 1024). A factor estimated beyond it
raises TooLargeError before it is allocated."""
Threads = Union[None, int, str]
"""The factorisation's threads: None or 'own' (each back end's own), or a
positive int (docs/equal-terms.md)."""
Ordering = Union[None, str, Sequence[int]]
"""The fill-reducing ordering: None or 'own' (each back end's own), 'amd',
'metis', 'natural', or the unknowns in elimination order."""

def deform(
    V: npt.ArrayLike,
    F: npt.ArrayLike,
    constraints: Constraints,
    laplacian: Optional[str] = None,
    method: Optional[str] = None,
    qr: Optional[str] = None,
    factor: Optional[Factor] = None,
    weight: Optional[float] = None,
    refine: Refine = None,
    energy: Optional[str] = None,
    arap_energy: Optional[str] = None,
    iterations: Optional[int] = None,
    tolerance: Optional[float] = None,
    arap_init: Optional[str] = None,
    memory_limit: MemoryLimit = None,
    out_of_core: Optional[str | bytes | os.PathLike[str] | os.PathLike[bytes]] = None,
    spd: Optional[str] = None,
    threads: Threads = None,
    ordering: Ordering = None,
) -> Tuple[npt.NDArray[np.float64], Report]:
    """Deforms (V, F) under the constraints; returns (U, report).

    Every keyword left None takes the library's default (DeformOptions,
    ArapOptions), the values named below.
    laplacian: 'uniform', 'cotan' (default), 'cotan-symmetric',
    'intrinsic-delaunay'.
    method: 'nullspace-qr' (the paper; default), 'penalty' (needs weight),
    'kkt', 'eliminate'. qr: 'sparse-givens' (default), 'dense-householder'.
    factor: the matrix factorisation, the Cholesky back end ('faer-auto'
    (default), 'faer-supernodal', 'faer-simplicial', 'nalgebra', and
    'mumps' in a wheel built with the feature mumps) and for kkt the LDLT
    variant (the faer ones or 'mumps'); or your own object (FactorBackend:
    not with kkt), whose name the report gives as factor_backend. spd: its
    old name, words only, still accepted (both given with different values
    is an InputError).
    energy: 'laplacian' (default) or 'arap' (as-rigid-as-possible, cotangent
    weights; report['arap'] says what the iterations did), with
    arap_energy 'spokes' or 'spokes-and-rims' (default), iterations (default
    10), tolerance on the relative energy decrease (default 0: run all) and
    arap_init 'linear' (default) or 'rest'. Options the energy does not use
    are RuntimeWarnings, as the CLI warns.
    memory_limit: the memory budget of the call: the arrays' conversion and
    the precompute (see MemoryLimit).
    threads: the factorisation's threads, an int or 'own' (default: each
    back end's own); ordering: its fill-reducing ordering, 'own' (default),
    'amd', 'metis' (wheels with SuiteSparse), 'natural', or a sequence of
    ints (the unknowns in elimination order). report['ordering'] and
    report['threads'] say what was used (docs/equal-terms.md).
    out_of_core: a directory (it must exist) in which factor='mumps' keeps
    its factor (removed afterwards, also on error); only what stays in
    memory then counts against memory_limit. Any other factor with
    out_of_core is an InputError.
    """

def compare(
    V: npt.ArrayLike,
    F: npt.ArrayLike,
    constraints: Constraints,
    laplacian: Optional[str] = None,
    methods: Optional[Sequence[str]] = None,
    qr: Optional[Sequence[str]] = None,
    factor: Optional[Sequence[Factor]] = None,
    weights: Optional[Sequence[float]] = None,
    refine: Refine = None,
    repeat: Optional[int] = None,
    condition: Optional[bool] = None,
    spd: Optional[Sequence[str]] = None,
    memory_limit: MemoryLimit = None,
    threads: Threads = None,
    ordering: Ordering = None,
) -> List[Dict[str, Any]]:
    """`lse-deform compare`: every configuration against the refined
    null-space reference; one dict per configuration with the keys of
    `compare --json` (label, method, qr, spd, weight, status, precompute_s,
    solve_median_s, refine_s, max_constraint_residual, delta_x, delta_e,
    forward_error_estimate, condition, report).

    methods: default all four; qr, factor (spd: its old name): default
    every back end of this build; factor may hold FactorBackend objects
    next to words, each with rows under its name (spd) for every method
    but kkt; weights: penalty weights (default 1e4,
    1e8, 1e12); repeat: solves per configuration (default 5); condition:
    estimate condition numbers (default True); memory_limit, threads and
    ordering as for deform, the same for every configuration. None: the
    default.
    """

def laplacian(
    V: npt.ArrayLike, F: npt.ArrayLike, kind: Optional[str] = None
) -> scipy.sparse.csc_matrix:
    """The n x n Laplacian (L_ii = sum_j w_ij, L_ij = -w_ij, delta = L V)."""

def solve_lse(
    A: Matrix,
    C: npt.ArrayLike,
    B: Matrix,
    D: npt.ArrayLike,
    method: Optional[str] = None,
    qr: Optional[str] = None,
    factor: Optional[Factor] = None,
    weight: Optional[float] = None,
    refine: Refine = None,
    memory_limit: MemoryLimit = None,
    out_of_core: Optional[str | bytes | os.PathLike[str] | os.PathLike[bytes]] = None,
    spd: Optional[str] = None,
    threads: Threads = None,
    ordering: Ordering = None,
) -> Tuple[npt.NDArray[np.float64], Report]:
    """min ||A X - C|| subject to B X = D; returns (X, report).

    Row i of B is hard constraint i (earlier rows win); report['redundant']
    and report['conflicting'] name the dependent rows. X is 1-D when C is.
    """

class Deformer:
    """A mesh with constraints, deformed again and again."""

    def __init__(
        self,
        V: npt.ArrayLike,
        F: npt.ArrayLike,
        constraints: Constraints,
        laplacian: Optional[str] = None,
        method: Optional[str] = None,
        qr: Optional[str] = None,
        factor: Optional[Factor] = None,
        weight: Optional[float] = None,
        refine: Refine = None,
        memory_limit: MemoryLimit = None,
        out_of_core: Optional[str | bytes | os.PathLike[str] | os.PathLike[bytes]] = None,
        spd: Optional[str] = None,
        threads: Threads = None,
        ordering: Ordering = None,
    ) -> None: ...
    def precompute(self) -> None:
        """Factors the system (GIL released)."""
    def set_targets(self, indices: npt.ArrayLike, targets: npt.ArrayLike) -> None:
        """New targets (k x 3) for constraints `indices` (also the rest targets)."""
    def transform_group(self, name: str, M: npt.ArrayLike) -> None:
        """Applies M (3 x 4 [R | t] or 4 x 4, last row [0, 0, 0, 1] within
        1e-12) to the rest targets of group `name`."""
    def group(self, name: str) -> List[int]:
        """The constraint indices of group `name`."""
    def solve(self, refine: Refine = None, estimate: bool = True) -> npt.NDArray[np.float64]:
        """The deformed positions (n x 3) for the current targets.

        refine: this call's refinement (None: the Deformer's own).
        refine='off' still computes one correction, not applied, for the
        forward-error estimate. estimate=False (with refinement off only,
        else InputError) skips it and the diagnostics: the cheap frame;
        report then has forward_error_estimate, refinement and the
        residuals None."""
    def basis(self, groups: Sequence[str]) -> "HandleBasis":
        """The affine response basis of the constraint groups `groups`, on
        this deformer's factor with its refinement; TooLargeError beyond
        the memory budget. See HandleBasis."""
    @property
    def report(self) -> Report:
        """The report of the last precompute and solve."""

Affine = Union[npt.ArrayLike, Sequence[Sequence[float]]]
"""A 3 x 4 [R | t] or a 4 x 4 map whose last row is [0, 0, 0, 1] (within
1e-12), as an array or nested lists."""

class HandleBasis:
    """Positions for affine maps of some constraint groups without a solve
    (Deformer.basis(groups)).

    evaluate(T) equals, for every group g of the basis,
    transform_group(g, T.get(g, identity)) followed by solve() (to the
    forward error of the two): a group left out of T is at its rest pose,
    and every other constraint keeps the target it had when the basis was
    built. After precompute(), set_targets() of any constraint or
    transform_group() of a group outside the basis, evaluate raises
    InputError: build a new basis. transform_group() of a group of the
    basis does not make it stale."""

    def evaluate(
        self,
        transforms: Mapping[str, Affine],
        out: Optional[npt.NDArray[np.float64]] = None,
    ) -> npt.NDArray[np.float64]:
        """The (n, 3) float64 positions for `transforms` (group name -> map),
        into `out` (C-contiguous, writable, float64, (n, 3)) when given.
        Releases the GIL for large n."""
    @property
    def groups(self) -> List[str]:
        """The group names, in the order given."""
    @property
    def bytes(self) -> int:
        """The bytes of the basis: what one evaluation reads."""
    @property
    def build_time_s(self) -> float:
        """Seconds the basis took to build."""
    @property
    def forward_error_estimate(self) -> float:
        """The largest forward-error estimate of its 3 + 4G refined
        columns, relative to the length scale (the bounding-box
        diagonal); positions combine the columns with the maps' entries
        as weights."""
