"""Linear solvers by name, and the ``"auto"`` choice between them.

Names: ``"default"`` (CHOLMOD, the design's solver; scipy's SuperLU without scikit-sparse),
``"cholmod"``, ``"scipy"``, ``"pardiso"`` (MKL PARDISO, optional ``pypardiso``), ``"cg_amg"``
(CG + smoothed-aggregation AMG, ``pyamg``) and ``"auto"`` (:class:`AutoSolver`).

:class:`AutoSolver` picks on the first matrix it sees, by what was measured on the project's
own Hessians (the timings are in ``docs/guide/performance.md``):

- FEM meshes and 2D MPM grids (up to ~60 nonzeros per row): PARDISO where ``pypardiso`` is
  installed, else CHOLMOD;
- 3D MPM grids (a node couples with 125 nodes: ~300 nonzeros per row): CHOLMOD; CG + AMG only
  above ``cg_min_dofs`` (default 200,000, beyond what was measured: at 55,539 DOFs CHOLMOD still
  wins), where the direct factor's fill grows faster than the matrix.

CHOLMOD keeps its own default ordering (AMD, METIS tried when AMD's fill is large): no ordering
won on every matrix measured.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from solvers.blas import cholmod_blas
from solvers.iterative import CgAmgSolver, amg_available
from solvers.linear import (
    CholmodSolver,
    LinearSolver,
    ScipySolver,
    cholmod_available,
    default_linear_solver,
)
from solvers.pardiso import PardisoSolver, pardiso_available

__all__ = [
    "LINEAR_SOLVER_NAMES",
    "AutoSolver",
    "format_linear_algebra",
    "linear_algebra",
    "make_linear_solver",
]

logger = logging.getLogger(__name__)

#: the names :func:`make_linear_solver` accepts
LINEAR_SOLVER_NAMES = ("default", "auto", "cholmod", "scipy", "pardiso", "cg_amg")

#: nonzeros per row above which a matrix counts as a dense-coupling (3D MPM grid) matrix
DENSE_ROW_NNZ = 150


def make_linear_solver(name: str, *, block_size: int = 1) -> LinearSolver:
    """A new linear solver of the given name.

    Args:
        name: one of :data:`LINEAR_SOLVER_NAMES`.
        block_size: unknowns per node (the space dimension for positions), for ``"cg_amg"``.

    Raises:
        ValueError: an unknown name.
        RuntimeError: the package the named solver needs is not installed (the message says
            how to install it).
    """
    makers = {
        "default": default_linear_solver,
        "cholmod": CholmodSolver,
        "scipy": ScipySolver,
        "pardiso": PardisoSolver,
        "cg_amg": lambda: CgAmgSolver(block_size=block_size),
        "auto": lambda: AutoSolver(block_size=block_size),
    }
    if not isinstance(name, str) or name not in makers:
        raise ValueError(f"linear solver must be one of {LINEAR_SOLVER_NAMES}, got {name!r}")
    return makers[name]()


class AutoSolver:
    """Delegates to the solver that measured fastest for the first matrix's kind and size.

    Args:
        block_size: unknowns per node, handed to ``CgAmgSolver``.
        cg_min_dofs: dense-coupling matrices with at least this many unknowns go to CG + AMG.

    Attributes:
        chosen: the name of the solver in use (None before the first solve).
    """

    def __init__(self, *, block_size: int = 1, cg_min_dofs: int = 200_000) -> None:
        self.block_size = block_size
        self.cg_min_dofs = cg_min_dofs
        self.chosen: str | None = None
        self._inner: LinearSolver | None = None

    def choose(self, A: sp.spmatrix) -> str:
        """The solver name for a matrix like A (n, n)."""
        n = A.shape[0]
        dense = A.nnz > DENSE_ROW_NNZ * max(n, 1)
        if dense and n >= self.cg_min_dofs and amg_available():
            return "cg_amg"
        if not dense and pardiso_available():
            return "pardiso"
        return "cholmod" if cholmod_available() else "default"

    @property
    def last_timings(self) -> dict[str, float]:
        """The phase seconds of the last solve of the chosen solver."""
        inner = getattr(self._inner, "last_timings", None)
        return inner if isinstance(inner, dict) else {}

    #: a per-solve ``rtol`` is handed on when the chosen solver takes one (else dropped)
    accepts_rtol = True

    @property
    def last_iterations(self) -> int:
        """Iterations of the chosen solver's last solve (0 for a direct one)."""
        return int(getattr(self._inner, "last_iterations", 0) or 0)

    def solve(
        self,
        A: sp.csc_matrix,
        b: np.ndarray,
        *,
        pattern_version: int | None = None,
        rtol: float | None = None,
    ) -> np.ndarray:
        """Solve ``A x = b`` with the chosen solver (chosen on the first call)."""
        if self._inner is None:
            self.chosen = self.choose(A)
            self._inner = make_linear_solver(self.chosen, block_size=self.block_size)
            logger.info("linear solver 'auto' chose %r for a %d x %d matrix", self.chosen, *A.shape)
        if rtol is not None and getattr(self._inner, "accepts_rtol", False):
            return self._inner.solve(A, b, pattern_version=pattern_version, rtol=rtol)
        return self._inner.solve(A, b, pattern_version=pattern_version)

    def solve_again(self, b: np.ndarray) -> np.ndarray | None:
        """Back-solve with the chosen solver's last factorisation, or None."""
        again = getattr(self._inner, "solve_again", None)
        return None if again is None else again(b)


def linear_algebra() -> dict:
    """The linear-algebra stack of this process, for ``bfemp --version`` and benchmark records.

    Returns:
        ``{"cholmod_blas": name, "cholmod_blas_path": path, "blas_threads": int | None,
        "solvers": {name: installed}}`` for the solvers of ``solvers.choice``.
    """
    info = cholmod_blas()
    return {
        "cholmod_blas": info.name,
        "cholmod_blas_path": info.path,
        "blas_threads": info.threads,
        "solvers": {
            "cholmod": cholmod_available(),
            "scipy": True,
            "pardiso": pardiso_available(),
            "cg_amg": amg_available(),
        },
    }


def format_linear_algebra(report: dict) -> str:
    """Two lines of :func:`linear_algebra`'s report for a console."""
    blas = report["cholmod_blas"]
    threads = "" if report["blas_threads"] is None else f", {report['blas_threads']} threads"
    have = ", ".join(k for k, v in report["solvers"].items() if v)
    missing = ", ".join(k for k, v in report["solvers"].items() if not v)
    line2 = f"linear solvers: {have}" + (f" (not installed: {missing})" if missing else "")
    return f"CHOLMOD BLAS: {blas}{threads} {report['cholmod_blas_path']}\n{line2}"
