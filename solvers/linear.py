"""Sparse symmetric positive definite linear solvers for the Newton system ``H p = -g``.

:class:`CholmodSolver` (scikit-sparse / SuiteSparse CHOLMOD, as in the BFEMP paper) splits the
Cholesky factorisation into the symbolic analysis (fill-reducing ordering and the structure of
``L``, which depends only on the sparsity pattern) and the numeric factorisation.  The analysis
is kept while the pattern stays the same, detected by an equal ``pattern_version`` from
:class:`solvers.assembly.TripletAssembler` or else by equal ``indptr``/``indices`` arrays, so
Newton iterations and time steps with an unchanged contact set pay for it once.

CHOLMOD may choose a supernodal ``L L^T`` (which fails on a non-positive pivot) or a simplicial
``L D L^T`` (which does not); after factorising, ``D`` is checked to be positive, so both raise
:class:`LinearSolveError` for a matrix that is not positive definite.

:class:`ScipySolver` is the fallback without scikit-sparse: SuperLU in symmetric mode with
diagonal pivoting only; positive definiteness is checked on the pivots the same way.

:func:`rounding_shift` and :func:`shift_diagonal` are the bounded retry for a matrix that is
positive definite by construction (projected Newton's proxy matrix) but whose floating-point
sum is not: :func:`solvers.newton.minimize` refactorises once with that diagonal shift.
"""

from __future__ import annotations

import logging
import warnings
from types import ModuleType
from typing import Protocol, runtime_checkable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from solvers._linear_base import LinearSolveError, SolverBase, _check_system, optional_import
from solvers.blas import report_cholmod_blas_once
from solvers.openmp import bounded_openmp

__all__ = [
    "CHOLMOD_INSTALL_HINT",
    "CholmodSolver",
    "LinearSolveError",
    "LinearSolver",
    "ROUNDING_SHIFT_ULPS",
    "ScipySolver",
    "cholmod_available",
    "default_linear_solver",
    "rounding_shift",
    "shift_diagonal",
]

logger = logging.getLogger(__name__)

CHOLMOD_INSTALL_HINT = (
    "scikit-sparse (CHOLMOD) is not available; falling back to scipy's SuperLU, which is much "
    "slower for large systems. Install it with `pip install 'scikit-sparse<0.5'` (needs the "
    "SuiteSparse headers, e.g. `apt-get install libsuitesparse-dev`) or `pip install "
    "'bfemp[cholmod]'`."
)

# One fallback warning per process (see default_linear_solver).
_fallback_warned = False


@runtime_checkable
class LinearSolver(Protocol):
    """Solves ``A x = b`` for a sparse symmetric positive definite ``A``.

    Implementations may keep state between calls (symbolic factorisations) and expose
    ``last_timings: dict[str, float]`` with keys ``analyze``, ``factorize``, ``solve`` (s).
    An iterative solver declares ``accepts_rtol = True`` when ``solve`` also takes a keyword
    ``rtol`` (the relative residual this solve may stop at; Newton hands it the forcing term)
    and exposes ``last_iterations``.
    """

    def solve(
        self, A: sp.csc_matrix, b: np.ndarray, *, pattern_version: int | None = None
    ) -> np.ndarray:
        """Return x (n,) with ``A x = b``; A (n, n) CSC, b (n,). Raises LinearSolveError."""
        ...


def _import_cholmod() -> ModuleType | None:
    """Import hook for ``sksparse.cholmod`` (tests monkeypatch it); None if unavailable."""
    return optional_import("sksparse.cholmod")


def cholmod_available() -> bool:
    """Whether ``sksparse.cholmod`` can be imported."""
    return _import_cholmod() is not None


#: Machine epsilons of a row's absolute sum that :func:`rounding_shift` adds to its diagonal.
#: A choice (no paper fixes it): a factor 4 above the largest multiple that MPM-FEM barrier
#: systems CHOLMOD refused needed (design note ``measurements``, rounding shift).
ROUNDING_SHIFT_ULPS = 16.0


