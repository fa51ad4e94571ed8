"""Conjugate gradients preconditioned by smoothed-aggregation AMG (pyamg), as a ``LinearSolver``.

For large 3D systems (an MPM grid node couples with 125 nodes in 3D) the fill of a direct
Cholesky factor grows faster than the matrix; CG with an algebraic multigrid V-cycle as
preconditioner costs O(nnz) per iteration.  The AMG hierarchy (``pyamg``'s
``smoothed_aggregation_solver``, near-null space: the ``block_size`` translations) is the
"factorisation" of this solver: it is built on the first matrix of a pattern and kept, as a
preconditioner, for the following Newton iterations with the same pattern (their matrices
differ a little); it is rebuilt when CG needs more than ``rebuild_factor`` times the
iterations it needed right after the last build, or fails.

Tolerance: CG stops at ``||b - A x|| <= rtol ||b||``.  ``rtol`` (default 1e-8, measured to
give the same Newton iteration counts as CHOLMOD on the perf benchmarks) is the floor; the
solver has ``accepts_rtol = True``, so Newton (:func:`solvers.newton.minimize`) hands each solve
a looser relative residual tied to its own progress, the Eisenstat-Walker forcing term, and
re-solves the increment that passes its stopping test at the floor: the inexact solves change
the number of CG iterations, not the solution (Newton converges to the minimiser for any
descent direction).

A matrix that is not positive definite is detected when CG breaks down (``p.Ap <= 0``, seen as
no convergence) or when the result gives ``b.x <= 0``; both raise :class:`LinearSolveError`.
"""

from __future__ import annotations

import logging
import time
from types import ModuleType

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from solvers._linear_base import LinearSolveError, SolverBase, _check_system, optional_import

__all__ = ["AMG_INSTALL_HINT", "CgAmgSolver", "amg_available"]

logger = logging.getLogger(__name__)

AMG_INSTALL_HINT = (
    "the 'cg_amg' linear solver needs pyamg, which is not installed; install it with "
    "`pip install pyamg` or choose linear_solver='cholmod'"
)


def _import_pyamg() -> ModuleType | None:
    """Import hook for ``pyamg`` (tests monkeypatch it); None if unavailable."""
    return optional_import("pyamg")


def amg_available() -> bool:
    """Whether ``pyamg`` can be imported."""
    return _import_pyamg() is not None


