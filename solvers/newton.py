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
from collections.abc import Callable

import numpy as np

from solvers._linear_base import LinearSolveError
from solvers._newton_direction import (
    _chord_increment,
    _chord_step_predicted_to_converge,
    _increment_norm,
    _newton_direction,
    _NonFiniteHessian,
    _timed,
    forcing_term,
)
from solvers.assembly import TripletAssembler
from solvers.blas import serial_wheel_blas
from solvers.line_search import LineSearchResult, backtracking_line_search
from solvers.linear import LinearSolver, default_linear_solver
from solvers.objective import Objective
from solvers.options import NewtonOptions
from solvers.result import NewtonIteration, NewtonResult, NewtonStatus

__all__ = ["Objective", "forcing_term", "minimize"]

logger = logging.getLogger(__name__)


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


#: Energy changes below this many machine epsilons of |E| are round-off (terms cancel).
_ROUND_OFF_ULPS = 1e4


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
        t_start = time.perf_counter()
        if options is None:
            options = NewtonOptions()
        elif not isinstance(options, NewtonOptions):
            raise ValueError(f"options must be NewtonOptions, got {type(options).__name__}")
        x = _check_x0(x0)
        free = _free_mask(objective, x.size)
        solver = default_linear_solver() if linear_solver is None else linear_solver
        if assembler is None or not assembler.fits(x.size, free):
            assembler = TripletAssembler(x.size, free=free)
        res = NewtonResult(x=x, success=False, status=NewtonStatus.MAX_ITERATIONS, message="")
        run = _Run(objective, options, solver, assembler, free, res)
        try:
            with _timed(res.timings, "line_search"):
                objective.solution_changed(x)
                energy = float(objective.value(x))
            res.nfev += 1
            res.fun = energy
            if not math.isfinite(energy):
                raise _Finish(NewtonStatus.NON_FINITE, f"energy at x0 is {energy}")
            while True:
                g_free = run.gradient(x)
                p_free, p_inf = run.chord_step(g_free, energy) or run.newton_step(x, g_free, energy)
                if res.nit >= options.max_iter:
                    raise _Finish(
                        NewtonStatus.MAX_ITERATIONS,
                        f"max_iter = {options.max_iter}, ||p||_inf / step_scale = "
                        f"{p_inf / options.step_scale:.3e} >= tol = {options.tol:.3e}",
                    )
                search, alpha0 = run.line_search(x, energy, g_free, p_free, p_inf)
                x, energy = search.x, search.fun
                run.accept(search, p_inf, alpha0)
                if callback is not None and _callback_stops(
                    callback, NewtonIteration(x.copy(), energy, res.nit, p_inf, search.alpha)
                ):
                    raise _Finish(NewtonStatus.CALLBACK_STOP, f"at iteration {res.nit}")
        except _Finish as end:
            res.status = end.status
            res.success = end.status == NewtonStatus.CONVERGED
            res.message = f"{end.status.description}: {end.detail}"
            res.timings["total"] = time.perf_counter() - t_start
            log = logger.debug if res.success else logger.info
            log("newton %s after %d iterations (%s)", end.status.name, res.nit, end.detail)
            return res


def _callback_stops(
    callback: Callable[[NewtonIteration], bool | None], info: NewtonIteration
) -> bool:
    """Whether the user's callback asks to stop (returns True or raises StopIteration)."""
    try:
        return bool(callback(info))
    except StopIteration:
        return True


class _Finish(Exception):
    """Ends :func:`minimize` with ``status``; ``detail`` completes the message."""

    def __init__(self, status: NewtonStatus, detail: str) -> None:
        super().__init__(detail)
        self.status = status
        self.detail = detail