def rounding_shift(A: sp.spmatrix, ulps: float = ROUNDING_SHIFT_ULPS) -> np.ndarray:
    """Per-row bound on the rounding of a sum of PSD terms: ``ulps eps sum_j |a_ij|`` (n,).

    Projected Newton (BFEMP sec. 5, Algorithm 2 line 5) sums per-stencil Hessians projected to
    PSD with the mass matrix: positive definite in exact arithmetic, but each term carries
    rounding of ``O(eps)`` times its own size (the eigen-decomposition of the projection, the
    chain rule ``W^T H W`` to grid nodes, the summation). Near contact the barrier's curvature
    grows like ``kappa / d^2`` (IPC / BFEMP eq. 27), so at ``d ~ 1e-9 d-hat`` a pair's block
    reaches ``1e17`` N/m and its rounding (``eps x 1e17 ~ 27``) exceeds the masses of the grid
    nodes it touches (``2e-5`` to a few kg): the computed sum is indefinite although no term is
    (issue 44; ``tests/bfemp/test_psd_rounding.py``).

    With ``A = A_exact + E`` and ``|E_ij| <= c eps |a_ij|`` (the entrywise model of a rounded
    sum without cancellation), Gershgorin's theorem bounds every eigenvalue of ``E`` below by
    ``-max_i c eps sum_j |a_ij|``; adding this row's bound to each diagonal entry gives
    ``A + D >= A_exact``, positive definite. The model is a choice, not a proof: a block's
    rounding is relative to the block's norm, not to each entry, so a row that a block barely
    touches may carry more; :data:`ROUNDING_SHIFT_ULPS` says how much room the measurements
    found. The shift is a rounding-level perturbation (relative ``ulps eps`` of the row), so a
    matrix that is indefinite by more than its rounding (a negative block, an unprojected
    barrier block, whose negative curvature is ``~ d / L ~ 1e-12`` of it) still fails after it.

    Args:
        A: sparse square matrix ``(n, n)`` (both triangles stored), any units.
        ulps: the multiple ``c`` of the machine epsilon, > 0.

    Returns:
        The shift ``(n,)`` float64, in the units of ``A``.
    """
    if not (np.isfinite(ulps) and ulps > 0.0):
        raise ValueError(f"rounding_shift ulps must be finite and > 0, got {ulps!r}")
    if not sp.issparse(A) or A.shape[0] != A.shape[1]:
        raise ValueError(f"A must be a square scipy sparse matrix, got {type(A).__name__}")
    A = sp.csc_matrix(A)
    row_abs = np.bincount(A.indices, weights=np.abs(A.data), minlength=A.shape[0])
    return ulps * np.finfo(np.float64).eps * row_abs


def shift_diagonal(A: sp.csc_matrix, shift: np.ndarray) -> tuple[sp.csc_matrix, bool]:
    """``A + diag(shift)`` as a new CSC matrix; A is not modified.

    Args:
        A: CSC matrix ``(n, n)`` with sorted indices.
        shift: diagonal increments ``(n,)`` in the units of A.

    Returns:
        The shifted matrix and whether it kept A's sparsity pattern (every diagonal entry was
        stored): then a linear solver may reuse A's symbolic analysis (same pattern version).
    """
    n = A.shape[0]
    shift = np.asarray(shift, dtype=np.float64)
    if shift.shape != (n,):
        raise ValueError(f"shift must have shape ({n},), got {shift.shape}")
    cols = np.repeat(np.arange(n), np.diff(A.indptr))
    on_diag = np.flatnonzero(A.indices == cols)
    if on_diag.size == n:
        out = A.copy()
        out.data[on_diag] += shift[cols[on_diag]]
        return out, True
    return sp.csc_matrix(A + sp.diags(shift)), False


def _check_pivots(pivots: np.ndarray) -> None:
    # A symmetric matrix is positive definite iff all pivots of its LDL^T factorisation are > 0.
    bad = np.flatnonzero(~(pivots > 0.0))
    if bad.size:
        raise LinearSolveError(
            f"matrix is not positive definite: {bad.size} non-positive pivot(s), smallest "
            f"{np.min(pivots):.3e} (at permuted index {bad[0]})"
        )


class CholmodSolver(SolverBase):
    """Sparse Cholesky with CHOLMOD, reusing the symbolic analysis across equal patterns.

    Args:
        mode: CHOLMOD factorisation mode, ``"auto"``, ``"simplicial"`` or ``"supernodal"``.
        ordering_method: CHOLMOD fill-reducing ordering (``"default"``, ``"amd"``,
            ``"metis"``, ``"nesdis"``, ``"colamd"``, ``"natural"``, ``"best"``).

    Attributes:
        n_symbolic, n_numeric, last_timings: as in :class:`~solvers._linear_base.SolverBase`;
            ``analyze`` is the pattern comparison plus the symbolic analysis (when not reused).
    """

    def __init__(self, *, mode: str = "auto", ordering_method: str = "default") -> None:
        cholmod = _import_cholmod()
        if cholmod is None:
            raise RuntimeError(CHOLMOD_INSTALL_HINT)
        if mode not in ("auto", "simplicial", "supernodal"):
            raise ValueError(
                f"CholmodSolver mode must be 'auto', 'simplicial' or 'supernodal', got {mode!r}"
            )
        report_cholmod_blas_once()  # says once per process which BLAS CHOLMOD runs on
        super().__init__()
        self._cholmod = cholmod
        self.mode = mode
        self.ordering_method = ordering_method
        self._factor = None

    def _analyse(self, A: sp.csc_matrix) -> None:
        self._factor = self._cholmod.analyze(
            A, mode=self.mode, ordering_method=self.ordering_method
        )
        logger.debug("CHOLMOD symbolic analysis of a %d x %d matrix", *A.shape)

    def solve(
        self, A: sp.csc_matrix, b: np.ndarray, *, pattern_version: int | None = None
    ) -> np.ndarray:
        """Solve ``A x = b``.

        Args:
            A: symmetric positive definite matrix (n, n), CSC with sorted indices, full
                (both triangles) or lower triangle.
            b: right-hand side (n,).
            pattern_version: id of A's sparsity pattern (from ``TripletAssembler``); equal ids
                skip the pattern comparison.

        Returns:
            x (n,) float64.

        Raises:
            LinearSolveError: A not positive definite, or a non-finite input or solution.
        """
        A, b = _check_system(A, b)
        if A.shape[0] == 0:
            return np.zeros(0)
        with bounded_openmp():  # CHOLMOD's compiled-in 4 OpenMP threads cost 1.3-1.8x on 2 cores
            t1 = self._analysed(A, pattern_version, self._start(), anew=self._factor is None)
            try:
                self._factor.cholesky_inplace(A)
                self.n_numeric += 1
                _check_pivots(self._factor.D())
            except (self._cholmod.CholmodError, LinearSolveError) as err:
                # A failed numeric factorisation may leave the factor unusable: analyse afresh.
                self._factor = None
                self._lap("factorize", t1)
                if isinstance(err, LinearSolveError):
                    raise
                raise LinearSolveError(f"CHOLMOD factorisation failed: {err}") from err
            t2 = self._lap("factorize", t1)
            x = np.asarray(self._factor.solve_A(b), dtype=np.float64).reshape(-1)
            self._lap("solve", t2)
            if not np.all(np.isfinite(x)):
                raise LinearSolveError("CHOLMOD solution has non-finite entries")
            return x

    def solve_again(self, b: np.ndarray) -> np.ndarray | None:
        """Solve with the last numeric factorisation (a back-solve, no new factorisation).

        Args:
            b: right-hand side ``(n,)`` of the size of the last factorised matrix.

        Returns:
            x ``(n,)``, or None when no factorisation is kept, b has another size or x is not
            finite.
        """
        if self._factor is None or not self._pattern.fits(b):
            return None
        with bounded_openmp():
            x = self._factor.solve_A(np.asarray(b, dtype=np.float64))
        x = np.asarray(x, dtype=np.float64).reshape(-1)
        return x if np.all(np.isfinite(x)) else None


