"""Projected Newton minimisation with a feasible backtracking line search (BFEMP Algorithm 2).

Each iteration at the iterate ``x`` (flattened DOFs, e.g. node positions in m):

1. ``g = grad E(x)`` and the proxy matrix ``H`` = sum of the per-stencil Hessians projected to
   PSD (``objective.hessian(x, psd=True)``), assembled with sparsity-pattern reuse;
2. ``H p = -g`` on the free DOFs (fixed DOFs are eliminated: ``p = 0`` there), solved with
   CHOLMOD whose symbolic analysis is reused while the pattern is unchanged; where the projected
   H (positive definite by construction) fails to factorise, once more with a rounding-level
   diagonal shift (:func:`solvers.linear.rounding_shift`; counted in ``shifted_solves``);
3. stop if ``||p||_inf / step_scale < tol`` (paper Sec. 5: with ``step_scale = dt`` the Newton
   increment as a velocity, in m/s, a second-order estimate of the distance to the solution);
   the test comes before the line search, so the returned ``x`` is the iterate where it held;
4. if ``g.p >= 0`` (possible only without PSD projection) take ``p = -g`` instead;
5. ``alpha0 = min(1, objective.max_step_size(x, p))`` (CCD / first ``det F = 0``; the paper's
   0.9 safety factor belongs to the objective) and Armijo backtracking from there.

After a full step (alpha = 1) the next iteration first tries the exact Hessian
(``NewtonOptions.exact_near_solution``): per-stencil projection changes the Hessian even where
the global one is positive definite, which would make the final convergence linear. If the exact
Hessian is not positive definite or gives no descent, projection is used for the rest of the solve.

Choices not fixed by the paper: the convergence test is repeated at the iterate reached after
``max_iter`` steps (so ``max_iter`` steps may still end ``CONVERGED``); a failed line search
calls ``objective.solution_changed(x)`` again so the objective's caches match the returned
``x``; a non-finite energy, gradient or Hessian at an accepted iterate ends the run with
``NON_FINITE``, while a non-finite trial energy just makes the line search backtrack.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Protocol

import numpy as np
import scipy.sparse as sp

from solvers.assembly import TripletAssembler, Triplets
from solvers.blas import serial_wheel_blas
from solvers.line_search import LineSearchResult, backtracking_line_search
from solvers.linear import (
    ROUNDING_SHIFT_ULPS,
    LinearSolveError,
    LinearSolver,
    default_linear_solver,
    rounding_shift,
    shift_diagonal,
)
from solvers.options import NewtonOptions
from solvers.result import NewtonIteration, NewtonResult, NewtonStatus

__all__ = ["Objective", "minimize"]

logger = logging.getLogger(__name__)


class Objective(Protocol):
    """The energy contract :func:`minimize` relies on (units: J for E, x in m typically).

    An optional attribute ``fixed_dofs: np.ndarray | None`` (bool mask (n,)) marks DOFs held at
    their ``x0`` value; it is read with ``getattr(objective, "fixed_dofs", None)``. An optional
    method ``increment_norm(p) -> float`` (p (n,), zero on fixed DOFs) replaces ``||p||_inf`` in
    the stopping rule (e.g. measured on what the unknowns move, not on the unknowns).
    """

    def solution_changed(self, x: np.ndarray) -> None:
        """Called once per new iterate x (n,) (line-search trials too), before value/gradient/
        hessian at that x: refresh x-dependent caches."""
        ...

    def value(self, x: np.ndarray) -> float:
        """Energy E(x); may be inf outside the feasible set."""
        ...

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dE/dx (n,)."""
        ...

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets:
        """d2E/dx2 as COO triplets (full symmetric), per-stencil PSD-projected when ``psd``."""
        ...

    def max_step_size(self, x: np.ndarray, p: np.ndarray) -> float:
        """Largest feasible step along p (n,) from x: a value in (0, 1], or larger."""
        ...