class _Run:
    """One call of :func:`minimize`: its inputs and what the iterations carry.

    Each phase of an iteration is a method: :meth:`gradient`, then :meth:`chord_step` (a step
    with the last factorisation) or :meth:`newton_step` (a new one), :meth:`line_search` and
    :meth:`accept`. A phase that ends the run raises :class:`_Finish`.
    """

    def __init__(
        self,
        objective: Objective,
        options: NewtonOptions,
        solver: LinearSolver,
        assembler: TripletAssembler,
        free: np.ndarray | None,
        res: NewtonResult,
    ) -> None:
        self.objective, self.options, self.solver = objective, options, solver
        self.assembler, self.free, self.res = assembler, free, res
        self.n = res.x.size
        self.timings = res.timings
        self.try_exact = self.exact_failed = False
        # An inexact solver (CG) stops at the forcing term eta_k, tied to Newton's progress.
        self.inexact = bool(getattr(solver, "accepts_rtol", False))
        self.g_norm_prev: float | None = None
        self.eta: float | None = None
        self.g_best = math.inf  # the least gradient norm of the iterates so far
        self.chord_ready = False  # the last factorisation is this solve's, its step was full
        self.factor_stepped = False  # the last factorisation has already made a chord step
        self.last_p_inf = math.inf  # the increment of the last accepted step

    def near_solution_step(
        self,
        x: np.ndarray,
        p: np.ndarray,
        alpha0: float,
        energy: float,
        slope: float,
        near: bool,
        g_free: np.ndarray,
        g_best: float = math.inf,
    ) -> LineSearchResult | None:
        """Accept ``x + alpha0 p`` on a falling gradient norm where the energy cannot judge it.

        Close to a minimiser a Newton step predicts an energy decrease ~ |g.p| that can be
        smaller than the round-off of E (the terms of E are evaluated with errors ~ eps times
        their own scale, e.g. eps mu V for elasticity, much larger than eps |E|). Armijo then
        rejects good steps or accepts tiny noisy ones and the iteration stalls. In that regime -
        the increment within ``NewtonOptions.near_solution_factor`` of the tolerance (``near``),
        or |g.p| below ``_ROUND_OFF_ULPS`` eps |E| - the full step is taken when the gradient
        norm falls below both its value at x and ``g_best``, the least norm of the iterates so
        far; otherwise None (use Armijo). Without ``g_best`` two iterates can take turns (design
        note ``measurements``, newton).
        """
        round_off = abs(slope) * alpha0 <= _ROUND_OFF_ULPS * np.finfo(float).eps * abs(energy)
        if not (near or round_off):
            return None
        trial = x + alpha0 * p
        self.objective.solution_changed(trial)
        fun = float(self.objective.value(trial))
        grad = np.asarray(self.objective.gradient(trial), dtype=np.float64)
        self.res.njev += 1
        g_trial = grad if self.free is None else grad[self.free]
        if not (math.isfinite(fun) and np.all(np.isfinite(g_trial))):
            return None
        if np.linalg.norm(g_trial) >= min(float(np.linalg.norm(g_free)), g_best):
            return None
        logger.debug("newton: near the solution, full step accepted on the gradient norm")
        return LineSearchResult(success=True, alpha=alpha0, x=trial, fun=fun, nfev=1, n_nonfinite=0)

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """The gradient on the free DOFs at x (checked finite)."""
        res = self.res
        with _timed(self.timings, "gradient"):
            grad = np.asarray(self.objective.gradient(x), dtype=np.float64)
        res.njev += 1
        if grad.shape != (self.n,):
            raise ValueError(
                f"objective.gradient returned shape {grad.shape}, expected ({self.n},)"
            )
        res.jac = grad
        g_free = grad if self.free is None else grad[self.free]
        if not np.all(np.isfinite(g_free)):
            raise _Finish(NewtonStatus.NON_FINITE, f"non-finite gradient at iteration {res.nit}")
        self.g_best = min(self.g_best, float(np.linalg.norm(g_free)))
        return g_free

    def chord_step(self, g_free: np.ndarray, energy: float) -> tuple[np.ndarray, float] | None:
        """The chord test with the last factorisation, and ``(p_free, p_inf)`` of a chord step
        where one is predicted to converge; None: a new factorisation is needed."""
        o, res = self.options, self.res
        if not (self.chord_ready and o.chord_stop_factor > 0.0):
            return None
        p_chord = _chord_increment(self.solver, g_free, self.timings)
        if p_chord is None:
            return None
        p_inf = _increment_norm(self, p_chord)
        if p_inf / o.step_scale < o.chord_stop_factor * o.tol:
            res.step_inf_norm = p_inf
            raise _Finish(
                NewtonStatus.CONVERGED,
                f"chord test: ||p||_inf / step_scale = {p_inf / o.step_scale:.3e}"
                f" < {o.chord_stop_factor:g} tol = {o.tol:.3e} with the last"
                f" factorisation, E = {energy:.10e}",
            )
        chord_tol = o.chord_stop_factor * o.tol * o.step_scale
        if not (
            o.chord_steps
            and not self.factor_stepped
            and _chord_step_predicted_to_converge(p_inf, self.last_p_inf, chord_tol)
        ):
            return None
        # one back-solve instead of a factorisation; the chord test decides next
        self.factor_stepped = True
        res.step_inf_norm = p_inf
        res.chord_steps += 1
        logger.debug("newton it %d: chord step, ||p||_inf = %.3e", res.nit, p_inf)
        return p_chord, p_inf

    def _direction(
        self,
        x: np.ndarray,
        exact: bool,
        g_free: np.ndarray,
        rtol: float | None,
        finish: bool = True,
    ) -> np.ndarray:
        """``_newton_direction``; a failed solve ends the run too unless ``finish`` is False."""
        try:
            return _newton_direction(self, x, exact, g_free, rtol)
        except _NonFiniteHessian:
            raise _Finish(
                NewtonStatus.NON_FINITE, f"non-finite Hessian at iteration {self.res.nit}"
            ) from None
        except LinearSolveError as err:
            if not finish:
                raise
            raise _Finish(
                NewtonStatus.LINEAR_SOLVE_FAILED, f"{err} (iteration {self.res.nit})"
            ) from err

    def newton_step(self, x: np.ndarray, g_free: np.ndarray, energy: float) -> tuple:
        """``(p_free, p_inf)`` of a new factorisation (exact Hessian after a full step while it
        gives descent, else projected); ends the run when the increment meets the tolerance."""
        o, res = self.options, self.res
        self.factor_stepped = False  # a new factorisation: it may make one chord step
        rtol = None
        if self.inexact:
            g_norm = float(np.linalg.norm(g_free))
            self.eta = forcing_term(g_norm, self.g_norm_prev, self.eta, o.linear_rtol_max)
            self.g_norm_prev, rtol = g_norm, self.eta
        exact = self.try_exact and not self.exact_failed
        try:  # a projected Hessian's failed solve ends the run (``_direction``)
            p_free = self._direction(x, exact or not o.project_psd, g_free, rtol, not exact)
            if exact and not float(g_free @ p_free) < 0.0:
                raise LinearSolveError("exact Hessian gives no descent direction")
        except LinearSolveError as err:
            # The exact Hessian is indefinite here: projected Newton for the rest of the solve.
            logger.debug("newton it %d: exact Hessian rejected (%s), projecting", res.nit, err)
            self.exact_failed = True
            p_free = self._direction(x, False, g_free, rtol)
        if not np.all(np.isfinite(p_free)):
            raise _Finish(
                NewtonStatus.LINEAR_SOLVE_FAILED, f"non-finite Newton step at iteration {res.nit}"
            )
        p_inf = _increment_norm(self, p_free)
        if rtol is not None and p_inf / o.step_scale < o.tol:
            # The increment that decides convergence is solved to the solver's own tolerance,
            # so that an inexact solve never stops Newton early.
            exact = (exact and not self.exact_failed) or not o.project_psd
            p_free = self._direction(x, exact, g_free, None)
            p_inf = _increment_norm(self, p_free)
        res.step_inf_norm = p_inf
        if p_inf / o.step_scale < o.tol:
            raise _Finish(
                NewtonStatus.CONVERGED,
                f"||p||_inf / step_scale = {p_inf / o.step_scale:.3e} < tol = "
                f"{o.tol:.3e}, E = {energy:.10e}",
            )
        return p_free, p_inf

    def line_search(
        self, x: np.ndarray, energy: float, g_free: np.ndarray, p_free: np.ndarray, p_inf: float
    ) -> tuple[LineSearchResult, float]:
        """The accepted trial along p (steepest descent where p is no descent direction) and
        the first step length ``alpha0`` (BFEMP Algorithm 2: the objective's feasible bound)."""
        o, res, objective, free = self.options, self.res, self.objective, self.free
        slope = float(g_free @ p_free)
        if not slope < 0.0:
            # H not positive definite (no projection): fall back to steepest descent.
            logger.debug("newton it %d: g.p = %.3e >= 0, using -g", res.nit, slope)
            p_free = -g_free
            slope = -float(g_free @ g_free)
            if not slope < 0.0:
                raise _Finish(
                    NewtonStatus.LINE_SEARCH_STALLED,
                    f"no descent direction: zero gradient but ||p||_inf = {p_inf:.3e}",
                )
        if free is None:
            p = p_free
        else:
            p = np.zeros(self.n)
            p[free] = p_free
        with _timed(self.timings, "step_bound"):
            bound = float(objective.max_step_size(x, p))
        if not bound > 0.0:
            raise _Finish(
                NewtonStatus.LINE_SEARCH_STALLED,
                f"max_step_size returned {bound} at iteration {res.nit} (no feasible step)",
            )
        alpha0 = min(1.0, bound)
        with _timed(self.timings, "line_search"):
            near = p_inf <= o.near_solution_factor * o.tol * o.step_scale
            search = self.near_solution_step(x, p, alpha0, energy, slope, near, g_free, self.g_best)
            if search is None:
                search = backtracking_line_search(
                    objective,
                    x,
                    p,
                    energy,
                    slope,
                    alpha0,
                    armijo_c=o.armijo_c,
                    backtrack_factor=o.backtrack_factor,
                    min_step=o.min_step,
                )
        res.nfev += search.nfev
        if not search.success:
            # Armijo found no decrease: where the energy is at round-off (stiff materials, tight
            # tolerances) the full step may still be good; judge it by the gradient norm.
            rescue = self.near_solution_step(x, p, alpha0, energy, slope, True, g_free)
            if rescue is not None:
                search = rescue
        if not search.success:
            objective.solution_changed(x)
            raise _Finish(
                NewtonStatus.LINE_SEARCH_STALLED,
                f"alpha = {search.alpha:.3e} < min_step = {o.min_step:.3e} at iteration "
                f"{res.nit} with ||p||_inf = {p_inf:.3e}, alpha0 = {alpha0:.3e}, "
                f"E = {energy:.10e}, g.p = {slope:.3e}, {search.n_nonfinite} non-finite trial(s)",
            )
        return search, alpha0

    def accept(self, search: LineSearchResult, p_inf: float, alpha0: float) -> None:
        """Take the line search's trial as the next iterate."""
        o, res = self.options, self.res
        self.last_p_inf = p_inf * search.alpha
        res.nit += 1
        self.try_exact = o.project_psd and o.exact_near_solution and search.alpha == 1.0
        self.chord_ready = search.alpha == 1.0
        res.alphas.append(search.alpha)
        res.x = search.x
        res.fun = search.fun
        res.jac = None
        logger.debug(
            "newton it %d: E = %.12e, ||p||_inf = %.3e, alpha = %.3e (alpha0 = %.3e, %d trials)",
            res.nit,
            search.fun,
            p_inf,
            search.alpha,
            alpha0,
            search.nfev,
        )
