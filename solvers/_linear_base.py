"""What every linear solver shares: the error it raises and the check of ``A x = b``'s inputs.

A module of its own so that the concrete solvers (:mod:`solvers.linear`,
:mod:`solvers.iterative`, :mod:`solvers.pardiso`) import it without importing each other.
"""

from __future__ import annotations

import importlib
from types import ModuleType

import numpy as np
import scipy.sparse as sp

__all__ = ["LinearSolveError", "SparsityPattern", "optional_import"]


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