class CgAmgSolver(SolverBase):
    """CG preconditioned by a smoothed-aggregation AMG V-cycle, hierarchy kept per pattern.

    Args:
        rtol: relative residual tolerance of CG (dimensionless, > 0).
        maxiter: CG iteration cap per solve.
        block_size: unknowns per node (2 or 3 for displacements, 1 for scalars): the near-null
            space handed to the aggregation is the ``block_size`` translations.
        rebuild_factor: rebuild the hierarchy when CG needs more than this many times the
            iterations of the solve right after the last build.

    Attributes:
        n_symbolic, n_numeric: hierarchies built (the analogue of an analysis), solves performed.
        last_iterations: CG iterations of the last solve.
        accepts_rtol: True: ``solve`` takes a per-solve ``rtol`` (an inexact Newton solve).
        last_timings: seconds of the last call: ``analyze`` (hierarchy build, 0 when reused),
            ``factorize`` (0), ``solve`` (CG).
    """

    accepts_rtol = True

    def __init__(
        self,
        *,
        rtol: float = 1e-8,
        maxiter: int = 500,
        block_size: int = 1,
        rebuild_factor: float = 2.0,
    ) -> None:
        pyamg = _import_pyamg()
        if pyamg is None:
            raise RuntimeError(AMG_INSTALL_HINT)
        if not (isinstance(rtol, float | int) and 0.0 < rtol < 1.0):
            raise ValueError(f"CgAmgSolver rtol must be in (0, 1), got {rtol!r}")
        if not (isinstance(maxiter, int) and maxiter >= 1):
            raise ValueError(f"CgAmgSolver maxiter must be an integer >= 1, got {maxiter!r}")
        if block_size not in (1, 2, 3):
            raise ValueError(f"CgAmgSolver block_size must be 1, 2 or 3, got {block_size!r}")
        if not rebuild_factor >= 1.0:
            raise ValueError(f"CgAmgSolver rebuild_factor must be >= 1, got {rebuild_factor!r}")
        super().__init__()
        self._pyamg = pyamg
        self.rtol = float(rtol)
        self.maxiter = maxiter
        self.block_size = block_size
        self.rebuild_factor = float(rebuild_factor)
        self.last_iterations = 0
        self._M: spla.LinearOperator | None = None
        self._fresh_iterations = 0
        self._A: sp.csr_matrix | None = None

    def _analyse(self, A: sp.csc_matrix) -> None:
        """The AMG hierarchy of A (n, n), built on the solve's CSR copy ``self._A``."""
        A = self._A
        n = A.shape[0]
        bs = self.block_size if n % self.block_size == 0 else 1
        near_null = np.kron(np.ones((n // bs, 1)), np.eye(bs))
        matrix = A if bs == 1 else A.tobsr(blocksize=(bs, bs))
        hierarchy = self._pyamg.smoothed_aggregation_solver(
            matrix, B=near_null, symmetry="symmetric", max_coarse=500
        )
        self._M = hierarchy.aspreconditioner(cycle="V")
        logger.debug("AMG hierarchy: %d levels for a %d x %d matrix", len(hierarchy.levels), n, n)

    def _cg(
        self, A: sp.csr_matrix, b: np.ndarray, rtol: float | None = None
    ) -> tuple[np.ndarray, int, int]:
        count = [0]

        def step(_xk: np.ndarray) -> None:
            count[0] += 1

        tol = self.rtol if rtol is None else max(float(rtol), self.rtol)
        x, info = spla.cg(A, b, rtol=tol, atol=0.0, maxiter=self.maxiter, M=self._M, callback=step)
        return x, info, count[0]

    def solve(
        self,
        A: sp.csc_matrix,
        b: np.ndarray,
        *,
        pattern_version: int | None = None,
        rtol: float | None = None,
    ) -> np.ndarray:
        """Solve ``A x = b`` to the relative residual ``max(rtol, self.rtol)`` (``rtol`` None:
        ``self.rtol``); A (n, n) symmetric positive definite given in full (both triangles),
        b (n,).  Raises LinearSolveError."""
        A, b = _check_system(A, b)
        n = A.shape[0]
        if n == 0:
            return np.zeros(0)
        self._A = csr = A.tocsr()  # A symmetric: its CSR is its CSC transposed, as cheap
        t0 = self._start()
        built = self.n_symbolic
        t1 = self._analysed(A, pattern_version, t0, anew=self._M is None)
        fresh = self.n_symbolic > built
        timings = self.last_timings
        x, info, its = self._cg(csr, b, rtol)
        limit = self.rebuild_factor * max(self._fresh_iterations, 1)
        if not fresh and (info != 0 or its > limit):
            # The kept hierarchy no longer fits the matrix: rebuild and solve again.
            t2 = time.perf_counter()
            self._analyse(A)
            self.n_symbolic += 1
            timings["analyze"] += time.perf_counter() - t2
            fresh = True
            x, info, its = self._cg(csr, b, rtol)
        if fresh:
            self._fresh_iterations = its
        self.n_numeric += 1
        self.last_iterations = its
        timings["solve"] = time.perf_counter() - t1 - (timings["analyze"] - (t1 - t0))
        if info != 0 or not np.all(np.isfinite(x)):
            self._M = None
            raise LinearSolveError(
                f"CG did not reach rtol = {self.rtol:.1e} in {self.maxiter} iterations "
                "(matrix not positive definite or badly preconditioned)"
            )
        if float(b @ x) <= 0.0 and np.any(b):
            self._M = None
            raise LinearSolveError("matrix is not positive definite: CG gave b.x <= 0")
        return x

    def solve_again(self, b: np.ndarray) -> np.ndarray | None:
        """Solve with the last matrix and hierarchy (CG again); None when there is none."""
        if self._A is None or self._M is None or b.shape != (self._A.shape[0],):
            return None
        x, info, _ = self._cg(self._A, np.asarray(b, dtype=np.float64))
        return x if info == 0 and np.all(np.isfinite(x)) else None