class ScipySolver(SolverBase):
    """Fallback SPD solver: SuperLU (``scipy.sparse.linalg.splu``) in symmetric mode.

    Every call orders and factorises afresh (SuperLU cannot reuse a symbolic analysis), so
    ``n_symbolic == n_numeric``. The timings of the joint ordering + factorisation are
    reported under ``factorize`` (``analyze`` stays 0).
    """

    def __init__(self) -> None:
        super().__init__()
        self._lu: spla.SuperLU | None = None

    def solve(
        self, A: sp.csc_matrix, b: np.ndarray, *, pattern_version: int | None = None
    ) -> np.ndarray:
        """Solve ``A x = b`` for a symmetric positive definite A (n, n) given in full (both
        triangles; unlike CHOLMOD, SuperLU reads all entries), b (n,); see
        :meth:`CholmodSolver.solve`. ``pattern_version`` is accepted and ignored."""
        A, b = _check_system(A, b)
        if A.shape[0] == 0:
            return np.zeros(0)
        t0 = self._start()
        try:
            # Symmetric mode with a zero pivot threshold keeps the pivots on the diagonal of
            # the symmetrically permuted matrix, so diag(U) are the LDL^T pivots.
            lu = spla.splu(
                A,
                permc_spec="MMD_AT_PLUS_A",
                diag_pivot_thresh=0.0,
                options={"SymmetricMode": True},
            )
        except RuntimeError as err:
            self._lap("factorize", t0)
            raise LinearSolveError(f"SuperLU factorisation failed: {err}") from err
        self.n_symbolic += 1
        self.n_numeric += 1
        if not np.array_equal(lu.perm_r, lu.perm_c):
            self._lap("factorize", t0)
            raise LinearSolveError(
                "matrix is not positive definite: SuperLU needed off-diagonal pivoting"
            )
        _check_pivots(lu.U.diagonal())
        self._lu = lu
        t1 = self._lap("factorize", t0)
        x = lu.solve(b)
        self._lap("solve", t1)
        if not np.all(np.isfinite(x)):
            raise LinearSolveError("SuperLU solution has non-finite entries")
        return x

    def solve_again(self, b: np.ndarray) -> np.ndarray | None:
        """Solve with the last factorisation; see :meth:`CholmodSolver.solve_again`."""
        if self._lu is None or b.shape != (self._lu.shape[0],):
            return None
        x = self._lu.solve(np.asarray(b, dtype=np.float64))
        return x if np.all(np.isfinite(x)) else None


def default_linear_solver() -> LinearSolver:
    """A :class:`CholmodSolver` if scikit-sparse imports, else a :class:`ScipySolver`.

    The fallback emits one ``RuntimeWarning`` per process naming scikit-sparse and how to
    install it, and no log record beside it (that printed it twice); the ``bfemp`` command
    line routes warnings through ``logging``, so ``--quiet`` silences it.
    """
    global _fallback_warned
    if cholmod_available():
        return CholmodSolver()
    if not _fallback_warned:
        _fallback_warned = True
        warnings.warn(CHOLMOD_INSTALL_HINT, RuntimeWarning, stacklevel=2)
    return ScipySolver()
