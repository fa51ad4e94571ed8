"""The Newton direction of one iteration of :func:`solvers.newton.minimize`.

Assembly and solve of ``H p = -g`` on the free DOFs (BFEMP Algorithm 2, steps 1-2): the
projected Hessian retried once with a rounding-level diagonal shift, the Eisenstat-Walker
forcing term for an inexact (iterative) solver, the stopping rule's increment norm, and the
chord increment that reuses the last factorisation.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import scipy.sparse as sp

from solvers._linear_base import LinearSolveError
from solvers.assembly import Triplets
from solvers.linear import ROUNDING_SHIFT_ULPS, LinearSolver, rounding_shift, shift_diagonal

__all__ = ["forcing_term"]

logger = logging.getLogger("solvers.newton")


@contextmanager
def _timed(timings: dict[str, float], key: str) -> Iterator[None]:
    start = time.perf_counter()
    try:
        yield
    finally:
        timings[key] += time.perf_counter() - start


def _timed_solve(
    solver: LinearSolver,
    matrix: sp.csc_matrix,
    rhs: np.ndarray,
    pattern_version: int | None,
    timings: dict[str, float],
    kwargs: dict[str, float],
) -> np.ndarray:
    """``solver.solve`` with its phase seconds added to ``timings``."""
    start = time.perf_counter()
    try:
        return np.asarray(
            solver.solve(matrix, rhs, pattern_version=pattern_version, **kwargs),
            dtype=np.float64,
        )
    finally:
        phases = getattr(solver, "last_timings", None)
        if isinstance(phases, dict):
            for key in ("analyze", "factorize", "solve"):
                timings[key] += float(phases.get(key, 0.0))
        else:
            timings["solve"] += time.perf_counter() - start


class _NonFiniteHessian(Exception):
    pass


#: Eisenstat-Walker "choice 2" constants (gamma, alpha), SIAM J. Sci. Comput. 17 (1996) 16-32.
_EW_GAMMA = 0.9
_EW_ALPHA = 2.0


def forcing_term(
    g_norm: float, g_norm_prev: float | None, eta_prev: float | None, eta_max: float
) -> float:
    """The relative residual an inexact linear solve of Newton iteration k may stop at.

    Eisenstat-Walker choice 2: ``eta_k = gamma (||g_k|| / ||g_{k-1}||)^alpha``, with the
    safeguard ``eta_k >= gamma eta_{k-1}^alpha`` when that is above 0.1 (it keeps eta from
    dropping while the gradient stalls), capped at ``eta_max``; the first iteration gets
    ``eta_max``. Loose solves far from the solution, tight ones as the gradient falls: the
    linear tolerance follows Newton's progress instead of being fixed. Dimensionless.
    """
    if g_norm_prev is None or eta_prev is None or not g_norm_prev > 0.0:
        return eta_max
    eta = _EW_GAMMA * (g_norm / g_norm_prev) ** _EW_ALPHA
    safeguard = _EW_GAMMA * eta_prev**_EW_ALPHA
    if safeguard > 0.1:
        eta = max(eta, safeguard)
    return min(eta, eta_max)


def _chord_increment(
    solver: LinearSolver, g_free: np.ndarray, timings: dict[str, float]
) -> np.ndarray | None:
    """The increment ``-H_old^{-1} g`` (free DOFs) with the last factorisation, or None.

    After a full Newton step the Hessian has changed by O(||p||); the back-solve costs a
    fraction of a factorisation and decides most convergence tests (a step that ends in one
    iteration otherwise pays two factorisations, measured on perf_3d: 2.9x the factorisation
    per Newton iteration).
    """
    again = getattr(solver, "solve_again", None)
    if again is None or g_free.size == 0:
        return None
    with _timed(timings, "solve"):
        p = again(-g_free)
    return None if p is None or not np.all(np.isfinite(p)) else np.asarray(p, dtype=np.float64)


#: The largest ratio of the chord increment to the last step for a chord step
#: (:func:`_chord_step_predicted_to_converge`).
_CHORD_STEP_MAX_RATIO = 0.05


def _chord_step_predicted_to_converge(p_chord: float, p_last: float, chord_tol: float) -> bool:
    """Whether a step along the chord increment is expected to end Newton at the next test.

    After a Newton step of size ``p_last`` from the point of the last factorisation, the chord
    iteration ``x+ = x - H_old^{-1} g(x)`` contracts at ``theta ~ ||H_old^{-1} (H - H_old)|| ~
    2 ||p_chord|| / p_last`` (Newton's error squares, e+ ~ (1/2) H^{-1} H' e^2, while the stale
    Hessian is off by H' p_last), so the chord increment after the step is about ``2 ||p_chord||^2
    / p_last``. The step is taken when twice that, ``4 ||p_chord||^2 / p_last``, is below the
    chord test's tolerance: then one back-solve and one line search replace a factorisation.

    It is also asked that the stale factorisation shrank the increment at least 20-fold
    (``p_chord <= 0.05 p_last``): the estimate holds in Newton's quadratic regime, not where
    the iterates creep at a linear rate (a chord step there tunnelled: design note
    ``measurements``, newton). All norms in the units of x.
    """
    if not (p_last > 0.0 and math.isfinite(p_last)):
        return False
    return (
        p_chord <= _CHORD_STEP_MAX_RATIO * p_last and 4.0 * p_chord * p_chord < chord_tol * p_last
    )


def _increment_norm(run: Any, p_free: np.ndarray) -> float:
    """The stopping rule's size of the increment on the free DOFs of ``run`` (the
    ``solvers.newton._Run`` of the call): ``objective.increment_norm`` or ||p||_inf."""
    norm = getattr(run.objective, "increment_norm", None)
    if norm is None:
        return float(np.abs(p_free).max()) if p_free.size else 0.0
    if run.free is None:
        return float(norm(p_free))
    p = np.zeros(run.n)
    p[run.free] = p_free
    return float(norm(p))


def _newton_direction(
    run: Any, x: np.ndarray, exact: bool, g_free: np.ndarray, rtol: float | None = None
) -> np.ndarray:
    """Assemble and solve ``H p = -g`` on the free DOFs with the exact (or per-stencil
    projected) Hessian, with the objective, linear solver, assembler, timings and result of
    ``run`` (the ``solvers.newton._Run`` of the call); ``rtol``: the relative residual an
    inexact solver may stop at (None: its own).

    The projected H is positive definite by construction (BFEMP sec. 5), and a failed
    factorisation is retried once with the rounding-level diagonal shift of
    :func:`solvers.linear.rounding_shift` (its floating-point sum can be indefinite by the
    rounding of a barrier block near ``d = 0``); a success counts in ``res.shifted_solves``, a
    second failure raises :class:`LinearSolveError` with both messages. The exact Hessian gets
    no retry (it may be indefinite for real).
    """
    solver, assembler, timings, res = run.solver, run.assembler, run.timings, run.res
    with _timed(timings, "hessian"):
        triplets = run.objective.hessian(x, psd=not exact)
    res.nhev += 1
    if not isinstance(triplets, Triplets):
        raise ValueError(f"objective.hessian must return Triplets, got {type(triplets)}")
    if not np.all(np.isfinite(triplets.vals)):
        raise _NonFiniteHessian
    rhs = -g_free
    try:
        with _timed(timings, "assemble"):
            matrix = assembler.assemble(triplets)
        timings["assemble"] -= assembler.last_pattern_s  # reported apart
        timings["pattern"] += assembler.last_pattern_s
        if rhs.size == 0:
            return np.zeros(0)
        kwargs = {"rtol": rtol} if rtol is not None else {}
        try:
            return _timed_solve(solver, matrix, rhs, assembler.pattern_version, timings, kwargs)
        except LinearSolveError as err:
            if exact:
                raise
            with _timed(timings, "assemble"):
                shift = rounding_shift(matrix)
                shifted, same = shift_diagonal(matrix, shift)
            version = assembler.pattern_version if same else None
            try:
                p = _timed_solve(solver, shifted, rhs, version, timings, kwargs)
            except LinearSolveError as err2:
                raise LinearSolveError(
                    f"{err}; again with the rounding shift ({ROUNDING_SHIFT_ULPS:g} eps x the "
                    f"row's absolute sum on the diagonal, at most {shift.max():.3e}): {err2}"
                ) from err2
            res.shifted_solves += 1
            res.max_shift = max(res.max_shift, float(shift.max()))
            logger.info(
                "newton: the projected Hessian's factorisation failed (%s); solved with the "
                "rounding-level diagonal shift (at most %.3e, %g eps x the row's absolute sum)",
                err,
                shift.max(),
                ROUNDING_SHIFT_ULPS,
            )
            return p
    finally:
        res.linear_iterations += int(getattr(solver, "last_iterations", 0) or 0)
