"""What every linear solver shares: the error it raises, the check of ``A x = b``'s inputs, and
the counters, phase timings and kept sparsity pattern of :class:`SolverBase`.

A module of its own so that the concrete solvers (:mod:`solvers.linear`,
:mod:`solvers.iterative`, :mod:`solvers.pardiso`) import it without importing each other.
"""

from __future__ import annotations

import importlib
import time
from types import ModuleType

import numpy as np
import scipy.sparse as sp

__all__ = ["LinearSolveError", "SolverBase", "SparsityPattern", "optional_import"]


class LinearSolveError(RuntimeError):
    """The linear system could not be solved (not positive definite, singular, non-finite)."""


def _check_system(A: sp.spmatrix, b: np.ndarray) -> tuple[sp.csc_matrix, np.ndarray]:
    """A (n, n) as CSC and b (n,) as contiguous float64.

    Raises ValueError on a bad type or shape, LinearSolveError on non-finite entries.
    """
    if not sp.issparse(A):
        raise ValueError(f"A must be a scipy sparse matrix, got {type(A).__name__}")
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise ValueError(f"A must be square, got shape {A.shape}")
    if not isinstance(A, sp.csc_matrix):
        A = sp.csc_matrix(A)
    b = np.ascontiguousarray(b, dtype=np.float64)
    if b.shape != (A.shape[0],):
        raise ValueError(f"b must have shape ({A.shape[0]},), got {b.shape}")
    if not np.all(np.isfinite(A.data)):
        raise LinearSolveError("matrix has non-finite entries")
    if not np.all(np.isfinite(b)):
        raise LinearSolveError("right-hand side has non-finite entries")
    return A, b


def optional_import(name: str) -> ModuleType | None:
    """The module ``name`` (dotted) of an optional solver package, None where it cannot be
    imported (not installed, or a library it loads is missing)."""
    try:
        return importlib.import_module(name)
    except ImportError:
        return None


class SparsityPattern:
    """The sparsity pattern of the matrix a solver last analysed, to reuse the analysis.

    A matrix has it when its ``pattern_version`` (from :class:`solvers.assembly.TripletAssembler`)
    equals the remembered one, or else when its shape and index arrays are equal.
    """

    def __init__(self) -> None:
        self.version: int | None = None
        self.shape: tuple[int, int] | None = None
        self._indptr: np.ndarray | None = None
        self._indices: np.ndarray | None = None

    def matches(self, A: sp.csc_matrix, pattern_version: int | None) -> bool:
        """Whether the CSC matrix A (n, n) has the remembered pattern."""
        if self._indptr is None or A.shape != self.shape:
            return False
        if pattern_version is not None and pattern_version == self.version:
            return True
        return bool(
            np.array_equal(A.indptr, self._indptr) and np.array_equal(A.indices, self._indices)
        )

    def remember(self, A: sp.csc_matrix) -> None:
        """Keep the pattern of A (copies of its index arrays)."""
        self.shape = A.shape
        self._indptr = A.indptr.copy()
        self._indices = A.indices.copy()

    def fits(self, b: np.ndarray) -> bool:
        """Whether ``b`` has shape ``(n,)`` of the remembered matrix (n, n)."""
        return self.shape is not None and b.shape == (self.shape[0],)

    def forget(self) -> None:
        """Match no matrix until the next :meth:`remember` (analyse afresh)."""
        self._indptr = None


class SolverBase:
    """The scaffolding of the solvers that keep an analysis per sparsity pattern; a subclass's
    ``_analyse(A)`` analyses a new one (for :meth:`_analysed`).

    Attributes:
        n_symbolic: analyses performed (symbolic factorisations, AMG hierarchies).
        n_numeric: numeric factorisations (solves, for an iterative solver) performed.
        last_timings: seconds of the last call, keys ``analyze``, ``factorize``, ``solve``.
    """

    def __init__(self) -> None:
        self.n_symbolic = 0
        self.n_numeric = 0
        self.last_timings = {"analyze": 0.0, "factorize": 0.0, "solve": 0.0}
        self._pattern = SparsityPattern()

    def _start(self) -> float:
        """Zero the timings of a new call; the start time (s)."""
        self.last_timings = {"analyze": 0.0, "factorize": 0.0, "solve": 0.0}
        return time.perf_counter()

    def _lap(self, phase: str, since: float) -> float:
        """Record the seconds since ``since`` as ``phase``'s; the time now (s)."""
        now = time.perf_counter()
        self.last_timings[phase] = now - since
        return now

    def _analysed(
        self, A: sp.csc_matrix, pattern_version: int | None, t0: float, *, anew: bool = False
    ) -> float:
        """Run :meth:`_analyse` unless A (n, n) has the pattern analysed last (and not ``anew``),
        and remember it; the time since ``t0`` is the call's ``analyze``. The time now (s)."""
        if anew or not self._pattern.matches(A, pattern_version):
            self._analyse(A)
            self._pattern.remember(A)
            self.n_symbolic += 1
        self._pattern.version = pattern_version
        return self._lap("analyze", t0)
