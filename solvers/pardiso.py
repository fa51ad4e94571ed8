"""MKL PARDISO (through the optional ``pypardiso`` package) behind the ``LinearSolver`` interface.

PARDISO is called in its three phases, as CHOLMOD is: the analysis (phase 11: METIS ordering and
symbolic factorisation) is kept while the sparsity pattern is unchanged, the numeric Cholesky
factorisation (phase 22) runs every call, then the solve (phase 33).  The matrix type is real
symmetric positive definite (``mtype = 2``), so PARDISO reads the upper triangle (CSR) and
reports a non-positive pivot as error -4, raised as :class:`LinearSolveError`.

``pypardiso`` pulls MKL from PyPI (several hundred MB), so it is an optional extra
(``pip install 'bfemp[pardiso]'``), never a requirement; :func:`pardiso_available` says whether
it is installed and :class:`PardisoSolver` raises :data:`PARDISO_INSTALL_HINT` without it.
"""

from __future__ import annotations

import logging
from types import ModuleType

import numpy as np
import scipy.sparse as sp

from solvers._linear_base import LinearSolveError, SolverBase, _check_system, optional_import

__all__ = ["PARDISO_INSTALL_HINT", "PardisoSolver", "pardiso_available"]

logger = logging.getLogger(__name__)

PARDISO_INSTALL_HINT = (
    "the 'pardiso' linear solver needs pypardiso (MKL PARDISO), which is not installed; "
    "install it with `pip install 'bfemp[pardiso]'` or choose linear_solver='cholmod'"
)

# PARDISO phases (MKL reference): analysis, numeric factorisation, solve, release memory.
_ANALYSIS, _NUMERIC, _SOLVE, _RELEASE = 11, 22, 33, -1
#: real symmetric positive definite
_MTYPE_SPD = 2
#: PARDISO error code of a zero or negative pivot
_NOT_POSITIVE_DEFINITE = -4


def _import_pypardiso() -> ModuleType | None:
    """Import hook for ``pypardiso`` (tests monkeypatch it); None if unavailable."""
    return optional_import("pypardiso")


def pardiso_available() -> bool:
    """Whether ``pypardiso`` (and the MKL it loads) can be imported."""
    return _import_pypardiso() is not None


class PardisoSolver(SolverBase):
    """Sparse Cholesky with MKL PARDISO, reusing the analysis (phase 11) across equal patterns;
    ``n_numeric`` counts the numeric factorisations (phase 22)."""

    def __init__(self) -> None:
        pypardiso = _import_pypardiso()
        if pypardiso is None:
            raise RuntimeError(PARDISO_INSTALL_HINT)
        super().__init__()
        self._solver = pypardiso.PyPardisoSolver(mtype=_MTYPE_SPD)
        self._error = pypardiso.pardiso_wrapper.PyPardisoError
        self._solver.set_iparm(12, 0)  # CSR input, not transposed
        self._upper: sp.csr_matrix | None = None
        self._factorised = False

    def _analyse(self, A: sp.csc_matrix) -> None:
        self._call(_ANALYSIS, np.zeros(A.shape[0]))
        logger.debug("PARDISO analysis of a %d x %d matrix", *A.shape)

    def _call(self, phase: int, b: np.ndarray) -> np.ndarray:
        self._solver.set_phase(phase)
        try:
            return self._solver._call_pardiso(self._upper, b)
        except self._error as err:
            self._factorised = False
            code = int(err.args[0]) if err.args else 0
            if code == _NOT_POSITIVE_DEFINITE:
                raise LinearSolveError(
                    "matrix is not positive definite (PARDISO: zero or negative pivot)"
                ) from err
            raise LinearSolveError(f"PARDISO phase {phase} failed: {err}") from err

    def solve(
        self, A: sp.csc_matrix, b: np.ndarray, *, pattern_version: int | None = None
    ) -> np.ndarray:
        """Solve ``A x = b`` for a symmetric positive definite A (n, n) given in full (both
        triangles), b (n,); see :meth:`solvers.linear.CholmodSolver.solve`."""
        A, b = _check_system(A, b)
        if A.shape[0] == 0:
            return np.zeros(0)
        t0 = self._start()
        # A is symmetric, so the CSR arrays of its upper triangle are those of the CSC lower
        # triangle read transposed.
        lower = sp.tril(A, format="csc")
        lower.sort_indices()
        self._upper = sp.csr_matrix((lower.data, lower.indices, lower.indptr), shape=A.shape)
        if np.any(np.diff(lower.indptr) == 0):
            raise LinearSolveError("matrix is singular: a row has no diagonal or upper entries")
        t1 = self._analysed(A, pattern_version, t0)
        try:
            self._call(_NUMERIC, np.zeros(A.shape[0]))
        except LinearSolveError:
            self._pattern.forget()  # analyse afresh after a failed factorisation
            self._lap("factorize", t1)
            raise
        self.n_numeric += 1
        self._factorised = True
        t2 = self._lap("factorize", t1)
        x = np.asarray(self._call(_SOLVE, b), dtype=np.float64).reshape(-1)
        self._lap("solve", t2)
        if not np.all(np.isfinite(x)):
            raise LinearSolveError("PARDISO solution has non-finite entries")
        return x

    def solve_again(self, b: np.ndarray) -> np.ndarray | None:
        """Solve with the last numeric factorisation; see
        :meth:`solvers.linear.CholmodSolver.solve_again`."""
        if not (self._factorised and self._pattern.fits(b)):
            return None
        try:
            x = self._call(_SOLVE, np.asarray(b, dtype=np.float64)).reshape(-1)
        except LinearSolveError:
            return None
        return x if np.all(np.isfinite(x)) else None

    def __del__(self) -> None:
        solver = getattr(self, "_solver", None)
        if solver is not None and getattr(self, "_upper", None) is not None:
            try:
                solver.set_phase(_RELEASE)
                solver._call_pardiso(self._upper, np.zeros(self._upper.shape[0]))
            except Exception:  # noqa: BLE001 - best effort at interpreter shutdown
                pass