@contextmanager
def _timed(timings: dict[str, float], key: str) -> Iterator[None]:
    start = time.perf_counter()
    try:
        yield
    finally:
        timings[key] += time.perf_counter() - start


def _check_x0(x0: np.ndarray) -> np.ndarray:
    x = np.array(x0, dtype=np.float64, order="C", copy=True)
    if x.ndim != 1:
        raise ValueError(f"x0 must be 1-D (n,), got shape {x.shape}")
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        raise ValueError(f"x0 has non-finite entries at indices {bad[:10].tolist()}")
    return x


def _free_mask(objective: Objective, n: int) -> np.ndarray | None:
    fixed = getattr(objective, "fixed_dofs", None)
    if fixed is None:
        return None
    fixed = np.asarray(fixed)
    if fixed.dtype != np.bool_ or fixed.shape != (n,):
        raise ValueError(
            f"objective.fixed_dofs must be a bool mask of shape ({n},), "
            f"got dtype {fixed.dtype} and shape {fixed.shape}"
        )
    return None if not fixed.any() else ~fixed


def _solve(
    solver: LinearSolver,
    assembler: TripletAssembler,
    triplets: Triplets,
    rhs: np.ndarray,
    timings: dict[str, float],
    rtol: float | None = None,
    res: NewtonResult | None = None,
) -> np.ndarray:
    """Assemble and solve ``H p = rhs`` on the free DOFs.

    ``res`` given: H is PSD-projected, positive definite by construction (BFEMP sec. 5), and a
    failed factorisation is retried once with the rounding-level diagonal shift of
    :func:`solvers.linear.rounding_shift` (its floating-point sum can be indefinite by the
    rounding of a barrier block near ``d = 0``); a success counts in ``res.shifted_solves``, a
    second failure raises :class:`LinearSolveError` with both messages. ``res`` None: no retry
    (the exact Hessian may be indefinite for real).
    """
    with _timed(timings, "assemble"):
        matrix = assembler.assemble(triplets)
    if rhs.size == 0:
        return np.zeros(0)
    kwargs = {"rtol": rtol} if rtol is not None else {}
    try:
        return _timed_solve(solver, matrix, rhs, assembler.pattern_version, timings, kwargs)
    except LinearSolveError as err:
        if res is None:
            raise
        with _timed(timings, "assemble"):
            shift = rounding_shift(matrix)
            shifted, same = shift_diagonal(matrix, shift)
        version = assembler.pattern_version if same else None
        try:
            p = _timed_solve(solver, shifted, rhs, version, timings, kwargs)
        except LinearSolveError as err2:
            raise LinearSolveError(
                f"{err}; again with the rounding shift ({ROUNDING_SHIFT_ULPS:g} eps x the row's "
                f"absolute sum on the diagonal, at most {shift.max():.3e}): {err2}"
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


#: Energy changes below this many machine epsilons of |E| are round-off (terms cancel).
_ROUND_OFF_ULPS = 1e4


def _accept_near_solution(
    objective: Objective,
    x: np.ndarray,
    p: np.ndarray,
    alpha0: float,
    energy: float,
    slope: float,
    near: bool,
    g_free: np.ndarray,
    free: np.ndarray | None,
    res: NewtonResult,
    g_best: float = math.inf,
) -> LineSearchResult | None:
    """Accept ``x + alpha0 p`` on a falling gradient norm where the energy cannot judge the step.

    Close to a minimiser a Newton step predicts an energy decrease ~ |g.p| that can be smaller
    than the round-off of E (the terms of E are evaluated with errors ~ eps times their own
    scale, e.g. eps mu V for elasticity, much larger than eps |E|). Armijo then rejects good steps
    or accepts tiny noisy ones and the iteration stalls. In that regime - the increment within
    ``NewtonOptions.near_solution_factor`` of the tolerance (``near``), or |g.p| below
    ``_ROUND_OFF_ULPS`` eps |E| - the full step is taken when the gradient norm falls below
    both its value at x and ``g_best``, the least norm of the iterates so far; otherwise None
    (use Armijo). Without ``g_best`` two iterates can take turns (measured, frictional
    ``buckling`` at dt = 2e-2 s: A -> B on B's smaller gradient while E rose by 1.4e-6 J,
    B -> A by Armijo, 500 times over).
    """
    round_off = abs(slope) * alpha0 <= _ROUND_OFF_ULPS * np.finfo(float).eps * abs(energy)
    if not (near or round_off):
        return None
    trial = x + alpha0 * p
    objective.solution_changed(trial)
    fun = float(objective.value(trial))
    grad = np.asarray(objective.gradient(trial), dtype=np.float64)
    res.njev += 1
    g_trial = grad if free is None else grad[free]
    if not (math.isfinite(fun) and np.all(np.isfinite(g_trial))):
        return None
    if np.linalg.norm(g_trial) >= min(float(np.linalg.norm(g_free)), g_best):
        return None
    logger.debug("newton: near the solution, full step accepted on the gradient norm")
    return LineSearchResult(success=True, alpha=alpha0, x=trial, fun=fun, nfev=1, n_nonfinite=0)


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
    Measured on perf_fem 2D (chord tolerance 2.5e-7 m): after a step of 4.50e-4 m the chord
    increment was 3.34e-6 m and the one after the chord step 1.29e-7 m (the estimate 5.0e-8).

    It is also asked that the stale factorisation shrank the increment at least 20-fold
    (``p_chord <= 0.05 p_last``): the estimate holds in Newton's quadratic regime, not where
    the iterates creep at a linear rate. In the head-on disks of ``tests/bfemp/
    test_intersection.py`` (dt = 0.5 s) increments fell 0.07-fold per iteration; a chord step
    there at ratio 0.21 sent the solve along another path to an end state the step's
    straight-line motion reaches only through the other disk (TUNNELED). All norms in the
    units of x.
    """
    if not (p_last > 0.0 and math.isfinite(p_last)):
        return False
    return (
        p_chord <= _CHORD_STEP_MAX_RATIO * p_last and 4.0 * p_chord * p_chord < chord_tol * p_last
    )


def _increment_norm(
    objective: Objective, p_free: np.ndarray, free: np.ndarray | None, n: int
) -> float:
    """The stopping rule's size of the increment: ``objective.increment_norm`` or ||p||_inf."""
    norm = getattr(objective, "increment_norm", None)
    if norm is None:
        return float(np.abs(p_free).max()) if p_free.size else 0.0
    if free is None:
        return float(norm(p_free))
    p = np.zeros(n)
    p[free] = p_free
    return float(norm(p))


def _newton_direction(
    objective: Objective,
    x: np.ndarray,
    exact: bool,
    solver: LinearSolver,
    assembler: TripletAssembler,
    g_free: np.ndarray,
    timings: dict[str, float],
    res: NewtonResult,
    rtol: float | None = None,
) -> np.ndarray:
    """Solve ``H p = -g`` on the free DOFs with the exact (or per-stencil projected) Hessian;
    ``rtol``: the relative residual an inexact solver may stop at (None: its own). A projected
    Hessian that fails to factorise is retried with the rounding shift (:func:`_solve`)."""
    with _timed(timings, "hessian"):
        triplets = objective.hessian(x, psd=not exact)
    res.nhev += 1
    if not isinstance(triplets, Triplets):
        raise ValueError(f"objective.hessian must return Triplets, got {type(triplets)}")
    if not np.all(np.isfinite(triplets.vals)):
        raise _NonFiniteHessian
    try:
        return _solve(solver, assembler, triplets, -g_free, timings, rtol, None if exact else res)
    finally:
        res.linear_iterations += int(getattr(solver, "last_iterations", 0) or 0)


def minimize(
    objective: Objective,
    x0: np.ndarray,
    *,
    options: NewtonOptions | None = None,
    linear_solver: LinearSolver | None = None,
    callback: Callable[[NewtonIteration], bool | None] | None = None,
    assembler: TripletAssembler | None = None,
) -> NewtonResult:
    """Minimise ``objective`` from ``x0`` with projected Newton and a feasible line search.

    Args:
        objective: implements :class:`Objective` (optionally ``fixed_dofs``).
        x0: initial guess (n,), finite, in the units of the unknowns (m for positions); it is
            feasible (finite energy) for a meaningful run and is not modified.
        options: solver options (defaults: ``NewtonOptions()``).
        linear_solver: SPD solver; default :func:`solvers.linear.default_linear_solver`. Pass
            the same instance across calls to keep its symbolic factorisation.
        callback: called after each accepted iterate with a :class:`NewtonIteration`;
            returning True or raising StopIteration stops with ``CALLBACK_STOP``.
        assembler: a :class:`TripletAssembler` kept by the caller across calls (time steps),
            used when it fits (``assembler.fits(n, free)``): its pattern is then not rebuilt
            while the Hessian's pattern is unchanged (an ``np.unique`` over all triplets,
            measured: 0.04-0.2 s per step on the perf_fem meshes, about one factorisation).

    Returns:
        :class:`NewtonResult`; ``success`` is False, with ``status`` and ``message`` saying
        why, on every failure.

    Meanwhile numpy's and scipy's own BLAS runs on one thread
    (:func:`solvers.blas.serial_wheel_blas`): its idle threads otherwise spin beside CHOLMOD's,
    which made the back-solve after every gradient 8x slower (issue 13).
    """
    with serial_wheel_blas():
        return _minimize(
            objective,
            x0,
            options=options,
            linear_solver=linear_solver,
            callback=callback,
            assembler=assembler,
        )


def _minimize(
    objective: Objective,
    x0: np.ndarray,
    *,
    options: NewtonOptions | None,
    linear_solver: LinearSolver | None,
    callback: Callable[[NewtonIteration], bool | None] | None,
    assembler: TripletAssembler | None,
) -> NewtonResult:
    """:func:`minimize` itself (the same arguments), with the BLAS pools already set."""
    t_start = time.perf_counter()
    if options is None:
        options = NewtonOptions()
    elif not isinstance(options, NewtonOptions):
        raise ValueError(f"options must be NewtonOptions, got {type(options).__name__}")
    x = _check_x0(x0)
    n = x.size
    free = _free_mask(objective, n)
    solver = default_linear_solver() if linear_solver is None else linear_solver
    if assembler is None or not assembler.fits(n, free):
        assembler = TripletAssembler(n, free=free)
    res = NewtonResult(x=x, success=False, status=NewtonStatus.MAX_ITERATIONS, message="")
    timings = res.timings

    def finish(status: NewtonStatus, detail: str) -> NewtonResult:
        res.status = status
        res.success = status == NewtonStatus.CONVERGED
        res.message = f"{status.description}: {detail}"
        timings["total"] = time.perf_counter() - t_start
        log = logger.debug if res.success else logger.info
        log("newton %s after %d iterations (%s)", status.name, res.nit, detail)
        return res

    with _timed(timings, "line_search"):
        objective.solution_changed(x)
        energy = float(objective.value(x))
    res.nfev += 1
    res.fun = energy
    if not math.isfinite(energy):
        return finish(NewtonStatus.NON_FINITE, f"energy at x0 is {energy}")

    try_exact = exact_failed = False
    # An inexact solver (CG) stops at the forcing term eta_k, tied to Newton's progress.
    inexact = bool(getattr(solver, "accepts_rtol", False))
    g_norm_prev = eta = None
    g_best = math.inf  # the least gradient norm of the iterates so far (_accept_near_solution)
    chord_ready = False  # the last factorisation is this solve's, and its step was full
    factor_stepped = False  # the last factorisation has already made a chord step
    last_p_inf = math.inf  # the increment of the last accepted step
    while True:
        with _timed(timings, "gradient"):
            grad = np.asarray(objective.gradient(x), dtype=np.float64)
        res.njev += 1
        if grad.shape != (n,):
            raise ValueError(f"objective.gradient returned shape {grad.shape}, expected ({n},)")
        res.jac = grad
        g_free = grad if free is None else grad[free]
        if not np.all(np.isfinite(g_free)):
            return finish(NewtonStatus.NON_FINITE, f"non-finite gradient at iteration {res.nit}")
        g_best = min(g_best, float(np.linalg.norm(g_free)))
        chord_step = False
        if chord_ready and options.chord_stop_factor > 0.0:
            p_chord = _chord_increment(solver, g_free, timings)
            if p_chord is not None:
                p_inf = _increment_norm(objective, p_chord, free, n)
                if p_inf / options.step_scale < options.chord_stop_factor * options.tol:
                    res.step_inf_norm = p_inf
                    return finish(
                        NewtonStatus.CONVERGED,
                        f"chord test: ||p||_inf / step_scale = {p_inf / options.step_scale:.3e}"
                        f" < {options.chord_stop_factor:g} tol = {options.tol:.3e} with the last"
                        f" factorisation, E = {energy:.10e}",
                    )
                chord_step = (
                    options.chord_steps
                    and not factor_stepped
                    and _chord_step_predicted_to_converge(
                        p_inf,
                        last_p_inf,
                        options.chord_stop_factor * options.tol * options.step_scale,
                    )
                )
                if chord_step:
                    # one back-solve instead of a factorisation; the chord test decides next
                    p_free, factor_stepped = p_chord, True
                    res.step_inf_norm = p_inf
                    res.chord_steps += 1
                    logger.debug("newton it %d: chord step, ||p||_inf = %.3e", res.nit, p_inf)
        if not chord_step:
            factor_stepped = False  # a new factorisation: it may make one chord step
            rtol = None
            if inexact:
                g_norm = float(np.linalg.norm(g_free))
                eta = forcing_term(g_norm, g_norm_prev, eta, options.linear_rtol_max)
                g_norm_prev, rtol = g_norm, eta
            exact = try_exact and not exact_failed
            try:
                p_free = _newton_direction(
                    objective,
                    x,
                    exact or not options.project_psd,
                    solver,
                    assembler,
                    g_free,
                    timings,
                    res,
                    rtol,
                )
                if exact and not float(g_free @ p_free) < 0.0:
                    raise LinearSolveError("exact Hessian gives no descent direction")
            except LinearSolveError as err:
                if not exact:
                    return finish(NewtonStatus.LINEAR_SOLVE_FAILED, f"{err} (iteration {res.nit})")
                # The exact Hessian is indefinite here: projected Newton for the rest of the solve.
                logger.debug("newton it %d: exact Hessian rejected (%s), projecting", res.nit, err)
                exact_failed = True
                try:
                    p_free = _newton_direction(
                        objective, x, False, solver, assembler, g_free, timings, res, rtol
                    )
                except LinearSolveError as err2:
                    return finish(NewtonStatus.LINEAR_SOLVE_FAILED, f"{err2} (iteration {res.nit})")
            except _NonFiniteHessian:
                return finish(NewtonStatus.NON_FINITE, f"non-finite Hessian at iteration {res.nit}")
            if not np.all(np.isfinite(p_free)):
                return finish(
                    NewtonStatus.LINEAR_SOLVE_FAILED,
                    f"non-finite Newton step at iteration {res.nit}",
                )
            p_inf = _increment_norm(objective, p_free, free, n)
            if rtol is not None and p_inf / options.step_scale < options.tol:
                # The increment that decides convergence is solved to the solver's own tolerance,
                # so that an inexact solve never stops Newton early.
                try:
                    p_free = _newton_direction(
                        objective,
                        x,
                        (exact and not exact_failed) or not options.project_psd,
                        solver,
                        assembler,
                        g_free,
                        timings,
                        res,
                    )
                except LinearSolveError as err:
                    return finish(NewtonStatus.LINEAR_SOLVE_FAILED, f"{err} (iteration {res.nit})")
                p_inf = _increment_norm(objective, p_free, free, n)
            res.step_inf_norm = p_inf
            if p_inf / options.step_scale < options.tol:
                return finish(
                    NewtonStatus.CONVERGED,
                    f"||p||_inf / step_scale = {p_inf / options.step_scale:.3e} < tol = "
                    f"{options.tol:.3e}, E = {energy:.10e}",
                )
        if res.nit >= options.max_iter:
            return finish(
                NewtonStatus.MAX_ITERATIONS,
                f"max_iter = {options.max_iter}, ||p||_inf / step_scale = "
                f"{p_inf / options.step_scale:.3e} >= tol = {options.tol:.3e}",
            )

        slope = float(g_free @ p_free)
        if not slope < 0.0:
            # H not positive definite (no projection): fall back to steepest descent.
            logger.debug("newton it %d: g.p = %.3e >= 0, using -g", res.nit, slope)
            p_free = -g_free
            slope = -float(g_free @ g_free)
            if not slope < 0.0:
                return finish(
                    NewtonStatus.LINE_SEARCH_STALLED,
                    f"no descent direction: zero gradient but ||p||_inf = {p_inf:.3e}",
                )
        if free is None:
            p = p_free
        else:
            p = np.zeros(n)
            p[free] = p_free
        with _timed(timings, "step_bound"):
            bound = float(objective.max_step_size(x, p))
        if not bound > 0.0:
            return finish(
                NewtonStatus.LINE_SEARCH_STALLED,
                f"max_step_size returned {bound} at iteration {res.nit} (no feasible step)",
            )
        alpha0 = min(1.0, bound)
        with _timed(timings, "line_search"):
            near = p_inf <= options.near_solution_factor * options.tol * options.step_scale
            search = _accept_near_solution(
                objective, x, p, alpha0, energy, slope, near, g_free, free, res, g_best
            )
            if search is None:
                search = backtracking_line_search(
                    objective,
                    x,
                    p,
                    energy,
                    slope,
                    alpha0,
                    armijo_c=options.armijo_c,
                    backtrack_factor=options.backtrack_factor,
                    min_step=options.min_step,
                )
        res.nfev += search.nfev
        if not search.success:
            # Armijo found no decrease: where the energy is at round-off (stiff materials, tight
            # tolerances) the full step may still be good; judge it by the gradient norm.
            rescue = _accept_near_solution(
                objective, x, p, alpha0, energy, slope, True, g_free, free, res
            )
            if rescue is not None:
                search = rescue
        if not search.success:
            objective.solution_changed(x)
            return finish(
                NewtonStatus.LINE_SEARCH_STALLED,
                f"alpha = {search.alpha:.3e} < min_step = {options.min_step:.3e} at iteration "
                f"{res.nit} with ||p||_inf = {p_inf:.3e}, alpha0 = {alpha0:.3e}, "
                f"E = {energy:.10e}, g.p = {slope:.3e}, {search.n_nonfinite} non-finite trial(s)",
            )
        x = search.x
        energy = search.fun
        last_p_inf = p_inf * search.alpha
        res.nit += 1
        try_exact = options.project_psd and options.exact_near_solution and search.alpha == 1.0
        chord_ready = search.alpha == 1.0
        res.alphas.append(search.alpha)
        res.x = x
        res.fun = energy
        res.jac = None
        logger.debug(
            "newton it %d: E = %.12e, ||p||_inf = %.3e, alpha = %.3e (alpha0 = %.3e, %d trials)",
            res.nit,
            energy,
            p_inf,
            search.alpha,
            alpha0,
            search.nfev,
        )
        if callback is not None:
            info = NewtonIteration(x.copy(), energy, res.nit, p_inf, search.alpha)
            try:
                stop = bool(callback(info))
            except StopIteration:
                stop = True
            if stop:
                return finish(NewtonStatus.CALLBACK_STOP, f"at iteration {res.nit}")
